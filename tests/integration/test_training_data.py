"""Training and calibration data are disjoint from every evaluation suite (seeds and schedules), and
the shipped models carry the settings the documentation reports."""

from __future__ import annotations

import json

import pytest
import yaml

pytest.importorskip("torch")

from marine_fdi_env.benchmark.suites import SUITE_NAMES, load_suite  # noqa: E402
from marine_fdi_env.training.train import dataset_scenarios  # noqa: E402
from tests.paths import ROOT

HYPERPARAMS = ROOT / "training" / "hyperparams"
MODELS = ROOT / "training" / "models"


def _specs() -> dict[str, dict]:
    """Every dataset a training command simulates: name -> spec (for each training seed 0-2 where the
    entry moves its data with the seed)."""
    from marine_fdi_env.training.train import training_specs

    out = {}
    for f in sorted(HYPERPARAMS.glob("*.yml")):
        for env_id, hp in yaml.safe_load(f.read_text()).items():
            if "datasets" not in hp:
                continue
            for seed in (0, 1, 2) if hp.get("data_seed_stride") else (0,):
                data, cal, iso = training_specs(hp, seed)
                for k, spec in enumerate(data):
                    out[f"{f.stem}/{env_id}/s{seed}/data{k}"] = spec
                for kind, spec in (("calibration", cal), ("isolation_calibration", iso)):
                    if spec is not None:
                        out[f"{f.stem}/{env_id}/s{seed}/{kind}"] = spec
    return out


def _schedule(sc) -> tuple:
    return tuple((f.fault_id, round(f.onset_s, 6), f.magnitude, f.kind) for f in sc.faults)


@pytest.fixture(scope="module")
def suites():
    return {name: load_suite(name).scenarios for name in SUITE_NAMES}


def test_training_and_calibration_data_are_disjoint_from_every_suite(suites):
    """No training or calibration episode shares its sensor-noise stream with a suite episode, and no
    faulty one its fault schedule (ids, onsets, magnitudes); fault-free episodes of the one-parameter
    manoeuvring profile can share a profile with a suite episode, never its noise."""
    specs = _specs()
    assert any("classifier" in k and "calibration" in k for k in specs) and any("MarineFDI-v1" in k for k in specs)
    suite_noise = {s.noise_seed: name for name, scs in suites.items() for s in scs}
    suite_sched = {_schedule(s): name for name, scs in suites.items() for s in scs if s.faults}
    seen: dict[int, str] = {}
    for name, spec in specs.items():
        for sc in dataset_scenarios(spec):
            assert sc.noise_seed not in suite_noise, (name, sc.scenario_id, suite_noise.get(sc.noise_seed))
            if sc.faults:
                assert _schedule(sc) not in suite_sched, (name, sc.scenario_id, suite_sched.get(_schedule(sc)))
            # and the calibration episodes are not training episodes (nor are two datasets the same, but the
            # robust classifier's and PPO's, which are one spec simulated once, and the same draw at another
            # noise grid for another model: the decentralised teams' rated variants)
            owner = seen.setdefault(sc.noise_seed, name)
            assert (
                owner == name
                or spec == specs[owner]
                or (_model(owner) != _model(name) and _draw(spec) == _draw(specs[owner]))
            ), (name, owner, sc.scenario_id)


def _model(key: str) -> str:
    """The training run of a spec's key (``FILE/ENTRY``), whatever its seed and dataset."""
    return "/".join(key.split("/")[:2])


def _draw(spec: dict) -> dict:
    """What a spec draws its scenarios from, but its noise grid and its name."""
    out = {k: v for k, v in spec.items() if k != "noise_scales"}
    out["config"] = {k: v for k, v in spec["config"].items() if k != "name"}
    return out


def test_dataset_specs_draw_what_marine_fdi_dataset_draws(tmp_path):
    """The scenarios a training spec names are those of ``marine-fdi dataset --preset P --episodes N
    --seed S`` (so the documented export command reproduces the training data)."""
    from marine_fdi_env.cli import main as cli_main

    spec = {"preset": "nominal", "episodes": 2, "seed": 4}
    assert (
        cli_main(
            [
                "dataset",
                "--preset",
                "nominal",
                "--episodes",
                "2",
                "--seed",
                "4",
                "--out",
                str(tmp_path),
                "--no-progress",
            ]
        )
        == 0
    )
    exported = json.loads((tmp_path / "scenarios.json").read_text())["scenarios"]
    assert [{k: v for k, v in e.items() if k != "truth"} for e in exported] == [
        s.to_dict() for s in dataset_scenarios(spec)
    ]
