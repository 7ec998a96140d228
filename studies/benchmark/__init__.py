"""Studies of marine_fdi_env.benchmark: the frozen suites' builders."""
