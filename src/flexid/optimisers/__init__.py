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
        population = Param(int, 20, "population size", low=1)

        def search(self, space, rng):
            X = space.initial_population(self.population)
            F = yield X
            while True:
                ...
                F = yield X

A separate package exposes it through the entry-point group ``flexid.optimisers``.

The framework lives in private modules, each depending only on those before it:
``_budget`` (stop rules), ``_problem`` (problem and search space), ``_params``
(hyper-parameters and the Optimiser base class), ``_history`` (history and callback
information), ``registry`` (names, variants, plugins) and ``_driver`` (:func:`minimize`
and :class:`AskTell`, which resolve optimiser names through the registry).
"""

from __future__ import annotations

from ._budget import Budget
from ._driver import AskTell, minimize
from ._history import History, IterationInfo
from ._params import Optimiser, Param, SearchGenerator
from ._problem import Problem, SearchSpace
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
    "SearchGenerator",
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
