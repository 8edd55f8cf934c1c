"""Test objectives and wrappers shared by the optimiser test modules.

Every function takes a population ``X`` of shape ``(P, n)`` and returns ``(P,)``.
"""

from __future__ import annotations

import numpy as np

from flexid.optimisers import Problem


def shifted_sphere(shift: np.ndarray):
    """Sphere with its minimum 0 at ``shift``."""

    def sphere(X):
        return ((X - shift) ** 2).sum(axis=1)

    return sphere


def shifted_rastrigin(shift: np.ndarray):
    """Rastrigin with its global minimum 0 at ``shift``."""

    def rastrigin(X):
        Z = X - shift
        return 10 * Z.shape[1] + (Z**2 - 10 * np.cos(2 * np.pi * Z)).sum(axis=1)

    return rastrigin


N = 10  # the dimension of the optimiser tests' problems


def shifted_problems(extent: float):
    """The optimiser tests' ``N``-D sphere and Rastrigin with their minima 0 at ``shift``.

    Returns ``(shift, sphere, rastrigin)``, ``shift = linspace(-extent, extent, N)``.
    """
    shift = np.linspace(-extent, extent, N)
    return shift, shifted_sphere(shift), shifted_rastrigin(shift)


def flat(X):
    """Zero everywhere: only an optimiser's own dynamics move its points."""
    return np.zeros(X.shape[0])


def rosenbrock(X):
    return (100 * (X[:, 1:] - X[:, :-1] ** 2) ** 2 + (1 - X[:, :-1]) ** 2).sum(axis=1)


class Recorder:
    """Objective wrapper that counts rows and keeps every batch."""

    def __init__(self, f):
        self.f, self.rows, self.batches = f, 0, []

    def __call__(self, X):
        self.rows += X.shape[0]
        self.batches.append(np.array(X, copy=True))
        return self.f(X)

    @property
    def points(self) -> np.ndarray:
        """Every row evaluated, in order, shape ``(rows, n)``."""
        return np.concatenate(self.batches)

    @property
    def sizes(self) -> list[int]:
        """The number of rows of each batch, in order."""
        return [len(X) for X in self.batches]


def box(f, n: int = N, half: float = 2.0) -> Problem:
    """``f`` on the box ``[-half, half]^n``."""
    return Problem(f, -half * np.ones(n), half * np.ones(n))


class FakeSpace:
    """Minimal stand-in for SearchSpace so a test can drive ``search`` with its own rng."""

    def __init__(self, X0, lower, upper):
        self.X0, self.lower, self.upper, self.dim = X0, lower, upper, X0.shape[1]
        self.phases = []

    def initial_population(self, m):
        return self.X0[:m].copy()

    def uniform(self, k, rng):
        return self.lower + (self.upper - self.lower) * rng.random((int(k), self.dim))

    def clip(self, X):
        return np.clip(X, self.lower, self.upper)

    def end_iteration(self, phase):
        self.phases.append(phase)


def drive(opt, space, f, rng) -> list[tuple[np.ndarray, np.ndarray]]:
    """Run ``opt.search`` to the end of its own schedule; return every batch and its costs."""
    gen = opt.search(space, rng)
    X, out = next(gen), []
    try:
        while True:
            F = f(X)
            out.append((np.array(X, copy=True), F))
            X = gen.send(F)
    except StopIteration:
        pass
    return out
