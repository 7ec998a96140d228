"""transfer-v2: operating conditions no training or calibration data contains, and its evaluation."""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml

from marine_fdi_env.benchmark.evaluate import evaluate, run_episodes
from marine_fdi_env.benchmark.suites import TRANSFER_V2_NOISE_SCALE, load_suite
from marine_fdi_env.engine.profiles import TELEGRAPH_LEVELS, make_profile
from marine_fdi_env.engine.simulator import Simulator
from marine_fdi_env.envs.scenario_sampler import (
    HELD_OUT_PROFILES,
    PRESETS,
    SAMPLER_PROFILES,
    ScenarioConfig,
    ScenarioSpec,
)
from tests.paths import ROOT

HYPERPARAMS = ROOT / "training" / "hyperparams"


def _family(profile: str) -> str:
    return profile.split(":")[0]


def training_specs() -> dict[str, dict]:
    """Every dataset spec a training or calibration run simulates (training/hyperparams/*.yml:
    datasets, calibration sets, RL scenario configs), by name."""
    out = {}
    for f in sorted(HYPERPARAMS.glob("*.yml")):
        for env_id, hp in yaml.safe_load(f.read_text()).items():
            specs = list(hp.get("datasets", [])) + [hp[k] for k in ("calibration", "isolation_calibration") if k in hp]
            if "scenario_config" in hp:
                specs.append(
                    {"preset": hp["scenario_config"]}
                    if isinstance(hp["scenario_config"], str)
                    else {"config": hp["scenario_config"]}
                )
            for k, spec in enumerate(specs):
                out[f"{f.name} {env_id} #{k}"] = spec
    return out


def training_configs() -> dict[str, tuple[ScenarioConfig, set[float]]]:
    """Every scenario distribution a training or calibration run draws from, with the sensor-noise
    scales it draws: the presets and the specs of :func:`training_specs`."""
    from marine_fdi_env.training.datasets import scenario_config_of

    out = {f"preset {k}": (v, {v.noise_scale}) for k, v in PRESETS.items()}
    for name, spec in training_specs().items():
        cfg = scenario_config_of(spec)[1]
        out[name] = (cfg, set(spec.get("noise_scales", [cfg.noise_scale])))
    return out


def test_transfer_v2_holds_only_held_out_profiles_and_the_off_grid_noise():
    suite = load_suite("transfer-v2")
    assert len(suite.scenarios) == 64 and suite["env"]["reward"] == "v1"
    fams = [_family(s.profile) for s in suite.scenarios]
    assert set(fams) == {"harbour", "seastate"} and fams.count("harbour") == fams.count("seastate") == 32
    assert {s.noise_scale for s in suite.scenarios} == {TRANSFER_V2_NOISE_SCALE}
    assert {len(s.faults) for s in suite.scenarios} == {0, 1, 2}


def test_no_training_or_calibration_config_can_draw_transfer_v2():
    configs = training_configs()
    assert any("classifier.yml" in k for k in configs) and any("ppo.yml" in k for k in configs)
    assert any(len(noise) > 1 for _, noise in configs.values())  # the noise-invariant agents' grid
    for name, (cfg, noise) in configs.items():
        fams = {f for f, w in cfg.profiles if w > 0}
        assert fams <= set(SAMPLER_PROFILES) and not fams & set(HELD_OUT_PROFILES), name
        assert TRANSFER_V2_NOISE_SCALE not in noise, name
        drawn = [cfg.sample(e) for e in range(40)]  # and what they actually draw
        assert not {_family(s.profile) for s in drawn} & set(HELD_OUT_PROFILES), name
        assert {s.noise_scale for s in drawn} == {cfg.noise_scale}, name
    for name, spec in training_specs().items():  # the noise scales a spec's episodes get
        if "noise_scales" in spec:
            from marine_fdi_env.training.datasets import dataset_scenarios

            got = {s.noise_scale for s in dataset_scenarios(dict(spec, episodes=60))}
            assert got == set(spec["noise_scales"]), name
    # the sampler refuses the held-out families outright
    for fam in HELD_OUT_PROFILES:
        with pytest.raises(ValueError, match="held out for the transfer suites"):
            ScenarioConfig(profiles=((fam, 1.0),))


def test_held_out_profiles_are_what_they_say():
    h = make_profile("harbour:seed=4,u_min=0.3,u_max=1.0,dwell=20", 300.0)
    t, u = np.array(h.times), np.array(h.values)
    assert set(np.round(u, 9)) <= set(TELEGRAPH_LEVELS) and len(set(u)) >= 3
    slopes = np.abs(np.diff(u)) / np.maximum(np.diff(t), 1e-12)
    assert slopes.max() == pytest.approx(0.1)  # steps at the telegraph rate, 5x the governor rate
    s = make_profile("seastate:seed=1,u_mean=0.8,amplitude=0.05,period=8", 300.0)
    v = np.array(s.values)
    assert np.all(np.abs(v / 0.8 - 1.0) <= 0.05 + 1e-12) and abs(v.mean() / 0.8 - 1.0) < 0.01
    assert np.ptp(v) > 0.05 * 0.8  # it fluctuates (peak to peak over several waves)
    with pytest.raises(ValueError, match="harbour"):
        make_profile("harbour:u_min=0.5,u_max=0.55")
    # the engine follows both without leaving its physical range
    res = Simulator(n_engines=2, seeds=[1, 2], profiles=[h, s]).run(60.0)
    assert not res.failures and np.all(np.isfinite(res.measurements))


def test_evaluation_of_transfer_v2_records_v1_and_its_noise(tmp_path):
    suite = load_suite("transfer-v2")
    small = dict(suite, name="t2-small", scenarios=[s.to_dict() for s in suite.scenarios[:2]])
    for s in small["scenarios"]:
        s["duration_s"] = 20.0
        s["faults"] = [dict(f, onset_s=5.0) for f in s["faults"]]
    f = tmp_path / "t2-small.json"
    f.write_text(json.dumps(small))
    res = evaluate("oracle", str(f), tmp_path / "o.json", progress=False)
    assert res["env_id"] == "MarineFDI-v1" and res["env"]["reward"]["version"] == "v1"
    assert res["metrics"]["agent_compute_s_per_decision"] > 0 and res["metrics"]["feature_compute_s_per_sample"] > 0
    with pytest.raises(ValueError, match="scored with reward"):
        evaluate("oracle", str(f), tmp_path / "o0.json", progress=False, reward="v0")


def test_a_suite_mixing_noise_scales_runs_each_at_its_own():
    sc = [
        ScenarioSpec(profile="constant", noise_seed=3, noise_scale=ns, duration_s=5.0, scenario_id=f"n{ns}")
        for ns in (1.0, 0.5, 1.0)
    ]
    from marine_fdi_env.benchmark.agent_api import load_agent

    mixed = run_episodes(load_agent("null"), sc, {}, suite="x")
    assert [r["scenario_id"] for r in mixed] == ["n1.0", "n0.5", "n1.0"]
    alone = run_episodes(load_agent("null"), sc[1:2], {"scenario_config": ScenarioConfig(noise_scale=0.5)}, suite="x")
    strip = ("compute_s", "feature_compute_s", "agent_compute_s")
    assert {k: v for k, v in mixed[1].items() if k not in strip} == {
        k: v for k, v in alone[0].items() if k not in strip
    }
