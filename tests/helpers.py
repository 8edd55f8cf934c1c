"""Assertions, specifications and the walk of the public modules shared by several tests.

The optimiser checks compare costs against random search at the same budget and seeds: the
thresholds (``factor``) are modelling tolerances, far above rounding, and are chosen by the
calling test.
"""

from __future__ import annotations

import pkgutil
from collections.abc import Iterable, Mapping
from dataclasses import replace
from typing import Any

import numpy as np

import flexid
from flexid.config import ComparisonSpec, CostSpec, DataSpec, ModelSpec, OptimiserSpec
from flexid.optimisers import Problem, create, minimize
from objectives import Recorder, box


# ------------------------------------------------------------------------------ public API
def public_modules(packages_only: bool = False) -> list[str]:
    """Every module (or package) of flexid whose dotted name has no ``_``-prefixed part."""
    names = ["flexid"]
    for info in pkgutil.walk_packages(flexid.__path__, "flexid."):
        public = not any(part.startswith("_") for part in info.name.split("."))
        if public and (info.ispkg or not packages_only):
            names.append(info.name)
    return sorted(names)


# ------------------------------------------------------------------------------ optimisers
def assert_defaults(name: str, cls: type, **expected: Any) -> None:
    """``create(name)`` is a ``cls`` whose hyper-parameters equal ``expected``."""
    opt = create(name)
    assert isinstance(opt, cls)
    assert {key: getattr(opt, key) for key in expected} == expected


def assert_beats_random_search(
    name: str, problem: Problem, budget: int, seeds: Iterable[int], factor: float = 1.0
) -> None:
    """For every seed, ``name``'s best cost is below ``factor`` times random search's."""
    for seed in seeds:
        ours = minimize(name, problem, budget, seed=seed).fun
        rs = minimize("random-search", problem, budget, seed=seed).fun
        assert ours < factor * rs, (name, seed, ours, rs)


def median_cost(
    name: str,
    problem: Problem,
    budget: int,
    seeds: Iterable[int],
    params: Mapping[str, Any] | None = None,
) -> float:
    """Median over ``seeds`` of the best cost ``name`` reaches within ``budget`` FE."""
    return float(
        np.median([minimize(name, problem, budget, seed=s, params=params).fun for s in seeds])
    )


def assert_median_beats_random_search(
    name: str,
    problem: Problem,
    budget: int,
    seeds: Iterable[int],
    factor: float,
    params: Mapping[str, Any] | None = None,
) -> None:
    """Over ``seeds``, ``name``'s median best cost is below ``factor`` times random search's."""
    seeds = list(seeds)
    ours = median_cost(name, problem, budget, seeds, params)
    rs = median_cost("random-search", problem, budget, seeds)
    assert ours < factor * rs, (name, ours, rs)


# ----------------------------------------------------------------------------- comparisons
def manipulator_data(n_samples: int, seed: int) -> DataSpec:
    """A simulated manipulator record: uniform input, the tip acceleration measured."""
    return DataSpec(plant="manipulator", signal="uniform", n_samples=n_samples, seed=seed,
                    outputs=["tip_acceleration"])


def small_spec(**changes: Any) -> ComparisonSpec:
    """Three runs of SDA and random search at 600 FE on a 600-sample record, na = nb = 4."""
    spec = ComparisonSpec(
        name="small",
        data=manipulator_data(600, 1),
        model=ModelSpec(na=4, nb=4, nk=1),
        cost=CostSpec(metric="paper", predictor="one-step"),
        optimisers=(OptimiserSpec("sda", {"points": 10}), OptimiserSpec("random-search")),
        runs=3,
        seed=5,
        budget=600,
        targets=(10.0, 0.5),
    )
    return replace(spec, **changes)


def tiny_spec(name: str, **changes: Any) -> ComparisonSpec:
    """Two runs of SDA and random search at 300 FE on a 400-sample record, na = 2."""
    spec = ComparisonSpec(
        name=name,
        data=manipulator_data(400, 0),
        model=ModelSpec(na=2),
        optimisers=(OptimiserSpec("sda", {"points": 10}), OptimiserSpec("random-search")),
        runs=2,
        budget=300,
        targets=(1.0,),
    )
    return replace(spec, **changes)


def assert_absorbed_on_a_face(name: str, n: int, budget: int, atol: float) -> None:
    """With the optimum ``(3, ..., 3)`` outside the box ``[-1, 1]^n``, every point evaluated
    stays in the box and the result is within ``atol`` of the corner ``(1, ..., 1)``."""
    rec = Recorder(lambda X: ((X - 3.0) ** 2).sum(axis=1))
    r = minimize(name, box(rec, n, half=1.0), budget, seed=0)
    assert rec.points.min() >= -1 and rec.points.max() <= 1
    np.testing.assert_allclose(r.x, np.ones(n), atol=atol)
