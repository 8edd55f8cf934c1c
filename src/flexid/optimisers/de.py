"""Differential evolution, DE/rand/1/bin (Storn & Price 1997)."""

from __future__ import annotations

import numpy as np

from ._params import Optimiser, Param, SearchGenerator
from ._problem import SearchSpace
from .registry import register

__all__ = ["DifferentialEvolution"]


@register
class DifferentialEvolution(Optimiser):
    """DE/rand/1/bin with greedy one-to-one selection (Storn & Price 1997).

    For every member ``x_i`` (all at once, vectorised): mutant
    ``v_i = x_r1 + F (x_r2 - x_r3)`` with ``r1, r2, r3`` distinct and different from ``i``;
    binomial crossover ``u_ij = v_ij`` with probability ``CR`` (and for one random ``j``
    always), else ``x_ij``; ``u_i`` replaces ``x_i`` when its cost is not worse.

    Parameters
    ----------
    population : int
        ``NP`` (FE per generation), default 50 (Storn & Price suggest 5n-10n; 50 covers
        the ARX sizes of flexid, n <= 10).
    weight : float
        Differential weight ``F`` in (0, 2], default 0.5.
    crossover : float
        Crossover rate ``CR`` in [0, 1], default 0.9.
    dither : bool
        If True, ``F`` is drawn per member and generation uniformly in ``[weight, 1]``
        (dither, Das et al. 2005), which helps on multimodal functions.  Default False.

    Notes
    -----
    Bounds: a trial coordinate that leaves the box is reset half-way between its parent's
    coordinate and the violated bound (bounce-back), so it stays in the box and keeps
    the search direction.  One generation is one iteration (``population`` FE).
    """

    name = "de"
    reference = "Storn & Price, J. Global Optimization 11:341-359, 1997"
    bounds = "midpoint repair"
    bounds_note = (
        "A trial coordinate outside the box is set half-way between its "
        "parent's coordinate and the violated bound (bounce-back)."
    )
    stays_in_box = True
    population = Param(int, 50, "population size NP", low=4)
    weight = Param(float, 0.5, "differential weight F", low=0.0, high=2.0, low_open=True)
    crossover = Param(float, 0.9, "crossover rate CR", low=0.0, high=1.0)
    dither = Param(bool, False, "draw F per member in [weight, 1]")

    def search(self, space: SearchSpace, rng: np.random.Generator) -> SearchGenerator:
        NP, n = self.population, space.dim
        X = space.initial_population(NP)
        F = yield X
        idx = np.arange(NP)
        while True:
            r1, r2, r3 = _distinct_others(rng, NP, idx)
            if self.dither:
                Fw = rng.uniform(min(self.weight, 1.0), 1.0, (NP, 1))
            else:
                Fw = self.weight
            V = X[r1] + Fw * (X[r2] - X[r3])
            cross = rng.random((NP, n)) < self.crossover
            cross[idx, rng.integers(0, n, NP)] = True
            U = np.where(cross, V, X)
            low, high = U < space.lower, U > space.upper
            if low.any():
                U = np.where(low, (X + space.lower) / 2, U)
            if high.any():
                U = np.where(high, (X + space.upper) / 2, U)
            FU = yield U
            better = FU <= F
            X[better], F[better] = U[better], FU[better]


def _distinct_others(
    rng: np.random.Generator, size: int, idx: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For every member i, three indices distinct from each other and from i (uniform).

    Draws from the other ``size - 1`` members and redraws the (few) rows that collide,
    instead of shuffling a (size, size - 1) matrix each generation.
    """
    r = rng.integers(0, size - 1, (size, 3))
    r += r >= idx[:, None]  # skip i itself
    while True:
        clash = (r[:, 0] == r[:, 1]) | (r[:, 0] == r[:, 2]) | (r[:, 1] == r[:, 2])
        if not clash.any():
            return r[:, 0], r[:, 1], r[:, 2]
        redo = rng.integers(0, size - 1, (int(clash.sum()), 3))
        r[clash] = redo + (redo >= idx[clash, None])
