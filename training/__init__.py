"""Learned diagnosers for ``MarineFDI-v0`` (needs the ``train`` extra: torch, stable-baselines3, pyyaml).

* :mod:`training.train` - ``python -m training.train --algo ppo|ppo_lstm|classifier --seed N``
  (hyperparameters in ``training/hyperparams/ALGO.yml``, keyed by env id);
* :mod:`training.vec_adapter` - SB3 ``VecEnv`` over the batched vector environment;
* :mod:`training.classifier` - the supervised GRU diagnoser and its threshold calibration;
* :mod:`training.agents` - trained models as benchmark agents (``marine-fdi evaluate --agent
  training/models/NAME``);
* :mod:`training.compare` - every agent on every frozen suite, ``docs/learned_agents.md``.
"""
