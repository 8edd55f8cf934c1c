"""The output-error reference: Levenberg-Marquardt on the simulation residuals (MATLAB ``oe``).

On the simulation (output-error) cost least squares is not the optimum: it minimises the
equation error, which weights high frequencies and is biased under output noise.  MATLAB's
``oe``/``pem`` refine an initial estimate by Gauss-Newton/Levenberg-Marquardt on the
simulation residuals ``e(t) = y(t) - y_sim(t)``; :func:`output_error` does the same on an
:class:`~flexid.costs.arx.ARXCost` with ``predictor="simulation"``, from several stable
starts, and returns the best stable result.  It is the fair reference an optimiser's result
on the simulation cost is compared with.

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
  mirrored radii so the magnitude response is unchanged).  The residual function returns a
  constant vector whose sum of squares is far above the start's for an unstable candidate,
  so MINPACK's Levenberg-Marquardt rejects that step and increases its damping; the Jacobian
  is only evaluated at accepted, hence stable, points.  The result is stable by
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
  start when given.  The best result by ``cost(...)`` is returned; the starts themselves are
  candidates too, so ``cost(result.theta) <= cost(theta_ls)`` always.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from ._validate import integer, positive_int, real
from .config import REFERENCE_STARTS
from .costs.arx import ARXCost
from .errors import ConfigError, DataError
from .kernels import ar_recursion
from .stability import is_stable, pole_radius_batched

__all__ = ["OEResult", "OERun", "output_error", "simulation_jacobian", "simulation_residuals"]

# Sum of squares of the residual vector returned for an unstable candidate: this factor
# times (the start's SSE + the zero-prediction SSE), far above anything LM can reach from a
# stable start, so the step is always rejected.
_REJECT_FACTOR = 1e6
# Largest pole radius of a mirrored start (a pole exactly on the circle is its own mirror).
_MAX_RADIUS = 1.0 - 1e-6
# Steiglitz-McBride iterations of that start (its iterates settle within ~20 on the plants
# and records of the benchmarks; each is one filtering and one least-squares fit).
_SM_ITERATIONS = 30


# ==================================================================================== results
@dataclass
class OERun:
    """One Levenberg-Marquardt run of :func:`output_error`.

    Attributes
    ----------
    kind : str
        ``"least-squares"``, ``"steiglitz-mcbride"``, ``"perturbed"`` (least-squares poles
        perturbed), ``"random"`` (uniformly drawn stable poles) or ``"x0"``.
    theta0 : ndarray, shape (n_params,)
        The (stable) start.
    theta : ndarray, shape (n_params,)
        Where the run ended (stable).
    cost0, cost : float
        The cost's value at ``theta0`` and at ``theta``.
    nfev, njev : int
        Residual and Jacobian evaluations of this run.
    message : str
        The optimiser's stopping message.
    """

    kind: str
    theta0: np.ndarray
    theta: np.ndarray
    cost0: float
    cost: float
    nfev: int
    njev: int
    message: str


@dataclass
class OEResult:
    """Outcome of :func:`output_error`.

    Attributes
    ----------
    theta : ndarray, shape (n_params,)
        Best stable estimate ``[a_1 .. a_na, b ...]``.
    cost : float
        The cost's value at ``theta`` (same metric and units as ``cost(...)``).
    cost_ls : float
        The cost's value at the least-squares estimate (``penalty + ...`` when unstable).
    starts : list of float
        Final cost of each run, in the order of ``runs``.
    nfev : int
        Residual evaluations (one simulation each) over all runs.
    njev : int
        Analytic Jacobian evaluations over all runs (including the ``B`` refits of the
        random starts).
    nfev_equivalent : int
        ``nfev + njev * n_params``: a Jacobian is ``n_params`` sensitivity simulations, the
        work of ``n_params`` forward differences (run as one batched call).
    wall_time : float
        Seconds, start to finish.
    stable : bool
        Every pole of ``theta`` strictly inside the unit circle (True by construction).
    message : str
        Which start won and why its run stopped.
    best_start : int
        Index into ``runs`` (and ``starts``) of the winner.
    ls_stable : bool
        Whether the least-squares estimate itself was stable.
    runs : list of OERun
        Details of every run.
    """

    theta: np.ndarray
    cost: float
    cost_ls: float
    starts: list[float]
    nfev: int
    njev: int
    nfev_equivalent: int
    wall_time: float
    stable: bool
    message: str
    best_start: int
    ls_stable: bool
    runs: list[OERun] = field(default_factory=list, repr=False)


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
def _poles_to_a(poles: np.ndarray) -> np.ndarray:
    return np.real(np.poly(poles))[1:] if poles.size else np.zeros(0)


def _mirror(theta: np.ndarray, na: int) -> np.ndarray:
    """``theta`` with poles outside the circle mirrored to ``1/conj(p)`` (as ``pem`` does).

    ``B`` is divided by the product of the mirrored radii: ``|e^jw - 1/conj(p)| =
    |e^jw - p| / |p|``, so the magnitude response is unchanged (only the phase moves).
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


def _admissible(a: np.ndarray, r_max: float) -> bool:
    """Whether the denominator ``a`` (na,) is stable with every pole radius <= ``r_max``."""
    if not is_stable(a)[0]:
        return False
    return r_max >= 1.0 or a.size == 0 or float(pole_radius_batched(a[None, :])[0]) <= r_max


def _capped(a: np.ndarray, r_max: float) -> np.ndarray:
    """``a`` with every pole of radius above ``r_max`` pulled in radially to ``r_max``."""
    poles = np.roots(np.concatenate([[1.0], a]))
    r = np.abs(poles)
    shrink = r_max
    while True:
        out = np.where(r > shrink, poles * (shrink / np.maximum(r, 1e-300)), poles)
        new = _poles_to_a(out)
        if _admissible(new, r_max):
            return new
        shrink *= 1.0 - 1e-9  # np.poly rounding put a pole back just above the cap


def _perturbed_a(a_ls: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Least-squares poles (stable) with damping and angle perturbed; conjugacy kept."""
    real, upper = _pairs(np.roots(np.concatenate([[1.0], a_ls])))
    # damping 1 - |p| scaled log-normally keeps the pole inside the circle whatever the draw
    real_r = 1.0 - (1.0 - np.abs(real)) * np.exp(rng.normal(0.0, 0.5, real.size))
    real_new = np.sign(real + (real == 0)) * np.minimum(real_r, _MAX_RADIUS)
    rad = 1.0 - (1.0 - np.abs(upper)) * np.exp(rng.normal(0.0, 0.5, upper.size))
    ang = np.clip(np.angle(upper) * np.exp(rng.normal(0.0, 0.1, upper.size)), 1e-3, np.pi - 1e-3)
    up_new = np.minimum(rad, _MAX_RADIUS) * np.exp(1j * ang)
    return _poles_to_a(np.concatenate([real_new, up_new, np.conj(up_new)]))


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
    theta = _mirror(np.asarray(cost.theta_ls, dtype=float), na)
    for _ in range(iterations):
        den = np.concatenate([[1.0], theta[:na]])
        try:
            fitted = cost.structure.least_squares(
                signal.lfilter([1.0], den, cost.u, axis=0), signal.lfilter([1.0], den, cost.y)
            )
        except DataError:  # filtered regressors rank deficient
            return None
        new = _mirror(np.asarray(fitted.theta, dtype=float), na)
        if not np.isfinite(new).all():
            return None
        theta = new
    return theta


def _random_a(na: int, rng: np.random.Generator) -> np.ndarray:
    """Stable poles drawn uniformly over the disc of radius 0.95 (pairs) plus one real."""
    n_pairs = na // 2
    rad = 0.95 * np.sqrt(rng.uniform(0.0, 1.0, n_pairs))
    up = rad * np.exp(1j * rng.uniform(0.0, np.pi, n_pairs))
    real = rng.uniform(-0.95, 0.95, na % 2)
    return _poles_to_a(np.concatenate([real, up, np.conj(up)]))


# ==================================================================================== solver
def _run_lm(
    prob: _Problem,
    theta0: np.ndarray,
    kind: str,
    max_nfev: int | None,
    tol: float,
    r_max: float,
) -> OERun:
    """Levenberg-Marquardt (MINPACK) from an admissible start, rejecting other steps."""
    na = prob.na
    nfev0, njev0 = prob.nfev, prob.njev
    cache: dict[str, Any] = {"x": None, "y": None}
    r0 = prob.residuals(theta0[None, :])[0]
    prob.nfev += 1
    sse0 = float(r0 @ r0)
    bad_sse = _REJECT_FACTOR * (sse0 + float(prob.target @ prob.target)) + 1.0
    bad = np.full(prob.target.size, np.sqrt(bad_sse / prob.target.size))

    def fun(x: np.ndarray) -> np.ndarray:
        prob.nfev += 1
        if not (np.isfinite(x).all() and _admissible(x[:na], r_max)):
            return bad
        y = prob.simulate(x[None, :])[0]
        cache["x"], cache["y"] = x.copy(), y  # the Jacobian at x reuses this simulation
        return prob.target - y[prob.offset :]

    def jac(x: np.ndarray) -> np.ndarray:
        prob.njev += 1
        if cache["x"] is None or not np.array_equal(cache["x"], x):
            if not is_stable(x[:na])[0]:  # never happens: LM only differentiates accepted x
                return np.zeros((prob.target.size, prob.n))
            prob.nfev += 1
            cache["x"], cache["y"] = x.copy(), prob.simulate(x[None, :])[0]
        return prob.jacobian(x, cache["y"])

    sol = least_squares(
        fun,
        theta0,
        jac=jac,
        method="lm",
        x_scale="jac",
        ftol=tol,
        xtol=tol,
        gtol=tol,
        max_nfev=max_nfev,
    )
    theta = np.asarray(sol.x, dtype=float)
    # one row per call, as a user calls cost(theta): the compiled kernel's rounding may
    # depend on a row's position in a batch, and the guarantees are about cost(theta)
    cost0, cost1 = float(prob.cost(theta0)[0]), float(prob.cost(theta)[0])
    if not (_admissible(theta[:na], r_max) and cost1 <= cost0):
        # defensive: MINPACK returns its best accepted (stable) point, so this only guards
        # against rounding differences between its SSE and the cost's
        theta, cost1 = theta0.copy(), cost0
    return OERun(
        kind=kind,
        theta0=theta0,
        theta=theta,
        cost0=cost0,
        cost=cost1,
        nfev=prob.nfev - nfev0,
        njev=prob.njev - njev0,
        message=str(sol.message),
    )


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
    OEResult
        ``theta`` stable with ``cost(theta) <= cost(theta_ls)``.

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
    start_list: list[tuple[str, np.ndarray]] = [("least-squares", _mirror(theta_ls, na))]
    a_ls = start_list[0][1][:na]
    if na:
        sm = _steiglitz_mcbride(cost)
        if sm is not None:
            start_list.append(("steiglitz-mcbride", sm))
    for i in range(1, int(starts)):
        if na == 0:  # no poles to vary: B given A is the least-squares start again
            break
        a = _perturbed_a(a_ls, rng) if i % 2 == 1 else _random_a(na, rng)
        start_list.append(("perturbed" if i % 2 == 1 else "random", prob.refit_b(a)))
    if x0 is not None:
        start_list.append(("x0", _mirror(_as_theta(x0, prob.n, "x0"), na)))
    for i, (kind, th) in enumerate(start_list):
        if not _admissible(th[:na], r_max):
            start_list[i] = (kind, prob.refit_b(_capped(th[:na], r_max)))

    runs = [_run_lm(prob, th, kind, max_nfev, tol, r_max) for kind, th in start_list]
    best = int(np.argmin([r.cost for r in runs]))
    win = runs[best]
    theta = win.theta.copy()
    final_cost = float(cost(theta)[0])
    message = f"best of {len(runs)} start(s): {win.kind} ({win.message})"
    if not ls_stable:
        message += "; least squares was unstable, its start was mirrored to stable"
    return OEResult(
        theta=theta,
        cost=final_cost,
        cost_ls=float(cost.cost_ls),
        starts=[r.cost for r in runs],
        nfev=prob.nfev,
        njev=prob.njev,
        nfev_equivalent=prob.nfev + prob.njev * prob.n,
        wall_time=time.perf_counter() - t_begin,
        stable=bool(is_stable(theta[:na])[0]),
        message=message,
        best_start=best,
        ls_stable=ls_stable,
        runs=runs,
    )
