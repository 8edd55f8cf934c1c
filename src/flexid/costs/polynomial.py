"""Batched prediction-error costs of the polynomial family (ARMAX, OE, BJ, general).

A population ``X`` of shape ``(P, n_params)`` (``theta`` in
:class:`~flexid.models.polynomial.PolynomialStructure` order) in, ``(P,)`` costs out.  Two
predictors, as for ARX (:class:`flexid.costs.arx.ARXCost`):

* **one-step**: the structure's own prediction error ``e = D/C (A y - sum_j B_j/F_j u_j)``;
* **simulation**: ``e = y - sum_j B_j/(A F_j) u_j`` (no noise model: a structure with ``C`` or
  ``D`` is refused).  For OE both are the same.

How a population is evaluated
    Each candidate's predictor is one filter ``den yhat = num_y y + sum_j num_j u_j``
    (:meth:`flexid.models.polynomial.PolynomialModel.predictor_polynomials`).  The numerators of the
    whole population are batched polynomial products, their action on the record one GEMM
    against lagged copies of the data, and the recursion ``1/den`` the batched recursion of
    :func:`flexid.kernels.ar_recursion` (compiled when built).  Initial-condition rules:
    ``"zero"`` runs from ``t = 0`` at rest; ``"measured"`` starts at ``t = start`` from the
    measured outputs; ``"estimate"`` starts at ``t = start`` from rest and removes the best
    least-squares combination of the ``n`` free responses of ``1/den``, which are the shifts
    ``h(t - start + k)``, ``k = 1..n``, of its impulse response ``h`` (one more recursion).

    The sums of squares alone (:meth:`PolynomialCost.sse`, what a cost evaluation needs)
    take compiled routes without ``(P, K)`` arrays: under ``"zero"`` and ``"measured"`` the
    predictor is an ARX recursion on the shared regressors (the lags of ``y`` and ``u_j``),
    run by :func:`flexid.kernels.arx_recursion` with the input part and the squares summed
    in the kernel (from ``t = start`` only under ``"zero"``); under ``"estimate"`` one pass
    of :func:`flexid.kernels.initial_state_fit`.  Without the compiled kernels, or with more
    than 64 regressors, the route above.

Variable projection (:meth:`PolynomialCost.fit_numerator`)
    For fixed ``A, C, D, F`` every predictor is linear in ``B``:
    ``e = z - sum_ji b_ji g_j(t - nk_j - i)`` with ``z = (D A / C) y`` and
    ``g_j = (D / (C F_j)) u_j`` (one-step), or ``z = y``, ``g_j = (1 / (A F_j)) u_j``
    (simulation).  With one input and no ``C`` or ``D`` (OE, and the simulation predictor)
    the regressors are delays of one signal filtered by ``1/(A F)``, ARX's simulation with
    ``A F`` for ``A``: :func:`flexid.kernels.arx_fit_shifted` fits ``B`` by lag sums in one
    pass under every rule (with ``"estimate"`` the ``n`` free responses from ``start`` are
    unknowns beside ``B``; they also span the part of each regressor that the inputs before
    ``start`` drive).  With one input and ``C`` or ``D`` (BJ, ARMAX: the one-step
    predictor) the regressors are delays of ``D u`` filtered by ``1/(C F)`` and the target
    is ``(D A / C) y``, both per candidate: the same kernel with ``D`` on its input and a
    target per candidate, from rest, or with the state estimated where ``nb - 1 <= deg C F``
    (the inputs before ``start`` then enter only through the state).  Otherwise, and for the
    rows that kernel flags, each regressor is the response to one orthogonal numerator (one
    recursion per coefficient of ``B``, plus the ``n`` free responses under ``"estimate"``)
    and a small least-squares solve per candidate.  With one input and the compiled kernels
    that problem is solved by :func:`flexid.kernels.flagged_fit` (the same regressors and
    solve: one recursion of ``1/den`` and a lattice filter of it, each regressor's own recursion
    under ``"measured"``, the Gram matrix summed directly, no ``(P, nb, K)`` arrays); the
    recursions remain the reference route and take the rows it cannot solve.
"""

from __future__ import annotations

from itertools import pairwise
from typing import Any

import numpy as np
from scipy import linalg

from .. import kernels
from .._validate import real
from ..errors import ConfigError, DataError
from ..kernels import ar_recursion, arx_recursion, initial_state_fit
from ..models.polynomial import INITIAL_RULES, PolynomialStructure, _check_initial
from ..models.specs import CostSpec
from ..models.stability import is_stable, pole_radius_batched
from .arx import ErrorCost, _check_names, _record, metric_from_sse, population
from .metrics import describe_cost

__all__ = ["PolynomialCost", "orthogonal_numerators", "poly_mul_rows", "poly_mul_rows_reference"]

_DEFAULT = CostSpec()


def poly_mul_rows(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Row-wise polynomial products: ``p`` (P, a) times ``q`` (P, b) -> (P, a + b - 1).

    Parameters
    ----------
    p, q : ndarray
        Coefficients in powers of ``q^-1``, one polynomial per row.

    Returns
    -------
    ndarray
    """
    out = kernels.poly_mul_compiled(p, q)  # the same sums, in one call
    if out is not None:
        return out
    return poly_mul_rows_reference(p, q)


def poly_mul_rows_reference(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """NumPy route of :func:`poly_mul_rows`: one array operation per coefficient of the
    shorter factor (a loop over coefficients, not candidates).

    Parameters
    ----------
    p, q : ndarray
        Coefficients in powers of ``q^-1``, one polynomial per row: (P, a) and (P, b).

    Returns
    -------
    ndarray, shape (P, a + b - 1)
    """
    if q.shape[1] > p.shape[1]:
        p, q = q, p
    if q.shape[1] == 1:  # a constant factor (often the 1 of an absent A, C, D or F)
        return p * q
    out = np.zeros((p.shape[0], p.shape[1] + q.shape[1] - 1))
    for i in range(q.shape[1]):
        out[:, i : i + p.shape[1]] += q[:, i : i + 1] * p
    return out


# Rows whose refinement step moved the solution by more than this (relative) are refined
# once more, then solved again by SVD if they still move: the normal equations square the
# condition number, and the shifted free responses of a denominator with clustered poles
# reach kappa ~ 1e7.
_REFINE_TOL = 1e-9


def _least_squares_rows(blocks: list[np.ndarray], r: np.ndarray) -> list[np.ndarray]:
    """``argmin_c ||r_p - sum_i c_ip F_ip||`` for each ``p``, the regressors given in blocks.

    Parameters
    ----------
    blocks : list of ndarray, shapes (P, n_i, K)
        Regressor blocks (views are fine: they are never copied or joined).
    r : ndarray, shape (P, K)

    Returns
    -------
    list of ndarray, shapes (P, n_i)
        The coefficients of each block.

    Normal equations of the column-scaled regressors (the Gram matrix from one matmul per
    pair of blocks, scaled afterwards), refined with the residual; rows whose first refinement
    step is not negligible are refined once more, and rows where that step still moves the
    solution (ill conditioned) are solved again by SVD, row by row.
    """
    sizes = [F.shape[1] for F in blocks]
    edges = np.cumsum([0, *sizes])
    n_pop, n = r.shape[0], int(edges[-1])
    if n == 0:
        return [np.zeros((n_pop, 0)) for _ in blocks]
    G = np.empty((n_pop, n, n))
    for i, Fi in enumerate(blocks):
        for j in range(i, len(blocks)):
            Gij = Fi @ blocks[j].transpose(0, 2, 1)
            G[:, edges[i] : edges[i + 1], edges[j] : edges[j + 1]] = Gij
            G[:, edges[j] : edges[j + 1], edges[i] : edges[i + 1]] = Gij.transpose(0, 2, 1)
    scale = np.sqrt(np.einsum("pii->pi", G))
    scale[scale == 0] = 1.0
    inv = 1.0 / scale
    Gs = G * inv[:, :, None] * inv[:, None, :]

    def take(F: np.ndarray, rows: np.ndarray) -> np.ndarray:
        return F if rows.size == n_pop else F[rows]  # all rows: no copy

    def correlate(v: np.ndarray, rows: np.ndarray) -> np.ndarray:
        return np.concatenate([take(F, rows) @ v[:, :, None] for F in blocks], axis=1)[:, :, 0]

    def residual(c: np.ndarray, rows: np.ndarray) -> np.ndarray:
        out = take(r, rows) - (c[:, None, : edges[1]] @ take(blocks[0], rows))[:, 0]
        for F, lo, hi in zip(blocks[1:], edges[1:-1], edges[2:]):
            out -= (c[:, None, lo:hi] @ take(F, rows))[:, 0]
        return out

    every = np.arange(n_pop)
    redo = np.zeros(n_pop, dtype=bool)
    try:
        c = np.linalg.solve(Gs, (correlate(r, every) * inv)[:, :, None])[:, :, 0] * inv
        rows = every
        for _ in range(2):
            Gr = Gs[rows]
            step = np.linalg.solve(
                Gr, (correlate(residual(c[rows], rows), rows) * inv[rows])[:, :, None]
            )[:, :, 0] * inv[rows]
            c[rows] += step
            size = np.abs(c[rows]).max(axis=1)
            moved = ~(np.abs(step).max(axis=1) <= _REFINE_TOL * np.where(size > 0, size, 1.0))
            rows = rows[moved]
            if not rows.size:
                break
        redo[rows] = True
    except np.linalg.LinAlgError:
        c = np.zeros((n_pop, n))
        redo[:] = True
    for i in np.flatnonzero(redo):
        A = np.concatenate([F[i] for F in blocks], axis=0)
        c[i] = linalg.lstsq((A * inv[i][:, None]).T, r[i])[0] * inv[i]
    return [c[:, lo:hi] for lo, hi in pairwise(edges)]


def orthogonal_numerators(den: np.ndarray, count: int) -> np.ndarray:
    """Numerators ``P_m``, ``m = 0..count-1``, whose filters ``P_m(q)/den(q)`` are orthogonal.

    ``P_m`` has degree ``m`` and a unit coefficient at ``q^-m``, so the ``P_m`` span the
    polynomials of degree below ``count``, as the shifts ``q^-m`` do; but where the shifts
    ``q^-m/den`` of a lightly damped denominator are numerically dependent (condition
    numbers above 1e16 at order 16), the ``P_m/den`` are orthonormal for a white input over
    ``t >= 0`` up to scale: for ``m < n`` ``P_m`` is the reversed step-down (Levinson)
    polynomial of order ``m`` of ``den`` (backward prediction-error filters, the Szego
    polynomials of the weight ``1/|den|^2``), and for ``m >= n`` the reversed ``den`` delayed
    by ``m - n`` (shifts of an all-pass filter).

    Parameters
    ----------
    den : ndarray, shape (P, n + 1)
        Monic denominators, stable.
    count : int
        Number of numerators.

    Returns
    -------
    ndarray, shape (P, count, count)
        Row ``m`` holds the coefficients of ``P_m`` in powers of ``q^-1``: lower triangular
        with a unit diagonal.  Rows whose step-down breaks down in rounding (a product of
        factors stacked at the radius cap can reach ``|k_m| = 1``) are the plain shifts.
    """
    n_pop, n = den.shape[0], den.shape[1] - 1
    T = np.zeros((n_pop, count, count))
    cur = den
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        for m in range(n, 0, -1):  # step-down over the orders, batched over candidates
            k = cur[:, m : m + 1]
            cur = ((cur - k * cur[:, ::-1]) / (1.0 - k * k))[:, :m]
            if m - 1 < count:
                T[:, m - 1, :m] = cur[:, ::-1]  # P_(m-1): A_(m-1) reversed
    for m in range(n, count):
        T[:, m, m - n : m + 1] = den[:, ::-1]
    bad = ~np.isfinite(T).all(axis=(1, 2))
    if bad.any():
        T[bad] = np.eye(count)
    return T


def _energies(den: np.ndarray, basis: np.ndarray) -> np.ndarray:
    """Energies over ``t >= 0`` of the impulse responses of ``P_m(q)/den(q)``, shape (P, n).

    ``basis`` is :func:`orthogonal_numerators` ``(den, n)``.  The backward prediction
    errors of ``1/den`` have the step-down's prediction-error variances,
    ``E_m = 1 / prod_{j > m} (1 - k_j^2)``, with ``k_j`` the reflection coefficient of order
    ``j``: the last coefficient of ``A_j``, i.e. ``basis[:, j, 0]`` for ``j < n`` and
    ``den[:, n]``.  Rows whose step-down broke down (a plain-shift basis) are NaN.
    """
    n = den.shape[1] - 1
    k = np.concatenate([basis[:, 1:, 0], den[:, n:]], axis=1)  # k_1 .. k_n
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        E = 1.0 / np.cumprod((1.0 - k * k)[:, ::-1], axis=1)[:, ::-1]
    # a breakdown leaves the plain shifts, which are the step-down's own result only for
    # den = 1 + a_n q^-n
    broke = (basis == np.eye(n)).all(axis=(1, 2)) & (den[:, 1:n] != 0).any(axis=1)
    E[broke | ~(np.isfinite(E) & (E > 0)).all(axis=1)] = np.nan
    return E


def _monic(x: np.ndarray) -> np.ndarray:
    out = np.empty((x.shape[0], x.shape[1] + 1))
    out[:, 0] = 1.0
    out[:, 1:] = x
    return out


def _lags(x: np.ndarray, n_lags: int, t0: int, n: int) -> np.ndarray:
    """``(n_lags, n - t0)`` rows ``x(t - l)`` for ``t = t0 .. n-1``, zero before ``t = 0``."""
    pad = np.concatenate([np.zeros(n_lags), x])
    return np.stack([pad[n_lags + t0 - lag : n_lags + n - lag] for lag in range(n_lags)])


def _check_cost_options(
    structure: Any, metric: str, predictor: str, penalty_kind: str, initial: str,
    weight: float, penalty: float,
) -> None:
    """:class:`PolynomialCost`'s arguments other than the record, each with its own error."""
    if not isinstance(structure, PolynomialStructure):
        raise ConfigError(
            f"structure must be a PolynomialStructure, got {type(structure).__name__}"
        )
    _check_names(metric, predictor, penalty_kind)
    _check_initial(initial)
    if predictor == "simulation" and structure.has_noise_model:
        raise ConfigError(
            f"{structure!r} has a noise model (nc or nd > 0), which the simulation "
            "predictor ignores: use predictor='one-step' (its own prediction error), or a "
            "structure without C and D (oe)"
        )
    for name, value in (("weight", weight), ("penalty", penalty)):
        real(value, name, error=DataError, minimum=0)


class PolynomialCost(ErrorCost):
    """The cost an optimiser minimises to identify a polynomial model.

    Parameters
    ----------
    structure : PolynomialStructure
        Orders (any structure of the family; ARX is accepted, and equals
        :class:`~flexid.costs.arx.ARXCost` on the rules both have).
    data : IOData or (u, y)
        Estimation record (single output).
    metric, weight, penalty, penalty_kind : see :class:`~flexid.costs.arx.ARXCost`
        The error measure and the stability penalty (a candidate with ``A``, ``F_j`` or ``D``
        not stable, or ``C`` not minimum phase, costs the penalty plus the cost of the zero
        prediction).
    predictor : {"one-step", "simulation"}
        The structure's own prediction error, or the free-run simulation error (structures
        without ``C`` and ``D`` only).
    initial : {"estimate", "zero", "measured"}
        Initial-condition rule (see the module docstring).

    Attributes
    ----------
    K : int
        Error samples ``N - start``.
    records : tuple of (u, y)
        The record's arrays, ``u`` (N, n_u) and ``y`` (N,) (one pair: several are
        :class:`~flexid.costs.experiments.MultiExperimentCost`).
    n_params : int
    theta_ls : ndarray, shape (n_params,)
        The least-squares start: ARX least squares of orders ``(na + nf, nb, nk)`` read as
        this structure (``F = A`` for output error; ``C = D = 1``).  NaN when the
        structure's ``F_j`` have different orders.
    cost_ls : float
        This cost at ``theta_ls`` (NaN when ``theta_ls`` is).
    """

    def __init__(
        self,
        structure: PolynomialStructure,
        data: Any,
        *,
        metric: str = _DEFAULT.metric,
        predictor: str = _DEFAULT.predictor,
        weight: float = _DEFAULT.weight,
        penalty: float = _DEFAULT.penalty,
        initial: str = "estimate",
        penalty_kind: str = "flat",
    ) -> None:
        _check_cost_options(structure, metric, predictor, penalty_kind, initial, weight,
                            penalty)  # fmt: skip
        u, y = _record(structure, data)
        structure.check_samples(y.size)
        self.structure = structure
        self.metric, self.predictor, self.initial = metric, predictor, initial
        self.weight, self.penalty, self.penalty_kind = float(weight), float(penalty), penalty_kind
        self.u, self.y = u, y
        self.records = ((u, y),)
        s = structure
        self.n_params = s.n_params
        self.start = s.start
        self.N = y.size
        self.K = self.N - s.start
        self._target = y[s.start :]
        self._std_y = float(np.std(self._target))
        self._sse_zero = float(self._target @ self._target)
        self._slices = s.slices()
        self._degrees()
        self._record_lags()
        self._routes()
        self.theta_ls = self._least_squares_start()
        finite = bool(np.isfinite(self.theta_ls).all())
        self.cost_ls = float(self(self.theta_ls)[0]) if finite else float("nan")

    def _degrees(self) -> None:
        """The predictor's orders: its noise filter, denominator and numerators' degrees."""
        s = self.structure
        one_step = self.predictor == "one-step"
        # the noise filter only exists for the one-step predictor
        self._nc, self._nd = (s.nc, s.nd) if one_step else (0, 0)
        # first sample of the recursion: 0 from rest, start otherwise
        self._t0 = 0 if self.initial == "zero" else s.start
        sf = sum(s.nf)
        self._deg_den = (self._nc if one_step else s.na) + sf
        # num_y = C F - D A F vanishes for output error (and for the simulation)
        has_y = one_step and bool(s.na or s.nc or s.nd)
        self._deg_y = max(self._nc, self._nd + s.na) + sf if has_y else 0
        self._deg_u = [
            self._nd + sf - nf + nk + nb - 1 for nb, nf, nk in zip(s.nb, s.nf, s.nk)
        ]

    def _record_lags(self) -> None:
        """The record's lags, the measured state at ``start`` and the numerators' regressors."""
        s, y, u, t0 = self.structure, self.y, self.u, self._t0
        self._ylags = _lags(y, self._deg_y + 1, t0, self.N)
        self._ulags = [_lags(u[:, j], d + 1, t0, self.N) for j, d in enumerate(self._deg_u)]
        self._state = y[s.start - self._deg_den : s.start][::-1].copy()
        # the regressors of the predictor's numerators, one row per sample (the compiled
        # passes form the input part themselves); num_y's leading coefficient and the first
        # nk_j of num_j are exactly zero, so their rows are left out (see _numerator)
        self._reg = np.ascontiguousarray(
            np.concatenate([self._ylags[1:], *(x[nk:] for x, nk in zip(self._ulags, s.nk))]).T
        )

    def _routes(self) -> None:
        """Which fast routes the structure, predictor and rule take (see the module notes)."""
        s, initial = self.structure, self.initial
        one_step = self.predictor == "one-step"
        # Box-Jenkins' one-step predictor (no A; D of order at most that of C, at most two)
        # with the state estimated: its error from rest as the cascade D/C (y - B/F u), fewer
        # multiply-adds than the one filter (see kernels.initial_state_fit).  What the
        # cascade's rest leaves out is a free response of 1/(C F) (what the fit removes)
        # only where nd <= nc: the state of 1/F enters through D, the samples before the
        # record through D's delays.  The regressors of input j are the first
        # nb_j + sum(nf) - nf_j of its delays from nk_j (no D in the numerator)
        self._cascade = (
            one_step and initial == "estimate" and s.na == 0 and s.nc >= 1
            and s.nd <= s.nc <= 2 and self._deg_den >= 1
        )  # fmt: skip
        if self._cascade:
            blocks, col, sf = [], self._deg_y, sum(s.nf)
            for nb, nf, nk, deg in zip(s.nb, s.nf, s.nk, self._deg_u):
                blocks.append(self._reg[:, col : col + nb + sf - nf])
                col += deg + 1 - nk
            self._reg_cascade = np.ascontiguousarray(np.concatenate(blocks, axis=1))
        self._lag_sum_routes()

    def _lag_sum_routes(self) -> None:
        """Whether the numerator is fitted by the lag-sum kernel, plain or filtered."""
        s, initial = self.structure, self.initial
        one_step = self.predictor == "one-step"
        # one input whose predictor is B / (A F) u (the simulation, or output error): the
        # numerator's regressors are delays of one signal, fitted by lag sums
        # (kernels.arx_fit_shifted)
        self._lag_sum_fit = (
            s.n_inputs == 1
            and not (one_step and self._deg_y) and 1 <= self._deg_den <= 24
            and 1 <= s.nb[0] <= 16 and kernels.shifted_columns(self._reg)
        )  # fmt: skip
        # one input, the one-step predictor of a structure with A, C or D: the regressors
        # are delays of D u filtered by 1/(C F), the target (D A / C) y, both per candidate;
        # by lag sums from rest, or with the state fitted where the inputs before start
        # enter only through it (nb - 1 <= deg C F)
        self._lag_sum_fit_filtered = (
            s.n_inputs == 1 and one_step and bool(self._deg_y)
            and 1 <= self._deg_den <= 24 and 1 <= s.nb[0] <= 16 and s.nd < s.nb[0]
            and (initial == "zero" or (initial == "estimate" and s.nb[0] - 1 <= self._deg_den))
        )  # fmt: skip
        if self._lag_sum_fit_filtered:
            nk = s.nk[0]
            self._u_reg = np.ascontiguousarray(self._ulags[0][nk : nk + s.nb[0]].T)

    # ------------------------------------------------------------------ parts of theta
    def _parts(self, X: np.ndarray) -> dict[str, Any]:
        sl = self._slices
        return {
            "a": _monic(X[:, sl["a"]]),
            "b": [X[:, s] for s in sl["b"]],
            "c": _monic(X[:, sl["c"]]),
            "d": _monic(X[:, sl["d"]]),
            "f": [_monic(X[:, s]) for s in sl["f"]],
        }

    def _root_parts(self) -> list[slice]:
        """The slices of ``A``, ``C``, ``D`` and each ``F_j`` that hold coefficients."""
        sl = self._slices
        return [part for part in (sl["a"], sl["c"], sl["d"], *sl["f"]) if part.stop > part.start]

    def _admissible(self, X: np.ndarray) -> np.ndarray:
        """Rows whose ``A``, ``F_j`` and ``D`` are stable and ``C`` is minimum phase."""
        ok = np.ones(X.shape[0], dtype=bool)
        for part in self._root_parts():
            ok &= is_stable(X[:, part])
        return ok

    def _radius(self, X: np.ndarray) -> np.ndarray:
        rho = np.zeros(X.shape[0])
        for part in self._root_parts():
            rho = np.maximum(rho, pole_radius_batched(X[:, part]))
        return rho

    def _screen(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Costs of the rows that need no prediction, and which rows do.

        Returns ``(cost, ok)``: ``+inf`` for non-finite rows, the penalty for inadmissible
        ones, and ``ok`` marking the admissible rows, whose cost the caller fills in.
        """
        cost = np.full(X.shape[0], np.inf)
        # the common case, every entry finite (their sum is, unless it overflows): no copy
        if np.isfinite(X.sum()) or np.isfinite(X).all():
            ok = self._admissible(X)
            bad = ~ok
        else:
            finite = np.isfinite(X).all(axis=1)
            ok = finite.copy()
            ok[finite] = self._admissible(X[finite])
            bad = finite & ~ok
        if bad.any():
            cost[bad] = self._penalised(X[bad])
        return cost, ok

    def _from_sse(self, sse: np.ndarray) -> np.ndarray:
        return metric_from_sse(self.metric, sse, self.K, self.weight, self._std_y)

    def _penalised(self, X: np.ndarray) -> np.ndarray:
        zero = self._from_sse(np.array(self._sse_zero))
        if self.penalty_kind == "flat":
            return np.full(X.shape[0], self.penalty + zero)
        return self.penalty * np.maximum(self._radius(X), 1.0) + zero

    # ------------------------------------------------------------------ predictor filter
    def _predictor(self, p: dict[str, Any]) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
        """Batched ``den``, ``num_y`` and ``num_j`` of every candidate's predictor."""
        f_all = p["f"][0]
        for fj in p["f"][1:]:
            f_all = poly_mul_rows(f_all, fj)
        n_pop = f_all.shape[0]
        if self.predictor == "one-step" and self._deg_y:
            den = poly_mul_rows(p["c"], f_all)
            daf = poly_mul_rows(poly_mul_rows(p["d"], p["a"]), f_all)
            num_y = np.zeros((n_pop, self._deg_y + 1))
            num_y[:, : den.shape[1]] += den
            num_y[:, : daf.shape[1]] -= daf
            num_y[:, 0] = 0.0  # both monic: exactly zero
            lead = p["d"]
        else:  # the simulation, and output error's one-step predictor (the same filter)
            den = poly_mul_rows(p["a"], f_all)
            num_y = np.zeros((n_pop, 1))
            lead = np.ones((n_pop, 1))
        nums = []
        s = self.structure
        for j in range(s.n_inputs):
            num = np.zeros((n_pop, s.nk[j] + s.nb[j]))
            num[:, s.nk[j] :] = p["b"][j]
            num = poly_mul_rows(lead, num)
            for i, fi in enumerate(p["f"]):
                if i != j:
                    num = poly_mul_rows(num, fi)
            nums.append(num)
        return den, num_y, nums

    def _numerator(self, num_y: np.ndarray, nums: list[np.ndarray]) -> np.ndarray:
        """The coefficients (P, nb_total) that multiply the columns of ``_reg``.

        ``num_y[:, 0]`` and the first ``nk_j`` coefficients of ``num_j`` are exactly zero
        (products of monic polynomials with ``B_j`` delayed by ``nk_j``), so they are left
        out with their regressors: a zero product added changes no sum.
        """
        nk = self.structure.nk
        return np.concatenate([num_y[:, 1:], *(x[:, k:] for x, k in zip(nums, nk))], axis=1)

    def _forced(self, num_y: np.ndarray, nums: list[np.ndarray]) -> np.ndarray:
        forced = num_y @ self._ylags[: num_y.shape[1]]
        for num, lags in zip(nums, self._ulags):
            forced += num @ lags[: num.shape[1]]
        return forced

    # ------------------------------------------------------------------ evaluation
    def __call__(self, X: Any) -> np.ndarray:
        """Costs of a population.

        Parameters
        ----------
        X : array_like, shape (P, n_params) or (n_params,)

        Returns
        -------
        ndarray, shape (P,)
            Non-finite rows cost ``+inf``; inadmissible ones (see ``penalty``) the penalty
            plus the cost of the zero prediction.
        """
        X = population(X, self.n_params)
        out, ok = self._screen(X)
        if ok.all():
            return self._from_sse(self.sse(X))
        if ok.any():
            out[ok] = self._from_sse(self.sse(X[ok]))
        return out

    def sse(self, X: np.ndarray) -> np.ndarray:
        """Sums of squared prediction errors of admissible rows ``X`` (P, n_params).

        Parameters
        ----------
        X : ndarray, shape (P, n_params)
            Candidates with stable ``A``, ``F_j``, ``D`` and minimum-phase ``C``.

        Returns
        -------
        ndarray, shape (P,)
            Over ``t >= start``, in output units squared.
        """
        if self._cascade:
            return self._estimated_cascade(X, want_errors=False)[0]
        den, num_y, nums = self._predictor(self._parts(X))
        n = den.shape[1] - 1
        if self.initial == "estimate" and n:
            return self._estimated(den, num_y, nums, want_errors=False)[0]
        num = self._numerator(num_y, nums)
        if kernels.BACKEND == "c" and num.shape[1] <= kernels._ARX_MAXNB:
            # the predictor is an ARX recursion on the shared regressors: the compiled
            # kernel forms its input part and sums the squares itself (no (P, K) arrays);
            # from rest the samples before start are run but not counted
            state = self._state[:n] if self.initial == "measured" else np.zeros(n)
            return arx_recursion(den[:, 1:], num, self._reg, state, self._target,
                                 want_output=False, first=self.start - self._t0)[1]  # fmt: skip
        e = self._errors_from(den, num_y, nums)
        return np.einsum("pk,pk->p", e, e)

    def prediction_errors(self, X: np.ndarray) -> np.ndarray:
        """Prediction errors ``y - yhat`` of admissible candidates.

        Parameters
        ----------
        X : ndarray, shape (P, n_params)
            Candidates with stable ``A``, ``F_j``, ``D`` and minimum-phase ``C``.

        Returns
        -------
        ndarray, shape (P, K)
            Over ``t >= start``, in output units, under the cost's initial-condition rule.
        """
        if self._cascade:
            return self._estimated_cascade(X, want_errors=True)[1]
        den, num_y, nums = self._predictor(self._parts(X))
        if self.initial == "estimate" and den.shape[1] > 1:
            return self._estimated(den, num_y, nums, want_errors=True)[1]
        return self._errors_from(den, num_y, nums)

    def _errors_from(
        self, den: np.ndarray, num_y: np.ndarray, nums: list[np.ndarray]
    ) -> np.ndarray:
        """Errors (P, K) of the predictor filters under ``"zero"`` or ``"measured"``.

        The forced terms by one GEMM per numerator, then :func:`flexid.kernels.ar_recursion`
        (also the rule ``"estimate"`` when ``den`` is 1, which has no initial state).
        """
        n = den.shape[1] - 1
        forced = self._forced(num_y, nums)
        if self.initial == "measured":
            yhat, _ = ar_recursion(den[:, 1:], forced, self._state[:n])
            return self._target - yhat
        yhat, _ = ar_recursion(den[:, 1:], forced, np.zeros(n))
        return self._target - yhat[:, self.start - self._t0 :]

    def _estimated(
        self, den: np.ndarray, num_y: np.ndarray, nums: list[np.ndarray], *, want_errors: bool
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """SSE (P,) and, when wanted, errors (P, K) with the initial state fitted.

        One pass of :func:`flexid.kernels.initial_state_fit` per population: the error from
        rest, the right-hand side of the free responses' least squares by one anti-causal
        recursion, their Gram matrix from the step-down energies (the step-down in the
        compiled kernel) less the tail after the record, and the error with the fitted free
        response removed.  Rows whose step-down breaks down in rounding, or whose small solve
        fails, take the route of :meth:`_estimated_by_recursions`.
        """
        num = self._numerator(num_y, nums)
        n = den.shape[1] - 1
        basis = energies = None  # the compiled kernel runs the step-down itself
        if not kernels.free_fit_compiled(n, num.shape[1]):
            basis = orthogonal_numerators(den, n)
            energies = _energies(den, basis)
        sse, e, _ = initial_state_fit(
            den[:, 1:], num, self._reg, self._target, basis, energies, want_errors=want_errors
        )
        bad = ~np.isfinite(sse)
        if bad.any():
            self._by_recursions(sse, e, bad, den[bad], num_y[bad], [x[bad] for x in nums])
        return sse, e

    def _estimated_cascade(
        self, X: np.ndarray, *, want_errors: bool
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """:meth:`_estimated` of Box-Jenkins' one-step predictor by the cascade.

        The error from rest ``D/C (y - sum_j B_j/F_j u_j)``: one recursion of ``1/F``
        (``F`` the product of the ``F_j``) over the inputs through ``B_j prod_(i != j) F_i``,
        then ``D/C`` of ``y`` less its output, where the single filter of :meth:`_predictor`
        takes ``y`` through ``(C - D) F`` and the inputs through ``D B_j prod F_i``
        (:func:`flexid.kernels.initial_state_fit`'s ``first`` and ``noise``).  The fit of
        the initial state of ``1/(C F)`` is the same.
        """
        s, sl = self.structure, self._slices
        f = [_monic(X[:, part]) for part in sl["f"]]
        f_all = f[0]
        for fj in f[1:]:
            f_all = poly_mul_rows(f_all, fj)
        den = poly_mul_rows(_monic(X[:, sl["c"]]), f_all)
        n_pop, n = X.shape[0], den.shape[1] - 1
        first = np.zeros((n_pop, n))
        first[:, : f_all.shape[1] - 1] = f_all[:, 1:]
        noise = np.zeros((n_pop, 4))
        noise[:, : self._nc] = X[:, sl["c"]]
        noise[:, 2 : 2 + self._nd] = X[:, sl["d"]]
        nums = []
        for j in range(s.n_inputs):
            num = X[:, sl["b"][j]]
            for i, fi in enumerate(f):
                if i != j:
                    num = poly_mul_rows(num, fi)
            nums.append(num)
        num = nums[0] if len(nums) == 1 else np.concatenate(nums, axis=1)
        basis = energies = None  # the compiled kernel runs the step-down itself
        if not kernels.free_fit_compiled(n, num.shape[1]):
            basis = orthogonal_numerators(den, n)
            energies = _energies(den, basis)
        sse, e, _ = initial_state_fit(
            den[:, 1:], num, self._reg_cascade, self._target, basis, energies,
            want_errors=want_errors, first=first, noise=noise,
        )  # fmt: skip
        bad = ~np.isfinite(sse)
        if bad.any():
            self._by_recursions(sse, e, bad, *self._predictor(self._parts(X[bad])))
        return sse, e

    def _by_recursions(
        self,
        sse: np.ndarray,
        e: np.ndarray | None,
        bad: np.ndarray,
        den: np.ndarray,
        num_y: np.ndarray,
        nums: list[np.ndarray],
    ) -> None:
        """The rows ``bad`` of ``sse`` and ``e`` (when given) by
        :meth:`_estimated_by_recursions`, from those rows' predictor polynomials."""
        e_bad = self._estimated_by_recursions(den, num_y, nums)
        sse[bad] = np.einsum("pk,pk->p", e_bad, e_bad)
        if e is not None:
            e[bad] = e_bad

    def _estimated_by_recursions(
        self, den: np.ndarray, num_y: np.ndarray, nums: list[np.ndarray]
    ) -> np.ndarray:
        """Errors (P, K) with the initial state fitted: ``n`` recursions and least squares."""
        yhat, _ = ar_recursion(den[:, 1:], self._forced(num_y, nums), np.zeros(den.shape[1] - 1))
        e = self._target - yhat
        free = self._free_responses(den)
        (x0,) = _least_squares_rows([free], e)
        return e - (x0[:, None, :] @ free)[:, 0]

    def _free_responses(self, den: np.ndarray) -> np.ndarray:
        """``(P, n, K)`` basis of the free responses of ``1/den`` from ``t = start``.

        The free responses from ``t = start`` are the impulse responses of ``N(q)/den(q)``
        with ``deg N < n`` (the initial state acts as an input on the first ``n`` samples).
        The shifts ``q^-k / den`` span them but are numerically dependent for lightly damped
        high orders (condition numbers above 1e16 measured at order 16), so the basis is
        the backward prediction-error filters ``B_m(q) / den(q)``, ``m = 0..n-1``, with
        ``B_m`` the reversed step-down (Levinson) polynomial of order ``m``: their impulse
        responses are orthogonal over ``t >= 0`` (Szego polynomials of the weight
        ``1/|den|^2``), and nearly so over the record, so the least-squares fit of the
        initial state is well conditioned.
        """
        n_pop, n = den.shape[0], den.shape[1] - 1
        forcing = np.zeros((n_pop, n, self.K))
        forcing[:, :, :n] = orthogonal_numerators(den, n)
        g, _ = ar_recursion(
            np.repeat(den[:, 1:], n, axis=0), forcing.reshape(n_pop * n, self.K), np.zeros(n)
        )
        return g.reshape(n_pop, n, self.K)

    # ------------------------------------------------------------------ variable projection
    def fit_numerator(self, X: Any) -> np.ndarray:
        """Replace each row's ``B`` by the one that minimises this cost (variable projection).

        Parameters
        ----------
        X : array_like, shape (P, n_params) or (n_params,)
            Candidates; their ``B`` entries are ignored.  Inadmissible rows keep the ``B`` of
            :attr:`theta_ls` (their cost is the penalty whatever ``B`` is).

        Returns
        -------
        ndarray, shape like ``X``
        """
        X = np.asarray(X, dtype=float)
        single = X.ndim == 1
        theta = self.fitted_costs(np.atleast_2d(X))[1]
        return theta[0] if single else theta

    def fitted_costs(self, X: Any) -> tuple[np.ndarray, np.ndarray]:
        """Costs of the rows of ``X`` with their best ``B``, and those ``theta`` (one pass).

        Parameters
        ----------
        X : array_like, shape (P, n_params)
            Candidates; their ``B`` entries are ignored.

        Returns
        -------
        cost : ndarray, shape (P,)
        theta : ndarray, shape (P, n_params)
            ``X`` with the fitted ``B`` (see :meth:`fit_numerator`).
        """
        X = population(X, self.n_params).copy()
        b_cols = self.structure.b_columns
        X[:, b_cols] = np.nan_to_num(self.theta_ls[b_cols])
        cost, ok = self._screen(X)
        if ok.any():
            b, sse = self._fitted_b(X[ok])
            X[np.flatnonzero(ok)[:, None], b_cols] = b
            cost[ok] = self._from_sse(sse)
        return cost, X

    def _fitted_b(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Best ``B`` (P, sum nb) of admissible rows and the SSE it leaves (P,)."""
        if kernels.BACKEND == "c":
            if self._lag_sum_fit:
                return self._fitted_b_lag_sums(X)
            if self._lag_sum_fit_filtered:
                return self._fitted_b_lag_sums_filtered(X)
            if self._compiled_fit:
                # one input but no lag sums (BJ and ARMAX from the measured outputs, or with
                # the state estimated where nb - 1 > deg C F): the compiled orthogonal route
                return self._fitted_b_orthogonal(X)
        return self._fitted_b_recursions(X)

    def _fitted_b_orthogonal(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`_fitted_b_recursions`' problem: compiled where the structure allows it,
        the recursions for every row the compiled route cannot solve."""
        if not self._compiled_fit:
            return self._fitted_b_recursions(X)
        b, sse, ok = self._fitted_b_compiled(X)
        if not ok.all():
            b[~ok], sse[~ok] = self._fitted_b_recursions(X[~ok])
        return b, sse

    @property
    def _compiled_fit(self) -> bool:
        """Whether :meth:`_fitted_b_compiled` applies (one input, orders the kernel takes)."""
        s = self.structure
        one_step = self.predictor == "one-step"
        n = (self._nc if one_step else s.na) + (s.nf[0] if s.n_inputs == 1 else 0)
        return s.n_inputs == 1 and kernels.flagged_fit_compiled(n, s.nb[0], self._nd + 1)

    def _fitted_b_compiled(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`_fitted_b_recursions` of one input by :func:`flexid.kernels.flagged_fit`.

        The same least-squares problem (:meth:`b_regressors`: the regressors in the
        orthogonal numerators' basis, the free responses under ``"estimate"``, the target of
        the predictor) and the same solve, compiled: one recursion of ``1/den`` and a lattice
        filter of it in place of one recursion per coefficient (each regressor's own
        recursion from ``start`` under ``"measured"``), and no ``(P, nb, K)`` arrays.

        Returns
        -------
        b : ndarray, shape (P, nb)
        sse : ndarray, shape (P,)
        ok : ndarray of bool, shape (P,)
            False for the rows the kernel could not solve (the caller takes the recursions).
        """
        s = self.structure
        p = self._parts(X)
        one_step = self.predictor == "one-step"
        den = poly_mul_rows(p["c"] if one_step else p["a"], p["f"][0])
        nb = s.nb[0]
        n = den.shape[1] - 1
        target = targets = state = None
        if self.initial == "measured" and not (one_step and self._deg_y):
            # no output numerator: the free part is the free response from the measured
            # outputs, which the kernel subtracts from the shared target
            target, state = self._target, self._state[:n]
        elif self.initial == "measured":
            # the free part: the predictor with B = 0 from the measured outputs (its input
            # part is zero, so only num_y y is formed)
            num_y = self._predictor(p)[1]
            forced = num_y @ self._ylags[: num_y.shape[1]]
            y0, _ = ar_recursion(den[:, 1:], forced, self._state[:n])
            targets = self._target - y0
        elif one_step and self._deg_y:
            targets = self._filtered_target(p)
        else:
            target = self._target
        nk = s.nk[0]
        sig = np.concatenate([np.zeros(nk), self.u[: self.N - nk, 0]])
        return kernels.flagged_fit(
            den[:, 1:], nb, sig, target, targets, lead=p["d"] if self._nd else None,
            free=self.initial == "estimate", restart=self.initial == "measured", state=state,
            tol=_REFINE_TOL,
        )  # fmt: skip

    def _filtered_target(self, p: dict[str, Any]) -> np.ndarray:
        """``z = (D A / C) y`` (P, K) of the one-step predictor, from rest at ``t = 0``."""
        num_z = poly_mul_rows(p["d"], p["a"])
        den_z = p["c"]
        z_lags = _lags(self.y, num_z.shape[1], 0, self.N)
        z, _ = ar_recursion(den_z[:, 1:], num_z @ z_lags, np.zeros(den_z.shape[1] - 1))
        return z[:, self.start :]

    def _fitted_b_lag_sums_filtered(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`_fitted_b` by :func:`flexid.kernels.arx_fit_shifted` with ``C`` or ``D``.

        The one-step error is ``z - sum_i b_i w(t - nk - i)`` with ``z = (D A / C) y`` and
        ``w = (D / (C F)) u``: the kernel's lag sums with the numerator ``D`` on the input
        and ``z`` as each candidate's target.  Under ``"estimate"`` the free responses of
        ``1/(C F)`` from ``start`` also span the free responses of ``1/C`` in ``z``, so
        ``z`` may start from rest at ``t = 0``.  Rows the kernel flags take the recursions.
        """
        p = self._parts(X)
        den = self._predictor(p)[0]
        n = den.shape[1] - 1
        free = self.initial == "estimate"
        b, ok, _ = kernels.arx_fit_shifted(
            den[:, 1:], self._u_reg, np.zeros(n), self._target, 0 if free else self.start,
            free_state=free, num=p["d"], targets=self._filtered_target(p),
        )  # fmt: skip
        return self._completed(X, b, ok)

    def _completed(
        self, X: np.ndarray, b: np.ndarray, ok: np.ndarray, sse: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """A lag-sum fit's ``B`` and SSE: the SSE of its rows at their ``B`` where not given,
        the orthogonal route for the rows the kernel flagged (``ok`` False)."""
        if sse is None:
            sse = np.empty(X.shape[0])
            if ok.any():
                theta = X[ok]
                theta[:, self.structure.b_columns] = b[ok]
                sse[ok] = self.sse(theta)
        if not ok.all():
            b[~ok], sse[~ok] = self._fitted_b_orthogonal(X[~ok])
        return b, sse

    def _fitted_b_lag_sums(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`_fitted_b` by :func:`flexid.kernels.arx_fit_shifted` (one input, no C, D).

        The predictor is ``B / den u(t - nk)`` with ``den = A F``, ARX's simulation with
        ``A = den``: the kernel's one pass of lag sums and normal equations.  Under
        ``"estimate"`` the kernel fits the initial state at ``start`` with ``B``: the free
        responses from it span those from ``t = 0`` and the part of every regressor that the
        inputs before ``start`` drive, so its ``B`` is that of the rule's own problem.  Rows
        it flags (the bound on the normal equations' error above its tolerance) take the
        recursions.
        """
        den = self._predictor(self._parts(X))[0]
        n = den.shape[1] - 1
        if self.initial == "measured":
            b, ok, sse = kernels.arx_fit_shifted(den[:, 1:], self._reg, self._state[:n],
                                                 self._target, 0, want_sse=True)  # fmt: skip
            return self._completed(X, b, ok, sse)
        # from rest at t = 0, or the state at start fitted; errors counted from start
        free = self.initial == "estimate"
        b, ok, _ = kernels.arx_fit_shifted(den[:, 1:], self._reg, np.zeros(n), self._target,
                                           0 if free else self.start,
                                           free_state=free)  # fmt: skip
        return self._completed(X, b, ok)

    def _fitted_b_recursions(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`_fitted_b` by one recursion per coefficient of ``B``, any structure."""
        blocks, z, bases = self.b_regressors(X)
        coefs = _least_squares_rows(blocks, z)
        resid = z.copy()
        for F, c in zip(blocks, coefs):
            resid -= (c[:, None, :] @ F)[:, 0]
        n_u = self.structure.n_inputs
        return self._b_of(np.concatenate(coefs[:n_u], axis=1), bases), np.einsum(
            "pk,pk->p", resid, resid
        )

    def b_regressors(
        self, X: np.ndarray
    ) -> tuple[list[np.ndarray], np.ndarray, list[np.ndarray]]:
        """The linear least-squares problem of ``B`` given the other polynomials.

        The error is ``z - sum_j sum_m c_jm g_jm (- free responses)``: the regressors of
        each input's ``B_j`` in the orthogonal numerators' basis, then (under ``"estimate"``)
        the free responses from ``start``.

        Parameters
        ----------
        X : ndarray, shape (P, n_params)
            Admissible candidates (their ``B`` entries are ignored).

        Returns
        -------
        blocks : list of ndarray, shapes (P, n_i, K)
            One block per input (``nb_j`` rows), then the free responses' block (``n`` rows)
            when the initial state is estimated.
        z : ndarray, shape (P, K)
            The target.
        bases : list of ndarray, shapes (P, nb_j, nb_j)
            The numerators' bases: ``b_j = c_j @ bases[j]`` (:meth:`_b_of`).
        """
        if self.initial == "measured":
            return self._b_regressors_measured(X)
        p = self._parts(X)
        s = self.structure
        n_pop = X.shape[0]
        one_step = self.predictor == "one-step"
        n0 = self.N  # regressors from rest over the whole record, then cut to t >= start
        if one_step:
            z = self._filtered_target(p)
            lead = p["d"]
        else:
            # simulation: z = y, the A of the structure joins every F_j
            z = np.broadcast_to(self._target, (n_pop, self.K))
            lead = np.ones((n_pop, 1))
        blocks, bases = [], []
        for j in range(s.n_inputs):
            # the b_j regressors span {N(q)/den_g lead u_j(t - nk_j) : deg N < nb_j}: in the
            # orthogonal numerators' basis, not the shifts, which are numerically dependent
            # for lightly damped denominators (one recursion per coefficient, not one in all)
            den_g = poly_mul_rows(p["c"] if one_step else p["a"], p["f"][j])
            T = orthogonal_numerators(den_g, s.nb[j])
            bases.append(T)
            num = np.stack([poly_mul_rows(T[:, m], lead) for m in range(s.nb[j])], axis=1)
            width = num.shape[2]
            lags = _lags(self.u[:, j], s.nk[j] + width, 0, n0)[s.nk[j] :]
            forcing = (num @ lags).reshape(n_pop * s.nb[j], n0)
            h, _ = ar_recursion(
                np.repeat(den_g[:, 1:], s.nb[j], axis=0), forcing, np.zeros(den_g.shape[1] - 1)
            )
            blocks.append(h.reshape(n_pop, s.nb[j], n0)[:, :, self.start :])
        if self.initial == "estimate":
            den, _, _ = self._predictor({**p, "b": [np.zeros((n_pop, nb)) for nb in s.nb]})
            if den.shape[1] > 1:
                blocks.append(self._free_responses(den))
        return blocks, np.ascontiguousarray(z), bases

    def _b_of(self, coef: np.ndarray, bases: list[np.ndarray]) -> np.ndarray:
        """``b`` (P, sum nb) from coefficients in the orthogonal numerators' basis."""
        out, i = [], 0
        for T in bases:
            nb = T.shape[1]
            out.append(np.einsum("pmi,pm->pi", T, coef[:, i : i + nb]))
            i += nb
        return np.concatenate(out, axis=1) if out else coef

    def _b_regressors_measured(
        self, X: np.ndarray
    ) -> tuple[list[np.ndarray], np.ndarray, list[np.ndarray]]:
        """:meth:`b_regressors` under ``"measured"``: one recursion per ``b`` coefficient.

        The recursion starts at ``t = start`` from the measured outputs, so a shifted
        regressor is not a shift of another one (their transients differ).
        """
        s = self.structure
        n_pop = X.shape[0]
        group = sum(s.nb) + 1  # per candidate: the free part, then one row per b
        Xb = np.repeat(X, group, axis=0)
        Xb[:, s.b_columns] = 0.0
        # each b regressor is the response to one orthogonal numerator (see _fitted_b)
        p = self._parts(X)
        one_step = self.predictor == "one-step"
        bases = [
            orthogonal_numerators(
                poly_mul_rows(p["c"] if one_step else p["a"], p["f"][j]), s.nb[j]
            )
            for j in range(s.n_inputs)
        ]
        r = 1
        for j, sl in enumerate(self._slices["b"]):
            for m in range(s.nb[j]):
                Xb[r::group, sl] = bases[j][:, m]
                r += 1
        den, num_y, nums = self._predictor(self._parts(Xb))
        unit = np.ones(Xb.shape[0], dtype=bool)
        unit[::group] = False
        num_y[unit] = 0.0  # the b regressors: input part only, from rest
        forced = self._forced(num_y, nums)
        n = den.shape[1] - 1
        state = np.zeros((Xb.shape[0], n))
        state[::group] = self._state[:n]  # only the free part starts from data
        y, _ = ar_recursion(den[:, 1:], forced, state)
        y = y.reshape(n_pop, group, self.K)
        z = self._target - y[:, 0]
        edges = np.cumsum([0, *s.nb])
        return [y[:, 1 + lo : 1 + hi] for lo, hi in pairwise(edges)], z, bases

    # ------------------------------------------------------------------ least-squares start
    def _least_squares_start(self) -> np.ndarray:
        from ..models.arx import ARXStructure

        s = self.structure
        theta = np.full(self.n_params, np.nan)
        if len(set(s.nf)) > 1:
            return theta
        nf = s.nf[0]
        try:
            arx = ARXStructure(s.na + nf, s.nb, s.nk).least_squares(list(self.records))
        except Exception:  # rank deficient or too short: no least-squares start
            return theta
        a = arx.theta[: s.na + nf]
        sl = self._slices
        theta[:] = 0.0
        if s.na and nf:
            theta[sl["a"]] = a[: s.na]  # a split of AF is arbitrary: A gets the leading part
            for f in sl["f"]:
                theta[f] = a[s.na :]
        elif s.na:
            theta[sl["a"]] = a
        else:
            for f in sl["f"]:
                theta[f] = a
        theta[s.b_columns] = arx.theta[s.na + nf :]
        return theta

    # ------------------------------------------------------------------ reporting
    def residuals(self, theta: Any) -> np.ndarray:
        """Prediction errors of one admissible candidate over ``t >= start``.

        Parameters
        ----------
        theta : array_like, shape (n_params,)

        Returns
        -------
        ndarray, shape (K,)
        """
        theta = np.asarray(theta, dtype=float).reshape(1, -1)
        return self.prediction_errors(theta)[0]

    def realised_errors(self, theta: np.ndarray) -> np.ndarray | None:
        """The errors behind :meth:`realised_cost`: the predictor run by
        :meth:`PolynomialModel.predict <flexid.models.polynomial.PolynomialModel.predict>` /
        ``simulate``, correct to the bound stated there.

        Parameters
        ----------
        theta : ndarray, shape (n_params,)

        Returns
        -------
        ndarray, shape (K,), or None
            None for an inadmissible candidate (the penalty applies) and under the rule
            ``"measured"`` (a direct-form rule by definition).
        """
        X = population(theta[None, :], self.n_params)
        if self.initial == "measured" or not np.isfinite(theta).all() or not (
            self._admissible(X)[0]
        ):
            return None
        model = self.structure.model(theta)
        if self.predictor == "one-step":
            yhat = model.predict(self.u, self.y, initial=self.initial, from_start=True)
        else:
            yhat = model.simulate(self.u, self.y, initial=self.initial, from_start=True)
        return self._target - yhat[self.start :]

    def describe(self) -> str:
        """One line naming the metric, penalty, structure, predictor, rule and ``K``.

        Returns
        -------
        str
        """
        what = "one-step prediction" if self.predictor == "one-step" else "simulation"
        errors = f"{what} errors of {self.structure!r}{self._scope()}"
        return describe_cost(self.metric, errors, self.K, self.weight, self.penalty,
                             self.penalty_kind == "graded")  # fmt: skip

    def _scope(self) -> str:
        """Where the errors are counted, for :meth:`describe`."""
        return f" ({INITIAL_RULES[self.initial]})"

    def __repr__(self) -> str:
        return f"PolynomialCost({self.describe()})"
