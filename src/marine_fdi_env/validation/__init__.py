"""Validation of the engine model against measured data (docs/validation.md), stage by stage.

* :mod:`.measured` - data in: the measured-data format, its checked loader, the shipped datasets, the model run at
  each measured point and its discrepancies;
* :mod:`.fit` - the fitting problem, the mechanism library, fits and cross-validation, synthetic data;
* :mod:`.select` - which mechanisms the data name, what is left unexplained, replicas;
* :mod:`.explain` - the explanations the data do not decide between and the measurement that would decide;
* :mod:`.report` - the report (JSON, Markdown, plots) and ``validate --check``.

Each stage imports only the stages before it (``python -m marine_fdi_env.info --imports`` checks it).  The names
below are the measured-data entry points.
"""

from .measured.dataset import (
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
