"""training/sb3_inference.py gives SB3's ``predict(obs, deterministic=True)`` actions bit for bit: for
the shipped PPO models as ``PPO.load`` loads them and for small policies of every action space the
agents use, on seeded observations and on logits tied or one float apart (where an argmax of the raw
logits would differ from the argmax of ``Categorical``'s probabilities)."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("stable_baselines3")

import subprocess  # noqa: E402
import sys  # noqa: E402

from gymnasium import spaces  # noqa: E402
from stable_baselines3 import PPO  # noqa: E402
from stable_baselines3.common.policies import ActorCriticPolicy  # noqa: E402

from marine_fdi_env.benchmark.agent_api import load_agent  # noqa: E402
from marine_fdi_env.envs.actions import ACTION_MODES, action_space  # noqa: E402
from marine_fdi_env.training.sb3_inference import deterministic_actions, prepare  # noqa: E402
from tests.paths import ROOT  # noqa: E402

MODELS = ROOT / "training" / "models"


def _same(policy, obs: np.ndarray, reference=None) -> None:
    """``deterministic_actions(policy)`` equals ``reference.predict`` (default: the policy's own)."""
    want, _ = (policy if reference is None else reference).predict(obs, deterministic=True)
    got = deterministic_actions(policy, obs)
    assert got.dtype == want.dtype and got.shape == want.shape
    assert np.array_equal(got, want)


@pytest.mark.parametrize("folder", ["ppo-v1", "ppo/seed0"])
def test_shipped_ppo_models_act_as_predict(folder):
    policy = load_agent(str(MODELS / folder)).model
    reference = PPO.load(MODELS / folder / "model.zip", device="cpu")
    state, want = policy.state_dict(), reference.policy.state_dict()
    assert state.keys() == want.keys() and all(torch.equal(state[k], want[k]) for k in state)
    rng = np.random.default_rng(0)
    size = policy.observation_space.shape[0]
    for scale in (0.1, 1.0, 3.0, 10.0):  # the standardised inputs are clipped to +-10
        _same(policy, (scale * rng.standard_normal((32, size))).astype(np.float32), reference)
    _same(policy, np.zeros((1, size), np.float32), reference)


def test_loading_a_ppo_agent_builds_no_optimizer():
    """Acting needs no optimizer (building torch's first one imports torch._dynamo)."""
    code = (
        "import sys, stable_baselines3; from marine_fdi_env.benchmark.agent_api import load_agent; "
        "before = 'torch._dynamo' in sys.modules; a = load_agent('ppo-v1'); "
        "print(type(a.model.optimizer).__name__, before, 'torch._dynamo' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out[0] == "_NoOptimizer" and out[1] == out[2]  # loading imports nothing torch's import did not


def _policy(mode: str, seed: int = 0) -> ActorCriticPolicy:
    torch.manual_seed(seed)
    p = ActorCriticPolicy(spaces.Box(-10, 10, (6,), np.float32), action_space(mode), lambda _: 0.0, net_arch=[8])
    prepare(p)
    return p


@pytest.mark.parametrize("mode", ACTION_MODES)
def test_every_action_mode_acts_as_predict(mode):
    policy = _policy(mode)
    obs = np.random.default_rng(1).standard_normal((64, 6)).astype(np.float32)
    _same(policy, obs)
    _same(policy, obs[::2])  # a strided batch


@pytest.mark.parametrize("mode", ["discrete", "gated"])
def test_tied_and_adjacent_logits_act_as_predict(mode):
    """Logits equal, or one float32 apart, so that softmax's rounding decides the argmax."""
    policy = _policy(mode)
    with torch.no_grad():
        w = policy.action_net.weight
        w.zero_()
        b = policy.action_net.bias
        b.zero_()
        b[1] = torch.nextafter(torch.tensor(0.0), torch.tensor(1.0))  # one step above its tie with index 0
        b[3] = 1e-7
        b[4] = torch.nextafter(torch.tensor(1e-7), torch.tensor(1.0))
    obs = np.random.default_rng(2).standard_normal((16, 6)).astype(np.float32)
    _same(policy, obs)
