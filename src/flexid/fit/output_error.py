"""The output-error reference: Levenberg-Marquardt on the simulation residuals (MATLAB ``oe``).

On the simulation (output-error) cost least squares is not the optimum: it minimises the
equation error, which weights high frequencies and is biased under output noise.  MATLAB's
``oe``/``pem`` refine an initial estimate by Gauss-Newton/Levenberg-Marquardt on the
simulation residuals ``e(t) = y(t) - y_sim(t)``; :func:`output_error` does the same on an
:class:`~flexid.costs.arx.ARXCost` with ``predictor="simulation"``, from several stable
starts, and returns the best stable result.  It is the fair reference an optimiser's result
on the simulation cost is compared with.  This module holds the problem (residuals,
sensitivities, starts); the run and the result are the one reference's
(:func:`flexid.fit.reference.levenberg_marquardt`, :class:`~flexid.fit.reference.ReferenceResult`).

Notes
-----
* **Residuals.**  Exactly the cost's: ``target - y_sim`` over ``t >= start`` with the cost's
  initial-condition rule, simulated with the same batched machinery
  (:func:`flexid.kernels.ar_recursion`).  Every metric of the cost (paper, RMSE, NRMSE, SSE,
  MSE) is an increasing function of their sum of squares, so the minimiser of the SSE
  minimises the cost whatever its metric.
* **Jacobian.**  Analytic, the classic output-error gradient: with
  ``y_sim = B(q)/A(q) u``, ``d y_sim(t)/d b_j = (1/A) u_j-regressor(t)`` and
  ``d y_sim(t)/d a_i = -(1/A) y(t - i)`` (``y`` being the simulated output, or the measured
  one before the recursion starts under ``initial="measured"``), every sensitivity filtered
  from zero initial state.  The ``n_params`` sensitivities share the denominator ``A`` and
  are run as one population through :func:`~flexid.kernels.ar_recursion`: one Jacobian costs
  the same as ``n_params`` simulations, in a single batched call.
* **Stability.**  Every start is stable (an unstable one has the poles outside the unit
  circle mirrored to ``1/conj(p)`` as ``pem`` does, and ``B`` divided by the product of the
  mirrored radii so the magnitude response is unchanged,
  :func:`flexid.models.stability.mirror_inside`).
  An unstable candidate is rejected (:mod:`flexid.fit.reference`): the Jacobian is only
  evaluated at accepted, hence stable, points.  The result is stable by
  construction, and rejection (rather than reflecting inside the residual function) keeps
  the residual smooth where it is evaluated, so the analytic Jacobian stays exact.  An
  optimum beyond the stability boundary ends at a stable point next to it.
  Limitation: once a pole is within ~1e-9 of the circle every step with an outward
  component is rejected, so LM cannot slide along the boundary and stops there (``xtol``)
  even where a tangential move would still lower the cost.  Projection (mirroring each
  unstable step, as ``pem``) is no better on the robot-arm orders and slower, and a
  reflection-coefficient parametrisation converges badly (it is ill-conditioned for
  lightly damped 8th-order denominators), so several starts are the remedy.
* **Starts.**  Least squares (``cost.theta_ls``, mirrored when unstable), the end of 30
  Steiglitz-McBride iterations from it (it finds the dominant modes that local search from
  least squares misses, as on the simulated manipulator), then ``starts - 1`` stable starts
  from ``numpy.random.default_rng(seed)``, alternately the least-squares poles perturbed
  (damping ``1 - |p|`` scaled log-normally, angles jittered; conjugate pairs kept) and
  uniformly drawn stable poles; for each, ``B`` is the exact optimum given ``A`` (the
  simulated output is linear in ``B``, one small least-squares solve).  ``x0`` is one more
  start when given.  The run of least SSE is returned (every metric of the cost increases
  with the SSE); the starts themselves are candidates too, so
  ``cost(result.theta) <= cost(theta_ls)`` always.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from .._validate import integer, positive_int, real
from ..costs.arx import ARXCost
from ..errors import ConfigError, DataError
from ..kernels import ar_recursion
from ..models.stability import (
    is_stable,
    mirror_inside,
    perturbed_poles,
    pole_radius_batched,
    pull_inside,
    random_poles,
    within_radius,
)
from ..models.vocabulary import REFERENCE_STARTS
from .reference import (
    CAP_TOLERANCE,
    PULLED_TO,
    ReferenceResult,
    ReferenceRun,
    along_the_cap,
    cap_reason,
    levenberg_marquardt,
    restarts_on_the_cap,
)

__all__ = ["OEResult", "OERun", "output_error", "simulation_jacobian", "simulation_residuals"]

# Steiglitz-McBride iterations of that start (its iterates settle within ~20 on the plants
# and records of the benchmarks; each is one filtering and one least-squares fit).
_SM_ITERATIONS = 30


#: The result of :func:`output_error` (the one reference result type; its keys there).
OEResult = ReferenceResult
#: One run of :func:`output_error`.
OERun = ReferenceRun


# ==================================================================================== problem
class _Problem:
    """Batched simulation, residuals and sensitivities of a simulation-predictor cost.

    The recursion runs over ``T`` samples (``K`` from ``t = start`` under
    ``initial="measured"``, all ``N`` from ``t = 0`` under ``"zero"``); the error is over its
    last ``K`` samples (``offset`` = ``0`` or ``start``).
    """

    def __init__(self, cost: ARXCost) -> None:
        s = cost.structure
        self.cost = cost
        self.na = s.na
        self.n = cost.n_params
        self.target = cost._target  # (K,)
        self.phi_u_t = cost._phi_u_t  # (sum nb, T): B-regressors, one row per b coefficient
        if cost.initial == "measured":
            self.offset = 0
            self.state = np.asarray(cost._state, dtype=float)  # [y(s-1) .. y(s-na)]
        else:
            self.offset = s.start
            self.state = np.zeros(self.na)
        # outputs before the recursion's first sample, oldest first: y(-na) .. y(-1)
        self.pre = self.state[::-1].copy()
        self.T = self.phi_u_t.shape[1]
        self.nfev = 0
        self.njev = 0

    def simulate(self, X: np.ndarray) -> np.ndarray:
        """Simulated outputs (P, T) of stable rows ``X`` (P, n)."""
        forced = X[:, self.na :] @ self.phi_u_t
        y, _ = ar_recursion(X[:, : self.na], forced, self.state)
        return y

    def residuals(self, X: np.ndarray) -> np.ndarray:
        """``target - y_sim`` (P, K) of stable rows ``X`` (P, n)."""
        return self.target - self.simulate(X)[:, self.offset :]

    def sensitivities(self, theta: np.ndarray, ysim: np.ndarray, rows: slice) -> np.ndarray:
        """``d y_sim / d theta[rows]`` (len(rows), T) at stable ``theta`` with outputs ``ysim``.

        ``y(t) = f(t) - sum_i a_i y(t-i)`` differentiated: ``s(t) = g(t) - sum_i a_i s(t-i)``
        with ``g = B-regressor`` for a ``b`` and ``g(t) = -y(t-i)`` for ``a_i``; outputs
        before the recursion starts are data (or zero), so every ``s`` starts from rest.
        """
        na = self.na
        full = np.concatenate([self.pre, ysim])  # y(-na) .. y(T-1)
        forced = np.empty((self.n, self.T))
        for i in range(1, na + 1):
            forced[i - 1] = -full[na - i : na - i + self.T]
        forced[na:] = self.phi_u_t
        forced = forced[rows]
        a = np.broadcast_to(theta[:na], (forced.shape[0], na))
        s, _ = ar_recursion(a, forced, np.zeros(na))
        return s

    def jacobian(self, theta: np.ndarray, ysim: np.ndarray) -> np.ndarray:
        """Jacobian (K, n) of the residuals ``target - y_sim`` at stable ``theta``."""
        s = self.sensitivities(theta, ysim, slice(None))
        return -s[:, self.offset :].T

    def refit_b(self, a: np.ndarray) -> np.ndarray:
        """``theta`` with denominator ``a`` (na,) and the SSE-optimal ``B`` for it.

        ``y_sim = free response of A from the initial state + sum_j b_j (1/A) B-regressor_j``
        is linear in ``b``: one least-squares solve on the filtered regressors, counted as
        one Jacobian evaluation (it is the ``b`` part of one).
        """
        self.njev += 1
        return self.cost.fit_numerator(a)


def _simulation_problem(cost: Any) -> _Problem:
    if not isinstance(cost, ARXCost):
        raise ConfigError(f"the output-error reference needs an ARXCost, got {type(cost).__name__}")
    if cost.predictor != "simulation":
        raise ConfigError(
            f"the output-error reference needs a simulation-predictor cost, got "
            f"predictor={cost.predictor!r} (least squares is already the one-step optimum)"
        )
    return _Problem(cost)


def _as_theta(theta: Any, n: int, what: str) -> np.ndarray:
    theta = np.array(theta, dtype=float).reshape(-1) if np.ndim(theta) <= 1 else None
    if theta is None or theta.shape != (n,):
        raise DataError(f"{what} must have shape ({n},)")
    if not np.isfinite(theta).all():
        raise DataError(f"{what} has non-finite values")
    return theta


def simulation_residuals(cost: ARXCost, X: Any) -> np.ndarray:
    """Simulation residuals of a population, batched.

    Parameters
    ----------
    cost : ARXCost
        With ``predictor="simulation"``.
    X : array_like, shape (P, n_params) or (n_params,)
        Candidates; they must be stable (an unstable recursion overflows).

    Returns
    -------
    ndarray, shape (P, K)
        ``y(t) - y_sim(t)`` over the cost's error samples (output units); the row sums of
        squares are the SSE behind ``cost(X)``.

    Raises
    ------
    ConfigError
        For a one-step cost.
    DataError
        For a wrongly shaped, non-finite or unstable population.
    """
    prob = _simulation_problem(cost)
    X = np.asarray(X, dtype=float)
    X = X[None, :] if X.ndim == 1 else X
    if X.ndim != 2 or X.shape[1] != prob.n or not np.isfinite(X).all():
        raise DataError(f"the population must be finite with shape (P, {prob.n})")
    if not is_stable(X[:, : prob.na]).all():
        raise DataError("simulation residuals need stable candidates (|p| < 1)")
    return prob.residuals(X)


def simulation_jacobian(cost: ARXCost, theta: Any) -> tuple[np.ndarray, np.ndarray]:
    """Simulation residuals and their analytic Jacobian at one stable candidate.

    Parameters
    ----------
    cost : ARXCost
        With ``predictor="simulation"``.
    theta : array_like, shape (n_params,)
        A stable candidate.

    Returns
    -------
    r : ndarray, shape (K,)
        ``y - y_sim`` (output units).
    J : ndarray, shape (K, n_params)
        ``d r / d theta`` (output units per parameter unit), from the sensitivity filters
        ``-(1/A) y(t-i)`` and ``(1/A) u-regressors`` (see the module docstring).

    Raises
    ------
    ConfigError
        For a one-step cost.
    DataError
        For a wrongly shaped, non-finite or unstable ``theta``.
    """
    prob = _simulation_problem(cost)
    theta = _as_theta(theta, prob.n, "theta")
    if not is_stable(theta[: prob.na])[0]:
        raise DataError("the Jacobian needs a stable candidate (|p| < 1)")
    ysim = prob.simulate(theta[None, :])[0]
    return prob.target - ysim[prob.offset :], prob.jacobian(theta, ysim)


# ==================================================================================== starts
def _steiglitz_mcbride(cost: ARXCost, iterations: int = _SM_ITERATIONS) -> np.ndarray | None:
    """A start from the Steiglitz-McBride iteration (stable; ``None`` if it breaks down).

    Filter ``u`` and ``y`` by the current ``1/A`` and refit the ARX model by least squares on
    the filtered record, from least squares (Steiglitz & McBride, IEEE TAC 10(4), 1965; an
    output-error initialiser in Ljung, System Identification, 2nd ed., sec. 10.4).  Its fixed
    point is not the output-error optimum under coloured errors, but it lands in the basin of
    the dominant modes, which local search from least squares often misses (equation error
    weights high frequencies).
    """
    from scipy import signal

    na = cost.structure.na
    theta = mirror_inside(np.asarray(cost.theta_ls, dtype=float), na)
    for _ in range(iterations):
        den = np.concatenate([[1.0], theta[:na]])
        try:
            fitted = cost.structure.least_squares(
                signal.lfilter([1.0], den, cost.u, axis=0), signal.lfilter([1.0], den, cost.y)
            )
        except DataError:  # filtered regressors rank deficient
            return None
        new = mirror_inside(np.asarray(fitted.theta, dtype=float), na)
        if not np.isfinite(new).all():
            return None
        theta = new
    return theta


# ==================================================================================== solver
def _run_lm(
    prob: _Problem, theta0: np.ndarray, kind: str, max_nfev: int | None, tol: float,
    r_max: float,
) -> ReferenceRun:
    """Levenberg-Marquardt from a stable start within the cap ``r_max``, counted on ``prob``."""
    na = prob.na
    cache: dict[str, Any] = {"x": None, "y": None}

    def residuals(x: np.ndarray) -> np.ndarray:
        y = prob.simulate(x[None, :])[0]
        cache["x"], cache["y"] = x.copy(), y  # the Jacobian at x reuses this simulation
        return prob.target - y[prob.offset :]

    def jacobian(x: np.ndarray) -> np.ndarray:
        if cache["x"] is None or not np.array_equal(cache["x"], x):
            prob.nfev += 1
            cache["x"], cache["y"] = x.copy(), prob.simulate(x[None, :])[0]
        return prob.jacobian(x, cache["y"])

    run = levenberg_marquardt(
        residuals, jacobian, theta0, kind, admissible=lambda x: within_radius(x[:na], r_max),
        energy=float(prob.target @ prob.target), max_nfev=max_nfev, tol=tol,
    )
    prob.nfev += run.nfev
    prob.njev += run.njev
    return run


def output_error(
    cost: ARXCost,
    *,
    starts: int = REFERENCE_STARTS,
    seed: int | np.random.Generator | None = 0,
    max_nfev: int | None = None,
    x0: Any = None,
    tol: float = 1e-10,
    r_max: float = 1.0,
) -> OEResult:
    """The output-error reference: best stable Levenberg-Marquardt fit of the simulation cost.

    What a user of MATLAB's ``oe``/``pem`` expects: Levenberg-Marquardt (MINPACK, via
    ``scipy.optimize.least_squares(method="lm")``) on the simulation residuals
    ``y - y_sim`` with the analytic output-error Jacobian, from least squares and other
    stable starts; unstable steps are rejected (see the module docstring).

    Parameters
    ----------
    cost : ARXCost
        With ``predictor="simulation"`` (any metric, any initial-condition rule).
    starts : int
        Number of starts (>= 1): least squares plus ``starts - 1`` random stable ones (and
        the Steiglitz-McBride start besides, when ``na > 0``).
    seed : int, Generator or None
        Seed of ``numpy.random.default_rng`` for the random starts.
    max_nfev : int, optional
        Residual-evaluation budget of each run (default MINPACK's ``100 * n_params``).
    x0 : array_like, shape (n_params,), optional
        One more start (mirrored to stable when it is not).
    tol : float
        ``ftol``, ``xtol`` and ``gtol`` of each run (relative).
    r_max : float
        Largest pole radius of an accepted step, in (0, 1]: ``1`` keeps the model stable;
        below 1 the reference lives in the same set as a search of the ``"poles"`` space
        with that cap (starts with larger poles are pulled in to it, their ``B`` refitted).
        A fit whose best model has a pole a hair inside the circle is rarely the model a
        user wants.

    Returns
    -------
    ReferenceResult
        ``x`` (also ``theta``) stable with ``cost(x) <= cost(theta_ls)``; ``fun`` its SSE,
        ``status``, ``std`` (from the simulation residuals' Jacobian) and the other keys of
        :class:`~flexid.fit.reference.ReferenceResult`, and:

        ``cost``, ``cost_ls`` : float
            The cost's value at ``x`` and at the least-squares estimate (``penalty + ...``
            when unstable).
        ``stable``, ``ls_stable`` : bool
            Every pole of ``x`` strictly inside the circle (True by construction); whether
            the least-squares estimate itself was.
        ``on_cap`` : bool
            A pole within 1e-6 of ``r_max`` (``local_minimum`` is then False).
        ``max_radius`` : float
            The largest pole radius of ``x``.
        ``cap_reason`` : str
            Why ``x`` ends on the cap, ``""`` off it (a best run that ends on the cap is
            restarted along it and pulled in, :func:`flexid.fit.reference.restarts_on_the_cap`).

    Raises
    ------
    ConfigError
        For a cost that is not a simulation-predictor ARXCost, ``starts < 1``, a bad
        ``max_nfev`` or ``tol``.
    DataError
        For an ``x0`` of the wrong shape or with non-finite values.
    """
    t_begin = time.perf_counter()
    prob = _simulation_problem(cost)
    starts = positive_int(starts, "starts", error=ConfigError)
    max_nfev = integer(max_nfev, "max_nfev", error=ConfigError, minimum=1, none_ok=True)
    tol = real(tol, "tol", error=ConfigError, minimum=0, maximum=1, low_open=True, high_open=True)
    r_max = real(r_max, "r_max", error=ConfigError, minimum=0, maximum=1, low_open=True)
    na = prob.na
    rng = np.random.default_rng(seed)

    theta_ls = np.asarray(cost.theta_ls, dtype=float)
    ls_stable = bool(is_stable(theta_ls[:na])[0])
    start_list: list[tuple[str, np.ndarray]] = [("least-squares", mirror_inside(theta_ls, na))]
    a_ls = start_list[0][1][:na]
    if na:
        sm = _steiglitz_mcbride(cost)
        if sm is not None:
            start_list.append(("steiglitz-mcbride", sm))
    for i in range(1, int(starts)):
        if na == 0:  # no poles to vary: B given A is the least-squares start again
            break
        a = perturbed_poles(a_ls, rng) if i % 2 == 1 else random_poles(na, rng)
        start_list.append(("perturbed" if i % 2 == 1 else "random", prob.refit_b(a)))
    if x0 is not None:
        start_list.append(("x0", mirror_inside(_as_theta(x0, prob.n, "x0"), na)))
    for i, (kind, th) in enumerate(start_list):
        if not within_radius(th[:na], r_max):
            start_list[i] = (kind, prob.refit_b(pull_inside(th[:na], r_max)))

    runs = [_run_lm(prob, th, kind, max_nfev, tol, r_max) for kind, th in start_list]
    best = int(np.argmin([r.fun for r in runs]))
    win = runs[best]
    message = f"best of {len(runs)} start(s): {win.kind} ({win.message})"
    best, note, cap_reason = _along_the_cap(prob, runs, best, max_nfev, tol, r_max)
    theta = runs[best].x.copy()
    message += note
    if not ls_stable:
        message += "; least squares was unstable, its start was mirrored to stable"
    # the end's diagnostics are not part of the search: not counted in nfev, njev
    ysim = prob.simulate(theta[None, :])[0]
    e = prob.target - ysim[prob.offset :]
    jac = prob.jacobian(theta, ysim)
    max_radius = float(pole_radius_batched(theta[None, :na])[0]) if na else 0.0
    on_cap = bool(na) and max_radius >= r_max - CAP_TOLERANCE
    cap_reason = cap_reason if on_cap else ""
    if cap_reason:
        message += f"; ends on the cap: {cap_reason}"
    return ReferenceResult.at(
        runs, best, e, jac, on_cap=on_cap, nfev=prob.nfev, njev=prob.njev, message=message,
        t_begin=t_begin, cost=float(cost(theta)[0]), cost_ls=float(cost.cost_ls),
        stable=bool(is_stable(theta[:na])[0]), ls_stable=ls_stable, max_radius=max_radius,
        cap_reason=cap_reason,
    )


def _along_the_cap(
    prob: _Problem, runs: list[ReferenceRun], best: int, max_nfev: int | None, tol: float,
    r_max: float,
) -> tuple[int, str, str]:
    """Restarts of a best run that ends on the cap, as :func:`flexid.fit.prediction_error.pem`'s.

    Along the cap and pulled in (:func:`flexid.fit.reference.restarts_on_the_cap`), and below
    the unit circle one more LM free to cross the cap, its end kept when it is back within
    the cap and lower.  Returns the best run's index, the note for the message and why the
    end is on the cap (``""`` when it was not).
    """

    na = prob.na

    def on_cap(x: np.ndarray) -> bool:
        return float(pole_radius_batched(x[None, :na])[0]) >= r_max - CAP_TOLERANCE

    if not na or not on_cap(runs[best].x):
        return best, "", ""

    def residuals(x: np.ndarray) -> np.ndarray:
        return prob.target - prob.simulate(x[None, :])[0][prob.offset :]

    def jacobian(x: np.ndarray) -> np.ndarray:
        prob.nfev += 1  # the simulation the Jacobian's formulas need
        return prob.jacobian(x, prob.simulate(x[None, :])[0])

    def along(theta: np.ndarray) -> ReferenceRun | None:
        return along_the_cap(
            residuals, jacobian, theta, [slice(0, na)], r_max, within=within_radius,
            energy=float(prob.target @ prob.target), max_nfev=max_nfev, tol=tol, counter=prob,
        )

    def pulled(theta: np.ndarray) -> list[ReferenceRun]:
        out = []
        for radius in PULLED_TO:
            th = prob.refit_b(pull_inside(theta[:na], radius))
            if within_radius(th[:na], r_max):
                out.append(_run_lm(prob, th, f"pulled in to {radius:g}", max_nfev, tol, r_max))
        return out

    won, new, note = restarts_on_the_cap(
        runs[best], on_cap=on_cap, along=along, pulled=pulled,
        admissible=lambda x: within_radius(x[:na], r_max), cap=r_max,
    )
    runs += new
    best = next((i for i, r in enumerate(runs) if r is won), best)
    if r_max < 1.0 and on_cap(runs[best].x):
        # the cap may also block the way to a lower point inside it
        free = _run_lm(prob, runs[best].x, "across the cap", max_nfev, tol, 1.0)
        runs.append(free)
        if free.fun < runs[best].fun and within_radius(free.x[:na], r_max):
            note += f"; across it to SSE {free.fun:.6g}"
            best = len(runs) - 1
    return best, note, cap_reason(r_max, "pole")
