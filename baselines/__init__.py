"""Non-learned agents of the benchmark: null, random, oracle, the reference diagnoser and the
sequential diagnoser.

``marine-fdi evaluate --agent null|random|reference|sequential|oracle`` loads them by name
(:mod:`marine_fdi_env.benchmark.agent_api`).
"""
