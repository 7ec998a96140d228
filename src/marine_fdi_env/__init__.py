"""marine_fdi_env: a fault detection and isolation benchmark on an MVFP marine diesel engine model.

Importing the package registers the Gymnasium environments ``MarineFDI-v0`` and ``MarineFDI-v1``.
"""

from ._version import __version__
from .engine.params import EngineParams, list_parameter_sets, load_params
from .envs import ENV_ID, register_envs

__all__ = ["EngineParams", "load_params", "list_parameter_sets", "ENV_ID", "__version__"]

register_envs()
