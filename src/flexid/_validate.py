"""Argument validators shared by the modules of flexid.

Each validator takes the value, the name the message gives it (as the caller should see
it, e.g. ``"n_samples"`` or ``"beam parameter 'n_sections'"``) and the
:class:`~flexid.errors.FlexidError` subclass to raise, since each module has its own error
type.  They return the value converted to a Python ``int`` or ``float``.

The rules are the same everywhere: ``bool`` is never a number (``True`` is a Python ``int``
but never a sample count or a sample time); NumPy integers are integers; strings are never
numbers, even when ``float`` would parse them; a real number is finite unless the caller
allows infinities, and NaN is never accepted.

The types are told apart through :mod:`numbers` (NumPy registers its scalar types there), so
this module does not import NumPy: :mod:`flexid.config` uses it and stays light.
"""

from __future__ import annotations

import functools
import inspect
import math
import numbers
from collections.abc import Callable, Iterable
from typing import Any

from .errors import FlexidError, UnknownKeywordError

__all__ = ["checked_keywords", "integer", "is_integer", "positive_int", "positive_real", "real"]


def is_integer(value: Any) -> bool:
    """True for a Python or NumPy integer that is not a ``bool``.

    Parameters
    ----------
    value : object
        Anything.

    Returns
    -------
    bool
        Whether ``value`` is an ``int`` or ``numpy.integer`` (``bool`` and ``numpy.bool_``
        excluded).
    """
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def _is_real(value: Any) -> bool:
    """True for a Python or NumPy real number or a 0-d numeric array, not a ``bool``."""
    if isinstance(value, numbers.Real):
        return not isinstance(value, bool)
    # a 0-d array, e.g. the dt read back from an NPZ file
    dtype = getattr(value, "dtype", None)
    return getattr(value, "ndim", None) == 0 and getattr(dtype, "kind", None) in ("i", "u", "f")


def _interval(
    minimum: float | None, maximum: float | None, low_open: bool, high_open: bool
) -> str:
    """``">= 1"``, ``"< 8"`` or ``"in (0, 1]"``; empty when there is no bound."""
    if minimum is not None and maximum is not None:
        left, right = "(" if low_open else "[", ")" if high_open else "]"
        return f"in {left}{minimum}, {maximum}{right}"
    if minimum is not None:
        return f"{'>' if low_open else '>='} {minimum}"
    if maximum is not None:
        return f"{'<' if high_open else '<='} {maximum}"
    return ""


def integer(
    value: Any,
    name: str,
    *,
    error: type[FlexidError],
    minimum: int | None = None,
    maximum: int | None = None,
    none_ok: bool = False,
    integral_float: bool = False,
) -> int | None:
    """Check that ``value`` is an integer in ``[minimum, maximum]`` and return it as ``int``.

    Parameters
    ----------
    value : object
        The argument to check.
    name : str
        How the message names the argument.
    error : type of FlexidError
        The exception class to raise.
    minimum, maximum : int, optional
        Inclusive bounds; None for no bound.
    none_ok : bool, optional
        Accept None (and return it).
    integral_float : bool, optional
        Also accept a float with an integer value, such as ``8.0`` (model orders that come
        from float arrays).

    Returns
    -------
    int or None
        ``int(value)``; None only when ``none_ok`` and ``value`` is None.

    Raises
    ------
    FlexidError
        ``error``, naming the argument, the allowed values and the value given: for a
        ``bool``, a non-integer (a float or a string included) or a value out of range.
    """
    if value is None and none_ok:
        return None
    ok = is_integer(value)
    if not ok and integral_float and _is_real(value):
        ok = float(value).is_integer()  # False for NaN and the infinities
    if ok:
        number = int(value)
        ok = (minimum is None or number >= minimum) and (maximum is None or number <= maximum)
    if not ok:
        bounds = _interval(minimum, maximum, False, False)
        wanted = f"an integer {bounds}" if bounds else "an integer"
        if none_ok:
            wanted += " or None"
        raise error(f"{name} must be {wanted}, got {value!r}")
    return number


def positive_int(value: Any, name: str, *, error: type[FlexidError]) -> int:
    """Check that ``value`` is an integer >= 1 and return it as ``int``.

    Parameters
    ----------
    value : object
        The argument to check.
    name : str
        How the message names the argument.
    error : type of FlexidError
        The exception class to raise.

    Returns
    -------
    int
        ``int(value)``.

    Raises
    ------
    FlexidError
        ``error`` for a ``bool``, a non-integer or a value below 1.
    """
    return integer(value, name, error=error, minimum=1)


def real(
    value: Any,
    name: str,
    *,
    error: type[FlexidError],
    minimum: float | None = None,
    maximum: float | None = None,
    low_open: bool = False,
    high_open: bool = False,
    allow_inf: bool = False,
    none_ok: bool = False,
    unit: str = "",
) -> float | None:
    """Check that ``value`` is a real number in an interval and return it as ``float``.

    Parameters
    ----------
    value : object
        The argument to check: a Python or NumPy number, or anything else ``float`` accepts
        except a string or a ``bool``.
    name : str
        How the message names the argument.
    error : type of FlexidError
        The exception class to raise.
    minimum, maximum : float, optional
        Bounds; None for no bound.
    low_open, high_open : bool, optional
        Exclude the bound itself (``minimum=0, low_open=True`` is "> 0").
    allow_inf : bool, optional
        Accept ``inf`` and ``-inf`` (still subject to the bounds); NaN is never accepted.
    none_ok : bool, optional
        Accept None (and return it).
    unit : str, optional
        The unit, named in the message (e.g. ``"s"``, ``"Hz"``).

    Returns
    -------
    float or None
        ``float(value)``; None only when ``none_ok`` and ``value`` is None.

    Raises
    ------
    FlexidError
        ``error``, naming the argument, the allowed values and the value given: for a
        ``bool``, a string, a non-number, NaN, an infinity (unless ``allow_inf``) or a value
        out of range.
    """
    if value is None and none_ok:
        return None
    number = float(value) if _is_real(value) else None
    if number is not None and _within(number, minimum, maximum, low_open, high_open, allow_inf):
        return number
    if unit:
        name = f"{name} [{unit}]"
    if number is None:
        raise error(f"{name} must be a number, got {value!r}")
    wanted = _wanted(minimum, maximum, low_open, high_open, allow_inf)
    raise error(f"{name} must be {wanted}{', or None' if none_ok else ''}, got {value!r}")


def _within(
    number: float, minimum: float | None, maximum: float | None, low_open: bool,
    high_open: bool, allow_inf: bool,
) -> bool:
    """Whether ``number`` is not NaN, finite unless ``allow_inf``, and within the bounds."""
    if math.isnan(number) or (not allow_inf and not math.isfinite(number)):
        return False
    if minimum is not None and not (number > minimum if low_open else number >= minimum):
        return False
    return maximum is None or (number < maximum if high_open else number <= maximum)


def _wanted(
    minimum: float | None, maximum: float | None, low_open: bool, high_open: bool,
    allow_inf: bool,
) -> str:
    """What :func:`real` accepts, in words: ``"positive and finite"``, ``"finite and >= 1"``."""
    if minimum == 0 and low_open and maximum is None:
        wanted = "positive" if allow_inf else "positive and finite"
    else:
        interval = _interval(minimum, maximum, low_open, high_open)
        finite = "" if allow_inf else "finite"
        wanted = " and ".join(filter(None, [finite, interval])) or "a number"
    return wanted + (" (not NaN)" if allow_inf else "")


def level(value: Any, name: str, *, error: type[FlexidError]) -> float:
    """Check that ``value`` is a probability strictly between 0 and 1 (a test's level).

    Parameters
    ----------
    value : object
        The argument to check.
    name : str
        How the message names the argument.
    error : type of FlexidError
        The exception class to raise.

    Returns
    -------
    float
        ``float(value)``.
    """
    return float(real(value, name, error=error, minimum=0.0, maximum=1.0, low_open=True,
                      high_open=True))  # fmt: skip


def positive_real(value: Any, name: str, *, error: type[FlexidError], unit: str = "") -> float:
    """Check that ``value`` is a finite real number > 0 and return it as ``float``.

    Parameters
    ----------
    value : object
        The argument to check.
    name : str
        How the message names the argument.
    error : type of FlexidError
        The exception class to raise.
    unit : str, optional
        The unit, named in the message.

    Returns
    -------
    float
        ``float(value)``.

    Raises
    ------
    FlexidError
        ``error`` for a ``bool``, a string, a non-number, NaN, an infinity or a value <= 0.
    """
    return real(value, name, error=error, minimum=0, low_open=True, unit=unit)


def checked_keywords(
    func: Callable | None = None, *, also: Iterable[str] | Callable[[], Iterable[str]] = ()
) -> Callable:
    """Decorator: an unknown keyword argument raises :class:`UnknownKeywordError` naming the
    function that was called, before anything runs.

    Python's own ``TypeError`` names the function too, but is not a ``FlexidError``; a
    function whose ``**kwargs`` are forwarded (to a reader, a reference) would otherwise
    fail inside the function it forwards to, under that one's name.

    Parameters
    ----------
    func : callable
        The function (the decorator may be used bare or called with ``also``).
    also : iterable of str, or a callable returning one
        The names a ``**kwargs`` parameter accepts (those of the function it forwards to).

    Returns
    -------
    callable
        The function, checked; ``__wrapped__`` is the original.
    """

    def wrap(f: Callable) -> Callable:
        sig = inspect.signature(f)
        own = {
            name for name, p in sig.parameters.items()
            if p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)
        }
        open_ended = any(p.kind is p.VAR_KEYWORD for p in sig.parameters.values())

        def accepted() -> set[str]:
            return own | (set(also() if callable(also) else also) if open_ended else set())

        @functools.wraps(f)
        def checked(*args: Any, **kwargs: Any) -> Any:
            if kwargs and not kwargs.keys() <= own:
                known = accepted()
                extra = kwargs.keys() - known
                if extra:
                    raise UnknownKeywordError(
                        f"{f.__name__}() got unexpected keyword argument(s) "
                        f"{', '.join(map(repr, sorted(extra)))}; it takes "
                        f"{', '.join(sorted(known))}"
                    )
            return f(*args, **kwargs)

        return checked

    return wrap(func) if func is not None else wrap
