"""Minari datasets (marine-fdi dataset --format minari): minari.load_dataset opens them, their manifest
verifies, regenerating them from their seeds gives the same manifest, and a change is named."""

from __future__ import annotations

import json
import shutil
import sys

import numpy as np
import pytest

pytest.importorskip("minari")

from marine_fdi_env.benchmark.dataset import load_dataset  # noqa: E402
from marine_fdi_env.benchmark.minari_data import minari_arrays  # noqa: E402
from marine_fdi_env.cli import main as cli_main  # noqa: E402
from marine_fdi_env.engine.faults import FAULT_IDS  # noqa: E402

DID = "marine_fdi/default/null-v0"
ARGS = ["--preset", "default", "--episodes", "3", "--seed", "1", "--no-progress"]


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    d = tmp_path_factory.mktemp("minari")
    assert cli_main(["dataset", *ARGS, "--format", "minari", "--out", str(d / "root")]) == 0
    assert cli_main(["dataset", *ARGS, "--out", str(d / "npz")]) == 0  # the same episodes as dense arrays
    return d


def run(capsys, *argv):
    code = cli_main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_minari_load_dataset_opens_it_with_the_truth(root, monkeypatch):
    import minari

    monkeypatch.setenv("MINARI_DATASETS_PATH", str(root / "root"))
    ds = minari.load_dataset(DID)
    truth = json.loads((root / "root" / DID / "scenarios.json").read_text())["scenarios"]
    assert ds.total_episodes == 3 and ds.spec.env_spec.id == "MarineFDI-v1"
    assert ds.spec.env_spec.kwargs["reward"] == "v1" and ds.spec.env_spec.kwargs["scenario_config"]["name"] == "default"
    dense = load_dataset(root / "npz")
    for k, ep in enumerate(ds.iterate_episodes()):
        T = len(ep.actions)
        assert ep.observations.shape == (T + 1, 115) and ep.observations.dtype == np.float32
        assert ep.actions.shape == (T, 28) and not ep.actions.any()  # the silent agent
        assert ep.rewards.shape == (T,) and ep.truncations[-1] and not ep.terminations.any()
        assert np.array_equal(ep.observations[:T], dense["obs"][k, :T])  # bit for bit the dataset's arrays
        assert np.array_equal(ep.infos["active"][:T], dense["active"][k, :T])
        meta = next(iter(ds.storage.get_episode_metadata([k])))
        assert meta["options"]["scenario"]["scenario_id"] == truth[k]["scenario_id"] == f"default/1/{k}"
        assert meta["seed"] == truth[k]["noise_seed"]
        for f in truth[k]["truth"]:  # the faults active after their onset, in FAULT_IDS order
            j, t = FAULT_IDS.index(f["id"]), np.asarray(ep.infos["t_s"])
            assert np.array_equal(ep.infos["active"][:, j], t >= f["onset_s"]), f["id"]
    arrays = minari_arrays(root / "root", DID)
    for key in ("obs", "active", "valid", "t_s"):
        assert np.array_equal(arrays[key], dense[key]), key


def test_the_manifest_verifies_and_regenerating_gives_the_same(root, capsys):
    code, out, err = run(capsys, "dataset", "--check", root / "root" / DID, "--regenerate", "--no-progress")
    assert code == 0, err
    assert "every decoded array has the manifest's sha256" in out and "regenerated from its seeds, the same" in out


def test_a_changed_array_or_seed_is_named(root, tmp_path, capsys):
    copy = tmp_path / "root"
    shutil.copytree(root / "root", copy)
    man = copy / DID / "manifest.json"
    m = json.loads(man.read_text())
    m["episodes"][1]["sha256"]["rewards"] = "0" * 64
    man.write_text(json.dumps(m))
    code, _, err = run(capsys, "dataset", "--check", copy / DID)
    assert code == 2 and "episode 1 (default/1/1): rewards differs from the manifest's sha256" in err, err
    shutil.rmtree(copy)
    shutil.copytree(root / "root", copy)
    sc = copy / DID / "scenarios.json"
    s = json.loads(sc.read_text())
    s["scenarios"][2]["noise_seed"] += 1  # other seeds: other arrays
    sc.write_text(json.dumps(s))
    code, _, err = run(capsys, "dataset", "--check", copy / DID, "--regenerate", "--no-progress")
    assert code == 2 and "regenerated from its seeds: episode 2 (default/1/2): observations differs" in err, err


def test_without_minari_one_line_names_the_extra(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "minari", None)  # import minari raises ImportError
    code, _, err = run(capsys, "dataset", *ARGS, "--format", "minari", "--out", tmp_path / "r")
    assert code == 2 and err.strip() == (
        "marine-fdi dataset: error: --format minari needs minari: pip install 'marine-fdi-env[minari]'"
    )
    assert not (tmp_path / "r").exists()
    code, _, err = run(capsys, "dataset", *ARGS, "--format", "minari", "--out", tmp_path / "r", "--dataset-id", "x")
    assert code == 2
