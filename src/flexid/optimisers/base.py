"""Optimiser framework: problems, budgets, hyper-parameters, the driver and its results.

An optimiser is a class whose :meth:`Optimiser.search` is a *generator*: it yields
populations ``X`` of shape ``(P, n)`` to evaluate and receives their costs ``F`` of shape
``(P,)``.  The search reads like the algorithm's paper, while the driver owns everything
that must be the same for every algorithm:

* the **function-evaluation (FE) count**: every row passed to the objective is one FE; the
  last batch is truncated so a run stops *exactly* at its budget;
* **cost hygiene**: NaN and infinite costs are treated as ``+inf``;
* **best-so-far** tracking, **history** (FE, iteration, phase, best cost), timing,
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
from collections.abc import Callable, Generator, Iterator, Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from scipy.optimize import OptimizeResult

from ..errors import BudgetError, HyperParameterError, OptimiserError

__all__ = [
    "AskTell",
    "Budget",
    "History",
    "IterationInfo",
    "Optimiser",
    "Param",
    "Problem",
    "SearchSpace",
    "minimize",
]

Objective = Callable[[np.ndarray], np.ndarray]
SearchGenerator = Generator[np.ndarray, np.ndarray, Any]


# =============================================================================== budget
@dataclass(frozen=True)
class Budget:
    """When a run stops: whichever limit is reached first.

    Parameters
    ----------
    max_fe : int, optional
        Function evaluations (rows passed to the objective), the primary budget.  The
        last batch is truncated so exactly ``max_fe`` rows are evaluated.
    max_iter : int, optional
        Iterations (as the optimiser defines them; the initial evaluation is iteration 0).
    target : float, optional
        Stop as soon as the best cost is ``<= target``.
    max_time : float, optional
        Wall-clock seconds, checked after each batch.

    Raises
    ------
    BudgetError
        If no limit that guarantees termination (``max_fe``, ``max_iter`` or ``max_time``)
        is given, or a limit is not positive.
    """

    max_fe: int | None = None
    max_iter: int | None = None
    target: float | None = None
    max_time: float | None = None

    def __post_init__(self) -> None:
        for name in ("max_fe", "max_iter"):
            value = getattr(self, name)
            if value is not None:
                if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
                    raise BudgetError(f"{name} must be a positive integer, got {value!r}")
                if value < 1:
                    raise BudgetError(f"{name} must be a positive integer, got {value!r}")
                object.__setattr__(self, name, int(value))
        if self.max_time is not None and not (
            isinstance(self.max_time, (int, float)) and self.max_time > 0
        ):
            raise BudgetError(
                f"max_time must be a positive number of seconds, got {self.max_time!r}"
            )
        if self.target is not None and not (
            isinstance(self.target, (int, float)) and not math.isnan(self.target)
        ):
            raise BudgetError(f"target must be a number, got {self.target!r}")
        if self.max_fe is None and self.max_iter is None and self.max_time is None:
            raise BudgetError("a budget needs max_fe, max_iter or max_time")

    @classmethod
    def coerce(cls, budget: Budget | int | Mapping[str, Any] | None) -> Budget:
        """Accept a :class:`Budget`, an FE count, or a mapping of its fields."""
        if isinstance(budget, Budget):
            return budget
        if budget is None:
            raise BudgetError(
                "a budget is required (for example budget=10_000 function evaluations)"
            )
        if isinstance(budget, Mapping):
            try:
                return cls(**budget)
            except TypeError as exc:
                raise BudgetError(f"invalid budget fields: {exc}") from None
        return cls(max_fe=budget)


# =============================================================================== problem
class Problem:
    """A batched objective over a box, with the initial population every optimiser shares.

    Parameters
    ----------
    objective : callable
        ``objective(X) -> F`` with ``X`` of shape ``(P, n)`` and ``F`` of shape ``(P,)``.
        ``P`` may be any positive size; optimisers may evaluate subsets of a population.
    lower, upper : array_like, shape (n,)
        The box.  It defines the initial population (uniform in the box), the
        re-initialisation of some algorithms, and clipping where an optimiser clips.
    x0 : array_like, shape (n,), optional
        Start point for single-point methods; default: the first initial point.
    name : str, optional
        Free label recorded in results.
    sampler : callable, optional
        ``sampler(size, rng) -> X`` of shape ``(size, n)`` inside the box: the initial
        population drawn from a ``numpy.random.Generator`` (default: uniform in the box).  It
        must draw row by row, so that a smaller population is the first rows of a larger one.

    Raises
    ------
    OptimiserError
        If the bounds are not finite 1-D arrays of equal length with ``lower < upper``.
    """

    def __init__(
        self,
        objective: Objective,
        lower: Any,
        upper: Any,
        *,
        x0: Any = None,
        name: str = "",
        sampler: Callable[[int, np.random.Generator], np.ndarray] | None = None,
    ) -> None:
        if not callable(objective):
            raise OptimiserError("objective must be callable: objective(X[(P, n)]) -> F[(P,)]")
        lower = np.array(lower, dtype=float).reshape(-1)
        upper = np.array(upper, dtype=float).reshape(-1)
        if lower.shape != upper.shape or lower.size == 0:
            raise OptimiserError(
                f"lower and upper bounds must have the same non-zero length, got "
                f"{lower.size} and {upper.size}"
            )
        if not (np.all(np.isfinite(lower)) and np.all(np.isfinite(upper))):
            raise OptimiserError("bounds must be finite")
        bad = np.flatnonzero(lower >= upper)
        if bad.size:
            i = int(bad[0])
            raise OptimiserError(
                f"lower bound must be below upper bound; coordinate {i}: "
                f"{lower[i]!r} >= {upper[i]!r}"
            )
        if x0 is not None:
            x0 = np.array(x0, dtype=float).reshape(-1)
            if x0.shape != lower.shape or not np.all(np.isfinite(x0)):
                raise OptimiserError(f"x0 must be a finite vector of length {lower.size}")
        lower.setflags(write=False)
        upper.setflags(write=False)
        self.objective = objective
        self.lower = lower
        self.upper = upper
        if sampler is not None and not callable(sampler):
            raise OptimiserError("sampler must be callable: sampler(size, rng) -> X[(size, n)]")
        self.x0 = x0
        self.name = name
        self.sampler = sampler
        self.width = upper - lower
        self.width.setflags(write=False)

    @property
    def dim(self) -> int:
        """Number of decision variables ``n``."""
        return self.lower.size

    def initial_population(self, size: int, seed: Any = None) -> np.ndarray:
        """``size`` initial points in the box, shape ``(size, n)``.

        Uniform in the box unless the problem has a ``sampler``.  The points depend only on
        the problem and ``seed`` (an int or a ``numpy.random.SeedSequence``), and the first
        ``k`` rows of a population of size ``m >= k`` equal the population of size ``k``.
        """
        return self.from_unit(self.initial_unit(size, seed))

    def initial_unit(self, size: int, seed: Any = None) -> np.ndarray:
        """The initial population in the unit box, shape ``(size, n)``."""
        rng = np.random.default_rng(seed)
        if self.sampler is None:
            return rng.random((int(size), self.dim))
        X = np.asarray(self.sampler(int(size), rng), dtype=float)
        if X.shape != (int(size), self.dim) or not np.all(np.isfinite(X)):
            raise OptimiserError(
                f"sampler returned shape {X.shape} (or non-finite points) for {size} points; "
                f"expected ({size}, {self.dim})"
            )
        return np.clip((X - self.lower) / self.width, 0.0, 1.0)

    def from_unit(self, Z: np.ndarray) -> np.ndarray:
        """Points ``lower + Z (upper - lower)`` of the box for points ``Z`` of the unit box."""
        return self.lower + Z * self.width

    def to_unit(self, X: np.ndarray) -> np.ndarray:
        """Points of the unit box for points ``X`` of the box (the inverse of ``from_unit``)."""
        return (np.asarray(X, dtype=float) - self.lower) / self.width

    def __repr__(self) -> str:
        label = f"{self.name!r}, " if self.name else ""
        return f"Problem({label}n={self.dim})"


_UNIT_CACHE: dict[int, tuple[np.ndarray, np.ndarray]] = {}


def _unit_box(n: int) -> tuple[np.ndarray, np.ndarray]:
    if n not in _UNIT_CACHE:
        lower, upper = np.zeros(n), np.ones(n)
        lower.setflags(write=False)
        upper.setflags(write=False)
        _UNIT_CACHE[n] = (lower, upper)
    return _UNIT_CACHE[n]


class SearchSpace:
    """What an optimiser's :meth:`~Optimiser.search` sees of a problem during one run.

    It never exposes the objective: optimisers only *yield* points to evaluate.  The space
    is the unit box ``[0, 1]^n``; the driver maps the yielded points to the problem's box.

    Attributes
    ----------
    lower, upper : ndarray, shape (n,)
        The unit box (zeros and ones).
    dim : int
        ``n``.
    x0 : ndarray, shape (n,)
        The start point for single-point methods (in the unit box).
    """

    def __init__(self, problem: Problem, init_seed: np.random.SeedSequence, run: _Run) -> None:
        self._problem = problem
        self._init_seed = init_seed
        self._run = run
        self.lower, self.upper = _unit_box(problem.dim)
        self.dim = problem.dim
        self.x0 = (
            np.clip(problem.to_unit(problem.x0), 0.0, 1.0)
            if problem.x0 is not None
            else self.initial_population(1)[0]
        )

    def initial_population(self, size: int) -> np.ndarray:
        """The shared initial population of this run in the unit box, shape ``(size, n)``."""
        if isinstance(size, bool) or not isinstance(size, (int, np.integer)) or size < 1:
            raise OptimiserError(f"population size must be a positive integer, got {size!r}")
        return self._problem.initial_unit(size, self._init_seed)

    def uniform(self, size: int, rng: np.random.Generator) -> np.ndarray:
        """``size`` fresh points uniform in the box drawn from ``rng``, shape ``(size, n)``."""
        return rng.random((int(size), self.dim))

    def clip(self, X: np.ndarray) -> np.ndarray:
        """``X`` clipped to the box (a new array)."""
        return np.clip(X, 0.0, 1.0)

    def end_iteration(self, phase: str) -> None:
        """Mark the end of one iteration of the algorithm in phase ``phase``.

        Call it only from optimisers with ``auto_iterations = False``; the driver records
        a history row and checks the iteration, target and time stops.
        """
        self._run.end_iteration(phase)


# ========================================================================= hyper-parameters
_MISSING = object()


class Param:
    """A validated hyper-parameter, declared as a class attribute of an optimiser.

    Parameters
    ----------
    kind : type
        ``int``, ``float``, ``bool`` or ``str``.  An ``int`` parameter refuses floats and
        booleans; a ``float`` parameter accepts ints and refuses booleans, NaN and inf.
    default : object
        The default value (validated like any other).
    doc : str
        One-line description, with units where there are any.
    low, high : float, optional
        Bounds of the allowed range.
    low_open, high_open : bool, optional
        Whether ``low``/``high`` themselves are excluded (default: included).
    choices : sequence, optional
        The allowed values (for ``str`` parameters).
    none_ok : bool, optional
        Whether ``None`` is allowed (e.g. "no limit").

    Examples
    --------
    >>> class Toy(Optimiser):
    ...     name = "toy"
    ...     points = Param(int, 20, "population size", low=2)
    >>> Toy(points=30).points
    30
    """

    def __init__(
        self,
        kind: type,
        default: Any,
        doc: str = "",
        *,
        low: float | None = None,
        high: float | None = None,
        low_open: bool = False,
        high_open: bool = False,
        choices: tuple | list | None = None,
        none_ok: bool = False,
    ) -> None:
        if kind not in (int, float, bool, str):
            raise TypeError(f"Param kind must be int, float, bool or str, not {kind!r}")
        self.kind = kind
        self.doc = doc
        self.low = low
        self.high = high
        self.low_open = low_open
        self.high_open = high_open
        self.choices = tuple(choices) if choices is not None else None
        self.none_ok = none_ok
        self.name = "?"
        self.owner = "?"
        self.default = default

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name
        self.owner = getattr(owner, "name", owner.__name__)
        self.default = self.validate(self.default)

    def __get__(self, instance: Any, owner: type | None = None) -> Any:
        if instance is None:
            return self
        return instance._params[self.name]

    def __set__(self, instance: Any, value: Any) -> None:
        raise AttributeError(
            f"hyper-parameter {self.name!r} is fixed at construction; create a new optimiser"
        )

    def range_text(self) -> str:
        """The allowed values in interval notation, e.g. ``(0, 1]``."""
        if self.choices is not None:
            return "one of " + ", ".join(repr(c) for c in self.choices)
        if self.low is None and self.high is None:
            return "any"
        left = ("(" if self.low_open else "[") + (
            f"{self.low:g}" if self.low is not None else "-inf"
        )
        right = (f"{self.high:g}" if self.high is not None else "inf") + (
            ")" if self.high_open or self.high is None else "]"
        )
        if self.low is None:
            left = "(-inf"
        return f"{left}, {right}"

    def validate(self, value: Any, owner: str | None = None) -> Any:
        """Return ``value`` converted to the parameter's type, or raise HyperParameterError.

        ``owner`` is the optimiser name used in the message (default: the declaring class).
        """
        where = f"{owner or self.owner}: hyper-parameter {self.name!r}"
        if self.none_ok and isinstance(value, str) and value.strip().lower() in ("none", "null"):
            value = None  # TOML has no null: "none" stands for None in configuration files
        if value is None:
            if self.none_ok:
                return None
            raise HyperParameterError(f"{where} must not be None")
        kind = self.kind
        if kind is bool:
            if isinstance(value, (bool, np.bool_)):
                return bool(value)
            raise HyperParameterError(f"{where} must be true or false, got {value!r}")
        if isinstance(value, (bool, np.bool_)):
            raise HyperParameterError(f"{where} must be {kind.__name__}, got the boolean {value!r}")
        if kind is int:
            if isinstance(value, (int, np.integer)):
                value = int(value)
            else:
                raise HyperParameterError(
                    f"{where} must be an integer, got {type(value).__name__} {value!r}"
                )
        elif kind is float:
            if not isinstance(value, (int, float, np.integer, np.floating)):
                raise HyperParameterError(
                    f"{where} must be a number, got {type(value).__name__} {value!r}"
                )
            value = float(value)
            if not math.isfinite(value):
                raise HyperParameterError(f"{where} must be finite, got {value!r}")
        elif kind is str and not isinstance(value, str):
            raise HyperParameterError(f"{where} must be a string, got {value!r}")
        if self.choices is not None and value not in self.choices:
            raise HyperParameterError(f"{where} must be {self.range_text()}, got {value!r}")
        if kind in (int, float):
            too_low = self.low is not None and (
                value < self.low or (self.low_open and value == self.low)
            )
            too_high = self.high is not None and (
                value > self.high or (self.high_open and value == self.high)
            )
            if too_low or too_high:
                raise HyperParameterError(f"{where} must lie in {self.range_text()}, got {value!r}")
        return value

    def describe(self) -> dict[str, Any]:
        """A plain description: type, default, range, doc."""
        return {
            "type": self.kind.__name__ + (" or None" if self.none_ok else ""),
            "default": self.default,
            "range": self.range_text(),
            "doc": self.doc,
        }


class Optimiser:
    """Base class of every optimiser.

    Subclasses set ``name``, declare hyper-parameters as :class:`Param` class attributes
    and implement :meth:`search` as a generator.  Construction validates the
    hyper-parameters: an unknown name, a wrong type or an out-of-range value raises
    :class:`~flexid.errors.HyperParameterError`; :meth:`check` may add cross-parameter
    rules.

    Class attributes
    ----------------
    name : str
        Registry name.
    auto_iterations : bool
        If True (default), every yielded batch after the first is one iteration.  If False,
        the search calls ``space.end_iteration(phase)`` itself (needed when an iteration
        evaluates several batches, as the swims of bacterial foraging do); the first batch
        is always iteration 0, phase ``"init"``.
    reference : str
        Where the algorithm comes from.
    """

    name: ClassVar[str] = ""
    auto_iterations: ClassVar[bool] = True
    reference: ClassVar[str] = ""

    def __init__(self, **params: Any) -> None:
        spec = self.hyperparameters()
        unknown = sorted(set(params) - set(spec))
        if unknown:
            raise HyperParameterError(
                f"{self.name or type(self).__name__}: unknown hyper-parameter(s) "
                f"{', '.join(map(repr, unknown))}; valid: {', '.join(spec) or 'none'}"
            )
        values = {}
        for key, param in spec.items():
            values[key] = (
                param.validate(params[key], owner=self.name or None)
                if key in params
                else param.default
            )
        self._params = values
        self.check()

    @classmethod
    def hyperparameters(cls) -> dict[str, Param]:
        """The declared hyper-parameters, in declaration order (base classes first)."""
        spec: dict[str, Param] = {}
        for klass in reversed(cls.__mro__):
            for key, value in vars(klass).items():
                if isinstance(value, Param):
                    spec[key] = value
        return spec

    @property
    def params(self) -> dict[str, Any]:
        """The hyper-parameter values of this instance (a copy)."""
        return dict(self._params)

    def check(self) -> None:
        """Cross-parameter validation; raise HyperParameterError.  Default: nothing."""

    def search(self, space: SearchSpace, rng: np.random.Generator) -> SearchGenerator:
        """The algorithm: ``F = yield X`` for every population to evaluate.

        Parameters
        ----------
        space : SearchSpace
            Box, shared initial population, clipping, iteration marks.
        rng : numpy.random.Generator
            The run's only source of randomness.
        """
        raise NotImplementedError

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self._params.items())
        return f"{type(self).__name__}({args})"


# =============================================================================== history
class History:
    """Best cost against function evaluations, one row per iteration.

    Attributes
    ----------
    fe : ndarray of int, shape (T,)
        FE used at the end of each iteration (cumulative).
    iteration : ndarray of int, shape (T,)
        Iteration index (0 = initial evaluation).
    phase : list of str, length T
        Phase name (``"init"``, ``"chemotaxis"``, ``"spiral"``...).
    best : ndarray of float, shape (T,)
        Best cost found so far (non-increasing).
    """

    def __init__(self) -> None:
        self._fe: list[int] = []
        self._it: list[int] = []
        self._phase: list[str] = []
        self._best: list[float] = []

    def append(self, fe: int, iteration: int, phase: str, best: float) -> None:
        self._fe.append(fe)
        self._it.append(iteration)
        self._phase.append(phase)
        self._best.append(best)

    @property
    def fe(self) -> np.ndarray:
        return np.asarray(self._fe, dtype=np.int64)

    @property
    def iteration(self) -> np.ndarray:
        return np.asarray(self._it, dtype=np.int64)

    @property
    def phase(self) -> list[str]:
        return list(self._phase)

    @property
    def best(self) -> np.ndarray:
        return np.asarray(self._best, dtype=float)

    def __len__(self) -> int:
        return len(self._fe)

    def best_at(self, fe: Any) -> np.ndarray:
        """Best cost after ``fe`` evaluations (step function; ``inf`` before the first row)."""
        fe = np.asarray(fe)
        idx = np.searchsorted(self.fe, fe, side="right") - 1
        best = np.concatenate([[np.inf], self.best])
        return best[idx + 1]

    def fe_to_reach(self, target: float) -> int | None:
        """Fewest FE after which the best cost is ``<= target`` (row resolution), or None."""
        hits = np.flatnonzero(self.best <= target)
        return int(self.fe[hits[0]]) if hits.size else None

    def to_dict(self) -> dict[str, list]:
        """Plain lists, for JSON."""
        return {
            "fe": list(self._fe),
            "iteration": list(self._it),
            "phase": list(self._phase),
            "best": [float(b) for b in self._best],
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, list]) -> History:
        history = cls()
        for row in zip(data["fe"], data["iteration"], data["phase"], data["best"]):
            history.append(int(row[0]), int(row[1]), str(row[2]), float(row[3]))
        return history

    def __repr__(self) -> str:
        if not self._fe:
            return "History(empty)"
        return f"History({len(self)} rows, fe={self._fe[-1]}, best={self._best[-1]:.6g})"


@dataclass(frozen=True)
class IterationInfo:
    """What a callback receives after each iteration.

    A callback returning ``True`` stops the run (message ``"stopped by callback"``).
    """

    fe: int
    iteration: int
    phase: str
    best: float
    x_best: np.ndarray
    elapsed: float
    max_fe: int | None


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
        self.stop_message: str | None = None
        self.stop_reason: str | None = None
        self.t0 = time.perf_counter()
        self.elapsed = 0.0
        self._generator: Iterator | None = None
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
        F = np.where(np.isnan(F), np.inf, F)
        F[F == -np.inf] = np.inf  # -inf is as meaningless as NaN for a cost
        return F

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

    def absorb(self, X: np.ndarray, F: np.ndarray, full_size: int) -> np.ndarray:
        """Count, track the best, record an automatic iteration, and check FE/target stops."""
        self.nfev += X.shape[0]
        self.batches += 1
        if F.size:
            i = int(np.argmin(F))
            if F[i] < self.best_f:
                self.best_f = float(F[i])
                self.best_x = X[i].copy()
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
        return F

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
            message=self.stop_message,
            stop=self.stop_reason,
            success=math.isfinite(self.best_f),
            seed=self.seed,
            optimiser=self.optimiser.name,
            params=self.optimiser.params,
            wall_time=self.elapsed,
        )


def _normalise_seed(seed: Any) -> int:
    """An int seed, drawing fresh entropy for None so the run is still reproducible."""
    if seed is None:
        return int(np.random.SeedSequence().entropy)
    if isinstance(seed, np.random.SeedSequence):
        return (
            int(seed.entropy) if isinstance(seed.entropy, int) else int(seed.generate_state(1)[0])
        )
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise OptimiserError(f"seed must be a non-negative integer or None, got {seed!r}")
    return int(seed)


def _resolve(optimiser: Optimiser | str, params: Mapping[str, Any] | None) -> Optimiser:
    if isinstance(optimiser, str):
        from .registry import create

        return create(optimiser, **(params or {}))
    if params:
        raise OptimiserError("hyper-parameters go with an optimiser name, not an instance")
    if isinstance(optimiser, type) and issubclass(optimiser, Optimiser):
        return optimiser()
    if not isinstance(optimiser, Optimiser):
        raise OptimiserError(f"not an optimiser: {optimiser!r}")
    return optimiser


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
        ``nit`` (iterations), ``history`` (:class:`History`), ``message`` and ``stop``
        (``"budget"``, ``"iterations"``, ``"target"``, ``"time"``, ``"callback"`` or
        ``"converged"`` when the optimiser ended its own schedule), ``success`` (a finite
        cost was found), ``seed``, ``optimiser``, ``params`` and ``wall_time`` (s).

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
            F = run.absorb(X, run.evaluate(X), full)
            if run.stop_reason is not None:
                break
            X = generator.send(F)
    except _StopRun:
        pass
    except StopIteration:
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
        """The next population to evaluate, shape ``(P, n)`` (truncated at the FE budget)."""
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
        """Report the costs of the last asked population, shape ``(P,)``."""
        if self._pending is None:
            raise OptimiserError("tell() without a pending ask()")
        X = self._pending
        F = np.asarray(F, dtype=float).reshape(-1)
        if F.shape != (X.shape[0],):
            raise OptimiserError(f"tell() needs {X.shape[0]} costs, got {F.size}")
        F = np.where(np.isnan(F) | (F == -np.inf), np.inf, F)
        self._pending = None
        run = self._run
        try:
            run.absorb(X, F, self._full)
            if run.stop_reason is not None:
                self.done = True
                return
            self._next = self._generator.send(F)
        except _StopRun:
            self.done = True
        except StopIteration:
            self.done = True

    def result(self) -> OptimizeResult:
        """The result so far (as :func:`minimize` returns it)."""
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
