"""The driver: runs an optimiser's search generator on a problem within a budget.

An optimiser is a class whose :meth:`Optimiser.search` is a *generator*: it yields
populations ``X`` of shape ``(P, n)`` to evaluate and receives their costs ``F`` of shape
``(P,)``.  The search reads like the algorithm's paper, while the driver owns everything
that must be the same for every algorithm:

* the **function-evaluation (FE) count**: every row passed to the objective is one FE; the
  last batch is truncated so a run stops *exactly* at its budget;
* **cost hygiene**: NaN and infinite costs are treated as ``+inf``;
* **best-so-far** tracking, **history** (FE, iteration, phase, best cost) and the exact
  FE of every improvement, timing,
  callbacks and the stop rules (FE budget, iterations, target cost, wall time);
* the **initial population**, which depends only on the problem and the seed, so every
  optimiser given the same seed starts from the same points (a smaller population is the
  first rows of a larger one);
* the **scale**: an optimiser searches the unit box ``[0, 1]^n`` and the driver maps each
  point to the problem's box, ``x = lower + z (upper - lower)``, before evaluating it.  A
  hyper-parameter that is a length (a step size, a radius, a velocity limit, a mutation
  width) is therefore a fraction of each side of the box, and a run visits the same
  normalised points on a box of width 0.01 as on one of width 100.

The generator protocol gives an ask/tell interface for free (:class:`AskTell`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
from scipy.optimize import OptimizeResult

from .._validate import checked_keywords, integer
from ..errors import OptimiserError
from ._budget import Budget
from ._history import History, IterationInfo
from ._params import Optimiser
from ._problem import Problem, SearchSpace
from .registry import create

__all__ = ["AskTell", "minimize"]


class _StopRun(Exception):
    """Internal: a stop rule fired inside end_iteration."""


# =============================================================================== the driver
class _Run:
    """State of one optimisation run; shared by :func:`minimize` and :class:`AskTell`."""

    def __init__(
        self,
        optimiser: Optimiser,
        problem: Problem,
        budget: Budget,
        seed: Any,
        callbacks: list[Callable[[IterationInfo], Any]],
    ) -> None:
        self.optimiser = optimiser
        self.problem = problem
        self.budget = budget
        self.seed = _normalise_seed(seed)
        init_ss, run_ss = np.random.SeedSequence(self.seed).spawn(2)
        self.rng = np.random.default_rng(run_ss)
        self.space = SearchSpace(problem, init_ss, self)
        self.callbacks = callbacks
        self.nfev = 0
        self.nit = 0
        self.batches = 0
        self.best_f = math.inf
        self.best_x = problem.from_unit(self.space.x0)
        self.history = History()
        # every evaluation that lowered the best cost, at its exact FE count
        self._improved_fe: list[int] = []
        self._improved_f: list[float] = []
        self.stop_message: str | None = None
        self.stop_reason: str | None = None
        self.t0 = time.perf_counter()
        self.elapsed = 0.0
        self._manual = not optimiser.auto_iterations

    # -- bookkeeping
    def _stop(self, reason: str, message: str) -> None:
        if self.stop_reason is None:
            self.stop_reason = reason
            self.stop_message = message

    def end_iteration(self, phase: str) -> None:
        if self.batches == 0:
            return
        self.nit += 1
        self._record(phase)
        if self.stop_reason is not None:
            raise _StopRun

    def _record(self, phase: str) -> None:
        self.elapsed = time.perf_counter() - self.t0
        self.history.append(self.nfev, self.nit, phase, self.best_f)
        b = self.budget
        if b.max_iter is not None and self.nit >= b.max_iter:
            self._stop("iterations", f"iteration limit reached ({b.max_iter})")
        if b.max_time is not None and self.elapsed >= b.max_time:
            self._stop("time", f"wall-time limit reached ({b.max_time:g} s)")
        if self.callbacks:
            info = IterationInfo(
                self.nfev, self.nit, phase, self.best_f, self.best_x.copy(), self.elapsed, b.max_fe
            )
            for callback in self.callbacks:
                if callback(info) is True:
                    self._stop("callback", "stopped by callback")

    def evaluate(self, X: np.ndarray) -> np.ndarray:
        """Evaluate (a truncated part of) X, update the counters and the best."""
        F = np.asarray(self.problem.objective(X), dtype=float)
        if F.shape != (X.shape[0],):
            F = F.reshape(-1)
            if F.shape != (X.shape[0],):
                raise OptimiserError(
                    f"objective returned shape {np.shape(F)} for a population of "
                    f"{X.shape[0]} points; it must return one cost per row"
                )
        return _clean_costs(F)

    def check_population(self, X: Any) -> np.ndarray:
        X = np.asarray(X, dtype=float)
        if X.ndim == 1 and X.size == self.problem.dim:
            X = X[None, :]
        if X.ndim != 2 or X.shape[1] != self.problem.dim or X.shape[0] == 0:
            raise OptimiserError(
                f"{self.optimiser.name}: yielded a population of shape {X.shape}; expected "
                f"(P, {self.problem.dim}) with P >= 1"
            )
        return X

    def truncate(self, X: np.ndarray) -> np.ndarray:
        if self.budget.max_fe is not None:
            room = self.budget.max_fe - self.nfev
            if X.shape[0] > room:
                return X[:room]
        return X

    def absorb(self, X: np.ndarray, F: np.ndarray, full_size: int) -> None:
        """Count, track the best, record an automatic iteration, and check FE/target stops."""
        if F.size:
            self._improve(X, F)
        self.nfev += X.shape[0]
        self.batches += 1
        b = self.budget
        if b.max_fe is not None and self.nfev >= b.max_fe:
            self._stop("budget", f"function-evaluation budget reached ({b.max_fe})")
        if b.target is not None and self.best_f <= b.target:
            self._stop("target", f"target cost reached ({self.best_f:.6g} <= {b.target:.6g})")
        if self.batches == 1:
            self.history.append(self.nfev, 0, "init", self.best_f)
            self.elapsed = time.perf_counter() - self.t0
        elif not self._manual:
            self.nit += 1
            self._record(self.optimiser.name)
        elif self.stop_reason is not None:
            # manual iterations: record the partial iteration at which the run stops
            self.nit += 1
            self._record("partial")
        if X.shape[0] < full_size:
            self._stop("budget", f"function-evaluation budget reached ({b.max_fe})")

    def _improve(self, X: np.ndarray, F: np.ndarray) -> None:
        """Log each evaluation of the batch that lowers the best cost; keep the new best.

        The last improvement is the batch's first row at its minimum, the row ``argmin``
        picks.
        """
        running = np.minimum(np.minimum.accumulate(F), self.best_f)
        before = np.concatenate(([self.best_f], running[:-1]))
        k = np.flatnonzero(running < before)
        if k.size:
            self._improved_fe.extend((self.nfev + 1 + k).tolist())
            self._improved_f.extend(running[k].tolist())
            self.best_f = float(F[k[-1]])
            self.best_x = X[k[-1]].copy()

    def finish(self, reason: str | None = None, message: str | None = None) -> OptimizeResult:
        if reason is not None:
            self._stop(reason, message or reason)
        if self.stop_reason is None:
            self._stop("converged", "optimiser finished its own schedule")
        self.elapsed = time.perf_counter() - self.t0
        if not len(self.history) or self.history.fe[-1] != self.nfev:
            if self.nfev:
                self.history.append(self.nfev, self.nit, "final", self.best_f)
        return OptimizeResult(
            x=self.best_x.copy(),
            fun=self.best_f,
            nfev=self.nfev,
            nit=self.nit,
            history=self.history,
            improvements={
                "fe": np.asarray(self._improved_fe, dtype=np.int64),
                "best": np.asarray(self._improved_f, dtype=float),
            },
            message=self.stop_message,
            stop=self.stop_reason,
            status=STATUS.get(self.stop_reason, 0)
            if math.isfinite(self.best_f)
            else NO_FINITE_COST,
            success=math.isfinite(self.best_f),
            seed=self.seed,
            optimiser=self.optimiser.name,
            params=self.optimiser.params,
            wall_time=self.elapsed,
        )


#: ``status`` of a result by its ``stop`` reason, in scipy.optimize's manner: 0 the optimiser
#: ended by itself or reached the target, 1 an evaluation or iteration limit, 2 the wall-time
#: limit, 3 the callback; 4 is a run with no finite cost found, whatever stopped it.
STATUS = {"converged": 0, "target": 0, "budget": 1, "iterations": 1, "time": 2, "callback": 3}
NO_FINITE_COST = 4


def _clean_costs(F: np.ndarray) -> np.ndarray:
    """``F`` with NaN and ``-inf`` as ``+inf`` (a new array): neither means anything as a cost."""
    return np.where(np.isnan(F) | (F == -np.inf), np.inf, F)


def _normalise_seed(seed: Any) -> int:
    """An int seed, drawing fresh entropy for None so the run is still reproducible."""
    if isinstance(seed, np.random.SeedSequence):
        return (
            int(seed.entropy) if isinstance(seed.entropy, int) else int(seed.generate_state(1)[0])
        )
    seed = integer(seed, "seed", error=OptimiserError, minimum=0, none_ok=True)
    return int(np.random.SeedSequence().entropy) if seed is None else seed


def _resolve(optimiser: Optimiser | str, params: Mapping[str, Any] | None) -> Optimiser:
    """The instance to run: a registry name is created with ``params``, a class with defaults."""
    if isinstance(optimiser, str):
        return create(optimiser, **(params or {}))
    if params:
        raise OptimiserError("hyper-parameters go with an optimiser name, not an instance")
    if isinstance(optimiser, type) and issubclass(optimiser, Optimiser):
        return optimiser()
    if not isinstance(optimiser, Optimiser):
        raise OptimiserError(f"not an optimiser: {optimiser!r}")
    return optimiser


@checked_keywords
def minimize(
    optimiser: Optimiser | str,
    problem: Problem,
    budget: Budget | int | Mapping[str, Any],
    seed: int | None = None,
    *,
    params: Mapping[str, Any] | None = None,
    callback: Callable[[IterationInfo], Any] | list | None = None,
) -> OptimizeResult:
    """Minimise ``problem`` with ``optimiser`` within ``budget``.

    Parameters
    ----------
    optimiser : Optimiser or str
        An instance, or a registry name (then ``params`` are its hyper-parameters).
    problem : Problem
        Objective, box and shared initial population.
    budget : Budget, int or mapping
        An int is a function-evaluation budget.
    seed : int, optional
        Seed of the run.  The initial population depends only on it; the optimiser's own
        random draws come from a separate stream spawned from it.  ``None`` draws fresh
        entropy and records it in the result.
    params : mapping, optional
        Hyper-parameters when ``optimiser`` is a name.
    callback : callable or list of callables, optional
        Called with an :class:`IterationInfo` after every iteration; returning ``True``
        stops the run.

    Returns
    -------
    scipy.optimize.OptimizeResult
        ``x`` (best point, shape ``(n,)``), ``fun`` (its cost), ``nfev`` (exact FE used),
        ``nit`` (iterations), ``history`` (:class:`History`, one row per iteration),
        ``improvements`` (``{"fe": int array, "best": float array}``, shape ``(K,)`` each:
        every evaluation that lowered the best cost, at its exact FE count, as
        IOHprofiler's on-improvement logger records it), ``message`` and ``stop``
        (``"budget"``, ``"iterations"``, ``"target"``, ``"time"``, ``"callback"`` or
        ``"converged"`` when the optimiser ended its own schedule), ``status`` (an int, as
        scipy's: 0 converged or target reached, 1 an evaluation or iteration limit, 2 the
        wall-time limit, 3 the callback, 4 no finite cost found),
        ``success`` (a finite cost was found), ``seed``, ``optimiser``, ``params`` and
        ``wall_time`` (s).

    Raises
    ------
    UnknownOptimiserError, HyperParameterError, BudgetError, OptimiserError
        For an unknown name, invalid hyper-parameters or budget, or an objective that
        returns the wrong shape.
    """
    opt = _resolve(optimiser, params)
    budget = Budget.coerce(budget)
    callbacks = (
        [] if callback is None else list(callback) if isinstance(callback, list) else [callback]
    )
    run = _Run(opt, problem, budget, seed, callbacks)
    generator = opt.search(run.space, run.rng)
    try:
        X = next(generator)
        while True:
            X = run.check_population(X)
            full = X.shape[0]
            X = problem.from_unit(run.truncate(X))
            F = run.evaluate(X)
            run.absorb(X, F, full)
            if run.stop_reason is not None:
                break
            X = generator.send(F)
    except (_StopRun, StopIteration):
        pass
    finally:
        generator.close()
    return run.finish()


class AskTell:
    """Ask/tell interface to any optimiser.

    Parameters
    ----------
    optimiser : Optimiser or str
        An instance or a registry name.
    problem : Problem
        Only its box, ``x0`` and initial population are used: the caller evaluates the
        points :meth:`ask` returns, which are in the problem's box.
    budget : Budget, int or mapping, optional
        Stop rules; default: no FE limit (``max_time`` of one year).
    seed : int, optional
        As in :func:`minimize`.
    params : mapping, optional
        Hyper-parameters when ``optimiser`` is a name.

    Examples
    --------
    >>> import numpy as np
    >>> problem = Problem(lambda X: (X**2).sum(1), -np.ones(3), np.ones(3))
    >>> at = AskTell("random-search", problem, budget=200, seed=1)  # doctest: +SKIP
    >>> while not at.done:  # doctest: +SKIP
    ...     X = at.ask()
    ...     at.tell((X**2).sum(1))
    """

    def __init__(
        self,
        optimiser: Optimiser | str,
        problem: Problem,
        budget: Budget | int | Mapping[str, Any] | None = None,
        seed: int | None = None,
        *,
        params: Mapping[str, Any] | None = None,
    ) -> None:
        opt = _resolve(optimiser, params)
        budget = Budget(max_time=3.15e7) if budget is None else Budget.coerce(budget)
        self._run = _Run(opt, problem, budget, seed, [])
        self._generator = opt.search(self._run.space, self._run.rng)
        self._pending: np.ndarray | None = None
        self._full = 0
        self._next: np.ndarray | None = None
        self._started = False
        self.done = False

    def ask(self) -> np.ndarray:
        """The next population to evaluate.

        Asking again before :meth:`tell` returns the same population.

        Returns
        -------
        ndarray, shape (P, n)
            Points in the problem's box (original units), truncated so that the FE budget is
            not exceeded.

        Raises
        ------
        OptimiserError
            If the run has finished (``done``) or the optimiser ended its schedule.
        """
        if self.done:
            raise OptimiserError("the run has finished; call result()")
        if self._pending is not None:
            return self._pending.copy()
        try:
            X = next(self._generator) if not self._started else self._next
        except StopIteration:
            self.done = True
            raise OptimiserError("the optimiser finished its schedule; call result()") from None
        self._started = True
        X = self._run.check_population(X)
        self._full = X.shape[0]
        self._pending = self._run.problem.from_unit(self._run.truncate(X))
        return self._pending.copy()

    def tell(self, F: Any) -> None:
        """Report the costs of the last asked population.

        Parameters
        ----------
        F : array_like, shape (P,)
            Cost of each row of the last :meth:`ask`, in order; NaN and ``-inf`` count as
            ``+inf``.

        Raises
        ------
        OptimiserError
            If no population is pending or ``F`` does not hold P values.
        """
        if self._pending is None:
            raise OptimiserError("tell() without a pending ask()")
        X = self._pending
        F = np.asarray(F, dtype=float).reshape(-1)
        if F.shape != (X.shape[0],):
            raise OptimiserError(f"tell() needs {X.shape[0]} costs, got {F.size}")
        F = _clean_costs(F)
        self._pending = None
        run = self._run
        try:
            run.absorb(X, F, self._full)
            if run.stop_reason is not None:
                self.done = True
                return
            self._next = self._generator.send(F)
        except (_StopRun, StopIteration):
            self.done = True

    def result(self) -> OptimizeResult:
        """End the run and return its result (as :func:`minimize` returns it).

        The optimiser is closed and ``done`` becomes True: no further :meth:`ask`.

        Returns
        -------
        OptimizeResult
            Best point and cost told so far, FE count, history and stop reason.
        """
        self._generator.close()
        self.done = True
        return self._run.finish()

    @property
    def nfev(self) -> int:
        """Function evaluations told so far."""
        return self._run.nfev

    @property
    def best(self) -> tuple[np.ndarray, float]:
        """Best point and cost told so far."""
        return self._run.best_x.copy(), self._run.best_f
