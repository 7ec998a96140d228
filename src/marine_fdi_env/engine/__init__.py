"""The engine: the mean-value first-principle (MVFP) model of a marine diesel engine (thesis ch. 3-4).

Parameters (:mod:`.params`, :mod:`.submodels`, derived by :mod:`.calibration` from
:mod:`.geometry`; data files in ``marine_fdi_env/data/params``), the cycle (:mod:`.seiliger`,
:mod:`.constants`), the subsystems Σ1-Σ4 (:mod:`.subsystems`) coupled in :mod:`.model`, its
steady states (:mod:`.steady_state`, :mod:`.operating_point`, :mod:`.turbocharger_speed`), the
integrators (:mod:`.integrators`), sensors, faults and load profiles (:mod:`.sensors`,
:mod:`.faults`, :mod:`.profiles`) and the batched simulator (:mod:`.simulator`).

Layer: the engine imports only the parameters and the package's small utilities
(``_jit``, ``coldstart``, ``suggest``); nothing here imports diagnosis, environments or agents
(checked by ``python -m marine_fdi_env.info --imports``).  This ``__init__`` imports nothing, so
that importing one engine module does not load the others.
"""
