"""Studies of marine_fdi_env.engine: the shipped parameter sets."""
