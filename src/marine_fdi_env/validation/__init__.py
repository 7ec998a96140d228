"""Validation of the engine model against measured data (docs/validation.md).

* :mod:`.dataset` - the measured-data format (CSV with units in the column names + ``.meta.json``
  sidecar), its checked loader and the datasets shipped with the package;
* :mod:`.columns` - the column registry (column name -> model quantity, unit conversion);
* :mod:`.matching` - running the model at each measured operating point, load-law inference;
* :mod:`.discrepancy` - bias, RMSE, relative error and the structure of the residuals, ranked.
"""

from .dataset import (
    DatasetError,
    DataWarning,
    MeasuredDataset,
    list_shipped,
    load_dataset,
    load_shipped,
    write_dataset,
)

__all__ = [
    "DataWarning",
    "DatasetError",
    "MeasuredDataset",
    "list_shipped",
    "load_dataset",
    "load_shipped",
    "write_dataset",
]
