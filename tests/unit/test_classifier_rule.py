"""The classifier agent's declaration rule (training/agents.py), for every ``use_reference`` mode,
with a scripted network: what the rows "classifier" and "classifier+reference" mean."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from marine_fdi_env.engine.faults import FAULT_IDS  # noqa: E402
from marine_fdi_env.envs.hypotheses import HYPOTHESES, UNKNOWN  # noqa: E402
from marine_fdi_env.envs.observation import observation_size  # noqa: E402
from marine_fdi_env.training.agents import ClassifierAgent  # noqa: E402

NF = observation_size(False)
COL = {f: k for k, f in enumerate(FAULT_IDS)}


class ScriptedNet:
    """Returns, call after call, the scripted probabilities: (P(some fault), {fault: p})."""

    def __init__(self, script):
        self.script = list(script)

    def __call__(self, x, h=None):
        p_alarm, faults = self.script.pop(0)
        p = np.full((x.shape[0], 1, len(FAULT_IDS) + 1), 1e-4)
        for f, v in faults.items():
            p[:, 0, COL[f]] = v
        p[:, 0, -1] = p_alarm
        return torch.logit(torch.as_tensor(p, dtype=torch.float32)), h


def _agent(script, mode):
    cfg = {
        "name": "classifier",
        "observation": {"size": NF},
        "declaration": {"alarm_threshold": 0.9, "isolation_threshold": 0.5, "use_reference": mode},
    }
    a = ClassifierAgent(ScriptedNet(script), cfg, where=None)
    a.reset([0])
    return a


def _run(agent, refs):
    """``refs``: per decision the reference's conclusion: None (not detected), [] (detected, no
    decisive diagnosis) or a fault set (its one minimal diagnosis)."""
    out = []
    for ref in refs:
        diagnoses = np.empty(1, dtype=object)
        diagnoses[0] = [ref] if ref else []
        infos = {"reference": {"detected": np.array([ref is not None]), "diagnoses": diagnoses}}
        b = agent.act(np.zeros((1, NF), np.float32), infos)[0]
        declared = [HYPOTHESES[k] for k in np.flatnonzero(b[:-2] >= 0.5)]
        out.append(("alarm" if (declared or b[UNKNOWN] >= 0.5) else "quiet", declared))
    return out


SCRIPT = [
    (0.5, {"S4.2": 0.9}),  # fault probabilities but no alarm: nothing declared
    (0.95, {}),  # alarm, no fault above 0.5: unknown
    (0.2, {"S4.2": 0.8}),  # alarm latched although P(some fault) fell
    (0.2, {"S4.2": 0.8}),
    (0.1, {}),
]
NO_REF = [None] * 5


def test_classifier_alone_latches_its_alarm_and_ignores_the_reference():
    got = _run(_agent(SCRIPT, False), [None, None, ["S3.4"], ["S3.4"], ["S3.4"]])
    assert got == [("quiet", []), ("alarm", []), ("alarm", ["S4.2"]), ("alarm", ["S4.2"]), ("alarm", [])]


def test_first_mode_takes_the_reference_isolation_whenever_it_has_one():
    script = [(0.1, {"S4.2": 0.9})] + SCRIPT[1:]
    got = _run(_agent(script, "first"), [["S3.4"], None, ["S3.4"], [], None])
    # decision 1: the reference's alarm and isolation before the classifier alarms;
    # 3: the reference's S3.4 over the classifier's S4.2; 4: the reference detected but undecided
    assert got == [("alarm", ["S3.4"]), ("alarm", []), ("alarm", ["S3.4"]), ("alarm", ["S4.2"]), ("alarm", [])]


def test_fallback_mode_takes_the_reference_only_when_the_classifier_names_nothing():
    script = [(0.1, {})] + SCRIPT[1:]
    got = _run(_agent(script, "fallback"), [["S3.4"], None, ["S3.4"], None, ["S3.4"]])
    assert got == [("alarm", ["S3.4"]), ("alarm", []), ("alarm", ["S4.2"]), ("alarm", ["S4.2"]), ("alarm", ["S3.4"])]


def test_unknown_mode_is_refused():
    with pytest.raises(ValueError, match="use_reference"):
        ClassifierAgent(
            ScriptedNet([]),
            {"observation": {"size": NF}, "declaration": {"alarm_threshold": 0.9, "use_reference": "always"}},
            where=__import__("pathlib").Path("m"),
        )
