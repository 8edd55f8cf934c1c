"""The modal search space and the prediction-error reference of state-space models (``ssest``).

:class:`ModalBox` is the space every optimiser searches for a
:class:`~flexid.models.statespace.StateSpaceStructure`: ``log10`` of each mode's natural
frequency and damping ratio and of each real pole's corner frequency, inside the user's
bounds (every point a stable model).  :func:`ssest` is its gradient reference, as MATLAB
``ssest`` refines a subspace estimate: Levenberg-Marquardt on the simulation errors of every
output, over the modal parameters, with the gains and the initial state fitted for each
step (variable projection), from the :func:`flexid.n4sid` model's poles and from random
starts.

Notes
-----
The Jacobian is by central differences in the search box scaled to the unit cube (step
``1e-6``: truncation ``~1e-12`` and rounding ``~1e-10`` relative), all ``2 k`` points in one
batched call of the cost; at a bound the difference is one-sided, inward.  Each step of the
run stays in the box (the bounded trust-region variant), so every model it visits is stable.
"""

from __future__ import annotations

import functools
import math
import time
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from .._validate import checked_keywords, integer
from ..costs.modal import ModalCost
from ..data.records import IOData
from ..errors import ConfigError
from ..models.modes import modes
from ..models.statespace import StateSpaceStructure
from .reference import ReferenceResult, levenberg_marquardt
from .subspace import _record, n4sid

__all__ = ["ModalBox", "StateSpaceResult", "modal_start", "refine", "ssest"]

#: Random starts of :func:`ssest` after the subspace one.
SSEST_STARTS = 3
#: Central-difference step in the unit cube of the search box.
_STEP = 1e-6
#: First-order optimality below which the reference's end is a local minimum (as the
#: polynomial references: the cosine between the residual and the Jacobian's span; the
#: finite-difference Jacobian is good to about 1e-10, far below it).
OPTIMALITY = 1e-6
#: Residual evaluations of the best run's last steps on the orthogonal route (it starts at
#: the normal equations' minimum, where a few steps settle it).
POLISH_NFEV = 50
#: A coordinate within this distance of a face of the unit cube is held by that bound.
_ON_BOUND = 1e-9


@dataclass(frozen=True)
class ModalBox:
    """The search coordinates of a modal structure on a record.

    Attributes
    ----------
    structure : StateSpaceStructure
    lower, upper : ndarray, shape (2 m + r,)
        ``log10`` bounds: per mode its frequency (Hz) and damping ratio, per real pole its
        corner frequency (Hz).
    rule : str
        The bounds in words, as a result records them.
    """

    structure: StateSpaceStructure
    lower: np.ndarray
    upper: np.ndarray
    rule: str

    @classmethod
    def on(cls, structure: StateSpaceStructure, dt: float, n_samples: int) -> ModalBox:
        """The box of ``structure`` on a record of ``n_samples`` at ``dt``.

        Parameters
        ----------
        structure : StateSpaceStructure
        dt : float
            Sample time (s).
        n_samples : int

        Returns
        -------
        ModalBox
        """
        (f_lo, f_hi), (z_lo, z_hi), (c_lo, c_hi) = structure.bounds(dt, n_samples)
        m, r = structure.n_modes, structure.n_real
        lower = np.log10([f_lo, z_lo] * m + [c_lo] * r)
        upper = np.log10([f_hi, z_hi] * m + [c_hi] * r)
        parts = []
        if m:
            parts.append(f"mode frequencies {f_lo:.4g}-{f_hi:.4g} Hz, damping ratios "
                         f"{z_lo:g}-{z_hi:g}")  # fmt: skip
        if r:
            parts.append(f"corner frequencies {c_lo:.4g}-{c_hi:.4g} Hz")
        rule = ", ".join(parts) + ", log scale"
        return cls(structure, lower, upper, rule)

    def physical(self, z: Any) -> np.ndarray:
        """Modal parameters of search vectors (a point outside the box read at its nearest
        point of it).

        Parameters
        ----------
        z : array_like, shape (P, 2 m + r) or (2 m + r,)

        Returns
        -------
        ndarray, same shape
        """
        return 10.0 ** np.clip(np.asarray(z, dtype=float), self.lower, self.upper)

    def random(self, rng: np.random.Generator, count: int) -> list[tuple[str, np.ndarray]]:
        """``count`` named starts drawn uniformly in the box, in physical units.

        Parameters
        ----------
        rng : numpy.random.Generator
        count : int

        Returns
        -------
        list of (str, ndarray)
            ``("random 1", modal), ...``.
        """
        width = self.upper - self.lower
        return [(f"random {i + 1}", self.physical(self.lower + rng.random(width.size) * width))
                for i in range(count)]  # fmt: skip

    def coordinates(self, modal: Any) -> np.ndarray:
        """Search vectors of modal parameters, clipped to the box.

        Parameters
        ----------
        modal : array_like, shape (..., 2 m + r)

        Returns
        -------
        ndarray, same shape
        """
        with np.errstate(divide="ignore"):
            z = np.log10(np.asarray(modal, dtype=float))
        return np.clip(np.nan_to_num(z, nan=-np.inf), self.lower, self.upper)


def modal_start(poles: Any, box: ModalBox, dt: float) -> np.ndarray:
    """The modal parameters nearest to a model's poles that the structure can hold.

    The ``m`` least damped complex pairs become its modes; a pair more becomes two real
    poles at its frequency, and two real poles (neighbours in frequency) one critically
    damped mode at their geometric mean, until the counts match.  A pole with no continuous
    equivalent (negative real, at the origin) is read at the Nyquist frequency, an
    integrator or an unstable real pole at the box's lowest corner, an unstable pair at its
    frequency with the least damping; everything is clipped to the box.

    Parameters
    ----------
    poles : array_like of complex, shape (order,)
        Poles of a model of the structure's order (conjugate pairs complete).
    box : ModalBox
    dt : float
        Sample time (s).

    Returns
    -------
    ndarray, shape (2 m + r,)
        Physical modal parameters.
    """
    s = box.structure
    nyquist = 0.5 / dt
    pairs, reals = [], []
    for mode in modes(poles, dt):
        if mode.kind == "pair":  # an unstable pair at its frequency, least damped
            pairs.append((min(max(mode.damping, 0.0), 1.0), mode.frequency))
        elif mode.kind in ("integrator", "real") and not mode.damping > 0:
            reals.append(0.0)  # an integrator or unstable: the box's lowest corner
        elif mode.kind == "real":
            reals.append(mode.frequency)
        else:  # negative real or at the origin: no continuous equivalent
            reals.append(nyquist)
    pairs.sort()  # least damped first
    while len(pairs) > s.n_modes:
        _, f = pairs.pop()
        reals += [f, f]
    reals.sort()
    while len(pairs) < s.n_modes and len(reals) >= 2:
        f1, f2 = reals.pop(0), reals.pop(0)
        pairs.append((1.0, math.sqrt(f1 * f2)))
    modal = []
    for zeta, f in sorted(pairs, key=lambda p: p[1]):
        modal += [f, zeta]
    modal += reals[: s.n_real]
    return box.physical(box.coordinates(np.array(modal)))


class StateSpaceResult(ReferenceResult):
    """Outcome of :func:`ssest`, a :class:`~flexid.fit.reference.ReferenceResult`.

    Keys besides the reference's (where ``x`` is the modal parameters ``[f_1, zeta_1, ..,
    f_c1, ..]``, the modes and the real poles each by increasing frequency, and ``std`` their
    standard errors):

    model : StateSpaceModel
        The estimate, its gains and initial state fitted for ``x``.
    theta : ndarray
        Its whole parameter vector (:class:`~flexid.models.statespace.StateSpaceStructure`).
    stable : bool
        Whether the model is stable (every model of the modal space is).
    subspace : SubspaceResult or None
        The :func:`flexid.n4sid` estimate the first start came from.
    """

    @property
    def theta(self) -> np.ndarray:  # the whole vector, not x (the modal parameters)
        """The model's whole parameter vector."""
        return self["theta"]


def refine(
    cost: ModalCost, box: ModalBox, starts: list[tuple[str, np.ndarray]], *,
    max_nfev: int | None = None, tol: float = 1e-10, t_begin: float | None = None,
    **keys: Any,
) -> StateSpaceResult:  # fmt: skip
    """Levenberg-Marquardt from each start in the box; the best run's result.

    Parameters
    ----------
    cost : ModalCost
        The estimation record's cost (its residuals are the run's).
    box : ModalBox
    starts : list of (str, ndarray)
        Each start's name and physical modal parameters.
    max_nfev : int, optional
        Residual evaluations per run (default ``100 k``).
    tol : float
        ``ftol``, ``xtol`` and ``gtol``.
    t_begin : float, optional
        ``time.perf_counter()`` at the reference's start (default now).
    **keys
        Extra keys of the result (``subspace``).

    Returns
    -------
    StateSpaceResult
    """
    t_begin = time.perf_counter() if t_begin is None else t_begin
    width = box.upper - box.lower
    k = width.size
    count = {"points": 0}

    def physical(v: np.ndarray) -> np.ndarray:
        return box.physical(box.lower + np.atleast_2d(v) * width)

    def errors(v: np.ndarray) -> np.ndarray:
        count["points"] += np.atleast_2d(v).shape[0]
        return route[0](physical(v))[1].reshape(np.atleast_2d(v).shape[0], -1)

    def residual(v: np.ndarray) -> np.ndarray:
        return errors(v)[0]

    def jacobian(v: np.ndarray) -> np.ndarray:
        up = np.where(v + _STEP > 1.0, 0.0, _STEP)
        down = np.where(v - _STEP < 0.0, 0.0, _STEP)
        e = errors(np.vstack([v + np.diag(up), v - np.diag(down)]))
        return ((e[:k] - e[k:]) / (up + down)[:, None]).T

    budget = max_nfev or 100 * k
    route = [cost.residuals]
    runs = []
    for name, x in starts:
        v0 = np.clip((box.coordinates(x) - box.lower) / width, 0.0, 1.0)
        runs.append(levenberg_marquardt(residual, jacobian, v0, name, bounds=(0.0, 1.0),
                                        max_nfev=budget, tol=tol))  # fmt: skip
    best = int(np.argmin([run.fun for run in runs]))
    # the normal equations' rounding (about 1e-9 of the residual) is, through the
    # finite-difference Jacobian, a gradient noise above the optimality test's 1e-6: the best
    # run goes on from its end on the orthogonal route, and is judged there
    route[0] = functools.partial(cost.residuals, orthogonal=True)
    polish = levenberg_marquardt(residual, jacobian, runs[best].x, runs[best].kind,
                                 bounds=(0.0, 1.0), max_nfev=POLISH_NFEV, tol=tol)  # fmt: skip
    first = runs[best]
    runs[best] = replace(first, x=polish.x, fun=polish.fun, nfev=first.nfev + polish.nfev,
                         njev=first.njev + polish.njev,
                         message=f"{first.message.rstrip('.')}; then {polish.message}")  # fmt: skip
    v = runs[best].x
    e, J = residual(v), jacobian(v)
    for run in runs:  # starts and ends in physical units
        run.x0, run.x = physical(run.x0)[0], physical(run.x)[0]
    grad = J.T @ e
    norms = np.linalg.norm(J, axis=0) * np.linalg.norm(e)
    cosine = np.divide(np.abs(grad), norms, out=np.zeros(k), where=norms > 0)
    held = ((v <= _ON_BOUND) & (grad > 0)) | ((v >= 1.0 - _ON_BOUND) & (grad < 0))
    reached = float(np.max(cosine[~held], initial=0.0))
    sse = float(e @ e)
    sigma2 = sse / max(e.size - k - cost.structure.n_params, 1)
    modal = physical(v)[0]
    scale = modal * math.log(10.0) * width  # d modal / d v
    cov = sigma2 * np.linalg.pinv(J.T @ J)
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None)) * np.abs(scale)
    order = _by_frequency(cost.structure.n_modes, modal)  # the same model, modes in order
    modal, std = modal[order], std[order]
    on_bound = sorted(int(i) for i in np.flatnonzero(held[order]))
    theta = cost.residuals(modal[None], orthogonal=True)[0][0]
    model = cost.structure.model(theta, cost.dt)
    where = f"; held by a bound in coordinate(s) {on_bound}" if on_bound else ""
    return StateSpaceResult.assemble(
        runs, best, x=modal, fun=sse, std=std, optimality=reached,
        local_minimum=reached < OPTIMALITY, on_cap=False,
        nfev=sum(r.nfev for r in runs), njev=sum(r.njev for r in runs),
        nfev_equivalent=count["points"],
        message=f"best of {len(runs)} start(s): {runs[best].kind} ({runs[best].message}){where}",
        t_begin=t_begin, theta=theta, model=model, stable=bool(model.is_stable),
        noise_variance=sigma2, **keys,
    )


def _by_frequency(m: int, modal: np.ndarray) -> np.ndarray:
    """The permutation of a modal vector that puts its modes, then its real poles, in order
    of frequency (the cost does not depend on their order)."""
    modes = np.argsort(modal[0 : 2 * m : 2], kind="stable")
    reals = 2 * m + np.argsort(modal[2 * m :], kind="stable")
    return np.concatenate([np.column_stack([2 * modes, 2 * modes + 1]).reshape(-1), reals])


@checked_keywords
def ssest(
    data: Any,
    order: int | None = None,
    *,
    modes: int | None = None,
    feedthrough: bool = False,
    initial: str = "estimate",
    frequency: tuple[float, float] | None = None,
    damping: tuple[float, float] | None = None,
    starts: int = SSEST_STARTS,
    seed: int | np.random.Generator | None = 0,
    max_nfev: int | None = None,
) -> StateSpaceResult:
    """A state-space model by prediction-error refinement of a subspace estimate (``ssest``).

    Levenberg-Marquardt on the simulation errors of every output over the modal parameters
    (module notes), from the poles of :func:`flexid.n4sid`'s model and from ``starts``
    uniform random points of the box; the best run wins.

    Parameters
    ----------
    data : IOData or (u, y) pair
        One record; every output is fitted (with several, each divided by its standard
        deviation).
    order : int, optional
        The number of poles (default: n4sid's choice from the singular values).
    modes : int, optional
        Lightly damped modes among them (default ``order // 2``).
    feedthrough : bool, optional
        Estimate ``D`` (default False).
    initial : {"estimate", "zero"}, optional
        Fit the initial state (default) or start from rest.
    frequency, damping : (float, float), optional
        Bounds of the search (see :class:`~flexid.models.statespace.StateSpaceStructure`).
    starts : int, optional
        Random starts after the subspace one (default 3).
    seed : int or Generator, optional
        Seed of the random starts.
    max_nfev : int, optional
        Residual evaluations per start (default ``100 (2 m + r)``).

    Returns
    -------
    StateSpaceResult
        ``model`` is the estimate; ``status`` 0 when it passed the first-order test.

    Raises
    ------
    ConfigError
        Bad ``starts``, ``max_nfev`` or bounds.
    ModelOrderError
        An order the record cannot support, or more modes than it allows.
    DataError
        Non-finite data or a bad initial-condition rule.
    """
    t_begin = time.perf_counter()
    u, y, dt, inputs, outputs = _record(data)
    record = IOData(u, y, dt=dt, input_names=inputs, output_names=outputs)
    starts = integer(starts, "starts", error=ConfigError, minimum=0)
    if max_nfev is not None:
        max_nfev = integer(max_nfev, "max_nfev", error=ConfigError, minimum=1)
    sub = n4sid(record, order, feedthrough=feedthrough)
    structure = StateSpaceStructure(sub.order, u.shape[1], y.shape[1], modes, feedthrough,
                                    frequency, damping)  # fmt: skip
    cost = ModalCost(record, structure, initial=initial)
    box = ModalBox.on(structure, dt, record.n_samples)
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    points = [("subspace", modal_start(sub.model.poles(), box, dt)), *box.random(rng, starts)]
    out = refine(cost, box, points, max_nfev=max_nfev, t_begin=t_begin, subspace=sub)
    out["model"] = out["model"].named(record.input_names, record.output_names)
    return out

