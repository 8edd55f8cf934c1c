"""Adapters for ``scipy.optimize.minimize`` methods (Nelder-Mead, Powell, L-BFGS-B).

scipy drives its own loop and calls ``fun(x)``; the adapter runs it in a worker thread and
turns each call into a batch yielded to flexid's driver, so the FE budget, the history and
the shared initial population work exactly as for the population methods.  L-BFGS-B gets its
gradient by forward differences evaluated as one batch of ``n + 1`` points.  When scipy
finishes before the budget, the method restarts from a fresh point of the shared initial
population (so it uses its budget like the others).
"""

from __future__ import annotations

import queue
import threading

import numpy as np
from scipy import optimize

from .base import Optimiser, Param, SearchSpace
from .registry import register, register_variant

__all__ = ["ScipyMinimize"]


class _Stop(Exception):
    """Raised inside scipy's thread when flexid stops the run."""


@register
class ScipyMinimize(Optimiser):
    """A local method of ``scipy.optimize.minimize`` from a start point, with restarts.

    The first start is the best point of the shared initial population (``initial_points``
    points, evaluated as the first batch); each restart takes the next point of that
    population in order of cost.  Bounds are passed to the methods that accept them
    (Powell, L-BFGS-B, Nelder-Mead in scipy >= 1.7).
    """

    name = "scipy"
    reference = "Virtanen et al., Nature Methods 17:261-272, 2020 (scipy.optimize)"
    method = Param(str, "Nelder-Mead", "scipy method", choices=("Nelder-Mead", "Powell",
                                                                "L-BFGS-B"))
    initial_points = Param(int, 50, "size of the shared initial population", low=1)
    fd_step = Param(float, 1e-7, "relative forward-difference step (L-BFGS-B)", low=0.0,
                    low_open=True)

    def search(self, space: SearchSpace, rng: np.random.Generator):
        X0 = space.initial_population(self.initial_points)
        F0 = yield X0
        starts = X0[np.argsort(F0, kind="stable")]
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
        while True:
            x0 = starts[k % len(starts)] if k < len(starts) else space.uniform(1, rng)[0]
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


register_variant("nelder-mead", "scipy", "scipy.optimize Nelder-Mead with restarts",
                 method="Nelder-Mead")
register_variant("powell", "scipy", "scipy.optimize Powell with restarts", method="Powell")
register_variant("l-bfgs-b", "scipy",
                 "scipy.optimize L-BFGS-B, batched forward-difference gradient, restarts",
                 method="L-BFGS-B")
