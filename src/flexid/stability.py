"""Vectorised stability test of discrete-time denominators (Schur-Cohn step-down recursion).

A monic polynomial ``z^n + a_1 z^(n-1) + ... + a_n`` has all its roots strictly inside the
unit circle if and only if every reflection coefficient of the Schur-Cohn (backward
Levinson-Durbin) recursion has magnitude below one.  The recursion runs on the whole
population at once, no polynomial rooting: in the compiled kernel of :mod:`flexid.kernels`
when it was built, otherwise ``n`` NumPy array steps on ``(P, m)`` arrays.
"""

from __future__ import annotations

import numpy as np

from . import kernels
from ._validate import checked_keywords
from .errors import DataError

__all__ = [
    "is_stable",
    "is_stable_reference",
    "max_pole_radius",
    "pole_radius_batched",
    "poles_batched",
    "reflection_coefficients",
]


def _as_population(a) -> np.ndarray:
    a = np.asarray(a, dtype=float)
    if a.ndim == 1:
        a = a[None, :]
    if a.ndim != 2:
        raise DataError(f"denominator coefficients must have shape (P, na), got {a.shape}")
    return a


def reflection_coefficients(a) -> np.ndarray:
    """Reflection coefficients ``k_n, ..., k_1`` of monic denominators.

    Parameters
    ----------
    a : array_like, shape (P, na) or (na,)
        ``a_1 .. a_na`` of ``z^na + a_1 z^(na-1) + ... + a_na``.

    Returns
    -------
    ndarray, shape (P, na)
        Column ``j`` holds the reflection coefficient of degree ``na - j``.  Once a
        coefficient reaches magnitude 1 the remaining ones of that row are set to ``inf``.
    """
    a = _as_population(a).copy()
    p, n = a.shape
    k = np.empty((p, n))
    alive = np.ones(p, dtype=bool)
    for j, m in enumerate(range(n, 0, -1)):
        km = a[:, m - 1].copy()
        km[~alive] = np.inf
        k[:, j] = km
        ok = alive & (np.abs(km) < 1.0)
        alive = ok
        if m == 1:
            break
        denom = np.where(ok, 1.0 - km * km, 1.0)
        head = a[:, : m - 1]
        rev = head[:, ::-1]
        a[:, : m - 1] = np.where(ok[:, None], (head - km[:, None] * rev) / denom[:, None], 0.0)
    return k


@checked_keywords
def is_stable(a) -> np.ndarray:
    """Strict stability of monic denominators (every pole with ``|p| < 1``).

    Schur-Cohn step-down recursion on the whole population, no polynomial rooting: in
    compiled code when :mod:`flexid.kernels` has it (one pass per candidate, about 0.1 µs
    for ``na = 8``), otherwise :func:`is_stable_reference` (``na`` NumPy array steps).

    Parameters
    ----------
    a : array_like, shape (P, na) or (na,)
        ``a_1 .. a_na`` of ``A(z) = z^na + a_1 z^(na-1) + ... + a_na`` (the ARX ``A``
        polynomial without its leading 1).

    Returns
    -------
    ndarray of bool, shape (P,)
        True where all roots lie strictly inside the unit circle.  Non-finite rows are
        unstable; ``na = 0`` is always stable.
    """
    a = _as_population(a)
    if kernels.BACKEND == "c":
        return kernels.schur_cohn_compiled(a)
    return is_stable_reference(a)


def is_stable_reference(a) -> np.ndarray:
    """NumPy Schur-Cohn test, vectorised over the population (the reference path).

    Once a row has a reflection coefficient with ``|k| >= 1`` it is marked unstable; later
    steps may overflow in that row, which is ignored.  Same contract as :func:`is_stable`.

    Parameters
    ----------
    a : array_like, shape (P, na) or (na,)
        Denominator coefficients ``a1..a_na`` (``A = 1 + a1 q^-1 + ...``).

    Returns
    -------
    ndarray of bool, shape (P,)
        True where all roots lie strictly inside the unit circle.
    """
    a = _as_population(a)
    p, n = a.shape
    if n == 0:
        return np.ones(p, dtype=bool)
    ok = np.isfinite(a).all(axis=1)
    cur = np.where(ok[:, None], a, 0.0)
    with np.errstate(all="ignore"):  # rows already failed may overflow; they stay False
        for m in range(n, 0, -1):
            k = cur[:, m - 1 : m]
            ok &= np.abs(k[:, 0]) < 1.0
            if m == 1:
                break
            head = cur[:, : m - 1]
            cur = (head - k * head[:, ::-1]) / (1.0 - k * k)
    return ok


def max_pole_radius(a) -> np.ndarray:
    """Largest pole magnitude of each denominator, ``inf`` for a row with non-finite values.

    Parameters
    ----------
    a : array_like, shape (P, na) or (na,)

    Returns
    -------
    ndarray, shape (P,)
        ``max |p|`` (0 for ``na = 0``; see :func:`pole_radius_batched`).
    """
    a = _as_population(a)
    out = np.full(a.shape[0], np.inf)
    finite = np.isfinite(a).all(axis=1)
    out[finite] = pole_radius_batched(a[finite])
    return out


def poles_batched(a) -> np.ndarray:
    """Poles of each denominator, batched: eigenvalues of the stacked companion matrices.

    What ``np.roots`` does row by row, in one call to NumPy's batched ``eigvals`` (no Python
    loop).  LAPACK returns real eigenvalues with an imaginary part of exactly 0 and complex
    ones in exact conjugate pairs.

    Parameters
    ----------
    a : array_like, shape (P, na) or (na,)
        ``a_1 .. a_na`` of ``A(z) = 1 + a_1 z^-1 + ... + a_na z^-na``; finite.

    Returns
    -------
    ndarray, shape (P, na), complex
    """
    a = _as_population(a)
    p, na = a.shape
    if na == 0 or p == 0:
        return np.zeros((p, na), dtype=complex)
    companion = np.zeros((p, na, na))
    companion[:, 0, :] = -a
    idx = np.arange(na - 1)
    companion[:, idx + 1, idx] = 1.0
    return np.linalg.eigvals(companion).astype(complex)


def pole_radius_batched(a) -> np.ndarray:
    """Largest pole magnitude of each denominator, batched (see :func:`poles_batched`).

    Used by the graded stability penalty on the unstable rows of a population.

    Parameters
    ----------
    a : array_like, shape (P, na) or (na,)

    Returns
    -------
    ndarray, shape (P,)
        ``max |p|`` (0 for ``na = 0``).
    """
    poles = poles_batched(a)
    return np.abs(poles).max(axis=1, initial=0.0)
