"""flexid: flexible-plant simulators, identification with pluggable optimisers, fair comparison.

The names here are the front door; each is imported from its module on first use, so
``import flexid`` stays quick (it does not import Gymnasium).

Data and models
    :class:`IOData`, :func:`load`, :func:`save`, :func:`generate`, :class:`ARX`,
    :class:`ARXStructure`, :class:`ARXCost`, :func:`is_stable`, :func:`validate`,
    :class:`ValidationReport`; the polynomial family (ARX, ARMAX, OE, BJ):
    :func:`structure`, :class:`PolynomialStructure`, :class:`PolynomialModel`,
    :class:`PolynomialCost`
Structure selection
    :func:`select` (AIC, FPE, MDL and the held-out tests over a grid of structures);
    :func:`estimate_delay` (MATLAB ``delayest``, and the prewhitened cross-correlation)
Frequency responses
    :func:`frf` (MATLAB ``tfestimate``, ``spa``, ``etfe``) -> :class:`FrequencyResponseEstimate`
    with coherence and a confidence band; :func:`frequency_agreement` (the share of a
    model's response inside that band)
Grey-box models
    :class:`GreyBoxModel` of :class:`GreyParameter` (a plant's equations with named physical
    parameters), the built-in ones and a user's (``file.py:NAME``, or registered by
    :func:`register_greybox_model`) by :func:`greybox_model`, their simulation cost
    :class:`GreyBoxCost` and the reference :func:`greyest` -> :class:`GreyBoxResult`;
    :func:`identify` and :func:`compare` take them as ``structure``
References
    :func:`pem` and MATLAB's :func:`oe`, :func:`armax`, :func:`bj` (Levenberg-Marquardt on
    the prediction errors, analytic gradients); every reference, :func:`greyest` among them,
    returns a :class:`ReferenceResult` (a :class:`scipy.optimize.OptimizeResult`); subspace
    identification of a :class:`StateSpaceModel` with several inputs and outputs,
    :func:`n4sid`, and its prediction-error refinement over the modes, :func:`ssest`
    (:class:`StateSpaceStructure`: ``identify(structure="ss", order=...)``)
Identification
    :func:`identify` -> :class:`Identification`; the search box (:class:`SearchBox`,
    :func:`search_box`), search space (:class:`SearchSpec`) and cost (:class:`CostSpec`)
Comparison
    :func:`compare` (:class:`ComparisonSpec` of :class:`DataSpec`, :class:`ModelSpec`,
    :class:`CostSpec`, :class:`SearchSpec`, :class:`OptimiserSpec`) -> :class:`ComparisonResult`;
    :func:`check_spec`, :func:`load_result`
Optimisers
    :func:`minimize`, :class:`Problem`, :class:`Budget`, :class:`AskTell`; writing one:
    :class:`Optimiser`, :class:`Param`, :func:`register`
Modules
    :mod:`flexid.data.signals`, :mod:`flexid.optimisers`, :mod:`flexid.envs`; errors from
    :mod:`flexid.errors`

The Gymnasium environments ``flexid/FlexibleManipulator-v0`` and ``flexid/TwinRotor-v0``
are registered once both flexid and Gymnasium are imported, in either order (see
:mod:`flexid.envs`).
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from typing import Any

from ._gymnasium_hook import install as _install_gymnasium_hook
from ._lazy import lazy_exports
from ._moved import FINDER as _MOVED_FINDER
from ._version import __version__
from .errors import (
    ActionError,
    BudgetError,
    ConfigError,
    DataError,
    DataFileError,
    DataWarning,
    FlexidDeprecationWarning,
    FlexidError,
    FlexidWarning,
    HyperParameterError,
    IdentificationWarning,
    ModelOrderError,
    OptimiserError,
    PlantParameterError,
    RegistryError,
    StoreError,
    StoreWarning,
    UnknownKeywordError,
    UnknownNameError,
    UnknownOptimiserError,
)

# public name -> module that defines it (imported on first use)
_LAZY = {
    # data and models
    "IOData": "data.records",
    "load": "data.records",
    "save": "data.records",
    "generate": "data.datasets",
    "ARX": "models.arx",
    "ARXStructure": "models.arx",
    "ARXCost": "costs.arx",
    "is_stable": "models.stability",
    "validate": "validation.verdict",
    "ValidationReport": "validation.verdict",
    "structure": "models.polynomial",
    "PolynomialStructure": "models.polynomial",
    "PolynomialModel": "models.polynomial",
    "PolynomialCost": "costs.polynomial",
    "select": "jobs.selection",
    "estimate_delay": "fit.delay",
    # frequency responses
    "frf": "validation.frequency",
    "FrequencyResponseEstimate": "validation.frequency",
    "frequency_agreement": "validation.frequency",
    # grey-box models
    "GreyBoxModel": "models.greybox",
    "GreyParameter": "models.greybox",
    "GreyBoxCost": "costs.greybox",
    "greybox_model": "models.greybox_library",
    "register_greybox_model": "models.greybox_library",
    "greyest": "fit.greybox_fit",
    "GreyBoxResult": "fit.greybox_fit",
    # references
    "pem": "fit.prediction_error",
    "oe": "fit.prediction_error",
    "armax": "fit.prediction_error",
    "bj": "fit.prediction_error",
    "ReferenceResult": "fit.reference",
    "n4sid": "fit.subspace",
    "ssest": "fit.statespace_fit",
    "StateSpaceModel": "models.statespace",
    "StateSpaceStructure": "models.statespace",
    # identification (the function lives in a private module: no module shares its name)
    "identify": "jobs._identify",
    "Identification": "jobs._identification",
    "SearchBox": "fit.parametrisation",
    "search_box": "fit.estimation",
    # comparison
    "compare": "jobs._compare",
    "ComparisonResult": "jobs._comparison_result",
    "check_spec": "jobs._compare",
    "load_result": "jobs._compare",
    "ComparisonSpec": "config",
    "DataSpec": "config",
    "ModelSpec": "config",
    "CostSpec": "config",
    "SearchSpec": "config",
    "OptimiserSpec": "config",
    # optimisers
    "minimize": "optimisers",
    "Problem": "optimisers",
    "Budget": "optimisers",
    "AskTell": "optimisers",
    "Optimiser": "optimisers",
    "Param": "optimisers",
    "register": "optimisers",
    # public modules
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
    "DataWarning",
    "FlexidDeprecationWarning",
    "FlexidError",
    "FlexidWarning",
    "HyperParameterError",
    "IdentificationWarning",
    "ModelOrderError",
    "OptimiserError",
    "PlantParameterError",
    "RegistryError",
    "StoreError",
    "StoreWarning",
    "UnknownKeywordError",
    "UnknownNameError",
    "UnknownOptimiserError",
    "__version__",
    *sorted(_LAZY),
]


__getattr__, __dir__ = lazy_exports(__name__, _LAZY)


def _register_notebook_figures() -> None:
    """Give the notebook displays of the results their Bode figures.

    The results sit below the figures' module in the layers, so the front door joins them;
    matplotlib is imported when a display is first drawn, not by ``import flexid``.
    """
    from . import _html

    def drawer(kind: str) -> Callable[[Any], list[bytes]]:
        def draw(result: Any) -> list[bytes]:
            from .report.plots import notebook_figures

            return notebook_figures(kind, result)

        return draw

    for kind in ("identification", "comparison", "selection"):
        _html.register_figures(kind, drawer(kind))


if _MOVED_FINDER not in sys.meta_path:  # the public modules' import paths before the layers
    sys.meta_path.append(_MOVED_FINDER)
_install_gymnasium_hook()  # registers the environments once Gymnasium is imported
_register_notebook_figures()
