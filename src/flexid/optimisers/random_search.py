"""Pure random search: the floor every optimiser must beat."""

from __future__ import annotations

import numpy as np

from ._params import Optimiser, Param, SearchGenerator
from ._problem import SearchSpace
from .registry import register

__all__ = ["RandomSearch"]


@register
class RandomSearch(Optimiser):
    """Uniform random sampling of the box, a batch at a time.

    The first batch is the shared initial population; every later batch is drawn uniformly
    in the box from the run's generator.  The best point ever sampled is the result.

    Parameters
    ----------
    population : int
        Samples per batch (one batch is one iteration), default 50 (also accepted as
        ``points``).
    """

    name = "random-search"
    reference = "Brooks, Operations Research 6(2):244-251, 1958"
    bounds = "inside by construction"
    bounds_note = (
        "Every sample is drawn uniformly in the box."
    )
    stays_in_box = True
    population = Param(int, 50, "samples per batch (one iteration)", low=1, aliases=("points",))

    def search(self, space: SearchSpace, rng: np.random.Generator) -> SearchGenerator:
        yield space.initial_population(self.population)
        while True:
            yield space.uniform(self.population, rng)
