"""Batched ARX costs: a whole population ``X`` of shape ``(P, n)`` in, ``(P,)`` costs out.

Two predictors:

* **one-step** (equation error): ``e(t) = y(t) - phi(t) theta``.  With ``Phi = Q R`` and the
  least-squares solution ``theta*``, ``SSE(theta) = SSE* + ||R (theta - theta*)||^2`` exactly,
  so a population costs ``O(P n^2)`` whatever the record length.
* **simulation** (output error): ``e(t) = y(t) - y_sim(t)`` where ``y_sim`` is the free-run
  output.  The input part of the whole population is one GEMM, the autoregressive part the
  compiled batched recursion of :mod:`flexid.kernels` (or one ``lfilter`` per candidate
  without it; see :func:`simulate_population`); unstable candidates are never simulated.

Metrics: those of :data:`flexid.costs.metrics.METRIC_TABLE` (the paper's cost, eq. 5-6,
``w sqrt(SSE) / K``, plus a penalty when a pole has ``|p| >= 1``; RMSE, NRMSE, SSE, MSE).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy import linalg

from .. import kernels
from .._validate import real
from ..errors import DataError, UnknownNameError
from ..kernels import ar_recursion, arx_recursion
from ..models.arx import ARXStructure, _io_arrays
from ..models.polynomial import INITIAL_RULES
from ..models.specs import CostSpec
from ..models.stability import is_stable, pole_radius_batched
from .metrics import METRICS, describe_cost, metric_from_sse

__all__ = [
    "INITIAL",
    "METRICS",
    "PENALTY_KINDS",
    "PREDICTORS",
    "ARXCost",
    "ErrorCost",
    "metric_from_sse",
    "population",
    "simulate_population",
]

PREDICTORS = ("one-step", "simulation")
INITIAL = ("measured", "zero")
PENALTY_KINDS = ("flat", "graded")
_DEFAULT = CostSpec()  # the one definition of a cost's default settings
# Largest (rows x samples) work array of one block of simulation numerator fits: 2**22
# doubles, 32 MB.
_FIT_BLOCK = 1 << 22


def _least_squares_rows(F: np.ndarray, r: np.ndarray) -> np.ndarray:
    """``argmin_b ||r_p - b F_p||`` for each ``p``: ``F`` (P, n, K), ``r`` (P, K) -> (P, n).

    Normal equations of the column-scaled regressors, solved once and refined once with the
    residual (iterative refinement): each step divides the error by about ``kappa(F)^2 eps``,
    so two steps reach QR's accuracy for ``kappa(F)`` up to ~1e5, at a fraction of the cost of
    a batched QR (a (P, n, n) Gram matrix by one matmul instead of P Householder
    factorisations).  Blocks where that fails (singular or non-finite) fall back to SVD least
    squares, row by row.
    """
    scale = np.sqrt(np.einsum("pnk,pnk->pn", F, F))
    scale[scale == 0] = 1.0
    Fs = F / scale[:, :, None]
    G = Fs @ Fs.transpose(0, 2, 1)
    try:
        c = np.linalg.solve(G, Fs @ r[:, :, None])
        resid = r - np.einsum("pnk,pn->pk", Fs, c[:, :, 0])
        c += np.linalg.solve(G, Fs @ resid[:, :, None])
        b = c[:, :, 0] / scale
        if np.isfinite(b).all():
            return b
    except np.linalg.LinAlgError:
        pass
    return np.stack([linalg.lstsq(F[i].T, r[i])[0] for i in range(F.shape[0])])


def population(X: Any, n_params: int) -> np.ndarray:
    """A population as a float ``(P, n_params)`` array (one row for a 1-D ``X``).

    Parameters
    ----------
    X : array_like, shape (P, n_params) or (n_params,)
    n_params : int

    Returns
    -------
    ndarray, shape (P, n_params)

    Raises
    ------
    DataError
        For any other shape.
    """
    X = np.asarray(X, dtype=float)
    if X.ndim == 1:
        X = X[None, :]
    if X.ndim != 2 or X.shape[1] != n_params:
        raise DataError(f"the population must have shape (P, {n_params}), got {X.shape}")
    return X


def _check_names(metric: str, predictor: str, penalty_kind: str) -> None:
    """An error cost's metric, predictor and stability penalty, each a name it knows.

    Raises
    ------
    UnknownNameError
        For the first that is not.
    """
    if metric not in METRICS:
        raise UnknownNameError("cost metric", metric, METRICS)
    if predictor not in PREDICTORS:
        raise UnknownNameError("predictor", predictor, PREDICTORS)
    if penalty_kind not in PENALTY_KINDS:
        raise UnknownNameError("stability penalty", penalty_kind, PENALTY_KINDS)


def _record(structure: Any, data: Any) -> tuple[np.ndarray, np.ndarray]:
    """An error cost's record ``data`` (an IOData or ``(u, y)``) as ``u`` (N, n_u), ``y`` (N,).

    Raises
    ------
    DataError
        For bad signals, or other than ``structure.n_inputs`` inputs.
    """
    u, y = _io_arrays(*data) if isinstance(data, tuple) else _io_arrays(data, None)
    if u.shape[1] != structure.n_inputs:
        raise DataError(
            f"the model has {structure.n_inputs} input(s) but the data have {u.shape[1]}"
        )
    return u, y


def simulate_population(a: np.ndarray, forced: np.ndarray, state: np.ndarray) -> np.ndarray:
    """Run ``y(t) = f(t) - sum_i a_i y(t - i)`` for every candidate of a population.

    The input part ``f = B(q) u`` of the whole population is one GEMM (done by the caller);
    this function runs the autoregressive part: in the compiled kernel of
    :mod:`flexid.kernels` when it was built (the population in blocks of 16 candidates,
    four per SIMD register), otherwise one ``scipy.signal.lfilter`` per candidate.  Both
    are the exact recursion.  A blocked recursion with companion-matrix powers and batched
    Toeplitz products was tried too: no faster, and it lost up to 8 digits for clustered
    poles.

    Parameters
    ----------
    a : ndarray, shape (P, na)
        ``a_1 .. a_na`` of each candidate (should be stable; the cost never simulates an
        unstable one).
    forced : ndarray, shape (P, K)
        ``f(t) = B(q) u(t)`` of each candidate.
    state : ndarray, shape (P, na) or (na,)
        ``[y(-1), ..., y(-na)]`` before the first sample.

    Returns
    -------
    ndarray, shape (P, K)
    """
    y, _ = ar_recursion(a, forced, state)
    return y


class ErrorCost:
    """What a cost of one model's errors needs besides its batched route: the cost of an error
    vector and the rounding floor below which two routes' costs are the same.

    A cost class sets ``K`` (error samples), ``_std_y`` and ``_from_sse``, and says in
    ``realised_errors(theta)`` what its errors are in a well-conditioned realisation.
    """

    K: int
    _std_y: float

    def cost_of_errors(self, e: np.ndarray) -> float:
        """The cost of one model's error samples.

        Parameters
        ----------
        e : ndarray, shape (K,)
            ``y - yhat`` over the counted samples.

        Returns
        -------
        float
        """
        return float(self._from_sse(np.array([e @ e]))[0])

    def realised_cost(self, theta: Any) -> float:
        """This cost of one candidate with its predictor run in a well-conditioned realisation.

        The batched costs run each candidate in the direct form, which is fast and, for a
        lightly damped high-order candidate, can be far off the candidate's true cost (see
        :mod:`flexid.models.realisation`); a final model is rescored with this
        (:func:`flexid.jobs._identify.rescored`).

        Parameters
        ----------
        theta : array_like, shape (n_params,)

        Returns
        -------
        float
            The cost of :meth:`realised_errors`; the batched cost where they are None.
        """
        theta = np.asarray(theta, dtype=float).reshape(-1)
        e = self.realised_errors(theta)
        return float(self(theta)[0]) if e is None else self.cost_of_errors(e)

    def rounding_floor(self) -> float:
        """The cost of an error of 1e-8 output standard deviations at every sample.

        Two routes to a cost that differ by less than this differ by rounding (a noise-free
        record fitted exactly has a cost of that order); :func:`flexid.jobs._identify.rescored`
        rescores only above it.

        Returns
        -------
        float
        """
        return float(self._from_sse(np.array([self.K * (1e-8 * self._std_y) ** 2]))[0])


class ARXCost(ErrorCost):
    """The cost an optimiser minimises to identify an ARX model.

    Parameters
    ----------
    structure : ARXStructure
        Model orders.
    data : IOData or (u, y)
        Estimation record (single output).
    metric : {"paper", "rmse", "nrmse", "sse", "mse"}
        ``paper`` is eq. 5-6 of Nasir & Tokhi: ``weight * sqrt(SSE) / K``.
        ``nrmse`` divides the RMSE by the standard deviation of ``y`` over the same samples.
    predictor : {"one-step", "simulation"}
        Equation error or output error.
    weight : float
        ``w`` of the paper's cost (default 1e3).
    penalty : float
        Added when any pole has ``|p| >= 1`` (default 1e9; every metric).  With the
        simulation predictor an unstable candidate is not simulated: its cost is
        ``penalty`` plus the cost of the zero prediction (finite and worse than any stable
        candidate's).  ``penalty = 0`` switches the stability penalty off for the one-step
        predictor.
    penalty_kind : {"flat", "graded"}
        ``"flat"`` (the paper's): an unstable candidate costs as described under
        ``penalty``, the same whatever its poles.  ``"graded"``: the penalty is
        ``penalty * rho`` instead, where ``rho >= 1`` is the candidate's largest pole radius,
        so every unstable candidate still costs more than any stable one (as with the paper's
        penalty) and among unstable candidates the one nearer the stable region costs less.
    initial : {"measured", "zero", "auto"}
        Simulation predictor only: the first ``start`` outputs are the measured ones and
        the recursion starts at ``t = start`` (``"measured"``; ``"auto"`` is the same), or
        every signal is zero before ``t = 0`` (``"zero"``).  Either way the error is over
        ``t >= start``.  (The rule ``"estimate"`` is
        :class:`~flexid.costs.polynomial.PolynomialCost`'s, which covers ARX too.)

    Attributes
    ----------
    K : int
        Number of error samples, ``N - start``.
    theta_ls : ndarray, shape (n_params,)
        Least-squares estimate (the exact optimum of the one-step cost).
    cost_ls : float
        This cost at ``theta_ls``.
    """

    def __init__(
        self,
        structure: ARXStructure,
        data: Any,
        *,
        metric: str = _DEFAULT.metric,
        predictor: str = _DEFAULT.predictor,
        weight: float = _DEFAULT.weight,
        penalty: float = _DEFAULT.penalty,
        initial: str = _DEFAULT.initial,
        penalty_kind: str = "flat",
    ) -> None:
        _check_names(metric, predictor, penalty_kind)
        if initial == "auto":  # CostSpec's default: ARX's rule is "measured"
            initial = "measured"
        if initial not in INITIAL:
            raise UnknownNameError("initial condition rule", initial, INITIAL)
        for name, value in (("weight", weight), ("penalty", penalty)):
            real(value, name, error=DataError, minimum=0)
        u, y = _record(structure, data)
        self.structure = structure
        self.metric = metric
        self.predictor = predictor
        self.weight = float(weight)
        self.penalty = float(penalty)
        self.initial = initial
        self.penalty_kind = penalty_kind
        self.u, self.y = u, y
        phi, target = structure.regressors(u, y)
        self.K = target.shape[0]
        self.n_params = structure.n_params
        self._target = target
        scale = np.linalg.norm(phi, axis=0)
        scale[scale == 0] = 1.0
        q, r = linalg.qr(phi / scale, mode="economic")
        qty = q.T @ target
        theta_s = linalg.solve_triangular(r, qty)
        self.theta_ls = theta_s / scale
        resid = target - phi @ self.theta_ls
        self.sse_ls = float(resid @ resid)
        self._r_scaled, self._scale = r, scale
        self._r = r * scale[None, :]  # R (theta - theta*) in original units
        self._r_t = np.ascontiguousarray(self._r.T)
        self._std_y = float(np.std(target))
        self._sse_zero = float(target @ target)
        if predictor == "simulation":
            na = structure.na
            self._phi_u = phi[:, na:] if initial == "measured" else None
            if initial == "zero":
                self._phi_u = structure._phi_padded(u, y)[:, na:]
            self._phi_u_t = np.ascontiguousarray(self._phi_u.T)
            self._phi_u_rows = np.ascontiguousarray(self._phi_u)  # (K, nb): arx_recursion
            # state before the first simulated sample: [y(start-1), ..., y(start-na)]
            s = structure.start
            self._state = y[s - na : s][::-1].copy() if na else np.zeros(0)
            # one input's regressors are delays of one signal: the fit by lag sums applies
            self._shifted = (
                na >= 1 and self._phi_u_rows.shape[1] >= 1
                and kernels.shifted_columns(self._phi_u_rows)
            )  # fmt: skip
        self.cost_ls = float(self(self.theta_ls[None, :])[0])

    # ----------------------------------------------------------------------- metrics
    def _from_sse(self, sse: np.ndarray) -> np.ndarray:
        return metric_from_sse(self.metric, sse, self.K, self.weight, self._std_y)

    # ----------------------------------------------------------------------- evaluation
    def __call__(self, X: Any) -> np.ndarray:
        """Costs of a population.

        Parameters
        ----------
        X : array_like, shape (P, n_params) or (n_params,)

        Returns
        -------
        ndarray, shape (P,)
            Non-finite rows cost ``+inf``.
        """
        X = population(X, self.n_params)
        if np.isfinite(X.sum()):  # the common case: every row finite, no masking needed
            return self._costs(X)
        out = np.full(X.shape[0], np.inf)
        finite = np.isfinite(X).all(axis=1)
        if finite.any():
            out[finite] = self._costs(X[finite])
        return out

    def realised_errors(self, theta: np.ndarray) -> np.ndarray | None:
        """The simulation errors behind :meth:`realised_cost`, ``1/A`` run in a
        well-conditioned realisation.

        Parameters
        ----------
        theta : ndarray, shape (n_params,)

        Returns
        -------
        ndarray, shape (K,), or None
            None for the one-step predictor (no recursion), under ``"measured"`` (a
            direct-form rule by definition) and for an unstable candidate (the penalty
            applies).
        """
        from ..models.polynomial import PolynomialModel

        X = population(theta[None, :], self.n_params)
        na = self.structure.na
        if (self.predictor == "one-step" or self.initial == "measured"
                or not np.isfinite(theta).all() or not is_stable(X[:, :na])[0]):  # fmt: skip
            return None
        model = PolynomialModel.from_arx(self.structure.model(theta))
        ysim = model.simulate(self.u, initial="zero")
        return self.y[self.structure.start :] - ysim[self.structure.start :]

    def _costs(self, X: np.ndarray) -> np.ndarray:
        """Costs of finite rows ``X`` (P, n_params)."""
        stable = is_stable(X[:, : self.structure.na])
        if self.predictor == "one-step":
            d = (X - self.theta_ls) @ self._r_t
            sse = np.einsum("ij,ij->i", d, d)
            sse += self.sse_ls
            cost = self._from_sse(sse)
            if self.penalty > 0 and not stable.all():
                cost[~stable] += self._penalties(X[~stable])
            return cost
        if stable.all():
            return self._from_sse(self._simulated_sse(X))
        cost = np.empty(X.shape[0])
        cost[~stable] = self._penalties(X[~stable]) + self._from_sse(np.array(self._sse_zero))
        if stable.any():
            cost[stable] = self._from_sse(self._simulated_sse(X[stable]))
        return cost

    def _penalties(self, X: np.ndarray) -> np.ndarray | float:
        """Stability penalty of unstable rows ``X``: flat, or graded by the pole radius."""
        if self.penalty_kind == "flat":
            return self.penalty
        rho = pole_radius_batched(X[:, : self.structure.na])
        return self.penalty * np.maximum(rho, 1.0)

    def _simulated_sse(self, X: np.ndarray) -> np.ndarray:
        na = self.structure.na
        if kernels.BACKEND == "c":  # the input part computed in the kernel, no (P, K) GEMM
            a, b = X[:, :na], X[:, na:]
            if self.initial == "measured":
                return arx_recursion(a, b, self._phi_u_rows, self._state, self._target,
                                     want_output=False)[1]  # fmt: skip
            y, _ = arx_recursion(a, b, self._phi_u_rows, np.zeros(na))
            e = self._target - y[:, self.structure.start :]
            return np.einsum("ij,ij->i", e, e)
        forced = X[:, na:] @ self._phi_u_t  # (P, K) one GEMM
        if self.initial == "measured":
            _, sse = ar_recursion(X[:, :na], forced, self._state, self._target, want_output=False)
            return sse
        y, _ = ar_recursion(X[:, :na], forced, np.zeros(na))
        e = self._target - y[:, self.structure.start :]
        return np.einsum("ij,ij->i", e, e)

    # ----------------------------------------------------------------------- numerator
    def fit_numerator(self, a: Any) -> np.ndarray:
        """Complete each denominator with the numerator that minimises this cost.

        Both predictors are linear in ``b`` for a fixed ``A`` (variable projection, Golub &
        Pereyra 1973), so the best ``b`` of a denominator is one least-squares solve:

        * one-step: ``SSE = SSE* + ||R_a da + R_b db||^2`` with the cost's ``R`` (``d`` =
          distance from least squares), minimised over ``b`` by ``db = -G da`` with ``G``
          one small least-squares solve; one GEMM for the population;
        * simulation: ``y_sim = h_A + sum_j b_j (1/A) g_j``, the free response from the
          initial state plus the B-regressors ``g_j`` filtered by ``1/A``; ``n_b + 1``
          recursions and a small least-squares solve per candidate.  An unstable ``A``
          cannot be simulated: its row gets the least-squares ``b`` (its cost is the penalty
          whatever ``b`` is).

        Parameters
        ----------
        a : array_like, shape (P, na) or (na,)
            Denominator coefficients ``a_1 .. a_na``.

        Returns
        -------
        ndarray, shape (P, n_params) or (n_params,)
            ``[a, b]`` with the cost-minimising ``b`` for each row.
        """
        a = np.asarray(a, dtype=float)
        single = a.ndim == 1
        a = np.atleast_2d(a)
        na = self.structure.na
        if a.ndim != 2 or a.shape[1] != na:
            raise DataError(f"denominators must have shape (P, {na}), got {a.shape}")
        theta = np.empty((a.shape[0], self.n_params))
        theta[:, :na] = a
        theta[:, na:] = self.theta_ls[na:]
        finite = np.isfinite(a).all(axis=1)
        if self.n_params > na and finite.any():
            if self.predictor == "one-step":
                da = a[finite] - self.theta_ls[:na]
                theta[finite, na:] -= da @ self._numerator_gain().T
            else:
                rows = np.flatnonzero(finite & is_stable(a))
                if rows.size:
                    theta[rows, na:] = self._simulation_numerators(a[rows])
        return theta[0] if single else theta

    def _numerator_gain(self) -> np.ndarray:
        """``G`` (n_b, na) with ``db = -G da`` minimising the one-step SSE for a given ``da``.

        From the cost's own ``R`` (columns ``[a, b]``, scaled): the excess SSE is
        ``||R_a da + R_b db||^2``, least squares in ``db`` over the ``n x n_b`` matrix ``R_b``.
        """
        if getattr(self, "_gain", None) is None:
            na, r, scale = self.structure.na, self._r_scaled, self._scale
            gain = linalg.lstsq(r[:, na:], r[:, :na])[0]
            # back to original units: theta_s = S theta, so G = S_b^-1 G_s S_a
            self._gain = gain * (1.0 / scale[na:])[:, None] * scale[:na][None, :]
        return self._gain

    def fitted(self, a: Any) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`fit_numerator` and the costs of its rows, in one pass where possible.

        With the simulation predictor, the measured initial state and the compiled kernels,
        the kernel that fits ``b`` also runs the simulation at it (the plain cost's own
        recursion), so the costs are exactly ``self(theta)`` without a second call.

        Parameters
        ----------
        a : array_like, shape (P, na)
            Denominator coefficients ``a_1 .. a_na``.

        Returns
        -------
        theta : ndarray, shape (P, n_params)
            As :meth:`fit_numerator`.
        cost : ndarray, shape (P,)
            ``self(theta)``.
        """
        a = np.atleast_2d(np.asarray(a, dtype=float))
        na = self.structure.na
        nb = self.n_params - na
        if not (
            self.predictor == "simulation" and self.initial == "measured"
            and kernels.BACKEND == "c" and self._shifted and a.ndim == 2
            and a.shape[1] == na and 1 <= na <= 16 and 1 <= nb <= 16
        ):  # fmt: skip
            theta = self.fit_numerator(a)
            return theta, self(theta)
        theta = np.empty((a.shape[0], self.n_params))
        theta[:, :na] = a
        if np.isfinite(a.sum()):
            stable = is_stable(a)
            if stable.all():  # the common case: one call, no indexing
                b, ok, sse = kernels.arx_fit_shifted(a, self._phi_u_rows, self._state,
                                                     self._target, 0, want_sse=True)  # fmt: skip
                if ok.all():
                    theta[:, na:] = b
                    return theta, self._from_sse(sse)
        theta[:, na:] = self.theta_ls[na:]
        cost = np.empty(a.shape[0])
        done = np.zeros(a.shape[0], dtype=bool)
        finite = np.isfinite(a).all(axis=1)
        rows = np.flatnonzero(finite)
        rows = rows[is_stable(a[rows])] if rows.size else rows
        if rows.size:
            b, ok, sse = kernels.arx_fit_shifted(a[rows], self._phi_u_rows, self._state,
                                                 self._target, 0, want_sse=True)  # fmt: skip
            theta[rows, na:] = b
            if not ok.all():
                theta[rows[~ok], na:] = self._simulation_numerators_refined(
                    a[rows[~ok]], 0, self._state
                )
            cost[rows[ok]] = self._from_sse(sse[ok])
            done[rows[ok]] = True
        if not done.all():
            cost[~done] = self(theta[~done])
        return theta, cost

    def _simulation_numerators(self, a: np.ndarray) -> np.ndarray:
        """Least-squares ``b`` (P, n_b) of the simulation cost for stable denominators ``a``.

        By lag sums (:func:`kernels.arx_fit_shifted`) when the regressors are delays of one
        input; rows it flags, and other structures, by the ``nb + 1`` recursions.
        """
        na = self.structure.na
        offset = 0 if self.initial == "measured" else self.structure.start
        state0 = self._state if self.initial == "measured" else np.zeros(na)
        if self._shifted:
            out, ok, _ = kernels.arx_fit_shifted(a, self._phi_u_rows, state0, self._target,
                                                 offset)  # fmt: skip
            if not ok.all():
                out[~ok] = self._simulation_numerators_refined(a[~ok], offset, state0)
            return out
        return self._simulation_numerators_refined(a, offset, state0)

    def _simulation_numerators_refined(
        self, a: np.ndarray, offset: int, state0: np.ndarray
    ) -> np.ndarray:
        """Least-squares ``b`` by ``nb + 1`` recursions, the normal equations and a refinement."""
        na = self.structure.na
        nb = self.n_params - na
        if kernels.BACKEND == "c" and 1 <= na <= 16 and 1 <= nb <= 16:
            # the nb + 1 recursions, the normal equations and their refinement in one pass
            # of the compiled kernel (kernels.arx_fit); rows it cannot solve come back below
            out, ok = kernels.arx_fit(a, self._phi_u_rows, state0, self._target, offset)
            if ok.all():
                return out
            if ok.any():
                out[~ok] = self._simulation_numerators_numpy(a[~ok], offset, state0)
                return out
        return self._simulation_numerators_numpy(a, offset, state0)

    def _simulation_numerators_numpy(
        self, a: np.ndarray, offset: int, state0: np.ndarray
    ) -> np.ndarray:
        """:meth:`_simulation_numerators` by ``ar_recursion`` and ``_least_squares_rows``."""
        na = self.structure.na
        nb = self.n_params - na
        t = self._phi_u_t.shape[1]
        # row 0: free response from the initial state; rows 1..nb: filtered B-regressors
        forced = np.vstack([np.zeros((1, t)), self._phi_u_t])
        states = np.zeros((nb + 1, na))
        states[0] = state0
        out = np.empty((a.shape[0], nb))
        chunk = max(1, _FIT_BLOCK // ((nb + 1) * t))  # bounds the (rows, T) work array
        for lo in range(0, a.shape[0], chunk):
            block = a[lo : lo + chunk]
            p = block.shape[0]
            y, _ = ar_recursion(
                np.repeat(block, nb + 1, axis=0), np.tile(forced, (p, 1)), np.tile(states, (p, 1))
            )
            y = y.reshape(p, nb + 1, t)[:, :, offset:]
            out[lo : lo + p] = _least_squares_rows(y[:, 1:], self._target - y[:, 0])
        return out

    def residuals(self, theta: Any) -> np.ndarray:
        """Error samples of one candidate (for checks and plots).

        Parameters
        ----------
        theta : array_like, shape (n_params,)
            Candidate ``[a_1 .. a_na, b ...]``.

        Returns
        -------
        ndarray, shape (K,)
            ``y(t) - yhat(t)`` for ``t >= start``, in the units of ``y``, with this cost's
            predictor (and, for the simulation predictor, its ``initial``); no stability
            penalty is involved.
        """
        theta = np.asarray(theta, dtype=float).reshape(-1)
        model = self.structure.model(theta)
        if self.predictor == "one-step":
            phi, target = self.structure.regressors(self.u, self.y)
            return target - phi @ theta
        if self.initial == "measured":
            ysim = model.simulate(self.u, y_init=self.y[: self.structure.start])
        else:
            ysim = model.simulate(self.u)
        return self.y[self.structure.start :] - ysim[self.structure.start :]

    def describe(self) -> str:
        """One line naming the metric, penalty, predictor and number of error samples.

        Returns
        -------
        str
            In plain words (:func:`flexid.costs.metrics.describe_cost`), e.g. ``"1000 x the root
            of the sum of squared one-step prediction errors of ARX(na=8, nb=8, nk=1),
            divided by their number (the paper's cost, eq. 5-6), over K = 997 samples; an
            unstable candidate costs the zero prediction's cost plus 1e+09"``.
        """
        s = self.structure
        nb, nk = (list(v) if len(v) > 1 else v[0] for v in (s.nb, s.nk))
        model = f"ARX(na={s.na}, nb={nb}, nk={nk})"
        if self.predictor == "simulation":
            errors = f"simulation errors of {model} ({INITIAL_RULES[self.initial]})"
        else:
            errors = f"one-step prediction errors of {model}"
        return describe_cost(self.metric, errors, self.K, self.weight, self.penalty,
                             self.penalty_kind == "graded")  # fmt: skip

    def __repr__(self) -> str:
        return f"ARXCost({self.structure!r}, {self.describe()})"

