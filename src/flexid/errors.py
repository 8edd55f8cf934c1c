"""Typed exceptions raised by flexid.

Every error flexid raises on purpose derives from :class:`FlexidError`, so a caller can
catch them all in one place; each also derives from the built-in exception a Python user
would expect (``ValueError`` for bad values, ``LookupError`` for unknown names, ``OSError``
for unreadable files), so generic handlers keep working.  The command line turns any
``FlexidError`` into one line on stderr and exit status 2.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # pragma: no cover - NumPy is imported on first use: `import flexid` stays light
    import numpy as np

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
    "check_finite",
    "plain_number",
]


class FlexidError(Exception):
    """Base class of every error flexid raises on purpose."""


class DataError(FlexidError, ValueError):
    """Input-output data that cannot be used: NaN/inf, mismatched lengths, bad sample time..."""


class DataFileError(DataError, OSError):
    """A data or result file that is missing, unreadable or malformed."""


class ModelOrderError(FlexidError, ValueError):
    """Invalid model orders (``na``, ``nb``, ``nk``), or too few samples for them."""


class OptimiserError(FlexidError):
    """Base class of optimiser and registry errors."""


class UnknownNameError(FlexidError, LookupError):
    """A name (plant, signal, cost, optimiser...) that flexid does not know.

    Parameters
    ----------
    kind : str
        What was looked up, e.g. ``"optimiser"``.
    name : str
        The unknown name.
    known : iterable of str
        The names that would have worked; listed in the message.
    """

    def __init__(self, kind: str, name: str, known=()):
        self.kind = kind
        self.name = name
        self.known = sorted(known)
        listing = ", ".join(self.known) if self.known else "none"
        super().__init__(f"unknown {kind} {name!r}; known: {listing}")

    def __str__(self) -> str:  # LookupError/KeyError would quote the message
        return str(self.args[0])


class UnknownOptimiserError(UnknownNameError, OptimiserError):
    """An optimiser name that is neither built in nor provided by a plugin.

    Parameters
    ----------
    name : str
        The name that was asked for.
    known : sequence of str
        The names that exist (listed in the message).
    """

    def __init__(self, name: str, known=()):
        super().__init__("optimiser", name, known)


class RegistryError(OptimiserError, ValueError):
    """A registry misuse, such as registering a name twice."""


class HyperParameterError(OptimiserError, ValueError):
    """An unknown, wrongly typed or out-of-range optimiser hyper-parameter."""


class BudgetError(FlexidError, ValueError):
    """An invalid evaluation budget or stopping rule."""


class PlantParameterError(FlexidError, ValueError):
    """An invalid physical parameter or option of a simulated plant."""


class ActionError(FlexidError, ValueError):
    """An action given to an environment that cannot be applied (wrong shape, NaN, inf)."""


class ConfigError(FlexidError, ValueError):
    """An invalid configuration file or key."""


class StoreError(FlexidError):
    """A result store that cannot be opened, read or written."""


class UnknownKeywordError(FlexidError, TypeError):
    """A keyword argument the function that was called does not take (named in the message)."""


class FlexidWarning(UserWarning):
    """Base class of the warnings flexid issues: a result is computed, but read it with care.

    The command line prints each as one line, ``flexid: warning: ...``, on stderr.
    """


class DataWarning(FlexidWarning):
    """A record was read with an assumption the user should know (e.g. a non-uniform time
    column read at its median step)."""


class IdentificationWarning(FlexidWarning):
    """An identification problem that has an answer, but a fragile one (e.g. an input that is
    only barely persistently exciting for the model's orders)."""


class StoreWarning(FlexidWarning):
    """A result store read in part: damaged run records were skipped (and are named)."""


class FlexidDeprecationWarning(FlexidWarning, FutureWarning):
    """An old spelling that still works, with what to write instead in the message.

    A :class:`FutureWarning` as well, so Python shows it by default (a plain
    ``DeprecationWarning`` is hidden outside ``__main__``).
    """


def check_finite(array: np.ndarray, what: str, error: type[FlexidError] = DataError) -> None:
    """Raise ``error`` naming the first non-finite entry of ``array``.

    Parameters
    ----------
    array : ndarray
        Values to check; any shape.
    what : str
        Name of the array in the message, e.g. ``"input 'torque'"``.
    error : type, optional
        Exception class to raise (default :class:`DataError`).

    Raises
    ------
    FlexidError
        If any entry is NaN or infinite; the message gives its index, its value and how
        many entries are affected.
    """
    import numpy as np

    array = np.asarray(array)
    if array.dtype.kind not in "fc":
        return
    bad = ~np.isfinite(array)
    if bad.any():
        where = np.argwhere(bad)
        first = tuple(int(i) for i in where[0])
        index = first[0] if len(first) == 1 else first
        label = "sample" if array.ndim <= 1 else "index (sample, channel)"
        raise error(
            f"{what} has {int(bad.sum())} non-finite value(s); the first is "
            f"{plain_number(array[first])} at {label} {index}"
        )


def plain_number(value: object) -> str:
    """A number, or numbers, as a user reads them in a message: ``inf``, ``1e+308``,
    ``[0.5, nan]``, never a NumPy repr such as ``np.float64(inf)`` or ``array([nan])``.

    Parameters
    ----------
    value : object
        A number, a NumPy scalar or array, a list or tuple of them, a string (quoted), or
        anything else (shown with ``str``).

    Returns
    -------
    str
    """
    tolist = getattr(value, "tolist", None)
    if callable(tolist):  # NumPy scalars and arrays: Python numbers and lists
        value = tolist()
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(plain_number(v) for v in value) + "]"
    if isinstance(value, str):  # quoted, as a user typed it
        return repr(value)
    if isinstance(value, bool) or value is None:
        return str(value)
    try:
        number = complex(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return str(value)
    if number.imag == 0:
        real = number.real
        return str(value) if isinstance(value, int) else f"{real:g}"
    return str(number)


def _unreadable(
    path: str | os.PathLike,
    exc: OSError,
    *,
    error: type[FlexidError] = DataFileError,
    kind: str = "data file",
    missing: str = "file",
) -> FlexidError:
    """The one-line error of a file that could not be opened or read, for the modules that
    read files: ``"PATH: no such {missing}"``, ``"PATH: is a directory, not a {kind}"`` or
    ``"PATH: cannot read (REASON)"``, as an ``error`` to raise ``from None``."""
    if isinstance(exc, FileNotFoundError):
        return error(f"{path}: no such {missing}")
    if isinstance(exc, IsADirectoryError):
        return error(f"{path}: is a directory, not a {kind}")
    return error(f"{path}: cannot read ({exc.strerror or exc})")
