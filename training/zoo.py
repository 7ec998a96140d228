"""RL Zoo (``rl_zoo3``) with this environment: the shipped hyperparameters, the batched environment behind
RL Zoo's own env construction, and an RL Zoo run folder as a benchmark agent.

    pip install 'marine-fdi-env[zoo]'
    python -m rl_zoo3.train --algo ppo --env MarineFDI-v1 --gym-packages marine_fdi_env \\
        --conf-file marine_fdi_env.training.zoo --seed 0
    marine-fdi evaluate --agent logs/ppo/MarineFDI-v1_1 --suite single-v1

* :data:`hyperparams` is RL Zoo's ``--conf-file`` as a Python module (RL Zoo imports a ``--conf-file`` that
  is neither ``.yml`` nor ``.py`` and reads its ``hyperparams``): the content of the package's
  ``hyperparams/zoo_ppo.yml`` (:data:`CONF_FILE`, whose path works as ``--conf-file`` too).
* :func:`batched_env` is the ``vec_env_wrapper`` that entry names: RL Zoo builds ``n_envs`` single
  environments (``make_vec_env``); the wrapper closes them and returns the batched
  :class:`~marine_fdi_env.training.vec_adapter.SB3VecEnv` with the gated action, the reference's features
  and the training reward its keyword arguments give, seeded with RL Zoo's ``--seed``.
* :class:`ZooAgent` loads a run folder RL Zoo wrote (``ENV_ID.zip`` beside ``ENV_ID/config.yml``,
  ``args.yml`` and ``vecnormalize.pkl``) as a benchmark agent; ``marine-fdi evaluate --agent FOLDER`` finds
  it (:func:`marine_fdi_env.benchmark.agent_api.load_agent`).

RL Zoo refuses ``--env marine_fdi_env:MarineFDI-v1``: it looks the id up in ``gymnasium.registry`` as given,
and Gymnasium registers ``MarineFDI-v1`` (the ``module:`` prefix is a ``gymnasium.make`` convenience that
imports the module first, not part of the id).  ``--gym-packages marine_fdi_env`` imports the package,
which registers the ids, and ``--env MarineFDI-v1`` is found.
"""

from __future__ import annotations

from pathlib import Path

import yaml

__all__ = ["CONF_FILE", "hyperparams", "batched_env", "ZooAgent"]

CONF_FILE = Path(__file__).resolve().parent / "hyperparams" / "zoo_ppo.yml"

hyperparams: dict = yaml.safe_load(CONF_FILE.read_text(encoding="utf-8"))


def batched_env(venv, num_envs: int = 64, torch_threads: int | None = 1, **kwargs):
    """RL Zoo's ``vec_env_wrapper``: ``venv`` (RL Zoo's vector env of single environments) is closed and the
    batched :class:`~marine_fdi_env.training.vec_adapter.SB3VecEnv` of ``num_envs`` engines is returned,
    seeded with ``venv``'s seed (RL Zoo's ``--seed``), inside a ``VecMonitor`` (episode returns in RL Zoo's
    log).  ``kwargs`` go to ``SB3VecEnv`` (``action_mode``, ``reference_features``, ``reward``, ...);
    ``torch_threads``: ``torch.set_num_threads`` (None: leave it)."""
    from stable_baselines3.common.vec_env import VecMonitor

    from .vec_adapter import SB3VecEnv

    seeds = getattr(venv, "_seeds", None) or [None]
    venv.close()
    if torch_threads is not None:
        import torch

        torch.set_num_threads(int(torch_threads))
    return VecMonitor(SB3VecEnv(num_envs=int(num_envs), seed=seeds[0], **kwargs))


class ZooAgent:
    """An RL Zoo run folder as a benchmark agent (module docstring): the PPO policy of ``ENV_ID.zip``, acting
    deterministically like :class:`~marine_fdi_env.training.agents.SB3Agent`; the action mode and whether
    the reference's features are inputs are read from the model's own spaces."""

    @classmethod
    def from_dir(cls, path, **kwargs):
        from marine_fdi_env.benchmark.agent_api import zoo_run_model

        from .agents import SB3Agent

        path = Path(path)
        f = zoo_run_model(path)
        if f is None:
            raise ValueError(f"{path}: not an RL Zoo run folder (no ENV_ID.zip beside ENV_ID/args.yml)")
        _refuse_obs_normalisation(f.with_suffix("") / "vecnormalize.pkl")
        import torch

        torch.set_num_threads(1)
        try:
            from .sb3_inference import load_policy

            model = load_policy(f)
        except Exception as e:  # noqa: BLE001 - any failure inside SB3/torch is a bad file
            raise ValueError(f"{f}: corrupt or unreadable model ({type(e).__name__}: {e})") from None
        cfg = _config(model, f)
        return SB3Agent(model, cfg, path)


def _config(model, f: Path) -> dict:
    """The config an SB3Agent needs, from the model's action and observation spaces."""
    from marine_fdi_env.envs.actions import ACTION_MODES, action_space
    from marine_fdi_env.envs.observation import feature_names

    from .vec_adapter import N_REFERENCE_FEATURES

    modes = [m for m in ACTION_MODES if action_space(m) == model.action_space]
    if not modes:
        raise ValueError(
            f"{f}: action space {model.action_space} is none of this benchmark's ({', '.join(ACTION_MODES)})"
        )
    names = feature_names(False)
    shape = tuple(model.observation_space.shape)
    if shape not in ((len(names),), (len(names) + N_REFERENCE_FEATURES,)):
        raise ValueError(
            f"{f}: model made for another observation space (shape {shape}, this environment gives "
            f"({len(names)},), or ({len(names) + N_REFERENCE_FEATURES},) with the reference's features)"
        )
    return {
        "name": f"{f.parent.name}",
        "algo": "ppo",
        "action_mode": modes[0],
        "frame_stack": 1,
        "observation": {
            "size": len(names),
            "observe_sensors": False,
            "feature_names": names,
            "reference_features": shape[0] != len(names),
        },
    }


def _refuse_obs_normalisation(pkl: Path) -> None:
    """A run whose ``vecnormalize.pkl`` normalises observations would need its statistics at every decision:
    refused with a message (the shipped hyperparameters normalise the reward only, which acting never needs)."""
    if not pkl.is_file():
        return
    import pickle

    try:
        with pkl.open("rb") as fh:
            norm = pickle.load(fh)
    except Exception as e:  # noqa: BLE001
        raise ValueError(f"{pkl}: unreadable ({type(e).__name__}: {e})") from None
    if getattr(norm, "norm_obs", False):
        raise ValueError(
            f"{pkl}: the run normalises observations (normalize: norm_obs=True); this loader acts on raw "
            'observations: train with normalize: "dict(norm_obs=False, norm_reward=True)" as the shipped '
            "hyperparameters do"
        )
