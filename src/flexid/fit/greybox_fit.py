"""Gradient reference for grey-box models: what a MATLAB ``nlgreyest`` user would run.

:func:`greyest` minimises the simulation error of a :class:`~flexid.models.greybox.GreyBoxModel`
by a trust-region Gauss-Newton/Levenberg-Marquardt method
(:func:`scipy.optimize.least_squares`, ``method="trf"``, within the parameters' bounds) from
several starts, and reports what a user needs to trust the result: the parameters with
their standard errors, which parameter combinations the record cannot separate, whether
the search ended at a local minimum and which parameters sit on a bound.

Notes
-----
**Coordinates.**  Each estimated parameter is searched in ``s`` in ``[0, 1]``, its search
box (:meth:`GreyBoxModel.search_bounds <flexid.models.greybox.GreyBoxModel.search_bounds>`:
``log10`` of the value for log-scaled parameters) mapped linearly, so the problem is well
scaled whatever the units.

**Jacobian.**  Central differences with step ``h = 1e-5`` in ``s``, all ``2 n`` perturbed
parameter sets simulated as one population (one batched run).  Truncation ``O(h^2)`` is
about 1e-10 of the residual's scale and rounding ``eps / h`` about 1e-11; next to a bound
the stencil is shifted inside the box.  Every simulated parameter set counts as one
evaluation in ``nfev``.

**Standard errors** (Ljung, *System Identification*, 2nd ed., 9.3; ``nlgreyest``): with the
Jacobian ``J`` of the residuals with respect to the physical parameters at the optimum,
``cov = sigma^2 (J' J)^-1``, ``sigma^2 = SSE / (K - d)``.

**Identifiability.**  The Jacobian with respect to ``log|theta|`` (relative sensitivities)
is decomposed by SVD; a singular value below :data:`UNIDENTIFIABLE` of the largest is a
combination of parameters the record does not determine (an information matrix with
condition number above ``1 / UNIDENTIFIABLE^2``).  Each such direction is reported as the
parameters that move along it with their exponents: ``I1^+1 Mg^+1`` moving together means
only the ratio ``Mg / I1`` is determined.  Their standard errors are then ``inf``.

**Local minimum.**  First-order optimality, scale-free: for every free parameter not held
by a bound, the cosine between the residual and the parameter's column of the Jacobian is
below :data:`OPTIMALITY` (the residual is orthogonal to every direction the search could
still take); or the fit is exact to rounding (RMS error at most :data:`EXACT` of the output's
RMS), where the residual's direction is noise.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from .._validate import checked_keywords, integer, real
from ..costs.greybox import GreyBoxCost
from ..errors import ConfigError
from ..models.greybox import GreyBoxModel
from ..models.vocabulary import GREYBOX_REFERENCE_STARTS
from ..validation.diagnostics import fit_percent
from .reference import ReferenceResult, ReferenceRun, levenberg_marquardt

__all__ = ["EXACT", "OPTIMALITY", "UNIDENTIFIABLE", "GreyBoxResult", "GreyBoxRun", "greyest"]

#: Relative singular value of the relative-sensitivity Jacobian below which a parameter
#: combination counts as not determined by the record.
UNIDENTIFIABLE = 1e-6
#: Largest cosine between the residual and a free parameter's Jacobian column at a local
#: minimum (the central differences' error is about 1e-10 of that column).
OPTIMALITY = 1e-4
#: RMS error, relative to the output's RMS, at or below which a fit is exact within the
#: simulation's rounding: the residual is then rounding noise, its direction says nothing,
#: and an SSE that cannot fall below zero is a minimum.
EXACT = 1e-10
_STEP = 1e-5  # central-difference step in the unit box
_ON_BOUND = 1e-6  # distance in the unit box below which a parameter is on its bound


#: One start of :func:`greyest` (the one run record of every reference).
GreyBoxRun = ReferenceRun


class GreyBoxResult(ReferenceResult):
    """Result of :func:`greyest`: the one reference result, with a table and a summary.

    Keys besides those of :class:`~flexid.fit.reference.ReferenceResult` (where ``x`` is the
    estimated parameters' physical values, in ``model.free`` order, ``fun`` the SSE of the
    scaled simulation errors and ``std`` their standard errors, ``inf`` in an undetermined
    direction):

    Attributes
    ----------
    model : GreyBoxModel
        The model with the estimated values as its parameters' values.
    values : dict of str to float
        Every parameter's value (estimated and fixed), read from ``model``: a property, which
        hides ``dict.values`` on this result.
    covariance : ndarray, shape (n_free, n_free)
    rmse : float
        RMSE of the simulation error (scaled per output when there are several).
    cost : float
        The cost the reference served: ``rmse`` from :func:`greyest`, an estimation
        problem's own metric from its ``output_error_reference``.
    fit : float
        Simulation fit [%] on the estimation record (first output).
    simulations, nfev_equivalent : int
        Parameter sets simulated over every start, residuals and the ``2 n_free`` of each
        central-difference Jacobian together (what an optimiser's FE count compares with).
    on_bound : tuple of str
        Estimated parameters on a bound.
    singular_values : ndarray
        Of the relative-sensitivity Jacobian, divided by the largest.
    unidentifiable : tuple of str
        One description per undetermined combination.
    stable, on_cap : bool
        True and False: a grey-box model has no stability constraint (a model that
        diverges costs ``+inf``) and no radius cap.
    """

    @property
    def values(self) -> dict[str, float]:  # type: ignore[override]
        """Every parameter's value (estimated and fixed), by name."""
        return dict(zip(self.model.names, self.model.nominal.tolist()))

    @property
    def std_errors(self) -> dict[str, float]:
        """Standard error of each estimated parameter, by name."""
        return dict(zip(self.free, np.asarray(self["std"]).tolist()))

    @property
    def free(self) -> tuple[str, ...]:
        """The estimated parameters' names."""
        return self.model.free

    def table(self) -> str:
        """The estimated parameters with units, standard errors and bound flags, one per line.

        Returns
        -------
        str
        """
        lines = [f"{'parameter':<18}{'value':>14}{'std error':>12}  unit"]
        for name in self.free:
            p = self.model.parameter(name)
            se = self.std_errors[name]
            flag = "  on bound" if name in self.on_bound else ""
            lines.append(f"{name:<18}{p.value:>14.6g}{se:>12.3g}  {p.unit}{flag}")
        return "\n".join(lines)

    def summary(self) -> str:
        """A few lines: the fit, the minimum test, bounds and identifiability, the table.

        Returns
        -------
        str
        """
        status = (
            f"local minimum (optimality {self.optimality:.1e})"
            if self.local_minimum
            else f"NOT at a verified local minimum (optimality {self.optimality:.1e})"
        )
        lines = [
            f"grey-box model {self.model.name}: simulation fit {self.fit:.2f} % on the "
            f"estimation record, RMSE {self.rmse:.6g}, {self.simulations} simulations, "
            f"{len(self.runs)} "
            f"start(s); {status}",
        ]
        if self.on_bound:
            lines.append(f"on a bound: {', '.join(self.on_bound)}")
        for text in self.unidentifiable:
            lines.append(f"not determined by the record: {text}")
        lines.append(self.table())
        return "\n".join(lines)


class _Problem:
    """The least-squares problem in the unit box, counting simulations."""

    def __init__(self, cost: GreyBoxCost) -> None:
        self.cost = cost
        self.lo, self.hi = cost.model.search_bounds()
        self.nfev = 0

    def physical(self, s: np.ndarray) -> np.ndarray:
        z = self.lo + np.clip(s, 0.0, 1.0) * (self.hi - self.lo)
        values = self.cost.model.from_search(z)
        return np.clip(values, self.cost.lower, self.cost.upper)

    def unit(self, values: np.ndarray) -> np.ndarray:
        z = self.cost.model.to_search(np.clip(values, self.cost.lower, self.cost.upper))
        return np.clip((z - self.lo) / (self.hi - self.lo), 0.0, 1.0)

    def residuals(self, S: np.ndarray) -> np.ndarray:
        S = np.atleast_2d(S)
        self.nfev += S.shape[0]
        e = self.cost.residuals(self.physical(S))
        # an overflowing candidate gets a large finite residual so the trust region shrinks
        return np.where(np.isfinite(e), e, 1e150)

    def fun(self, s: np.ndarray) -> np.ndarray:
        return self.residuals(s)[0]

    def jac(self, s: np.ndarray) -> np.ndarray:
        n = s.size
        up = np.minimum(s + _STEP, 1.0)
        down = np.maximum(s - _STEP, 0.0)
        stencil = np.repeat(s[None, :], 2 * n, axis=0)
        stencil[np.arange(n), np.arange(n)] = up
        stencil[n + np.arange(n), np.arange(n)] = down
        e = self.residuals(stencil)
        return ((e[:n] - e[n:]) / (up - down)[:, None]).T


def _directions(J_rel: np.ndarray, names: tuple[str, ...]) -> tuple[np.ndarray, list[str]]:
    """Relative singular values and the undetermined combinations of the parameters."""
    _, sv, Vt = np.linalg.svd(J_rel, full_matrices=False)
    rel = sv / sv[0] if sv.size and sv[0] > 0 else np.zeros_like(sv)
    texts = []
    for value, v in zip(rel, Vt):
        if value >= UNIDENTIFIABLE:
            continue
        v = v / v[np.argmax(np.abs(v))]
        terms = [f"{names[i]}^{v[i]:+.2f}" for i in np.flatnonzero(np.abs(v) > 0.05)]
        texts.append(
            f"{' '.join(terms)} (relative singular value {value:.1e}): these parameters "
            "change together, with these exponents, without changing the fit"
        )
    return rel, texts


@checked_keywords
def greyest(
    data: Any,
    model: GreyBoxModel,
    *,
    starts: int = GREYBOX_REFERENCE_STARTS,
    seed: int | np.random.Generator = 0,
    x0: Any = None,
    max_nfev: int | None = None,
    tol: float = 1e-10,
    dt: float | None = None,
) -> GreyBoxResult:
    """Fit a grey-box model's estimated parameters by Levenberg-Marquardt on the simulation error.

    Parameters
    ----------
    data : IOData or (u, y)
        Estimation record (channels read by name, see
        :func:`flexid.costs.greybox.record_for`).
    model : GreyBoxModel
    starts : int
        Random starts, uniform in the search box, after the first start (the parameters'
        values, or ``x0``).
    seed : int or numpy.random.Generator
        Seeds the random starts.
    x0 : array_like, shape (n_free,), optional
        First start's estimated-parameter values (physical units); default their values.
    max_nfev : int, optional
        Budget of residual evaluations per start, as :func:`scipy.optimize.least_squares`
        counts them (Jacobians not included); default ``100 n_free``.
    tol : float
        ``ftol``, ``xtol`` and ``gtol`` of the solver.
    dt : float, optional
        Sample time of a ``(u, y)`` pair.

    Returns
    -------
    GreyBoxResult

    Raises
    ------
    ConfigError
        A model with nothing to estimate, a bad ``starts``, ``x0`` or ``max_nfev``.
    DataError
        A record without the model's channels (see :func:`flexid.costs.greybox.record_for`).
    """
    t_begin = time.perf_counter()
    cost = GreyBoxCost(model, data, metric="rmse", dt=dt)
    n = cost.n_params
    if n == 0:
        raise ConfigError(f"grey-box model {model.name!r} has no estimated parameter")
    starts = integer(starts, "starts", error=ConfigError, minimum=0)
    tol = real(tol, "tol", error=ConfigError, minimum=0, low_open=True)
    budget = 100 * n if max_nfev is None else integer(max_nfev, "max_nfev", error=ConfigError,
                                                     minimum=1)
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    problem = _Problem(cost)
    if x0 is None:
        first = np.array([model.parameter(name).value for name in model.free])
        label = "nominal"
    else:
        first, label = np.asarray(x0, dtype=float).reshape(-1), "given"
        if first.shape != (n,) or not np.isfinite(first).all():
            raise ConfigError(
                f"x0 must hold {n} finite values for {list(model.free)}, got {first.tolist()}"
            )
    points = [(label, problem.unit(first))]
    points += [(f"random {k + 1}", rng.random(n)) for k in range(starts)]
    runs = [
        levenberg_marquardt(
            problem.fun, problem.jac, s0, name, bounds=(0.0, 1.0), max_nfev=budget, tol=tol
        )
        for name, s0 in points
    ]
    best_start = int(np.argmin([run.fun for run in runs]))
    s_best, sse = runs[best_start].x, runs[best_start].fun
    for run in runs:  # the runs' starts and ends in physical units
        run.x0, run.x = problem.physical(run.x0), problem.physical(run.x)
    r = problem.fun(s_best)
    J_s = problem.jac(s_best)
    values = problem.physical(s_best)

    # first-order optimality in the unit box, where a bound holds a parameter
    grad = J_s.T @ r
    norms = np.linalg.norm(J_s, axis=0) * np.linalg.norm(r)
    cosine = np.divide(np.abs(grad), norms, out=np.zeros(n), where=norms > 0)
    at_lower, at_upper = s_best <= _ON_BOUND, s_best >= 1.0 - _ON_BOUND
    held = (at_lower & (grad > 0)) | (at_upper & (grad < 0))
    optimality = float(np.max(cosine[~held], initial=0.0))

    # d s / d theta of each parameter, for the physical and the relative Jacobians
    logs = np.array([model.parameter(name).log for name in model.free])
    dz = np.where(logs, 1.0 / (values * math.log(10.0)), 1.0)
    J_theta = J_s * (dz / (problem.hi - problem.lo))[None, :]
    rel, texts = _directions(J_theta * np.abs(values)[None, :], model.free)
    k = r.size
    sigma2 = sse / max(k - n, 1)
    _, sv, Vt = np.linalg.svd(J_theta, full_matrices=False)
    determined = sv > UNIDENTIFIABLE * sv[0] if sv.size and sv[0] > 0 else np.zeros(n, bool)
    inv = np.where(determined, 1.0 / np.where(determined, sv, 1.0) ** 2, 0.0)
    covariance = sigma2 * (Vt.T * inv) @ Vt
    std = np.sqrt(np.clip(np.diag(covariance), 0.0, None))
    # a parameter that moves in an undetermined direction has no finite standard error
    loose = (np.abs(Vt[~determined]) > 0.05).any(axis=0)
    std = np.where(loose, np.inf, std)

    fitted = model.with_parameters(**dict(zip(model.free, values.tolist())))
    y_sim = fitted.simulate(fitted.nominal, cost.u, cost.dt)[0, :, 0]
    fit_pct = fit_percent(cost.y[:, 0], y_sim)
    exact = math.sqrt(sse / k) <= EXACT * float(np.sqrt(np.mean(cost._target**2)))
    local = bool(optimality <= OPTIMALITY or exact)
    return GreyBoxResult.assemble(
        runs, best_start, x=fitted.theta, fun=sse, std=std, optimality=optimality,
        local_minimum=local, on_cap=False, nfev=sum(run.nfev for run in runs),
        njev=sum(run.njev for run in runs), nfev_equivalent=problem.nfev,
        message=f"best of {len(runs)} start(s): {runs[best_start].kind} "
        f"({runs[best_start].message})",
        t_begin=t_begin, model=fitted, covariance=covariance, cost=math.sqrt(sse / k),
        rmse=math.sqrt(sse / k), fit=fit_pct, simulations=problem.nfev,
        on_bound=tuple(name for name, b in zip(model.free, at_lower | at_upper) if b),
        singular_values=rel, unidentifiable=tuple(texts), stable=True,
    )
