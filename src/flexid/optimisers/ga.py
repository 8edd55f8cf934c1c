"""Real-coded genetic algorithm: tournament selection, SBX crossover, polynomial mutation."""

from __future__ import annotations

import numpy as np

from ._params import Optimiser, Param, SearchGenerator
from ._problem import SearchSpace
from .registry import register

__all__ = ["GeneticAlgorithm"]


@register
class GeneticAlgorithm(Optimiser):
    """Generational real-coded GA with elitism (Deb & Agrawal's SBX and polynomial mutation).

    Each generation (vectorised over the population): binary tournaments pick parents;
    pairs are recombined by simulated binary crossover (SBX, spread factor ``beta`` from
    ``u ~ U(0, 1)``: ``(2u)^(1/(eta_c+1))`` or ``(1/(2(1-u)))^(1/(eta_c+1))``, children
    ``0.5((1 +/- beta) p1 + (1 -/+ beta) p2)``, each coordinate swapped with probability
    1/2); genes are mutated by polynomial mutation (``delta = (2u)^(1/(eta_m+1)) - 1`` or
    ``1 - (2(1-u))^(1/(eta_m+1))`` times the box width); the ``elites`` best parents survive
    unchanged into the next population.

    Parameters
    ----------
    population : int
        Population size, default 50; a generation evaluates ``population - elites``
        children.
    p_crossover : float
        Probability that a pair is recombined (default 0.9; else children copy parents).
    eta_c : float
        SBX distribution index (default 15; larger keeps children closer to parents).
    p_mutation : float or None
        Mutation probability per gene; None means ``1/n``.
    eta_m : float
        Polynomial mutation index (default 20).
    elites : int
        Best parents copied unchanged (default 2; must be < population).

    Notes
    -----
    Bounds: children are clipped to the box after crossover and mutation.  This is the
    simple bounded form; Deb's bounded SBX variant that rescales the spread near the
    bounds is not used.  One generation is one iteration.
    """

    name = "ga"
    reference = "Deb & Agrawal, Complex Systems 9:115-148, 1995; Deb, 2001"
    bounds = "clip"
    bounds_note = (
        "Children are clipped to the box after crossover and mutation."
    )
    stays_in_box = True
    population = Param(int, 50, "population size (even)", low=4)
    p_crossover = Param(float, 0.9, "crossover probability per pair", low=0.0, high=1.0)
    eta_c = Param(float, 15.0, "SBX distribution index", low=0.0)
    p_mutation = Param(float, None, "mutation probability per gene (None: 1/n)", low=0.0,
                       high=1.0, none_ok=True)
    eta_m = Param(float, 20.0, "polynomial mutation distribution index", low=0.0)
    elites = Param(int, 2, "best parents kept each generation", low=0)

    def check(self) -> None:
        from ..errors import HyperParameterError

        if self.elites >= self.population:
            raise HyperParameterError(
                f"ga: elites ({self.elites}) must be smaller than population ({self.population})"
            )

    def search(self, space: SearchSpace, rng: np.random.Generator) -> SearchGenerator:
        N, n = self.population, space.dim
        lo, hi = space.lower, space.upper
        width = hi - lo
        pm = self.p_mutation if self.p_mutation is not None else 1.0 / n
        X = space.initial_population(N)
        F = yield X
        n_child = N - self.elites
        n_pairs = -(-n_child // 2)
        while True:
            # binary tournaments
            a = rng.integers(0, N, (2 * n_pairs, 2))
            winners = np.where(F[a[:, 0]] <= F[a[:, 1]], a[:, 0], a[:, 1])
            p1, p2 = X[winners[:n_pairs]], X[winners[n_pairs:]]
            # SBX
            u = rng.random((n_pairs, n))
            beta = np.where(
                u <= 0.5,
                (2 * u) ** (1 / (self.eta_c + 1)),
                (1 / (2 * (1 - u))) ** (1 / (self.eta_c + 1)),
            )
            pair = rng.random(n_pairs) < self.p_crossover
            do = pair[:, None] & (rng.random((n_pairs, n)) < 0.5)
            beta = np.where(do, beta, 1.0)
            c1 = 0.5 * ((1 + beta) * p1 + (1 - beta) * p2)
            c2 = 0.5 * ((1 - beta) * p1 + (1 + beta) * p2)
            C = np.concatenate([c1, c2])[:n_child]
            # polynomial mutation
            mut = rng.random(C.shape) < pm
            u = rng.random(C.shape)
            delta = np.where(
                u < 0.5,
                (2 * u) ** (1 / (self.eta_m + 1)) - 1,
                1 - (2 * (1 - u)) ** (1 / (self.eta_m + 1)),
            )
            C = np.where(mut, C + delta * width, C)
            C = space.clip(C)
            FC = yield C
            order = np.argsort(F, kind="stable")[: self.elites]
            X = np.concatenate([X[order], C])
            F = np.concatenate([F[order], FC])
