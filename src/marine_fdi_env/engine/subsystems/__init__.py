"""The four interconnected subsystems Σ1-Σ4 of the MVFP engine model (thesis ch. 3).

Each module gives its subsystem's differential part (linear coefficient and forcing of
``x' = a x + F``) and its algebraic part; :mod:`marine_fdi_env.engine.model` couples them.
"""
