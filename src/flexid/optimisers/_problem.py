"""The problem (a batched objective over a box) and the search space an optimiser sees.

An optimiser searches the unit box ``[0, 1]^n``; :class:`Problem` maps its points to the
problem's box, ``x = lower + z (upper - lower)``, and owns the initial population every
optimiser shares for a seed.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

import numpy as np

from .._validate import positive_int
from ..errors import OptimiserError
from ._budget import Budget

__all__ = ["Objective", "Problem", "SearchSpace"]


class _Run(Protocol):
    """What a search space needs of the driver's run (:mod:`flexid.optimisers._driver`)."""

    budget: Budget

    def end_iteration(self, phase: str) -> None: ...

Objective = Callable[[np.ndarray], np.ndarray]


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
        """``size`` initial points in the box.

        Uniform in the box unless the problem has a ``sampler``.  The points depend only on
        the problem and ``seed``, and the first ``k`` rows of a population of size
        ``m >= k`` equal the population of size ``k``.

        Parameters
        ----------
        size : int
            Number of points P.
        seed : int or numpy.random.SeedSequence, optional
            Seed of ``numpy.random.default_rng``; None draws fresh entropy (not
            reproducible).

        Returns
        -------
        ndarray, shape (P, n)
            The points, in the problem's box (original units).
        """
        return self.from_unit(self.initial_unit(size, seed))

    def initial_unit(self, size: int, seed: Any = None) -> np.ndarray:
        """The initial population in the unit box.

        Parameters
        ----------
        size : int
            Number of points P.
        seed : int or numpy.random.SeedSequence, optional
            Seed of ``numpy.random.default_rng``; None draws fresh entropy (not
            reproducible).

        Returns
        -------
        ndarray, shape (P, n)
            Points in ``[0, 1]^n``; :meth:`from_unit` maps them to :meth:`initial_population`.

        Raises
        ------
        OptimiserError
            If the problem's ``sampler`` returns the wrong shape or non-finite points.
        """
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
        """Map points of the unit box to the problem's box.

        Parameters
        ----------
        Z : ndarray, shape (P, n) or (n,)
            Points of the unit box ``[0, 1]^n`` (not clipped: points outside map outside).

        Returns
        -------
        ndarray, shape (P, n) or (n,)
            ``lower + Z (upper - lower)``, in the problem's units.
        """
        return self.lower + Z * self.width

    def to_unit(self, X: np.ndarray) -> np.ndarray:
        """Map points of the problem's box to the unit box (the inverse of :meth:`from_unit`).

        Parameters
        ----------
        X : array_like, shape (P, n) or (n,)
            Points in the problem's units.

        Returns
        -------
        ndarray, shape (P, n) or (n,)
            ``(X - lower) / (upper - lower)`` (not clipped).
        """
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
    The driver builds it; optimisers receive it in :meth:`~Optimiser.search`.

    Parameters
    ----------
    problem : Problem
        The problem of the run.
    init_seed : numpy.random.SeedSequence
        Seed of the shared initial population.
    run : object
        The driver's run, told of iterations that :meth:`end_iteration` ends.

    Attributes
    ----------
    lower, upper : ndarray, shape (n,)
        The unit box (zeros and ones).
    dim : int
        ``n``.
    x0 : ndarray, shape (n,)
        The start point for single-point methods (in the unit box).
    max_fe : int or None
        The run's function-evaluation budget (``None`` when the run has no FE limit).
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

    @property
    def max_fe(self) -> int | None:
        """The run's function-evaluation budget, ``None`` when the run has no FE limit."""
        return self._run.budget.max_fe

    def initial_population(self, size: int) -> np.ndarray:
        """The shared initial population of this run in the unit box.

        Parameters
        ----------
        size : int
            Number of points P, >= 1.

        Returns
        -------
        ndarray, shape (P, n)
            Points in ``[0, 1]^n``; the same for every optimiser given the run's seed.

        Raises
        ------
        OptimiserError
            If ``size`` is not a positive integer.
        """
        size = positive_int(size, "population size", error=OptimiserError)
        return self._problem.initial_unit(size, self._init_seed)

    def uniform(self, size: int, rng: np.random.Generator) -> np.ndarray:
        """Fresh points uniform in the unit box.

        Parameters
        ----------
        size : int
            Number of points P.
        rng : numpy.random.Generator
            The generator they are drawn from (the optimiser's).

        Returns
        -------
        ndarray, shape (P, n)
            Points in ``[0, 1)^n``.
        """
        return rng.random((int(size), self.dim))

    def clip(self, X: np.ndarray) -> np.ndarray:
        """Clip points to the unit box.

        Parameters
        ----------
        X : ndarray, shape (P, n) or (n,)
            Points of the search space.

        Returns
        -------
        ndarray, shape (P, n) or (n,)
            ``X`` clipped to ``[0, 1]`` (a new array).
        """
        return np.clip(X, 0.0, 1.0)

    def end_iteration(self, phase: str) -> None:
        """Mark the end of one iteration of the algorithm in phase ``phase``.

        Call it only from optimisers with ``auto_iterations = False``; the driver records
        a history row and checks the iteration, target and time stops.

        Parameters
        ----------
        phase : str
            Name of the algorithm's phase, recorded in the history (e.g. ``"chemotaxis"``).
        """
        self._run.end_iteration(phase)
