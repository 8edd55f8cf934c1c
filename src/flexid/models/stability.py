"""Vectorised stability test of discrete-time denominators (Schur-Cohn step-down recursion).

A monic polynomial ``z^n + a_1 z^(n-1) + ... + a_n`` has all its roots strictly inside the
unit circle if and only if every reflection coefficient of the Schur-Cohn (backward
Levinson-Durbin) recursion has magnitude below one.  The recursion runs on the whole
population at once, no polynomial rooting: in the compiled kernel of :mod:`flexid.kernels`
when it was built, otherwise ``n`` NumPy array steps on ``(P, m)`` arrays.
"""

from __future__ import annotations

import numpy as np

from .. import kernels
from .._validate import checked_keywords
from ..errors import DataError

# Largest pole radius of a mirrored start (a pole exactly on the circle is its own mirror).
_MAX_RADIUS = 1.0 - 1e-6

__all__ = [
    "UNDAMPED_TOLERANCE",
    "is_stable",
    "is_stable_reference",
    "max_pole_radius",
    "mirror_inside",
    "perturbed_poles",
    "pole_radius_batched",
    "poles_batched",
    "pull_inside",
    "random_poles",
    "reflection_coefficients",
    "stability_words",
    "within_radius",
]

#: A pole whose radius is within this of 1 is an undamped mode: the model rings for ever (its
#: damping prints as 0.0000), so it is reported as marginally stable, never as stable.
UNDAMPED_TOLERANCE = 1e-6


def stability_words(stable: bool, max_radius: float, digits: int = 6, sep: str = ": ") -> str:
    """What a model's largest pole radius says about its stability, in words.

    Parameters
    ----------
    stable : bool
        Whether every pole is strictly inside the unit circle.
    max_radius : float
        The largest pole radius.
    digits : int, optional
        Decimals of the radius printed.
    sep : str, optional
        Between the verdict and the radius of a stable or unstable model (a model's summary
        writes ``", "``).

    Returns
    -------
    str
        ``"stable: largest pole radius r"``, ``"UNSTABLE: largest pole radius r"``, or, for a
        pole within :data:`UNDAMPED_TOLERANCE` of the circle,
        ``"MARGINALLY STABLE: an undamped mode (pole radius r)"``.
    """
    if stable and max_radius >= 1.0 - UNDAMPED_TOLERANCE:
        return f"MARGINALLY STABLE: an undamped mode (pole radius {max_radius:.{digits}f})"
    return f"{'stable' if stable else 'UNSTABLE'}{sep}largest pole radius {max_radius:.{digits}f}"


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


# ================================================ moving roots inside (references' starts)
def _poles_to_a(poles: np.ndarray) -> np.ndarray:
    return np.real(np.poly(poles))[1:] if poles.size else np.zeros(0)


def mirror_inside(theta: np.ndarray, na: int) -> np.ndarray:
    """``theta`` with poles outside the circle mirrored to ``1/conj(p)``, as MATLAB's ``pem`` does.

    ``B`` is divided by the product of the mirrored radii: ``|e^jw - 1/conj(p)| =
    |e^jw - p| / |p|``, so the magnitude response is unchanged (only the phase moves).

    Parameters
    ----------
    theta : ndarray, shape (na + n_b,)
        Denominator coefficients ``a_1 .. a_na`` first, then the numerator's.
    na : int
        Number of denominator coefficients.

    Returns
    -------
    ndarray, shape (na + n_b,)
        A copy with every pole of radius at most ``1 - 1e-6`` (stable to the Schur-Cohn
        test); ``theta`` itself when it is already stable.
    """
    if na == 0 or is_stable(theta[:na])[0]:
        return theta.copy()
    poles = np.roots(np.concatenate([[1.0], theta[:na]]))
    r = np.abs(poles)
    out = poles.copy()
    outside = r >= 1.0
    out[outside] = 1.0 / np.conj(poles[outside])
    gain = float(np.prod(r[outside]))
    r_new = np.abs(out)
    too_big = r_new > _MAX_RADIUS  # on (or rounding onto) the circle: pull just inside
    out[too_big] *= _MAX_RADIUS / r_new[too_big]
    new = theta.copy()
    new[:na] = _poles_to_a(out)
    new[na:] /= gain
    shrink = _MAX_RADIUS
    while not is_stable(new[:na])[0]:  # np.poly rounding on a pole at the edge
        shrink *= _MAX_RADIUS
        new[:na] = _poles_to_a(out * shrink)
    return new


def _pairs(poles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Real poles and the upper-half-plane member of each conjugate pair."""
    tol = 1e-9 * max(1.0, float(np.abs(poles).max(initial=0.0)))
    real = np.real(poles[np.abs(poles.imag) <= tol])
    upper = poles[poles.imag > tol]
    # np.roots gives complex poles in conjugate pairs; an unpaired count would mean a pole
    # classified as complex whose partner fell under tol, so rebuild from what we have.
    n_missing = poles.size - real.size - 2 * upper.size
    if n_missing:
        real = np.concatenate([real, np.zeros(n_missing)])
    return real, upper


def within_radius(a: np.ndarray, r_max: float) -> bool:
    """Whether a denominator is stable with every pole radius at most ``r_max``.

    Parameters
    ----------
    a : ndarray, shape (na,)
        Coefficients ``a_1 .. a_na`` of the monic denominator.
    r_max : float
        The cap, in (0, 1]; 1 tests stability alone.

    Returns
    -------
    bool
    """
    if not is_stable(a)[0]:
        return False
    return r_max >= 1.0 or a.size == 0 or float(pole_radius_batched(a[None, :])[0]) <= r_max


def pull_inside(a: np.ndarray, r_max: float) -> np.ndarray:
    """A denominator with every pole of radius above ``r_max`` pulled in radially to it.

    Parameters
    ----------
    a : ndarray, shape (na,)
        Coefficients ``a_1 .. a_na`` of the monic denominator.
    r_max : float
        The cap, in (0, 1].

    Returns
    -------
    ndarray, shape (na,)
        Coefficients whose poles pass :func:`within_radius` (angles kept; the radius a hair
        below ``r_max`` where the coefficients' rounding needs it).
    """
    poles = np.roots(np.concatenate([[1.0], a]))
    r = np.abs(poles)
    shrink = r_max
    while True:
        out = np.where(r > shrink, poles * (shrink / np.maximum(r, 1e-300)), poles)
        new = _poles_to_a(out)
        if within_radius(new, r_max):
            return new
        shrink *= 1.0 - 1e-9  # np.poly rounding put a pole back just above the cap


def perturbed_poles(a_ls: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A stable denominator's poles with their damping and angles perturbed at random.

    The damping ``1 - |p|`` is scaled log-normally (sigma 0.5), which keeps every pole inside
    the circle whatever the draw, and each angle log-normally (sigma 0.1); conjugate pairs
    stay pairs.

    Parameters
    ----------
    a_ls : ndarray, shape (na,)
        Coefficients of a stable monic denominator (a least-squares start, say).
    rng : numpy.random.Generator

    Returns
    -------
    ndarray, shape (na,)
        Coefficients of a stable denominator.
    """
    real, upper = _pairs(np.roots(np.concatenate([[1.0], a_ls])))
    # damping 1 - |p| scaled log-normally keeps the pole inside the circle whatever the draw
    real_r = 1.0 - (1.0 - np.abs(real)) * np.exp(rng.normal(0.0, 0.5, real.size))
    real_new = np.sign(real + (real == 0)) * np.minimum(real_r, _MAX_RADIUS)
    rad = 1.0 - (1.0 - np.abs(upper)) * np.exp(rng.normal(0.0, 0.5, upper.size))
    ang = np.clip(np.angle(upper) * np.exp(rng.normal(0.0, 0.1, upper.size)), 1e-3, np.pi - 1e-3)
    up_new = np.minimum(rad, _MAX_RADIUS) * np.exp(1j * ang)
    return _poles_to_a(np.concatenate([real_new, up_new, np.conj(up_new)]))


def random_poles(na: int, rng: np.random.Generator) -> np.ndarray:
    """A stable denominator with poles drawn uniformly over the disc of radius 0.95.

    Parameters
    ----------
    na : int
        Its order: ``na // 2`` conjugate pairs plus one real pole when ``na`` is odd.
    rng : numpy.random.Generator

    Returns
    -------
    ndarray, shape (na,)
        Coefficients ``a_1 .. a_na``.
    """
    n_pairs = na // 2
    rad = 0.95 * np.sqrt(rng.uniform(0.0, 1.0, n_pairs))
    up = rad * np.exp(1j * rng.uniform(0.0, np.pi, n_pairs))
    real = rng.uniform(-0.95, 0.95, na % 2)
    return _poles_to_a(np.concatenate([real, up, np.conj(up)]))
