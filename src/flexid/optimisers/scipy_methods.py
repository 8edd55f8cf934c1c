"""Adapters for ``scipy.optimize.minimize`` methods (Nelder-Mead, Powell, L-BFGS-B).

scipy drives its own loop and calls ``fun(x)``; the adapter runs it in a worker thread and
turns each call into a batch yielded to flexid's driver, so the FE budget, the history and
the shared initial population work exactly as for the population methods.  L-BFGS-B gets its
gradient by forward differences evaluated as one batch of ``n + 1`` points.  When scipy
finishes before the budget, the method restarts from a fresh point (so it uses its budget
like the others).  Registered as ``nelder-mead``, ``powell`` and ``l-bfgs-b`` (variants of
``scipy``).
"""

from __future__ import annotations

import queue
import threading

import numpy as np
from scipy import optimize

from ._params import Optimiser, Param, SearchGenerator
from ._problem import SearchSpace
from .registry import register, register_variant

__all__ = ["ScipyMinimize"]


class _Stop(Exception):
    """Raised inside scipy's thread when flexid stops the run."""


@register
class ScipyMinimize(Optimiser):
    """A local method of ``scipy.optimize.minimize`` run inside flexid's driver, with restarts.

    Parameters
    ----------
    method : {"Nelder-Mead", "Powell", "L-BFGS-B"}
        The scipy method.  Bounds are passed to all three (scipy >= 1.7); every point is
        also clipped to the box before it is evaluated.
    start : {"x0", "best-initial"}
        ``"x0"`` (default): the first run starts at ``space.x0`` (the problem's ``x0``, or
        the first shared initial point).  ``"best-initial"``: the first batch is the shared
        initial population of ``initial_points`` points (like the population methods) and
        the runs start at its members in order of cost.
    initial_points : int
        Size of that initial population (``start="best-initial"`` only; the name CMA-ES
        gives its first batch too).
    restarts : bool
        When scipy stops before the FE budget (converged or its own iteration limit), start
        again from the next point: for ``"x0"`` a uniform point drawn from the run's
        generator, for ``"best-initial"`` the next initial point, then uniform points.
        ``False``: the run ends after the first local run (``stop == "converged"``).
    fd_step : float
        Relative forward-difference step for L-BFGS-B: ``h_j = fd_step * max(|x_j|,
        1e-3 * width_j)``, a backward step at the upper face.  The ``n + 1`` points of a
        gradient are one batch and count ``n + 1`` FE.

    Notes
    -----
    scipy drives its own loop and calls ``fun(x)``.  The adapter runs
    ``scipy.optimize.minimize`` in a worker thread that hands each request to the search
    generator through a pair of queues and blocks until the driver sends the cost back, so
    only one thread runs at a time and the run is deterministic.  Closing the generator
    (budget reached, callback stop, :class:`AskTell` abandoned) unblocks the worker with a
    private exception and joins it; an exception raised by scipy is re-raised in the
    caller's thread.  The hand-off adds a fixed cost per yielded batch (two queue
    transfers), small next to an ARX simulation.  Replaying scipy from the start with a
    cache of known values (the thread-free alternative) would cost O(k^2) evaluations of
    scipy's own bookkeeping for k FE.
    """

    name = "scipy"
    reference = "Virtanen et al., Nature Methods 17:261-272, 2020 (scipy.optimize)"
    bounds = "scipy bounds + clip"
    bounds_note = (
        "The box is passed to scipy as bounds and every point is clipped to "
        "it before it is evaluated."
    )
    stays_in_box = True
    method = Param(str, "Nelder-Mead", "scipy method", choices=("Nelder-Mead", "Powell",
                                                                "L-BFGS-B"))
    start = Param(str, "x0", "first start point", choices=("x0", "best-initial"))
    initial_points = Param(int, 50, "size of the shared initial population (best-initial)",
                           low=1)
    restarts = Param(bool, True, "restart when scipy stops before the budget")
    fd_step = Param(float, 1e-7, "relative forward-difference step (L-BFGS-B)", low=0.0,
                    low_open=True)

    def search(self, space: SearchSpace, rng: np.random.Generator) -> SearchGenerator:
        if self.start == "best-initial":
            X0 = space.initial_population(self.initial_points)
            F0 = yield X0
            starts = X0[np.argsort(F0, kind="stable")]
        else:
            starts = space.x0[None, :].copy()
        bounds = optimize.Bounds(space.lower, space.upper)
        requests: queue.Queue = queue.Queue()
        replies: queue.Queue = queue.Queue()
        width = space.upper - space.lower

        def ask(X: np.ndarray) -> np.ndarray:
            requests.put(("eval", X))
            reply = replies.get()
            if reply is None:
                raise _Stop
            return reply

        def fun(x: np.ndarray) -> float:
            return float(ask(np.clip(x, space.lower, space.upper)[None, :])[0])

        def fun_grad(x: np.ndarray):
            x = np.clip(x, space.lower, space.upper)
            h = self.fd_step * np.maximum(np.abs(x), width * 1e-3)
            h = np.where(x + h > space.upper, -h, h)  # backward step at the upper face
            pts = np.vstack([x, x + np.diag(h)])
            F = ask(pts)
            f0 = F[0]
            if not np.isfinite(f0):
                return 1e300, np.zeros_like(x)
            grad = np.where(np.isfinite(F[1:]), (F[1:] - f0) / h, 0.0)
            return float(f0), grad

        def worker(x0: np.ndarray) -> None:
            try:
                if self.method == "L-BFGS-B":
                    optimize.minimize(fun_grad, x0, jac=True, method="L-BFGS-B", bounds=bounds)
                else:
                    optimize.minimize(fun, x0, method=self.method, bounds=bounds)
            except _Stop:
                return
            except Exception as exc:  # surfaced in the driver's thread
                requests.put(("error", exc))
                return
            requests.put(("done", None))

        k = 0
        while k == 0 or self.restarts:
            x0 = starts[k] if k < len(starts) else space.uniform(1, rng)[0]
            k += 1
            thread = threading.Thread(target=worker, args=(x0,), daemon=True)
            thread.start()
            try:
                while True:
                    kind, payload = requests.get()
                    if kind == "done":
                        break
                    if kind == "error":
                        raise payload
                    replies.put((yield payload))
            finally:
                if thread.is_alive():
                    replies.put(None)
                thread.join()


register_variant("nelder-mead", "scipy", "scipy.optimize Nelder-Mead with restarts.",
                 method="Nelder-Mead")
register_variant("powell", "scipy", "scipy.optimize Powell with restarts.", method="Powell")
register_variant("l-bfgs-b", "scipy",
                 "scipy.optimize L-BFGS-B, batched forward-difference gradient, restarts.",
                 method="L-BFGS-B")
