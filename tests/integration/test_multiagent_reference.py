"""``reference-distributed`` declares the same in the single-agent and the multi-agent environments:
its records through ``marine-fdi evaluate``'s path (the team as one agent, stepped on the shared
simulation) and through the batched multi-agent path are equal, bit for bit but the wall clock."""

import numpy as np
import pytest

from marine_fdi_env.baselines.reference_distributed_agent import (
    ReferenceDistributedAgent,
    ThesisGlobal,
    reference_distributed_team,
)
from marine_fdi_env.benchmark.agent_api import load_agent
from marine_fdi_env.benchmark.evaluate import WALL_CLOCK_FIELDS, run_episodes, suite_env_kwargs
from marine_fdi_env.benchmark.suites import load_suite
from marine_fdi_env.diagnosis.decision import THESIS_EXAMPLES
from marine_fdi_env.diagnosis.modules import MODULE_IDS
from marine_fdi_env.envs.hypotheses import HYPOTHESES
from marine_fdi_env.multiagent.evaluate import team_records


def _strip(rec: dict) -> dict:
    return {k: v for k, v in rec.items() if k not in WALL_CLOCK_FIELDS}


@pytest.mark.parametrize("suite, picks", [("single-v1", [0, 40, 77, 120, 150]), ("multi-v1", [3, 17, 30])])
def test_same_declarations_in_both_environments(suite, picks):
    s = load_suite(suite)
    scs = [s.scenarios[i] for i in picks]
    env_kwargs, _ = suite_env_kwargs(s)
    single = run_episodes(ReferenceDistributedAgent(), scs, env_kwargs, suite=suite)
    multi = team_records(reference_distributed_team(), scs, env_kwargs, suite=suite)
    assert [_strip(r) for r in single] == [_strip(r) for r in multi]
    assert any(r["declared_changes"] and r["declared_changes"][-1][1] for r in single)  # it declares faults


def test_registered_by_name_and_the_thesis_examples():
    agent = load_agent("reference-distributed")
    assert agent.name == "reference-distributed"
    g = ThesisGlobal()
    ex = THESIS_EXAMPLES["thesis-6.4.2"]  # valve seizing and bore damage: the thesis's global diagnosis
    bits = np.array([m in ex.final_fired for m in MODULE_IDS], dtype=np.float32)
    b = g.declare(bits[None])[0]
    assert {HYPOTHESES[i] for i in np.flatnonzero(b >= 0.5)} == {"valve_seizing", "bore_damage"}
    assert not g.declare(np.zeros((1, 19), np.float32)).any()  # nothing fired: nothing declared
