"""Parametrisations of the ARX search space, batched over a population.

A metaheuristic searches a box; a :class:`Parametrisation` maps points of that box (the
*search vector* ``z``) to ARX parameters ``theta = [a_1 .. a_na, b ...]`` in the order of
:class:`flexid.models.arx.ARXStructure`.  Three maps are provided:

``"coefficients"``
    The identity over a box of ``a`` and ``b`` coefficients.  Most of a coefficient box is
    unstable for ``na >= 4``; kept as the reference.
``"poles"``
    ``A`` as a product of conjugate pole pairs ``1 - 2 r cos(w) z^-1 + r^2 z^-2`` with
    ``r`` in ``[0, r_max]``, ``w`` in ``[0, pi]``, plus one real pole ``p`` in
    ``[-r_max, r_max]`` (factor ``1 - p z^-1``) when ``na`` is odd.  Optionally
    ``real_pairs`` of the pairs are two real poles ``(p1, p2)`` instead, because a
    conjugate pair can only be a *double* real pole (``w = 0`` or ``pi``): with the
    default ``real_pairs = 0`` two distinct real poles cannot be represented.
    Every point of the box is stable, and a lightly damped mode at ``f`` Hz reads as
    ``r`` near 1 at ``w = 2 pi f dt``.
``"reflection"``
    Lattice (reflection) coefficients ``k_1 .. k_na`` in ``[-k_max, k_max]``, step-up
    recursion; one-to-one onto the stable set as ``k_max -> 1``.

The ``b`` part of the search vector always passes through unchanged; its bounds come from
the caller (they need a data scale, which this module does not have).  Every map works on a
population ``(P, n_search)`` at once; the only Python loops run over pole factors or lattice
orders, never over candidates (except in the pole map's inverse, which needs roots and is
not on the hot path).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any

import numpy as np

from .._validate import integer, real
from ..errors import ConfigError, DataError, UnknownNameError
from ..models.arx import ARXStructure
from ..models.stability import is_stable, poles_batched, reflection_coefficients
from ..models.vocabulary import REFLECTION_CAP

__all__ = [
    "BOX_RADIUS",
    "PARAMETRISATIONS",
    "CoefficientParametrisation",
    "Parametrisation",
    "PoleParametrisation",
    "ReflectionParametrisation",
    "SearchBox",
    "make_parametrisation",
]

PARAMETRISATIONS: tuple[str, ...] = ("coefficients", "poles", "reflection")

#: Default largest pole radius of a pole box built directly rather than from a
#: :class:`~flexid.config.SearchSpec` (whose cap is :data:`~flexid.config.POLE_RADIUS_CAP`):
#: the box's corners, where bound-clipping optimisers land, stack poles at this radius, and
#: in float64 they stay stable up to ``na = 4`` here, against ``na = 2`` at 0.9999 (a quarter
#: of the corners unstable from ``na = 3``; see :class:`PoleParametrisation`).
BOX_RADIUS = 0.999


# --------------------------------------------------------------------------- helpers


def _as_population(values: Any, n: int, what: str) -> tuple[np.ndarray, bool]:
    """``values`` as a float ``(P, n)`` array, and whether the caller gave one row (1-D).

    Raises DataError for a wrong shape, complex or non-numeric values, NaN or inf: a NaN
    would otherwise come out as a silently "unstable" candidate far from where it started.
    """
    if np.iscomplexobj(values):
        raise DataError(f"{what} must be real, got complex values")
    try:
        arr = np.asarray(values, dtype=float)
    except (TypeError, ValueError) as exc:
        raise DataError(f"{what} must be numeric: {exc}") from None
    single = arr.ndim == 1
    if single:
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != n:
        raise DataError(f"{what} must have shape (P, {n}) or ({n},), got {np.shape(values)}")
    if not np.isfinite(arr).all():
        raise DataError(f"{what} has non-finite values")
    return arr, single


def _bound_vector(value: Any, n: int, what: str) -> np.ndarray:
    """A scalar or ``(n,)`` bound as a finite float ``(n,)`` array (ConfigError otherwise)."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"{what} must be a number or an array of {n}: {exc}") from None
    if arr.ndim == 0:
        arr = np.full(n, float(arr))
    if arr.shape != (n,):
        raise ConfigError(f"{what} must be a scalar or have shape ({n},), got {arr.shape}")
    if not np.isfinite(arr).all():
        raise ConfigError(f"{what} must be finite (the search box is a finite box)")
    return arr.copy()


def _check_box(lower: np.ndarray, upper: np.ndarray, what: str) -> None:
    if (lower > upper).any():
        i = int(np.argmax(lower > upper))
        raise ConfigError(
            f"{what}: lower bound {lower[i]!r} exceeds upper bound {upper[i]!r} at index {i}"
        )


def _open_unit(value: Any, what: str) -> float:
    """A radius-like option in ``(0, 1)``; 1 itself would admit poles on the unit circle."""
    return real(value, what, error=ConfigError, minimum=0, maximum=1, low_open=True, high_open=True)


def _fmt(x: float) -> str:
    return f"{x:.6g}"


# --------------------------------------------------------------------------- base class


@dataclass(frozen=True)
class SearchBox:
    """The box an optimiser searches, and the rule that made it.

    Attributes
    ----------
    lower, upper : ndarray, shape (n_params,)
        Bounds in the parameter order of :class:`~flexid.models.arx.ARXStructure`
        (``a1..a_na``, then the ``b`` coefficients of each input).
    rule : str
        How the bounds were chosen (recorded with every result).
    """

    lower: np.ndarray
    upper: np.ndarray
    rule: str

    def to_dict(self) -> dict[str, Any]:
        """The box as a JSON-safe dictionary.

        Returns
        -------
        dict
            ``{"rule": str, "lower": list of float, "upper": list of float}`` (n_params
            values each).
        """
        return {"rule": self.rule, "lower": self.lower.tolist(), "upper": self.upper.tolist()}


class Parametrisation(ABC):
    """A map from a search box to ARX parameters, batched over a population.

    The search vector is ``[z_a, b]``: ``z_a`` (``structure.na`` values) encodes the
    denominator ``A`` in the parametrisation's own units, ``b`` is the numerator part of
    ``theta``, passed through unchanged.  Subclasses implement the ``A`` part only.

    Parameters
    ----------
    structure : ARXStructure
        Model orders; ``theta`` has ``structure.n_params`` entries.
    b_lower, b_upper : float or array_like, shape (n_b,)
        Bounds of the ``b`` coefficients, ``n_b = n_params - na`` (a scalar is used for
        every coefficient).  Finite, ``b_lower <= b_upper``.

    Attributes
    ----------
    name : str
        One of :data:`PARAMETRISATIONS`.
    structure : ARXStructure
    n_search : int
        Length of the search vector (``structure.n_params`` for every map here: each
        parametrisation of ``A`` uses ``na`` numbers).
    lower, upper : ndarray, shape (n_search,)
        Finite bounds of the search box, in the parametrisation's own units.
    labels : list of str
        Name of each search variable, e.g. ``["r1", "w1", "p", "b1"]``.
    """

    name: str = ""

    def __init__(self, structure: ARXStructure, *, b_lower: Any, b_upper: Any) -> None:
        if not isinstance(structure, ARXStructure):
            raise ConfigError(f"structure must be an ARXStructure, got {type(structure).__name__}")
        self.structure = structure
        self.na = structure.na
        self.n_b = structure.n_params - structure.na
        b_lo = _bound_vector(b_lower, self.n_b, "b_lower")
        b_hi = _bound_vector(b_upper, self.n_b, "b_upper")
        _check_box(b_lo, b_hi, "b bounds")
        a_lo, a_hi = self._a_bounds()
        self.n_search = self.na + self.n_b
        self.lower = np.concatenate([a_lo, b_lo])
        self.upper = np.concatenate([a_hi, b_hi])
        self.labels = self._a_labels() + structure.param_names[self.na :]

    # -- to implement -------------------------------------------------------------------

    @abstractmethod
    def _a_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounds ``(lower, upper)``, each shape (na,), of the ``A`` part of the box."""

    @abstractmethod
    def _a_labels(self) -> list[str]:
        """Names of the ``na`` search variables of the ``A`` part."""

    @abstractmethod
    def _to_a(self, za: np.ndarray) -> np.ndarray:
        """``(P, na)`` search values -> ``(P, na)`` coefficients ``a_1 .. a_na``."""

    @abstractmethod
    def _from_a(self, a: np.ndarray) -> np.ndarray:
        """``(P, na)`` coefficients -> ``(P, na)`` search values (DataError if none)."""

    @abstractmethod
    def options(self) -> dict[str, Any]:
        """The parametrisation's own options (JSON-safe), e.g. ``{"r_max": 0.999}``."""

    # -- public maps --------------------------------------------------------------------

    def to_coefficients(self, Z: Any) -> np.ndarray:
        """Map search vectors to ARX parameters.

        Parameters
        ----------
        Z : array_like, shape (P, n_search) or (n_search,)
            Search vectors ``[z_a, b]``.  Images of points inside ``[lower, upper]`` have a
            stable ``A`` (for ``"poles"`` and ``"reflection"``); points outside are mapped
            by the same formula without clipping, so they may be unstable.

        Returns
        -------
        ndarray, shape (P, n_params) or (n_params,)
            ``theta = [a_1 .. a_na, b ...]``, one row per search vector (1-D in, 1-D out).

        Raises
        ------
        DataError
            Wrong shape, or non-finite or non-real values.
        """
        z, single = _as_population(Z, self.n_search, "search vectors Z")
        out = np.empty_like(z)
        out[:, : self.na] = self._to_a(z[:, : self.na]) if self.na else z[:, :0]
        out[:, self.na :] = z[:, self.na :]
        return out[0] if single else out

    def denominator(self, Za: Any) -> np.ndarray:
        """Map the ``A`` part of search vectors to denominator coefficients.

        Parameters
        ----------
        Za : array_like, shape (P, na) or (na,)
            The first ``na`` entries of search vectors.

        Returns
        -------
        ndarray, shape (P, na) or (na,)
            ``a_1 .. a_na`` (stable for points of the box with ``"poles"`` and
            ``"reflection"``).

        Raises
        ------
        DataError
            Wrong shape, or non-finite values.
        """
        z, single = _as_population(Za, self.na, "denominator search vectors")
        out = self._to_a(z) if self.na else z
        return out[0] if single else out

    def from_coefficients(self, X: Any) -> np.ndarray:
        """Map ARX parameters back to search vectors, where an inverse exists.

        Parameters
        ----------
        X : array_like, shape (P, n_params) or (n_params,)
            ``theta = [a_1 .. a_na, b ...]``.

        Returns
        -------
        ndarray, shape (P, n_search) or (n_search,)
            Search vectors whose image is ``X``.  They may lie outside ``[lower, upper]``
            (e.g. a pole of radius above ``r_max``); clip them if a point inside the box is
            needed.

        Raises
        ------
        DataError
            Wrong shape or non-finite values, or an ``A`` with no preimage: an unstable
            ``A`` for ``"poles"`` and ``"reflection"``, or for ``"poles"`` real poles that
            the chosen ``real_pairs`` cannot hold.  The message names the first bad row.
        """
        x, single = _as_population(X, self.structure.n_params, "ARX parameters X")
        out = np.empty_like(x)
        out[:, : self.na] = self._from_a(x[:, : self.na]) if self.na else x[:, :0]
        out[:, self.na :] = x[:, self.na :]
        return out[0] if single else out

    # -- description --------------------------------------------------------------------

    def describe(self) -> str:
        """One paragraph in plain words: what each search variable means and its range.

        Returns
        -------
        str
            The parametrisation's name and structure, the meaning and range of the ``A``
            search variables, and the range of the ``b`` coefficients.
        """
        b = (
            f"{self.n_b} b coefficient(s) passed through in "
            f"[{_fmt(self.lower[self.na :].min())}, {_fmt(self.upper[self.na :].max())}]"
            if self.n_b
            else "no b coefficients"
        )
        return f"{self.name} parametrisation of {self.structure!r}: {self._describe_a()}; {b}."

    @abstractmethod
    def _describe_a(self) -> str:
        """The ``A`` part of :meth:`describe`."""

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe description: name, structure, options and the search box.

        Returns
        -------
        dict
            ``{"name", "structure", "options", "labels", "bounds": {"lower", "upper"}}``,
            plain Python types only.
        """
        return {
            "name": self.name,
            "structure": self.structure.to_dict(),
            "options": self.options(),
            "labels": list(self.labels),
            "bounds": {
                "lower": [float(v) for v in self.lower],
                "upper": [float(v) for v in self.upper],
            },
        }

    def __repr__(self) -> str:
        opts = ", ".join(f"{k}={v!r}" for k, v in self.options().items())
        sep = ", " if opts else ""
        return f"{type(self).__name__}({self.structure!r}{sep}{opts})"


# --------------------------------------------------------------------------- coefficients


class CoefficientParametrisation(Parametrisation):
    """The identity map over a box of ``a`` and ``b`` coefficients.

    Parameters
    ----------
    structure : ARXStructure
    b_lower, b_upper : float or array_like, shape (n_b,)
    a_lower, a_upper : float or array_like, shape (na,), optional
        Bounds of ``a_1 .. a_na``.  Default: ``|a_k| <= C(na, k)``, the coefficients of
        ``(1 + z^-1)^na``, the smallest box that holds every stable ``A``.
    """

    name = "coefficients"

    def __init__(
        self,
        structure: ARXStructure,
        *,
        b_lower: Any,
        b_upper: Any,
        a_lower: Any = None,
        a_upper: Any = None,
    ) -> None:
        na = structure.na if isinstance(structure, ARXStructure) else 0
        binom = np.array([math.comb(na, k) for k in range(1, na + 1)], dtype=float)
        self._a_lo = -binom if a_lower is None else _bound_vector(a_lower, na, "a_lower")
        self._a_hi = binom.copy() if a_upper is None else _bound_vector(a_upper, na, "a_upper")
        _check_box(self._a_lo, self._a_hi, "a bounds")
        super().__init__(structure, b_lower=b_lower, b_upper=b_upper)

    def _a_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return self._a_lo, self._a_hi

    def _a_labels(self) -> list[str]:
        return self.structure.param_names[: self.na]

    def _to_a(self, za: np.ndarray) -> np.ndarray:
        return za.copy()

    def _from_a(self, a: np.ndarray) -> np.ndarray:
        return a.copy()

    def options(self) -> dict[str, Any]:
        return {}

    def _describe_a(self) -> str:
        if not self.na:
            return "no A coefficients"
        return (
            f"{self.na} A coefficient(s) a1..a{self.na} searched directly in a box from "
            f"[{_fmt(self.lower[0])}, {_fmt(self.upper[0])}] (a1) to "
            f"[{_fmt(self.lower[self.na - 1])}, {_fmt(self.upper[self.na - 1])}] "
            f"(a{self.na}); candidates may be unstable"
        )


# --------------------------------------------------------------------------- pole pairs


class PoleParametrisation(Parametrisation):
    """``A`` as a product of pole pairs (and one real pole when ``na`` is odd).

    Search vector ``[r_1, w_1, ..., r_c, w_c, p_1a, p_1b, ..., p_ma, p_mb, (p), b ...]``
    with ``c = na // 2 - real_pairs`` conjugate pairs, factor
    ``1 - 2 r cos(w) z^-1 + r^2 z^-2`` (poles ``r e^(+-i w)``), ``r`` in ``[0, r_max]``,
    ``w`` in ``[0, pi]``; ``m = real_pairs`` pairs of real poles, factor
    ``(1 - p_a z^-1)(1 - p_b z^-1)``, each pole in ``[-r_max, r_max]``; and, when ``na``
    is odd, one real pole ``p`` in ``[-r_max, r_max]``, factor ``1 - p z^-1``.

    Why ``real_pairs``: a conjugate pair reaches the real axis only as a *double* pole
    (``w = 0`` or ``pi``), so with ``real_pairs = 0`` an even ``na`` cannot have two
    distinct real poles (an overdamped mode).  Each real pair trades one possible
    resonance for two independent real poles; ``real_pairs = na // 2`` is an all-real
    denominator.  (The alternative, a quadratic ``(s, d)`` restricted to the stability
    triangle, covers both cases but is not a box and loses the frequency reading.)

    The map is not one-to-one (pairs can be permuted, ``(r, w)`` with ``r = 0`` is the
    same for every ``w``): harmless for search.  :meth:`from_coefficients` returns a
    canonical preimage: conjugate pairs sorted by angle ``w`` (then radius), the real
    poles in descending order filling ``p_1a, p_1b, ..., p``.  A conjugate slot left over
    takes the two closest real poles as the nearest conjugate pair (``w = 0`` or ``pi``);
    the result is accepted only if it rebuilds ``A`` to ``1e-8`` (relative), which holds
    for a double pole split by rounding and fails, with DataError, for distinct ones.

    Stable by construction in exact arithmetic.  In float64, several poles stacked at
    radius ``r_max`` on the real axis (a box corner: ``w = 0`` or ``pi``, or real pairs at
    ``+-r_max``) are ill conditioned, a pole of multiplicity ``m`` moving by about
    ``eps^(1/m)``: measured at ``r_max = 0.999``, corners are all stable up to ``na = 4``
    but up to 30 % of them are unstable at ``na = 9``; with ``r_max = 0.95`` every corner
    is stable up to ``na = 10``.  Uniform draws in the box are stable at every order.

    Parameters
    ----------
    structure : ARXStructure
    b_lower, b_upper : float or array_like, shape (n_b,)
    r_max : float, optional
        Largest pole radius in the box, in (0, 1) (default :data:`BOX_RADIUS`): every image is
        stable with margin ``1 - r_max``.
    real_pairs : int, optional
        Number of pole pairs parametrised as two real poles, ``0 <= real_pairs <= na // 2``
        (default 0).
    """

    name = "poles"

    def __init__(
        self,
        structure: ARXStructure,
        *,
        b_lower: Any,
        b_upper: Any,
        r_max: float = BOX_RADIUS,
        real_pairs: int = 0,
    ) -> None:
        self.r_max = _open_unit(r_max, "r_max")
        na = structure.na if isinstance(structure, ARXStructure) else 0
        real_pairs = integer(
            real_pairs, "real_pairs (at most na // 2)", error=ConfigError, minimum=0,
            maximum=na // 2,
        )
        self.real_pairs = real_pairs
        self.n_pairs = na // 2
        self.n_complex = self.n_pairs - real_pairs
        self.odd = bool(na % 2)
        super().__init__(structure, b_lower=b_lower, b_upper=b_upper)

    def _a_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        lo = [0.0, 0.0] * self.n_complex + [-self.r_max] * (2 * self.real_pairs + self.odd)
        hi = [self.r_max, np.pi] * self.n_complex + [self.r_max] * (2 * self.real_pairs + self.odd)
        return np.array(lo, dtype=float), np.array(hi, dtype=float)

    def _a_labels(self) -> list[str]:
        labels: list[str] = []
        for j in range(1, self.n_complex + 1):
            labels += [f"r{j}", f"w{j}"]
        for j in range(1, self.real_pairs + 1):
            labels += [f"p{j}a", f"p{j}b"]
        if self.odd:
            labels.append("p")
        return labels

    def _to_a(self, za: np.ndarray) -> np.ndarray:
        n_pop = za.shape[0]
        # Running product, column k holds the coefficient of z^-k; the leading 1 is kept
        # in column 0 so that each factor is the same two shifted multiply-adds.
        poly = np.zeros((n_pop, self.na + 1))
        poly[:, 0] = 1.0
        factors: list[tuple[np.ndarray, np.ndarray | None]] = []
        for j in range(self.n_complex):
            r, w = za[:, 2 * j], za[:, 2 * j + 1]
            factors.append((-2.0 * r * np.cos(w), r * r))
        base = 2 * self.n_complex
        for j in range(self.real_pairs):
            pa, pb = za[:, base + 2 * j], za[:, base + 2 * j + 1]
            factors.append((-(pa + pb), pa * pb))
        if self.odd:
            factors.append((-za[:, self.na - 1], None))
        for c1, c2 in factors:
            new = poly.copy()
            new[:, 1:] += c1[:, None] * poly[:, :-1]
            if c2 is not None:
                new[:, 2:] += c2[:, None] * poly[:, :-2]
            poly = new
        return poly[:, 1:]

    def _from_a(self, a: np.ndarray, tol: float = 1e-8) -> np.ndarray:
        _raise_unstable(a)
        n_pop, na = a.shape
        # exact conjugate pairs and exactly real eigenvalues: the split below needs no
        # tolerance
        roots = poles_batched(a)
        z = np.empty((n_pop, na))
        for i in range(n_pop):  # variable root structure per row; inverse only
            z[i] = self._assign(roots[i])
        # The assignment may have squeezed two distinct real poles into a conjugate slot
        # (w = 0 or pi); accept only if the image reproduces A.
        err = np.abs(self._to_a(z) - a).max(axis=1)
        bad = err > tol * np.maximum(1.0, np.abs(a).max(axis=1))
        if bad.any():
            i = int(np.argmax(bad))
            poles = ", ".join(f"{p:.6g}" for p in np.sort_complex(roots[i])[::-1])
            raise DataError(
                f"row {i}: the poles of A ({poles}) do not fit {self.n_complex} conjugate "
                f"pair(s), {self.real_pairs} real pair(s)"
                f"{' and 1 real pole' if self.odd else ''} (best fit off by {err[i]:.3g}): "
                f"two distinct real poles need a real pair (raise real_pairs), a complex "
                f"pair needs a conjugate slot (lower real_pairs)"
            )
        return z

    def _assign(self, roots: np.ndarray) -> np.ndarray:
        """Canonical search values of one row from its roots (see the class docstring)."""
        upper = roots[roots.imag > 0]
        real = roots[roots.imag == 0].real
        excess = upper.size - self.n_complex
        if excess > 0:
            # More conjugate pairs than conjugate slots: the flattest ones (a double real
            # pole split into a pair by rounding) become two real poles at their real part;
            # a genuine resonance fails the check in _from_a.
            order = np.argsort(np.abs(upper.imag), kind="stable")
            flat, upper = upper[order[:excess]], upper[order[excess:]]
            real = np.concatenate([real, flat.real, flat.real])
        real = np.sort(real)[::-1]
        # Conjugate slots left over must hold real poles as (near-)double poles: take the
        # closest neighbours in sorted order, greedily, which is exact for true double
        # poles split apart by rounding.
        spare = self.n_complex - upper.size
        used = np.zeros(real.size, dtype=bool)
        doubles: list[tuple[float, float]] = []
        if spare:
            gaps = np.abs(np.diff(real))
            for k in np.argsort(gaps, kind="stable"):
                if len(doubles) == spare:
                    break
                if not used[k] and not used[k + 1]:
                    used[k] = used[k + 1] = True
                    doubles.append((real[k], real[k + 1]))
            # Greedy can strand a slot (middle gap smallest); pair what is left in sorted
            # order so the shape is right; such a fit is poor and the check rejects it.
            free = np.flatnonzero(~used)
            while len(doubles) < spare:
                k0, k1 = free[0], free[1]
                used[k0] = used[k1] = True
                doubles.append((real[k0], real[k1]))
                free = free[2:]
        pairs = [(abs(p), float(np.angle(p))) for p in upper]
        for pa, pb in doubles:
            # Nearest conjugate pair to (pa, pb): r^2 = pa pb, 2 r cos(w) = pa + pb (clipped).
            r = math.sqrt(max(pa * pb, 0.0))
            if r > 0.0:
                w = math.acos(min(1.0, max(-1.0, (pa + pb) / (2.0 * r))))
            else:
                w = 0.0 if pa + pb >= 0.0 else math.pi
            pairs.append((r, w))
        pairs.sort(key=lambda rw: (rw[1], rw[0]))
        rest = real[~used]
        out = [v for rw in pairs for v in rw]
        return np.array(out + rest.tolist(), dtype=float)

    def options(self) -> dict[str, Any]:
        return {"r_max": self.r_max, "real_pairs": self.real_pairs}

    def _describe_a(self) -> str:
        if not self.na:
            return "no poles"
        parts = []
        if self.n_complex:
            parts.append(
                f"{self.n_complex} conjugate pole pair(s) (radius r in [0, {_fmt(self.r_max)}], "
                f"angle w in [0, pi] rad; a mode at f Hz has w = 2 pi f dt)"
            )
        if self.real_pairs:
            parts.append(
                f"{self.real_pairs} pair(s) of real poles in [-{_fmt(self.r_max)}, "
                f"{_fmt(self.r_max)}]"
            )
        if self.odd:
            parts.append(f"1 real pole p in [-{_fmt(self.r_max)}, {_fmt(self.r_max)}]")
        return ", ".join(parts) + "; every candidate stable"


# --------------------------------------------------------------------------- reflection


class ReflectionParametrisation(Parametrisation):
    """``A`` from lattice (reflection) coefficients ``k_1, ..., k_na``.

    Step-up (Levinson) recursion, starting from ``A^(0) = 1``::

        a^(m)_i = a^(m-1)_i + k_m a^(m-1)_(m-i),   i = 1 .. m-1
        a^(m)_m = k_m

    ``A = A^(na)``.  It is the exact inverse of the Schur-Cohn step-down recursion of
    :func:`flexid.models.stability.reflection_coefficients` (which returns ``k_na .. k_1``), so
    ``A`` is stable if and only if every ``|k_m| < 1``: the map is one-to-one from
    ``(-1, 1)^na`` onto the stable set, and the box ``[-k_max, k_max]^na`` is a stable
    subset.  The map is strongly curved near ``|k| = 1``: the step-down divides by
    ``1 - k_m^2`` at each order, so the round trip ``k -> A -> k`` loses about
    ``prod 1 / (1 - k_m^2)`` in accuracy, and box corners with every ``|k_m| = 0.9999``
    put all poles within ~1e-5 of the circle, where float64 cannot hold them inside for
    ``na >= 5`` (measured: 18 % of corners unstable at ``na = 5``, all at ``na = 10``;
    with ``k_max = 0.99`` none up to ``na = 7``).

    Parameters
    ----------
    structure : ARXStructure
    b_lower, b_upper : float or array_like, shape (n_b,)
    k_max : float, optional
        Bound of every ``|k_m|``, in (0, 1) (default 0.9999).
    """

    name = "reflection"

    def __init__(
        self, structure: ARXStructure, *, b_lower: Any, b_upper: Any,
        k_max: float = REFLECTION_CAP,
    ) -> None:
        self.k_max = _open_unit(k_max, "k_max")
        super().__init__(structure, b_lower=b_lower, b_upper=b_upper)

    def _a_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return np.full(self.na, -self.k_max), np.full(self.na, self.k_max)

    def _a_labels(self) -> list[str]:
        return [f"k{m}" for m in range(1, self.na + 1)]

    def _to_a(self, za: np.ndarray) -> np.ndarray:
        a = np.zeros_like(za)
        for m in range(1, self.na + 1):
            k = za[:, m - 1 : m]
            head = a[:, : m - 1]
            # Right side is evaluated before assignment, so the reversed copy is the old one.
            a[:, : m - 1] = head + k * head[:, ::-1]
            a[:, m - 1] = k[:, 0]
        return a

    def _from_a(self, a: np.ndarray) -> np.ndarray:
        _raise_unstable(a)
        # Step-down recursion shared with the stability test (same sign convention by
        # construction); it lists k_na first.
        return reflection_coefficients(a)[:, ::-1].copy()

    def options(self) -> dict[str, Any]:
        return {"k_max": self.k_max}

    def _describe_a(self) -> str:
        if not self.na:
            return "no poles"
        return (
            f"{self.na} reflection coefficient(s) k1..k{self.na} in "
            f"[-{_fmt(self.k_max)}, {_fmt(self.k_max)}]; every candidate stable"
        )


def _raise_unstable(a: np.ndarray) -> None:
    """DataError naming the first unstable row: such an ``A`` has no stable preimage."""
    ok = is_stable(a)
    if not ok.all():
        i = int(np.argmin(ok))
        raise DataError(
            f"row {i} of A is not strictly stable (a poles or reflection parametrisation "
            f"only holds poles inside the unit circle): a = {a[i].tolist()}"
        )


# --------------------------------------------------------------------------- factory


def make_parametrisation(
    name: str,
    structure: ARXStructure,
    *,
    b_lower: Any,
    b_upper: Any,
    a_lower: Any = None,
    a_upper: Any = None,
    r_max: float = BOX_RADIUS,
    real_pairs: int = 0,
    k_max: float = REFLECTION_CAP,
) -> Parametrisation:
    """Build a parametrisation by name.

    Options that do not apply to ``name`` are ignored (``a_lower``/``a_upper`` for
    ``"coefficients"``, ``r_max``/``real_pairs`` for ``"poles"``, ``k_max`` for
    ``"reflection"``), so one call site can build any of them from one configuration.

    Parameters
    ----------
    name : str
        One of :data:`PARAMETRISATIONS`.
    structure : ARXStructure
        Model orders.
    b_lower, b_upper : float or array_like, shape (n_b,)
        Bounds of the ``b`` coefficients (``n_b = n_params - na``).
    a_lower, a_upper : float or array_like, shape (na,), optional
        ``"coefficients"`` only; default the binomial box ``|a_k| <= C(na, k)``.
    r_max : float, optional
        ``"poles"`` only: largest pole radius, in (0, 1).
    real_pairs : int, optional
        ``"poles"`` only: pairs parametrised as two real poles (see
        :class:`PoleParametrisation`).
    k_max : float, optional
        ``"reflection"`` only: bound of the reflection coefficients, in (0, 1).

    Returns
    -------
    Parametrisation

    Raises
    ------
    UnknownNameError
        ``name`` is not in :data:`PARAMETRISATIONS`.
    ConfigError
        Invalid bounds or options.
    """
    if name == "coefficients":
        return CoefficientParametrisation(
            structure, b_lower=b_lower, b_upper=b_upper, a_lower=a_lower, a_upper=a_upper
        )
    if name == "poles":
        return PoleParametrisation(
            structure, b_lower=b_lower, b_upper=b_upper, r_max=r_max, real_pairs=real_pairs
        )
    if name == "reflection":
        return ReflectionParametrisation(structure, b_lower=b_lower, b_upper=b_upper, k_max=k_max)
    raise UnknownNameError("parametrisation", str(name), PARAMETRISATIONS)
