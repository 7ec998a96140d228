"""Studies of marine_fdi_env.diagnosis (see studies/README.md)."""
