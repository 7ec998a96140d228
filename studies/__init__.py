"""Research studies of marine_fdi_env: the experiments behind the shipped calibrations, bounds and tables.

Not installed and never imported by the package: each study reads and writes through the package's
public API and runs from a checkout of the repository (``python -m studies.<part>.<study> ...`` from its
root).  Their outputs ship where the package or the docs load them from (:mod:`studies.paths`).
"""
