"""A learned decentralised team (training/decentralised.py) declares the same as one benchmark agent
(the locals fed their own columns) and in the batched multi-agent environment; its locals compute their
inputs from their own modules alone; its messages respect the budget."""

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from marine_fdi_env.baselines.reference_distributed_agent import DecisionVectorLocal  # noqa: E402
from marine_fdi_env.benchmark.evaluate import WALL_CLOCK_FIELDS, run_episodes, suite_env_kwargs  # noqa: E402
from marine_fdi_env.benchmark.suites import load_suite  # noqa: E402
from marine_fdi_env.envs.observation import feature_names  # noqa: E402
from marine_fdi_env.multiagent import BUDGETS, LOCAL_AGENTS  # noqa: E402
from marine_fdi_env.multiagent.evaluate import team_records  # noqa: E402
from marine_fdi_env.multiagent.roles import local_modules  # noqa: E402
from marine_fdi_env.multiagent.team import Team, TeamAgent  # noqa: E402
from marine_fdi_env.training.decentralised import DecentralisedNet, local_inputs  # noqa: E402
from marine_fdi_env.training.decentralised_agent import DecentralisedGlobal, DecentralisedLocal  # noqa: E402
from marine_fdi_env.training.features import AgentFeatures  # noqa: E402

FEATURES = {"noise_window": 4, "ewma_features": ["signed_mean_ratio"], "taus": [5, 20, 60], "previous_alarm": False}


def untrained_team(budget: str, seed: int = 0, locals_: str = "learned") -> Team:
    """A team with seeded random weights and a low alarm threshold (so that it declares); ``locals_``
    ``thesis``: the thesis's decision vectors and a learned global (``dec-global-decision``)."""
    torch.set_num_threads(1)  # as load_team: tiny networks, one row per engine
    torch.manual_seed(seed)
    names = AgentFeatures(feature_names(False), drop=(), **FEATURES).input_names()
    cols = {a: local_inputs(names, a) for a in LOCAL_AGENTS}
    net = DecentralisedNet(BUDGETS[budget], cols, 8, 16, locals_).eval()
    decl = {"alarm_threshold": 0.3, "isolation_threshold": 0.45, "isolation_conformal": {"quantile": 0.6}}
    if locals_ == "thesis":
        policies = {a: DecisionVectorLocal(a) for a in LOCAL_AGENTS}
    else:
        policies = {a: DecentralisedLocal(a, net.locals[a], dict(FEATURES, drop=[])) for a in LOCAL_AGENTS}
    return Team(f"untrained-{budget}-{locals_}", BUDGETS[budget], policies, DecentralisedGlobal(net.glob, decl))


def _strip(rec: dict) -> dict:
    return {k: v for k, v in rec.items() if k not in WALL_CLOCK_FIELDS}


@pytest.mark.parametrize(
    "budget, locals_",
    [("decision", "learned"), ("decision", "thesis"), pytest.param("scalar", "learned", marks=pytest.mark.slow)],
)
def test_learned_team_declares_the_same_in_both_environments(budget, locals_):
    suite = load_suite("multi-v1")
    scs = [suite.scenarios[i] for i in (1, 9, 22)]
    env_kwargs, _ = suite_env_kwargs(suite)
    single = run_episodes(TeamAgent(untrained_team(budget, locals_=locals_)), scs, env_kwargs, suite="multi-v1")
    multi = team_records(untrained_team(budget, locals_=locals_), scs, env_kwargs, suite="multi-v1")
    assert [_strip(r) for r in single] == [_strip(r) for r in multi]
    assert any(len(r["declared_changes"]) > 1 for r in single)  # the declarations change: the test can fail


def test_local_inputs_are_their_own_modules_only():
    names = AgentFeatures(feature_names(False), drop=(), **FEATURES).input_names()
    for a in LOCAL_AGENTS:
        cols = local_inputs(names, a)
        assert len(cols) == 6 * len(local_modules(a))
        assert all(any(m in names[c] for m in local_modules(a)) for c in cols)
    # a local's features from its own observation equal those columns of the whole observation's
    rng = np.random.default_rng(0)
    full = AgentFeatures(feature_names(False), drop=(), **FEATURES)
    obs = rng.uniform(0, 2, (5, 115)).astype(np.float32)
    x_full = full.raw(obs, full.initial_state(5))
    from marine_fdi_env.multiagent.roles import local_columns, local_feature_names

    for a in LOCAL_AGENTS:
        own = AgentFeatures(local_feature_names(a), drop=(), **FEATURES)
        x_own = own.raw(obs[:, local_columns(a, feature_names(False))], own.initial_state(5))
        assert np.array_equal(x_own, x_full[:, local_inputs(names, a)])


def test_messages_respect_the_budget():
    team = untrained_team("decision")
    team.reset([0, 1])
    obs = {a: np.random.default_rng(1).uniform(0, 1, (2, 6 * len(local_modules(a)) + 1)) for a in LOCAL_AGENTS}
    msgs = team.messages(obs, 2)
    assert all(set(np.unique(m)) <= {0.0, 1.0} for m in msgs.values())
    team = untrained_team("features")
    team.reset([0, 1])
    msgs = team.messages(obs, 2)
    assert [m.shape[1] for m in msgs.values()] == [12, 36, 30, 36]


def test_thesis_pairs_global_takes_the_thesis_declaration_only_where_it_names_a_pair():
    """``...+thesis-pairs``: the learned global's declaration, replaced by the thesis's logic's on exactly the
    rows where that names two faults or more (a pair pattern, a single-fault pattern, no bit)."""
    from marine_fdi_env.baselines.reference_distributed_agent import ThesisGlobal
    from marine_fdi_env.training.decentralised_agent import ThesisPairsGlobal

    thesis = ThesisGlobal()
    rng = np.random.default_rng(3)
    rows = [np.zeros(19, dtype=np.float32)] + [(rng.random(19) < p).astype(np.float32) for p in (0.1, 0.2, 0.5) * 20]
    bits = np.stack(rows)
    named = np.array([(thesis.belief(b)[:-2] >= 0.5).sum() for b in bits])
    assert (named >= 2).any() and (named < 2).any()  # both kinds of row: the test can fail
    learned = untrained_team("decision", locals_="thesis").global_policy
    hybrid = ThesisPairsGlobal(untrained_team("decision", locals_="thesis").global_policy)
    learned.reset(list(range(len(bits))))
    hybrid.reset(list(range(len(bits))))
    a, b = learned.declare(bits), hybrid.declare(bits)
    pairs = named >= 2
    assert np.array_equal(b[~pairs], a[~pairs])
    assert np.array_equal(b[pairs], np.stack([thesis.belief(x) for x in bits[pairs]]))


def test_shipped_thesis_pairs_teams_are_the_rated_teams_weights():
    """Each seed of ``dec-global-rated-decision+thesis-pairs`` holds its source team's weights (sha256) and
    calibration, with only the pairs rule and the name changed."""
    import hashlib
    import json

    from tests.paths import ROOT

    root = ROOT / "training" / "models"
    for s in (0, 1, 2):
        hybrid = root / "dec-global-rated-decision+thesis-pairs" / f"seed{s}"
        source = root / "dec-global-rated-decision" / f"seed{s}"
        cfg, src = (json.loads((d / "config.json").read_text()) for d in (hybrid, source))
        sha = hashlib.sha256((source / "model.pt").read_bytes()).hexdigest()
        assert (
            cfg["derived_from"]["model_sha256"] == sha == hashlib.sha256((hybrid / "model.pt").read_bytes()).hexdigest()
        )
        assert cfg["declaration"] == dict(src["declaration"], pairs="thesis")
        assert {k: v for k, v in cfg.items() if k not in ("name", "declaration", "derived_from", "command")} == {
            k: v for k, v in src.items() if k not in ("name", "declaration", "command")
        }


def test_a_pairs_rule_is_refused_by_name_where_it_cannot_apply(tmp_path):
    """``declaration.pairs``: ``thesis`` needs the thesis's decision vectors as messages; anything else but
    ``learned`` is refused, naming the config file."""
    import json
    import shutil

    from marine_fdi_env.training.decentralised_agent import load_team
    from tests.paths import ROOT

    src = ROOT / "training" / "models" / "dec-classifier-decision" / "seed0"
    for pairs, words in (("thesis", "decision vectors"), ("both", "must be one of")):
        d = tmp_path / pairs
        shutil.copytree(src, d)
        cfg = json.loads((d / "config.json").read_text())
        cfg["declaration"]["pairs"] = pairs
        (d / "config.json").write_text(json.dumps(cfg))
        with pytest.raises(ValueError, match=words) as e:
            load_team(d)
        assert "config.json" in str(e.value)
