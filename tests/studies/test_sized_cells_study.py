"""Size-aware exoneration (the ``sized`` cell set): the band rule, the derivation per band, the
decision logic on the thesis's examples, and the switch between the three cell sets."""

from __future__ import annotations

import json

import numpy as np

from marine_fdi_env.diagnosis.decision import declared_faults
from marine_fdi_env.diagnosis.modules import MODULE_IDS
from marine_fdi_env.diagnosis.peak_ratio import PeakRecorder
from marine_fdi_env.diagnosis.sized_cells import load_sized_cells
from marine_fdi_env.engine.faults import FAULT_IDS
from studies.diagnosis.sized_derivation import derive_sized_cells

M = {m: i for i, m in enumerate(MODULE_IDS)}
F = {f: j for j, f in enumerate(FAULT_IDS)}


def _grid(rows):
    """rows: (fault, size level, {module: (time after onset, peak)}) per run."""
    times = np.full((len(rows), 19), np.nan)
    runs, peaks = [], []
    for k, (f, lvl, fired) in enumerate(rows):
        runs.append(
            {
                "fault": f,
                "magnitude": float(lvl + 1),
                "grid_index": lvl,
                "size_index": lvl,
                "profile": "constant",
                "family": "constant",
                "seed": k,
            }
        )
        ev = [[] for _ in range(19)]
        for m, (t, q) in fired.items():
            if t is not None:
                times[k, M[m]] = t
            ev[M[m]].append([0.0 if t is None else t, q])
        peaks.append(ev)
    return {
        "runs": runs,
        "n_seeds": 1,
        "duration_s": 300.0,
        "sensor_onset_s": 30.0,
        "peak_events": peaks,
        "times_after_onset_s": {"reference": times.tolist()},
    }


def test_derivation_per_band_and_envelope():
    # S3.4 at 3 levels: M3.5 fires only from level 1 on, M4.6 only at level 2; the envelope of M3.4
    # is the largest peak over the levels up to each one
    grid = _grid(
        [
            ("S3.4", 0, {"M3.4": (0.0, 1.1)}),
            ("S3.4", 0, {"M3.4": (None, 0.97)}),
            ("S3.4", 1, {"M3.4": (0.0, 1.5), "M3.5": (4.0, 1.2)}),
            ("S3.4", 2, {"M3.4": (0.0, 3.0), "M3.5": (1.0, 2.0), "M4.6": (2.0, 1.5)}),
        ]
    )
    d = derive_sized_cells(grid, "reference")
    j = F["S3.4"]
    sure = np.asarray(d["sure"], dtype=bool)
    assert d["n_levels"][j] == 3
    assert [bool(sure[k, M["M3.4"], j]) for k in range(3)] == [True, True, True]
    assert [bool(sure[k, M["M3.5"], j]) for k in range(3)] == [False, True, True]
    assert [bool(sure[k, M["M4.6"], j]) for k in range(3)] == [False, False, True]
    assert d["lag_s"][1][M["M3.5"]][j] == 4.0 and d["lag_s"][2][M["M3.5"]][j] == 1.0
    assert [d["peak"][k][M["M3.4"]][j] for k in range(3)] == [1.1, 1.5, 3.0]
    assert d["detected_runs"][0][j] == 3 and d["runs"][0][j] == 4  # the silent run does not count
    never = np.asarray(d["never_fired"], dtype=bool)
    assert never[M["M3.2"], j] and not never[M["M4.6"], j] and not never[M["M3.4"], j]


def test_replay_on_the_peak_records_declares_as_the_streaming_diagnoser():
    # certainty.validate replays the decision logic on recorded firing times and 2 % peak steps;
    # on these runs it must end on the streaming diagnoser's declaration
    from marine_fdi_env.diagnosis.agent import ReferenceDiagnoser
    from marine_fdi_env.engine.simulator import Simulator
    from studies.diagnosis.certainty import replay_declarations

    faults = [["S3.4@30:6"], ["S4.2@30:9000"], ["S2.2@30:40000"]]
    sim = Simulator("thesis-12v28", 3, seeds=[41, 42, 43], faults=faults, profiles="constant")
    agent = ReferenceDiagnoser(n_engines=3, dt=sim.dt)
    rec = PeakRecorder(3)
    out = agent.observe(sim.y[:, None, :], sim.u[:, None])
    rec.update(out.residuals, out.thresholds, np.zeros(3), sim.dt)
    for k in range(12):
        blk = sim.advance(1000)
        out = agent.observe(blk.measurements, blk.u)
        rec.update(out.residuals, out.thresholds, np.full(3, (1 + 1000 * k) * sim.dt), sim.dt)
    for i, f in enumerate(faults):
        fid = f[0].split("@")[0]
        rep = replay_declarations(
            agent.first_violation[i], fid, load_sized_cells(), agent.samples * sim.dt - sim.dt, 30.0, rec.events[i]
        )
        assert rep["detected"]
        assert rep["declared_end"] == declared_faults(agent.diagnoses(i)), (fid, agent.diagnoses(i))


def test_comparison_table_of_the_cell_sets(tmp_path):
    from studies.diagnosis.cell_set_table import cell_set_table, proportion_ci95, summarize_results

    ep = lambda f, decl: {"faults": [{"id": f}], "declared_changes": [[1.0, decl, True]]}  # noqa: E731
    res = [
        {
            "agent": "reference",
            "suite": "single-v1",
            "metrics": {
                "n_faulty": 2,
                "n_episodes": 2,
                "isolation_accuracy": 0.5,
                "detection_rate": 1.0,
                "false_alarm_episode_rate": None,
            },
            "episodes": [ep("S3.4", ["S3.4"]), ep("S3.5", ["S3.4"])],
        }
    ]
    summary = summarize_results(res)
    v = summary["reference"]["single-v1"]
    assert v["isolated"] == 1 and v["wrong_isolations_ever"] == 1 and v["wrong_isolations_end"] == 1
    (tmp_path / "cell_sets.json").write_text(json.dumps({"agents": summary, "command": "x"}))
    lines = cell_set_table(tmp_path)
    assert len(lines) == 2 + 6  # header, rule, 2 diagnosers x 3 cell sets
    lo, hi = proportion_ci95(1, 2)
    rows = {tuple(x.strip() for x in line.split("|")[1:3]): line for line in lines[2:]}
    assert f"50.0 % ({100 * lo:.0f}-{100 * hi:.0f})" in rows[("reference", "sized")]
    assert rows[("reference", "sized")].split("|")[-3].strip() == "1 / 1"  # single-v1 wrong ever / end
    assert "50.0 %" not in rows[("reference", "grid")]  # no results of that agent: dashes
