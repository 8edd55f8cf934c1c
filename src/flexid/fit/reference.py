"""The gradient reference: one Levenberg-Marquardt run, its record and one result type.

Every gradient reference of flexid (:func:`flexid.fit.prediction_error.pem` and its MATLAB-named
forms, :func:`flexid.fit.output_error.output_error` for a simulation-predictor ARX cost,
:func:`flexid.fit.greybox_fit.greyest` for a grey-box model) runs :func:`levenberg_marquardt`
from several starts and returns a :class:`ReferenceResult`, shaped like the
:class:`scipy.optimize.OptimizeResult` flexid's optimisers return: ``x``, ``fun``,
``status``, ``success``, ``message``, ``nfev``, ``njev``, plus the standard errors ``std``,
the first-order ``optimality`` it reached and every run in ``runs``.

Notes
-----
**Rejected steps.**  A problem may admit only part of the parameter space (a stable model, a
minimum-phase noise model, every root within a cap).  The residual function returns, for a
point outside it, a constant vector whose sum of squares is ``1e6`` times (the start's SSE
plus the target's energy): MINPACK's Levenberg-Marquardt rejects that step and raises its
damping, and the Jacobian is only evaluated at accepted, hence admissible, points.

**Budget.**  ``chunks > 1`` continues a run its evaluation budget stopped while its SSE still
falls (by more than ``1e-9`` relative), a budget at a time; a run still above ``100`` times
``target`` (the best SSE of the other runs) after ``10 n`` evaluations is abandoned at its
best point, and with ``crawl`` also one whose fall over its last ``10 n`` evaluations,
repeated over the rest of its budget, would not bring it to ``1.1`` times ``target``.  The
reasons and the measurements behind these numbers are in :mod:`flexid.fit.prediction_error`.

**On the cap.**  Rejecting steps keeps every point admissible but, at a point with a root on
the cap, loses the directions along it: a Gauss-Newton step that would slide the root along
the cap has an outward part (the cap is curved in the coefficients) and is rejected, so LM
stops there by ``xtol`` on a point that is no minimum.  :func:`along_the_cap` restarts it
with the roots on the cap held at their radius (free angles, free cofactor): on the DaISy
robot arm, OE(8,8,1) on the first two thirds, the measured-output rule, it takes the SSE
from 0.015956 to 0.015555 (2.5 %) in a dozen evaluations, and LM restarts from its end with
the root pulled in to radii 0.995 to 0.9999 all climb back to the circle at a higher SSE.
The cap may also hide a lower basin: :func:`restarts_on_the_cap` alternates that
continuation with LM restarts from the point with its roots pulled in.  On the same record,
ARX(8,8,1) simulated (:func:`flexid.fit.output_error.output_error`, cap 0.9999) ends on the cap
at 0.027349; along it 0.026999, pulled in 0.015922, along it again 0.015588.

**Optimality.**  ``||J' e|| / (||J||_F ||e||)``: the cosine between the residual and the
span of the Jacobian's columns, scale-free; at a MINPACK stop with ``tol = 1e-10`` on the
test systems it is below 2e-8, so :data:`OPTIMALITY_THRESHOLD` (1e-6) separates minima from
points a budget or a constraint stopped, by orders of magnitude.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from scipy import linalg
from scipy.optimize import OptimizeResult, least_squares

from ..errors import ConfigError

__all__ = [
    "OPTIMALITY_THRESHOLD",
    "PULLED_TO",
    "STATUS",
    "ReferenceResult",
    "ReferenceRun",
    "StartOrReference",
    "along_the_cap",
    "cap_reason",
    "levenberg_marquardt",
    "lower_of",
    "optimality",
    "restarts_on_the_cap",
    "standard_errors",
    "status_of",
]

#: Threshold of :attr:`ReferenceResult.optimality` below which a polynomial reference's end
#: is a first-order local minimum (module notes).
OPTIMALITY_THRESHOLD = 1e-6

#: What :attr:`ReferenceResult.status` means, by value.
STATUS = {
    0: "first-order local minimum",
    1: "stopped short of the first-order test",
    2: "ended on the pole-radius cap",
    3: "the evaluation budget ran out",
}

#: A root counts as on the pole-radius cap within this radius distance.
CAP_TOLERANCE = 1e-6

# Sum of squares of the residual vector returned for an inadmissible point: this factor
# times (the start's SSE + the target's energy), far above anything LM reaches from an
# admissible start, so the step is always rejected.
REJECT_FACTOR = 1e6
# Continuation and abandonment of runs (module notes; measured in flexid.fit.prediction_error).
CHUNKS = 10
PROMISING = 1.1
STILL_FALLING = 1e-9
HOPELESS = 100.0
ABANDON_AFTER = 10


class _Abandoned(Exception):
    """Raised inside the residual function to stop a run that cannot win."""


@dataclass
class ReferenceRun:
    """One Levenberg-Marquardt run from one start.

    Attributes
    ----------
    kind : str
        Where it started: ``"least-squares"``, ``"steiglitz-mcbride"``,
        ``"hannan-rissanen"``, ``"output-error"``, ``"perturbed"``, ``"random"``, ``"x0"``,
        ``"nominal"``, ``"given"``, ``"random k"``; ``"<kind>, continued"`` (a run its budget
        stopped while it still descended), ``"cap r_max=<value>"`` or ``"polish"`` (a
        continuation of the best point).
    x0 : ndarray, shape (n_params,)
        The (admissible) start, in the reference's parameters.
    x : ndarray, shape (n_params,)
        Where the run ended (admissible).
    fun0, fun : float
        Sum of squared residuals at ``x0`` and at ``x`` (output units squared).
    nfev, njev : int
        Residual and Jacobian evaluations of this run.
    message : str
        Why it stopped.
    out_of_budget : bool
        Whether the evaluation budget stopped it (rather than a tolerance).
    """

    kind: str
    x0: np.ndarray
    x: np.ndarray
    fun0: float
    fun: float
    nfev: int
    njev: int
    message: str
    out_of_budget: bool = False

    @property
    def theta0(self) -> np.ndarray:
        """``x0``, under the polynomial references' name."""
        return self.x0

    @property
    def theta(self) -> np.ndarray:
        """``x``, under the polynomial references' name."""
        return self.x

    @property
    def sse0(self) -> float:
        """``fun0``: the sum of squared residuals at the start."""
        return self.fun0

    @property
    def sse(self) -> float:
        """``fun``: the sum of squared residuals at the end."""
        return self.fun


class ReferenceResult(OptimizeResult):
    """Outcome of a gradient reference, a :class:`scipy.optimize.OptimizeResult`.

    Every reference sets the keys below; each adds its own (listed in its docstring), and
    :meth:`keys` shows them all, as with scipy's solvers.

    Attributes
    ----------
    x : ndarray, shape (n_params,)
        The best admissible estimate.
    fun : float
        Its sum of squared residuals (output units squared).
    status : int
        A key of :data:`STATUS`: 0 a first-order local minimum, 1 stopped short of it by a
        tolerance, 2 on the pole-radius cap, 3 the evaluation budget ran out.
    success : bool
        ``status == 0``.
    message : str
        Which start won, why its run stopped, and any continuation.
    nfev, njev : int
        Residual and Jacobian evaluations over every run.
    nfev_equivalent : int
        The work in simulations of the model, what an optimiser's FE count compares with:
        ``nfev + njev * n_params`` for an analytic Jacobian (``n_params`` sensitivity
        simulations).
    std : ndarray, shape (n_params,)
        Standard errors of ``x`` from ``sigma^2 (J'J)^-1`` at the estimate (0 in a direction
        the record does not determine for the polynomial references, ``inf`` for grey-box).
    optimality : float
        First-order optimality reached (module notes).
    local_minimum : bool
        Whether ``x`` passed the first-order test.
    runs : list of ReferenceRun
        Every run, starts first, then continuations.
    best_start : int
        Index into ``runs`` of the run that produced ``x``.
    wall_time : float
        Seconds, start to finish.
    """

    @property
    def theta(self) -> np.ndarray:
        """``x``, under the polynomial references' name."""
        return self["x"]

    @property
    def sse(self) -> float:
        """``fun``: the sum of squared residuals at ``x``."""
        return self["fun"]

    @classmethod
    def assemble(
        cls, runs: list[ReferenceRun], best: int, *, x: np.ndarray, fun: float,
        std: np.ndarray, optimality: float, local_minimum: bool, on_cap: bool, nfev: int,
        njev: int, nfev_equivalent: int, message: str, t_begin: float, **keys: Any,
    ) -> ReferenceResult:
        """The result of a reference whose end has been judged; the status follows.

        Parameters
        ----------
        runs : list of ReferenceRun
        best : int
            Index of the winning run.
        x, fun, std, optimality, local_minimum, on_cap, nfev, njev, nfev_equivalent, message
            As the keys of the same names.
        t_begin : float
            ``time.perf_counter()`` at the reference's start.
        **keys
            The reference's own keys.

        Returns
        -------
        ReferenceResult
        """
        status = status_of(local_minimum, on_cap, runs[best].out_of_budget)
        return cls(
            x=x, fun=fun, status=status, success=status == 0, message=message, nfev=nfev,
            njev=njev, nfev_equivalent=nfev_equivalent, std=std, optimality=optimality,
            local_minimum=local_minimum, runs=runs, best_start=best,
            wall_time=time.perf_counter() - t_begin, on_cap=on_cap, **keys,
        )

    @classmethod
    def at(
        cls, runs: list[ReferenceRun], best: int, e: np.ndarray, jac: np.ndarray, *,
        on_cap: bool, nfev: int, njev: int, message: str, t_begin: float, **keys: Any,
    ) -> ReferenceResult:
        """The result at the winning run's end from its residuals and analytic Jacobian.

        ``std``, ``optimality`` and the key ``noise_variance`` (``SSE / (K - n_params)``)
        from ``e`` and ``jac``; a local minimum when the
        optimality is below :data:`OPTIMALITY_THRESHOLD` off the cap; ``nfev_equivalent``
        counts a Jacobian as ``n_params`` simulations.

        Parameters
        ----------
        runs : list of ReferenceRun
        best : int
            Index of the winning run, whose ``x`` is the result's.
        e : ndarray, shape (K,)
            Residuals at its end.
        jac : ndarray, shape (K, n_params)
            Their Jacobian.
        on_cap, nfev, njev, message, t_begin, **keys
            As :meth:`assemble` takes them.

        Returns
        -------
        ReferenceResult
        """
        x = runs[best].x.copy()
        sigma2, std = standard_errors(e, jac)
        reached = optimality(e, jac)
        return cls.assemble(
            runs, best, x=x, fun=float(e @ e), std=std, optimality=reached,
            local_minimum=bool(reached < OPTIMALITY_THRESHOLD and not on_cap), on_cap=on_cap,
            nfev=nfev, njev=njev, nfev_equivalent=nfev + njev * x.size, message=message,
            t_begin=t_begin, noise_variance=sigma2, **keys,
        )

    def __repr__(self) -> str:
        # scipy's repr prints every key; the runs and the model would fill a screen
        shown = ("message", "success", "status", "fun", "x", "std", "optimality", "nfev",
                 "njev")  # fmt: skip
        width = max(map(len, shown)) + 1
        lines = [f"{k.rjust(width)}: {self[k]!r}" for k in shown if k in self]
        lines.append(f"{'runs'.rjust(width)}: {len(self.get('runs', []))} run(s)")
        return "\n".join(lines)


def lower_of(start: float, start_name: str, reference: float,
             reference_name: str) -> tuple[float, str]:  # fmt: skip
    """The best known cost of a posed problem: the lower finite one of its start and its
    reference (the reference on a tie).

    Parameters
    ----------
    start, reference : float
        The costs of the problem's start (given values, a subspace estimate) and of its
        gradient reference.
    start_name, reference_name : str
        What each is, in words.

    Returns
    -------
    cost : float
        NaN when neither is finite.
    name : str
    """
    if math.isfinite(reference) and not (math.isfinite(start) and start < reference):
        return reference, reference_name
    if math.isfinite(start):
        return start, start_name
    return math.nan, "no finite reference"


class StartOrReference:
    """A posed problem whose best known cost is the lower finite one of its start and its
    gradient reference (:func:`lower_of`): a grey-box or state-space problem, whose start
    (given values, a subspace estimate) is a model of the structure as good as any.

    A subclass gives ``cost_ls`` (the start's cost), ``output_error_reference()`` (a result
    with ``cost``) and the class attributes ``start_name`` and ``reference_name``.
    """

    start_name: ClassVar[str]
    reference_name: ClassVar[str]

    def reference_cost(self) -> tuple[float, str]:
        """The lower finite cost of the start and the reference, and what it is.

        Returns
        -------
        cost : float
        name : str
        """
        return lower_of(self.cost_ls, self.start_name,  # type: ignore[attr-defined]
                        self.output_error_reference().cost,  # type: ignore[attr-defined]
                        self.reference_name)  # fmt: skip


def _simulation_in_own_bounds(cost: Any, bounds: Any, why: str, where: str) -> None:
    """Refuse what a :class:`StartOrReference` problem is not posed on: the one-step predictor
    (its cost is the simulation error) and bounds other than ``"auto"`` (it is searched in the
    bounds its model or structure carries).

    ``why`` is the first error message up to its ``use predictor='simulation', not ...``,
    ``where`` the second up to its ``, not bounds=...``.

    Raises
    ------
    ConfigError
    """
    if cost.predictor != "simulation":
        raise ConfigError(f"{why} use predictor='simulation', not {cost.predictor!r}")
    if not (isinstance(bounds, str) and bounds == "auto"):
        raise ConfigError(f"{where}, not bounds={bounds!r}")


def status_of(local_minimum: bool, on_cap: bool, out_of_budget: bool) -> int:
    """The :data:`STATUS` code of a reference's end.

    Parameters
    ----------
    local_minimum : bool
    on_cap : bool
    out_of_budget : bool
        Whether the budget stopped the winning run.

    Returns
    -------
    int
    """
    if local_minimum:
        return 0
    if on_cap:
        return 2
    return 3 if out_of_budget else 1


def optimality(e: np.ndarray, jac: np.ndarray) -> float:
    """First-order optimality ``||J' e|| / (||J||_F ||e||)``, 0 when ``e`` or ``J`` vanishes.

    Parameters
    ----------
    e : ndarray, shape (K,)
        Residuals.
    jac : ndarray, shape (K, n)
        Their Jacobian.

    Returns
    -------
    float
    """
    norm = float(np.linalg.norm(jac) * np.linalg.norm(e))
    return float(np.linalg.norm(jac.T @ e) / norm) if norm > 0 else 0.0


def standard_errors(e: np.ndarray, jac: np.ndarray) -> tuple[float, np.ndarray]:
    """The noise variance and the parameters' standard errors at a least-squares estimate.

    Parameters
    ----------
    e : ndarray, shape (K,)
        Residuals at the estimate.
    jac : ndarray, shape (K, d)
        Their Jacobian.

    Returns
    -------
    sigma2 : float
        ``SSE / (K - d)``.
    std : ndarray, shape (d,)
        ``sqrt(diag(sigma2 (J'J)^-1))`` from the SVD of ``J``; a direction whose singular
        value is below 1e-14 of the largest (undetermined to rounding) contributes nothing.
    """
    sigma2 = float(e @ e) / (jac.shape[0] - jac.shape[1])
    _, sv, vt = linalg.svd(jac, full_matrices=False)
    inv_sq = np.zeros_like(sv)
    ok = sv > sv[0] * 1e-14 if sv.size else sv.astype(bool)
    inv_sq[ok] = 1.0 / sv[ok] ** 2
    return sigma2, np.sqrt(sigma2 * np.sum(vt.T**2 * inv_sq, axis=1))


def levenberg_marquardt(
    residuals: Callable[[np.ndarray], np.ndarray],
    jacobian: Callable[[np.ndarray], np.ndarray],
    x0: np.ndarray,
    kind: str,
    *,
    admissible: Callable[[np.ndarray], bool] | None = None,
    energy: float = 0.0,
    bounds: tuple[float, float] | None = None,
    max_nfev: int | None = None,
    tol: float = 1e-10,
    chunks: int = 1,
    target: float = np.inf,
    crawl: bool = False,
) -> ReferenceRun:
    """One run of MINPACK's Levenberg-Marquardt from an admissible start, rejecting other steps.

    Parameters
    ----------
    residuals : callable
        ``residuals(x) -> e``, shape (K,), at an admissible ``x``.
    jacobian : callable
        ``jacobian(x) -> J``, shape (K, n), at an admissible ``x`` the solver accepted.
    x0 : ndarray, shape (n,)
        Admissible start.
    kind : str
        The run's name (:attr:`ReferenceRun.kind`).
    admissible : callable, optional
        ``admissible(x) -> bool``; default every finite ``x``.
    energy : float
        The target's sum of squares (sets the rejected step's residual, module notes).
    bounds : (float, float), optional
        Box bounds on every parameter: the bounded trust-region variant
        (``method="trf"``) instead of MINPACK's.
    max_nfev : int, optional
        Residual-evaluation budget of one chunk (default ``100 n``).
    tol : float
        ``ftol``, ``xtol`` and ``gtol``.
    chunks : int
        Budgets the run may continue for while its SSE still falls (module notes).
    target : float
        The best SSE of the other runs, for abandonment.
    crawl : bool
        Also abandon a run too slow to reach ``1.1 * target``.

    Returns
    -------
    ReferenceRun
        ``fun <= fun0`` always (the start is returned if nothing better was accepted).
    """
    n = x0.size
    r0 = residuals(x0)
    count = {"nfev": 1, "njev": 0}
    sse0 = float(r0 @ r0)
    bad = np.full(r0.size, np.sqrt((REJECT_FACTOR * (sse0 + energy) + 1.0) / r0.size))
    best = [sse0, x0]
    window = ABANDON_AFTER * n
    budget = chunks * (max_nfev or 100 * n)
    checkpoint = [sse0]  # the best SSE at the last multiple of window

    def ok(x: np.ndarray) -> bool:
        return bool(np.isfinite(x).all()) and (admissible is None or admissible(x))

    def fun(x: np.ndarray) -> np.ndarray:
        count["nfev"] += 1
        used = count["nfev"]
        if used > window and best[0] > HOPELESS * target:
            raise _Abandoned
        if crawl and used % window == 0:
            windows_left = (budget - used) / window
            if (checkpoint[0] - best[0]) * windows_left < best[0] - PROMISING * target:
                raise _Abandoned
            checkpoint[0] = best[0]
        if not ok(x):
            return bad
        r = residuals(x)
        if not np.isfinite(r).all():
            return bad
        sse = float(r @ r)
        if sse < best[0]:
            best[:] = [sse, np.array(x, dtype=float)]
        return r

    def jac(x: np.ndarray) -> np.ndarray:
        count["njev"] += 1
        if not ok(x):  # never happens: LM differentiates accepted points only
            return np.zeros((r0.size, n))
        return jacobian(x)

    if bounds is None:
        options: dict[str, Any] = {"method": "lm", "x_scale": "jac"}
    else:
        options = {"method": "trf", "bounds": bounds}
    x, done, last = x0, 0, sse0
    while True:
        try:
            sol = least_squares(fun, x, jac=jac, ftol=tol, xtol=tol, gtol=tol,
                                max_nfev=max_nfev or 100 * n, **options)  # fmt: skip
        except _Abandoned:
            sol = None
            break
        done += 1
        x = sol.x
        now = float(sol.fun @ sol.fun)
        if sol.status != 0 or done >= chunks or not now < last * (1.0 - STILL_FALLING):
            break  # status 0: the evaluation budget ran out
        last = now
    if sol is None:
        x, sse = best[1], best[0]
        why = (f"more than {HOPELESS:g} times" if best[0] > HOPELESS * target
               else "falling too slowly to reach")  # fmt: skip
        message = (f"abandoned after {count['nfev']} evaluations: SSE {best[0]:.6g}, {why} "
                   "the best of the other runs")  # fmt: skip
    else:
        # MINPACK's and the trust region's fun is the residual of their (accepted) x
        x, sse = np.asarray(sol.x, dtype=float), float(sol.fun @ sol.fun)
        message = str(sol.message) + (f" ({done} budgets)" if done > 1 else "")
    if not (ok(x) and sse <= sse0):  # defensive: both solvers return an accepted point
        x, sse = x0.copy(), sse0
    return ReferenceRun(
        kind=kind, x0=x0, x=x, fun0=sse0, fun=sse, nfev=count["nfev"], njev=count["njev"],
        message=message, out_of_budget=sol is not None and sol.status == 0,
    )


def _cap_layout(theta: np.ndarray, sl: slice, cap: float) -> tuple | None:
    """The roots of ``theta[sl]`` on the cap: ``(real roots, pair radii, pair angles,
    cofactor)``; None when none is on it or a complex root has no conjugate on it."""
    roots = np.roots(np.concatenate([[1.0], theta[sl]]))
    on = np.abs(roots) >= cap - CAP_TOLERANCE
    if not on.any():
        return None
    capped = roots[on]
    tol = 1e-9 * max(1.0, float(np.abs(capped).max()))
    reals = np.real(capped[np.abs(capped.imag) <= tol])
    upper = capped[capped.imag > tol]
    if reals.size + 2 * upper.size != capped.size:
        return None
    rest = roots[~on]
    cofactor = np.real(np.poly(rest))[1:] if rest.size else np.zeros(0)
    # a hair inside the cap: the rebuilt coefficients' roots, rounded, stay within it
    inside = cap * (1.0 - 1e-12)
    reals = np.sign(reals) * np.minimum(np.abs(reals), inside)
    return reals, np.minimum(np.abs(upper), inside), np.angle(upper), cofactor


class _OnTheCap:
    """Coefficients from free parameters that hold the roots found on the cap at their radii.

    ``p`` is the coefficients of the polynomials without a root on the cap, then per
    polynomial with one: the angles of its capped conjugate pairs, then its monic cofactor
    (the product of its other roots); the capped real roots are fixed.
    """

    def __init__(self, theta: np.ndarray, rooted: list[slice], cap: float):
        self.theta = theta.copy()
        self.layout = []
        held = np.zeros(theta.size, dtype=bool)
        for sl in rooted:
            found = _cap_layout(theta, sl, cap)
            if found is not None:
                self.layout.append((sl, *found))
                held[sl] = True
        self.free = np.flatnonzero(~held)
        self.others = [sl for sl in rooted if not held[sl].any()]
        parts = [theta[self.free]]
        for _, _, _, angles, cofactor in self.layout:
            parts += [angles, cofactor]
        self.p0 = np.concatenate(parts)

    def map(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
        """``theta(p)``, ``d theta / d p`` and the cofactors."""
        theta = self.theta.copy()
        theta[self.free] = p[: self.free.size]
        dtheta = np.zeros((theta.size, p.size))
        dtheta[self.free, np.arange(self.free.size)] = 1.0
        cofactors = []
        i = self.free.size
        for sl, reals, radii, _, cofactor in self.layout:
            angles = p[i : i + radii.size]
            rest = np.concatenate([[1.0], p[i + radii.size : i + radii.size + cofactor.size]])
            factors = [np.array([1.0, -x]) for x in reals]
            factors += [np.array([1.0, -2.0 * r * np.cos(w), r * r]) for r, w in zip(radii, angles)]
            fixed = np.ones(1)
            for f in factors:
                fixed = np.convolve(fixed, f)
            theta[sl] = np.convolve(fixed, rest)[1:]
            rows = np.arange(sl.start, sl.stop)
            for k, (r, w) in enumerate(zip(radii, angles)):
                others = np.ones(1)
                for m, f in enumerate(factors):
                    if m != reals.size + k:
                        others = np.convolve(others, f)
                d_pair = np.array([0.0, 2.0 * r * np.sin(w), 0.0])
                dtheta[rows, i + k] = np.convolve(np.convolve(others, rest), d_pair)[1:]
            for k in range(cofactor.size):
                unit = np.zeros(cofactor.size + 1)
                unit[k + 1] = 1.0
                dtheta[rows, i + radii.size + k] = np.convolve(fixed, unit)[1:]
            cofactors.append(rest[1:])
            i += radii.size + cofactor.size
        return theta, dtheta, cofactors


#: The radii a best point's roots on the cap are pulled in to for a restart (``B`` refitted):
#: on the DaISy robot arm, ARX(8,8,1) simulated with the measured-output rule and the cap
#: 0.9999, the end on the cap at SSE 0.0273 restarted from 0.998 to 0.99 reaches 0.0159 to
#: 0.0162; the polynomial and the ARX output-error references restart the same way.
PULLED_TO = (0.998, 0.995, 0.99)


def cap_reason(cap: float, kind: str = "root") -> str:
    """Why a reference ends on the cap ``cap`` after :func:`along_the_cap`, in words.

    Parameters
    ----------
    cap : float
        The cap in force, in (0, 1].
    kind : str, optional
        What is capped: ``"root"`` (of any polynomial) or ``"pole"``.

    Returns
    -------
    str
    """
    what = ("a pole on the unit circle (an undamped mode)" if cap >= 1.0
            else f"a {kind} of radius {cap:g}")  # fmt: skip
    return f"the SSE falls towards {what}; its minimum along the cap"


def along_the_cap(
    residuals: Callable[[np.ndarray], np.ndarray],
    jacobian: Callable[[np.ndarray], np.ndarray],
    theta: np.ndarray,
    rooted: list[slice],
    cap: float,
    *,
    within: Callable[[np.ndarray, float], bool],
    energy: float = 0.0,
    max_nfev: int | None = None,
    tol: float = 1e-10,
    counter: Any = None,
) -> ReferenceRun | None:
    """Levenberg-Marquardt from a point with roots on the cap, those roots held on it.

    The roots within :data:`CAP_TOLERANCE` of ``cap`` keep their radii (module notes, "On
    the cap"); their angles, the other roots (through each polynomial's cofactor) and every
    other parameter are free, and a step is rejected when a cofactor or a polynomial without
    a capped root leaves the cap.

    Parameters
    ----------
    residuals, jacobian : callable
        ``residuals(theta) -> e`` and ``jacobian(theta) -> J``, shape (K,) and (K, n).
    theta : ndarray, shape (n,)
        The admissible point with roots on the cap.
    rooted : list of slice
        The monic polynomials (coefficients after the leading 1) whose roots are capped.
    cap : float
        The cap in force, in (0, 1].
    within : callable
        ``within(coefficients, cap) -> bool``, the cap's test of one polynomial.
    energy, max_nfev, tol
        As :func:`levenberg_marquardt` takes them (``chunks`` is :data:`CHUNKS`).
    counter : object, optional
        The reference's problem, whose ``nfev`` and ``njev`` the run's evaluations are added
        to.

    Returns
    -------
    ReferenceRun or None
        Kind ``"along the cap"``, ``x0`` and ``x`` in ``theta``'s parameters; None when no
        root is on the cap.
    """
    held = _OnTheCap(theta, rooted, cap)
    if not held.layout:
        return None

    def admissible(p: np.ndarray) -> bool:
        th, _, cofactors = held.map(p)
        return all(within(c, cap) for c in cofactors) and all(
            within(th[sl], cap) for sl in held.others
        )

    run = levenberg_marquardt(
        lambda p: residuals(held.map(p)[0]),
        lambda p: (lambda th, dth, _: jacobian(th) @ dth)(*held.map(p)),
        held.p0, "along the cap", admissible=admissible, energy=energy, max_nfev=max_nfev,
        tol=tol, chunks=CHUNKS if max_nfev is None else 1,
    )
    # the rebuilt coefficients' roots are rounded: a point they put outside the cap is not
    # returned (the start is, as the original point when it is the one outside)
    def inside(th: np.ndarray) -> bool:
        return all(within(th[sl], cap) for sl in rooted)

    run.x0, run.x = held.map(run.x0)[0], held.map(run.x)[0]
    if not inside(run.x0):
        r0 = residuals(theta)
        run.x0, run.fun0 = theta.copy(), float(r0 @ r0)
    if not inside(run.x):
        run.x, run.fun = run.x0.copy(), run.fun0
        run.message += "; its end rounds outside the cap, the start kept"
    if counter is not None:
        counter.nfev += run.nfev
        counter.njev += run.njev
    return run


def restarts_on_the_cap(
    run: ReferenceRun,
    *,
    on_cap: Callable[[np.ndarray], bool],
    along: Callable[[np.ndarray], ReferenceRun | None],
    pulled: Callable[[np.ndarray], list[ReferenceRun]],
    admissible: Callable[[np.ndarray], bool],
    cap: float,
    rounds: int = 3,
) -> tuple[ReferenceRun, list[ReferenceRun], str]:
    """Restart a run that ends on the cap, along the cap and pulled in, while that helps.

    Each round continues the best point along the cap (when it is on it) and then restarts
    LM from it with its roots pulled in: the continuation finds the minimum along the cap,
    and from there a lower basin inside may lie behind the cap (module notes, "On the cap").

    Parameters
    ----------
    run : ReferenceRun
        The best run so far.
    on_cap : callable
        ``on_cap(x) -> bool``: a root of ``x`` on the cap.
    along : callable
        ``along(x)``: the run along the cap from ``x`` (:func:`along_the_cap`) or None.
    pulled : callable
        ``pulled(x)``: the runs from ``x`` with its roots pulled in.
    admissible : callable
        The cap's own test of an end (a rebuilt end may round outside it).
    cap : float
        The cap, for the note.
    rounds : int
        At most this many rounds; they stop at the first that lowers nothing.

    Returns
    -------
    best : ReferenceRun
    new : list of ReferenceRun
        Every run made, in order.
    note : str
        For the reference's message.
    """
    best, new, note = run, [], ""
    for _ in range(rounds):
        before = best
        if on_cap(best.x):
            cont = along(best.x)
            if cont is not None:
                new.append(cont)
                if cont.fun < best.fun and admissible(cont.x):
                    if cont.fun < best.fun * (1.0 - STILL_FALLING):
                        note += (f"; on the cap {cap:g}, minimised along it "
                                 f"(SSE {best.fun:.6g} -> {cont.fun:.6g})")  # fmt: skip
                    best = cont
        if not on_cap(best.x):
            break
        for restart in pulled(best.x):
            new.append(restart)
            if restart.fun < best.fun:
                if restart.fun < best.fun * (1.0 - STILL_FALLING):
                    note += (f"; restarted pulled in from the cap {cap:g} "
                             f"(SSE {best.fun:.6g} -> {restart.fun:.6g})")  # fmt: skip
                best = restart
        if not best.fun < before.fun * (1.0 - STILL_FALLING):
            break
    if not note:
        note = f"; on the cap {cap:g}, no lower point along it or pulled in"
    return best, new, note
