"""Tests of flexid.optimisers.ga (real-coded GA, SBX + polynomial mutation).

Cost thresholds are modelling tolerances, far above rounding.  Determinism, FE-exactness,
ask/tell and hyper-parameter validation of every optimiser are in test_conformance.py.
"""

from __future__ import annotations

import numpy as np
import pytest

from flexid.errors import HyperParameterError
from flexid.optimisers import Problem, create, minimize
from flexid.optimisers.ga import GeneticAlgorithm
from objectives import rosenbrock, shifted_rastrigin, shifted_sphere

N = 10
SHIFT = np.linspace(-1.4, 1.4, N)
sphere = shifted_sphere(SHIFT)
rastrigin = shifted_rastrigin(SHIFT)


def test_registered_defaults():
    opt = create("ga")
    assert isinstance(opt, GeneticAlgorithm)
    assert (opt.population, opt.elites, opt.eta_c, opt.eta_m) == (50, 2, 15.0, 20.0)


def test_generation_size_is_population_minus_elites():
    sizes = []

    def f(X):
        sizes.append(len(X))
        return sphere(X)

    p = Problem(f, -5 * np.ones(N), 5 * np.ones(N))
    minimize("ga", p, budget=20 + 4 * 17, seed=0, params={"population": 20, "elites": 3})
    assert sizes == [20, 17, 17, 17, 17]


def test_shifted_sphere_10d_reaches_1e_2_in_10000_fe():
    p = Problem(sphere, -5 * np.ones(N), 5 * np.ones(N))
    for seed in (0, 1):
        assert minimize("ga", p, budget=10_000, seed=seed).fun < 1e-2


@pytest.mark.parametrize("f, width", [(rastrigin, 5.12), (rosenbrock, 2.0)])
def test_beats_random_search(f, width):
    p = Problem(f, -width * np.ones(N), width * np.ones(N))
    for seed in (0, 1):
        ours = minimize("ga", p, budget=5000, seed=seed).fun
        rs = minimize("random-search", p, budget=5000, seed=seed).fun
        assert ours < 0.5 * rs


def test_elitism_and_bounds():
    """Best-of-generation never gets worse (elites survive) and children stay in the box."""
    seen, costs = [], []

    def f(X):
        seen.append(X.copy())
        F = rastrigin(X)
        costs.append(F)
        return F

    p = Problem(f, -5.12 * np.ones(N), 5.12 * np.ones(N))
    minimize("ga", p, budget=50 + 48 * 30, seed=1)
    X = np.concatenate(seen)
    assert X.min() >= -5.12 and X.max() <= 5.12
    # population after generation g = 2 elites of previous + children; its best is monotone
    pop_f = costs[0]
    bests = [pop_f.min()]
    for F in costs[1:]:
        pop_f = np.concatenate([np.sort(pop_f)[:2], F])
        bests.append(pop_f.min())
    assert np.all(np.diff(bests) <= 0)


def test_sbx_children_are_symmetric_about_parents_mean():
    """Without mutation, SBX keeps each pair's mean: children sums equal parent sums."""
    seen = []

    def f(X):
        seen.append(X.copy())
        return np.zeros(len(X))

    p = Problem(f, -1e3 * np.ones(3), 1e3 * np.ones(3))
    minimize("ga", p, budget=10 + 10, seed=0,
             params={"population": 10, "elites": 0, "p_mutation": 0.0})
    X0, C = seen
    half = 5
    pair_sum = C[:half] + C[half:]
    # each pair's sum is the sum of two members of the initial population
    sums = X0[:, None, :] + X0[None, :, :]
    for s in pair_sum:
        # rounding moves a pair sum by ~1e-13 (coordinates up to 1e3); another pairing moves
        # it by O(1): the isclose defaults (1e-5, 1e-8) sit far from both
        assert np.isclose(sums, s).all(axis=2).any()


def test_elites_must_be_fewer_than_the_population():
    # types and ranges of every hyper-parameter: test_conformance.py
    with pytest.raises(HyperParameterError, match="ga: elites"):
        create("ga", elites=50)
    with pytest.raises(HyperParameterError, match="ga: elites"):
        create("ga", population=10, elites=10)
