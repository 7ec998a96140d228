"""Non-learned agents of the benchmark: null, random, oracle and the reference diagnoser.

``marine-fdi evaluate --agent null|random|reference|oracle`` loads them by name
(:mod:`marine_fdi_env.envs.agent_api`).
"""
