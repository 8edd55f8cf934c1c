"""flexid: flexible-plant simulators, ARX identification with pluggable optimisers, fair comparison.

Importing ``flexid`` registers the Gymnasium environments ``flexid/FlexibleManipulator-v0``
and ``flexid/TwinRotor-v0``.  Public names are imported lazily from their modules, so
``import flexid`` stays quick.
"""

from __future__ import annotations

import importlib
from typing import Any

from . import envs as _envs  # noqa: F401  (registers the Gymnasium environments)
from .errors import (
    ActionError,
    BudgetError,
    ConfigError,
    DataError,
    DataFileError,
    FlexidError,
    HyperParameterError,
    ModelOrderError,
    OptimiserError,
    PlantParameterError,
    RegistryError,
    StoreError,
    UnknownNameError,
    UnknownOptimiserError,
)

__version__ = "0.1.0"

# public name -> module that defines it (imported on first use)
_LAZY = {
    "IOData": "data",
    "load": "data",
    "save": "data",
    "ARX": "arx",
    "ARXStructure": "arx",
    "ARXCost": "objective",
    "make_cost": "objective",
    "is_stable": "stability",
    "validate": "validation",
    "ValidationReport": "validation",
    "identify": "identify",
    "Identification": "identify",
    "compare": "compare",
    "SearchSpec": "config",
    "generate": "datasets",
    "minimize": "optimisers",
    "Problem": "optimisers",
    "Budget": "optimisers",
    "register": "optimisers",
    "signals": None,
    "optimisers": None,
    "envs": None,
}

__all__ = [
    "ActionError",
    "BudgetError",
    "ConfigError",
    "DataError",
    "DataFileError",
    "FlexidError",
    "HyperParameterError",
    "ModelOrderError",
    "OptimiserError",
    "PlantParameterError",
    "RegistryError",
    "StoreError",
    "UnknownNameError",
    "UnknownOptimiserError",
    "__version__",
    *sorted(_LAZY),
]


def __getattr__(name: str) -> Any:
    if name not in _LAZY:
        raise AttributeError(f"module 'flexid' has no attribute {name!r}")
    module_name = _LAZY[name]
    if module_name is None:
        value = importlib.import_module(f".{name}", __name__)
    else:
        value = getattr(importlib.import_module(f".{module_name}", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
