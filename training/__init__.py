"""Learned diagnosers for ``MarineFDI-v1`` (needs the ``train`` extra: torch, stable-baselines3, pyyaml).

* :mod:`marine_fdi_env.training.train` - ``marine-fdi train --algo ppo|ppo_lstm|classifier [--env ID] --seed N``
  (hyperparameters in ``training/hyperparams/ALGO.yml``, keyed by env id);
* :mod:`marine_fdi_env.training.rl`, :mod:`marine_fdi_env.training.replay`, :mod:`marine_fdi_env.training.features` - PPO on recorded
  MarineFDI-v1 episodes (bit-equal to the live env), with the agent's own input preprocessing;
* :mod:`marine_fdi_env.training.vec_adapter` - SB3 ``VecEnv`` over the batched vector environment, action modes;
* :mod:`marine_fdi_env.training.classifier` - the supervised GRU diagnoser and its threshold calibration;
* :mod:`marine_fdi_env.training.agents` - trained models as benchmark agents (``marine-fdi evaluate --agent
  training/models/NAME``).
"""
