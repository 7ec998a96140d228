"""The benchmark: frozen suites, metrics, episode records, the agent interface and registry, evaluation,
sweeps on serial / process / Ray backends, datasets for offline learning, reports, and the raw-data
(LiU-ICE / DX'25) export and scoring.  It runs agents on the environments of :mod:`marine_fdi_env.envs`.
"""
