"""Data in: measured engine data read, checked and set beside the model.

* :mod:`.columns` - the column registry (column name -> role, model quantity, unit conversion);
* :mod:`.dataset` - the measured-data format (CSV with units in the column names + ``.meta.json`` sidecar), its
  checked loader and the datasets shipped with the package;
* :mod:`.plausibility`, :mod:`.boundary_readings` - the checks that need no model: the engine's envelope,
  duplicates, boundary readings and per-cylinder groups;
* :mod:`.matching` - the model run at each measured operating point, the load law;
* :mod:`.discrepancy` - where and how the base model misses: bias, RMSE, trends, ranked.

Imports nothing of the other stages (``marine_fdi_env.layers``).
"""
