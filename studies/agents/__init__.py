"""The comparison of every agent on every suite (see studies/README.md)."""
