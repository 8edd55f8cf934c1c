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
from helpers import assert_beats_random_search, assert_defaults
from objectives import N, Recorder, box, flat, rosenbrock, shifted_problems

SHIFT, sphere, rastrigin = shifted_problems(1.4)


def test_registered_defaults():
    assert_defaults("ga", GeneticAlgorithm, population=50, elites=2, eta_c=15.0, eta_m=20.0)


def test_generation_size_is_population_minus_elites():
    rec = Recorder(sphere)
    minimize("ga", box(rec, half=5.0), budget=20 + 4 * 17, seed=0,
             params={"population": 20, "elites": 3})
    assert rec.sizes == [20, 17, 17, 17, 17]


def test_shifted_sphere_10d_reaches_1e_2_in_10000_fe():
    p = box(sphere, half=5.0)
    for seed in (0, 1):
        assert minimize("ga", p, budget=10_000, seed=seed).fun < 1e-2


@pytest.mark.parametrize("f, width", [(rastrigin, 5.12), (rosenbrock, 2.0)])
def test_beats_random_search(f, width):
    assert_beats_random_search("ga", box(f, half=width), 5000, seeds=(0, 1), factor=0.5)


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
    rec = Recorder(flat)
    minimize("ga", box(rec, 3, half=1e3), budget=10 + 10, seed=0,
             params={"population": 10, "elites": 0, "p_mutation": 0.0})
    X0, C = rec.batches
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
