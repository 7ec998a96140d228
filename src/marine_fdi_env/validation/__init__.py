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

from .measured.dataset import DataFinding, DatasetError, DataWarning, MeasuredDataset
from .measured.loader import list_shipped, load_measured, load_shipped, write_measured
from .measured.readers import READERS, RawTable, Reader

__all__ = [
    "DataFinding",
    "DataWarning",
    "DatasetError",
    "MeasuredDataset",
    "READERS",
    "RawTable",
    "Reader",
    "list_shipped",
    "load_measured",
    "load_shipped",
    "write_measured",
]

# the names these functions had before 0.2.2: kept working, with a DeprecationWarning, for users' code
_RENAMED = {"load_dataset": "load_measured", "write_dataset": "write_measured"}


def __getattr__(name: str):
    if name in _RENAMED:
        import warnings

        new = _RENAMED[name]
        warnings.warn(
            f"marine_fdi_env.validation.{name} is now {new} (load_dataset is the training features' loader of "
            "marine_fdi_env.benchmark.dataset)",
            DeprecationWarning,
            stacklevel=2,
        )
        return globals()[new]
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
