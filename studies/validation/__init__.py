"""Studies of marine_fdi_env.validation (see studies/README.md)."""
