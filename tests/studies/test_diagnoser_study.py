"""The reference diagnoser on simulated runs: no false alarms, detection, isolation, streaming."""

from __future__ import annotations

import numpy as np
import pytest

from marine_fdi_env.baselines.reference_diagnoser import ReferenceDiagnoser
from marine_fdi_env.engine.faults import FaultSpec
from marine_fdi_env.engine.simulator import Simulator


def test_decision_bookkeeping_equals_feeding_every_violating_row():
    # observe() only feeds the decision logic the rows that fire a new module or pass a grace
    # expiry; the outcome must equal feeding every violating row (the reference loop)
    from marine_fdi_env.diagnosis.decision import DiagnosisState
    from studies.diagnosis.certainty import grace_times, settle_times, sure_cells

    res = Simulator("thesis-12v28", 3, seeds=31, faults=[["S4.2@2"], ["S2.2@1", "S3.3@4"], []]).run(40.0)
    Y = res.measurements.transpose(1, 0, 2)
    U = res.truth_of("u").T
    agent = ReferenceDiagnoser(n_engines=3, cells="grid")
    viol = []
    for a in range(0, Y.shape[1], 250):
        viol.append(agent.observe(Y[:, a : a + 250], U[:, a : a + 250]).violations)
    viol = np.concatenate(viol, axis=1)
    t = np.arange(Y.shape[1]) * agent.dt
    for i in range(3):
        ref = DiagnosisState(
            exoneration=sure_cells(), max_cardinality=2, temporal=True, settle_s=settle_times(), grace_s=grace_times()
        )
        for k in range(Y.shape[1]):
            if viol[i, k].any():
                ref.update(viol[i, k], float(t[k]))
            if (k + 1) % 250 == 0 or k == Y.shape[1] - 1:
                ref.advance(float(t[k]))
        st = agent.decisions[i]
        assert np.array_equal(st.fired, ref.fired)
        assert np.array_equal(st.detection_times, ref.detection_times, equal_nan=True)
        assert st.diagnoses == ref.diagnoses
        assert agent.detected[i] == ref.detected


def test_turbine_seal_leak_at_table_magnitude_is_below_the_worst_case_threshold():
    # the documented reason the reference misses it (docs/diagnosis.md): at table 6.4 magnitude the
    # residual shift of M3.1/M3.2 in the last minute is ~1 % of their worst-case threshold, and it
    # grows linearly with the magnitude (φ_tur = β R s is linear in R)
    from studies.diagnosis.kpis import seal_leak_snr

    out = seal_leak_snr(3, multiples=(1.0, 16.0), profiles=("constant",))["result"]["constant"]
    one, big = out["1x"], out["16x"]
    assert -0.001 < one["state_change_relative"] < -0.0003  # 0.03-0.1 % of x3
    assert big["state_change_Pa"] / one["state_change_Pa"] == pytest.approx(16.0, rel=0.05)
    assert one["residual_shift_Pa"] < 0 and abs(one["residual_shift_Pa"]) < 0.05 * one["threshold_mean_Pa"]
    assert abs(big["residual_shift_Pa"]) < 0.5 * big["threshold_mean_Pa"]  # even 16x stays below it


def test_kpi_streaming_diagnosis_equals_diagnosing_a_recorded_run():
    # the KPI commands stream blocks from the simulator into the diagnoser (hour-long runs would not
    # fit in memory recorded); the reports must equal those of a recorded run diagnosed in one pass
    from studies.diagnosis.kpis import PARAMS, diagnose_batch

    sch = [[FaultSpec("S3.4", 20.0)], [FaultSpec("bore_damage", 15.0)], [], [FaultSpec("valve_seizing", 20.0)]]
    got = diagnose_batch(sch, [5, 6, 7, 8], "manoeuvring", duration_s=60.0, block_samples=777)
    sim = Simulator(PARAMS, 4, seeds=[5, 6, 7, 8], faults=sch, profiles="manoeuvring")
    res = sim.run(60.0)
    agent = ReferenceDiagnoser(PARAMS, n_engines=4, dt=sim.dt)
    agent.observe(res.measurements.transpose(1, 0, 2), res.truth_of("u").T)
    for i in range(4):
        want = dict(agent.report(i), failures=[f.to_dict() for f in res.failures if f.engine == i])
        assert got[i] == want
    assert got[0]["detected"] and not got[2]["detected"]
