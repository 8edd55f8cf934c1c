"""The vocabulary and its defaults: structure and reference names, the initial-state
rule of each structure, the residual tests' lags and level, the pole-radius cap and the
jobs' budgets, each stated once.

Every layer reads them from here; :mod:`flexid.config` shows them to users.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence

from ..errors import FlexidDeprecationWarning

__all__ = [
    "COMPARE_BUDGET",
    "COMPARE_RUNS",
    "CORRELATION_LAGS",
    "DEFAULT_OPTIMISERS",
    "DEPRECATED_REFERENCES",
    "GREYBOX",
    "IDENTIFY_BUDGET",
    "LEAST_SQUARES",
    "OUTPUT_ERROR",
    "POLE_RADIUS_CAP",
    "PREDICTION_ERROR",
    "REFERENCES",
    "REFLECTION_CAP",
    "SCHEDULE",
    "STATE_SPACE",
    "STRUCTURE_NAMES",
    "SUBSPACE",
    "VALIDATION_ALPHA",
    "VALIDATION_GUIDE",
    "add_structure_names",
    "auto_initial",
    "current_reference",
    "structure_names",
]


DEFAULT_OPTIMISERS = ("hbcsd", "bfa", "sda", "pso", "de")
#: Function evaluations of one identification by an optimiser (``identify``, ``greybox``).
IDENTIFY_BUDGET = 20_000
#: Function evaluations of each run of a comparison, and its runs per optimiser.
COMPARE_BUDGET = 10_000
COMPARE_RUNS = 5
SCHEDULE = "schedule"
#: The least-squares reference: an ``optimiser`` name of ``identify`` and the label of the
#: reference row every comparison includes.
LEAST_SQUARES = "ls"
#: A deprecated spelling of :data:`PREDICTION_ERROR` (it read as "an output-error model",
#: which is ``structure="oe"``); ``identify`` warns and runs ``"pem"``.
OUTPUT_ERROR = "oe"
#: The gradient reference of any structure's cost (Levenberg-Marquardt with analytic
#: gradients, :func:`flexid.fit.prediction_error.pem`): an ``optimiser`` name of ``identify``.
PREDICTION_ERROR = "pem"
#: Subspace identification of a state-space model (:func:`flexid.n4sid`): an ``optimiser``
#: name of ``identify`` for ``structure="ss"``.
SUBSPACE = "n4sid"
#: The ``optimiser`` names of the references, which take no FE budget (the deprecated
#: spellings among them, so they are recognised before they are replaced).
REFERENCES = (LEAST_SQUARES, OUTPUT_ERROR, PREDICTION_ERROR, SUBSPACE)
#: Old reference names and the one each now is.
DEPRECATED_REFERENCES = {OUTPUT_ERROR: PREDICTION_ERROR}
#: Levenberg-Marquardt starts of the polynomial references beside the deterministic ones
#: (least squares, Steiglitz-McBride, Hannan-Rissanen), in identify, compare and select alike,
#: so one structure gives one model whichever job fits it.
REFERENCE_STARTS = 4
#: Starts of the grey-box reference (:func:`flexid.fit.greybox_fit.greyest`).
GREYBOX_REFERENCE_STARTS = 3
#: The named model structures (their orders: :data:`flexid.models.polynomial.STRUCTURES`).
STRUCTURE_NAMES = ("arx", "armax", "oe", "bj")
#: The structure name of a grey-box model (:mod:`flexid.models.greybox`), beside the
#: polynomial ones.
GREYBOX = "greybox"
#: The structure name of a state-space model of every output (:mod:`flexid.models.statespace`;
#: its orders, ``order`` and ``modes``, in a :class:`ModelSpec`'s ``options``).
STATE_SPACE = "ss"
# Structure names of the model families registered beyond the built-in ones
# (flexid.models.families.register_family adds theirs): a ModelSpec may name them.
_REGISTERED_NAMES: set[str] = set()


def add_structure_names(names: Sequence[str]) -> None:
    """Let a :class:`ModelSpec` name these structures (a registered family builds them).

    Parameters
    ----------
    names : sequence of str
        Lower-case structure names.
    """
    _REGISTERED_NAMES.update(str(n).lower() for n in names)


def structure_names() -> tuple[str, ...]:
    """Every structure name a :class:`~flexid.config.ModelSpec` takes: the built-in ones,
    then those of the registered families (:func:`add_structure_names`), sorted.

    Returns
    -------
    tuple of str
    """
    builtin = (*STRUCTURE_NAMES, GREYBOX, STATE_SPACE)
    return (*builtin, *sorted(_REGISTERED_NAMES - set(builtin)))
#: Lags of the residual correlation tests (auto- and cross-correlation, Billings-Voon), as
#: MATLAB's ``resid`` and Ljung (System Identification, 2nd ed., sec. 16.6) use.
CORRELATION_LAGS = 25
#: Family-wise level of a validation verdict: the rate at which the residual tests together
#: reject a true model (Holm's correction over the tests; see :mod:`flexid.validation.diagnostics`).
VALIDATION_ALPHA = 0.05
#: The guide's page on reading a validation verdict, named beside every FAIL.
VALIDATION_GUIDE = "https://github.com/flexid/flexid/blob/main/docs/guide/validation.rst"
#: Largest pole radius of the ``"poles"`` search space, and of every reference fitted to
#: compare with it: a pole closer to the circle than 1e-4 is not a model a user wants.
POLE_RADIUS_CAP = 0.9999
#: Bound of every reflection coefficient ``|k|`` of the ``"reflection"`` search space.
REFLECTION_CAP = 0.9999


def current_reference(optimiser: str, *, stacklevel: int = 3) -> str:
    """The optimiser name to run: a deprecated reference spelling warns and gives its new one.

    Parameters
    ----------
    optimiser : str
        An ``optimiser`` name as a user wrote it.
    stacklevel : int
        Passed to :func:`warnings.warn`, so the warning points at the user's call.

    Returns
    -------
    str
        ``optimiser`` itself, or the name a deprecated spelling stands for (``"oe"`` ->
        ``"pem"``).

    Warns
    -----
    FlexidDeprecationWarning
        For a deprecated spelling, saying what to write.
    """
    new = DEPRECATED_REFERENCES.get(optimiser) if isinstance(optimiser, str) else None
    if new is None:
        return optimiser
    warnings.warn(
        f"optimiser {optimiser!r} is deprecated: write {new!r}; an output-error model is "
        "structure 'oe'",
        FlexidDeprecationWarning,
        stacklevel=stacklevel,
    )
    return new


def auto_initial(structure: str) -> str:
    """The initial-condition rule ``"auto"`` stands for with a structure of this name.

    ``"measured"`` for ARX (the setting of the paper's experiments, kept as it was) and
    ``"estimate"`` for every other structure: their predictors are recursive, and starting a
    lightly damped high-order recursion from measured outputs excites a transient that is not
    the model's (see :mod:`flexid.models.polynomial`).

    Parameters
    ----------
    structure : str
        A structure's name (:data:`STRUCTURE_NAMES`, or ``"polynomial"``).

    Returns
    -------
    str
    """
    return "measured" if structure == "arx" else "estimate"
