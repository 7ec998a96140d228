"""Learned diagnosers for ``MarineFDI-v1`` (needs the ``train`` extra: torch, stable-baselines3, pyyaml).

* :mod:`marine_fdi_env.training.train` - ``marine-fdi train --algo ppo|ppo_lstm|classifier [--env ID] --seed N``
  (hyperparameters in ``training/hyperparams/ALGO.yml``, keyed by env id);
* :mod:`marine_fdi_env.training.rl`, :mod:`marine_fdi_env.training.replay`,
  :mod:`marine_fdi_env.training.features` - PPO on recorded
  MarineFDI-v1 episodes (bit-equal to the live env), with the agent's own input preprocessing;
* :mod:`marine_fdi_env.training.vec_adapter` - SB3 ``VecEnv`` over the batched vector environment, action modes;
* :mod:`marine_fdi_env.training.classifier` - the supervised GRU diagnoser and its threshold calibration;
* :mod:`marine_fdi_env.training.agents` - trained models as benchmark agents (``marine-fdi evaluate --agent
  NAME`` for a shipped model, ``--agent FOLDER`` for any model folder);
* :mod:`marine_fdi_env.training.sb3_inference` - a PPO policy loaded alone and its deterministic actions, bit
  for bit SB3's ``predict`` without its per-call work.

``SB3VecEnv``, ``save_sb3_agent`` and ``ProgressLine`` (:mod:`.progress_line`: a line of progress while SB3
trains) are importable from here (loaded on first use, so that importing this package needs no extra)::

    from marine_fdi_env.training import ProgressLine, SB3VecEnv, save_sb3_agent
"""

__all__ = ["SB3VecEnv", "save_sb3_agent", "ProgressLine"]


def __getattr__(name: str):
    if name == "SB3VecEnv":
        from .vec_adapter import SB3VecEnv

        return SB3VecEnv
    if name == "ProgressLine":
        from .progress_line import ProgressLine

        return ProgressLine
    if name == "save_sb3_agent":
        from .artifacts import save_sb3_agent

        return save_sb3_agent
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
