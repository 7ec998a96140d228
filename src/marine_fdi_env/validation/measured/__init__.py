"""Data in: measured engine data read, checked and set beside the model.

* :mod:`.readers` - the reader seam: a :class:`~.readers.Reader` per file format (CSV, Parquet) turns a file into a
  :class:`~.readers.RawTable`; :mod:`.sidecar` - the ``FILE.meta.json`` beside it, whatever the format;
* :mod:`.checks` - every check of a file as read, once, whatever its format (:mod:`.plausibility`,
  :mod:`.boundary_readings`: the engine's envelope, duplicates, boundary readings, per-cylinder groups);
* :mod:`.dataset` - the format and the checked :class:`~.dataset.MeasuredDataset`; :mod:`.columns` - the column
  registry (column name -> role, model quantity, unit conversion);
* :mod:`.loader` - :func:`~.loader.load_measured` (read, then check), the shipped datasets, the CSV writer;
* :mod:`.matching` - the model run at each measured operating point, the load law;
* :mod:`.discrepancy` - where and how the base model misses: bias, RMSE, trends, ranked.

Imports nothing of the other stages (``marine_fdi_env.layers``).
"""
