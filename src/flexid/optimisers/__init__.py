"""Optimisers that minimise a batched objective over a box, and their registry.

Optimisers know nothing about ARX: they minimise ``objective(X[(P, n)]) -> F[(P,)]``.

>>> import numpy as np
>>> from flexid.optimisers import Problem, minimize
>>> sphere = Problem(lambda X: ((X - 0.5) ** 2).sum(axis=1), -np.ones(4), np.ones(4))
>>> result = minimize("pso", sphere, budget=2_000, seed=1)
>>> result.nfev
2000

Writing a new optimiser (in flexid or in your own package)::

    from flexid.optimisers import Optimiser, Param, register

    @register
    class MySearch(Optimiser):
        name = "my-search"
        points = Param(int, 20, "population size", low=1)

        def search(self, space, rng):
            X = space.initial_population(self.points)
            F = yield X
            while True:
                ...
                F = yield X

A separate package exposes it through the entry-point group ``flexid.optimisers``.
"""

from __future__ import annotations

from .base import (
    AskTell,
    Budget,
    History,
    IterationInfo,
    Optimiser,
    Param,
    Problem,
    SearchSpace,
    minimize,
)
from .registry import (
    ENTRY_POINT_GROUP,
    PluginWarning,
    available,
    create,
    describe,
    get,
    register,
    register_variant,
    reload_plugins,
    unregister,
)

__all__ = [
    "ENTRY_POINT_GROUP",
    "AskTell",
    "Budget",
    "History",
    "IterationInfo",
    "Optimiser",
    "Param",
    "PluginWarning",
    "Problem",
    "SearchSpace",
    "available",
    "create",
    "describe",
    "get",
    "minimize",
    "register",
    "register_variant",
    "reload_plugins",
    "unregister",
]
