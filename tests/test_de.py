"""Tests of flexid.optimisers.de (DE/rand/1/bin).

Cost thresholds are modelling tolerances, far above rounding.  Determinism, FE-exactness,
ask/tell and hyper-parameter validation of every optimiser are in test_conformance.py.
"""

from __future__ import annotations

import numpy as np
import pytest

from flexid.optimisers import Problem, create, minimize
from flexid.optimisers.de import DifferentialEvolution
from objectives import rosenbrock, shifted_rastrigin, shifted_sphere

N = 10
SHIFT = np.linspace(-1.4, 1.4, N)
sphere = shifted_sphere(SHIFT)
rastrigin = shifted_rastrigin(SHIFT)


def test_registered_defaults():
    opt = create("de")
    assert isinstance(opt, DifferentialEvolution)
    assert (opt.weight, opt.crossover, opt.population) == (0.5, 0.9, 50)


def test_shifted_sphere_10d_reaches_1e_5_in_10000_fe():
    p = Problem(sphere, -5 * np.ones(N), 5 * np.ones(N))
    for seed in (0, 1):
        assert minimize("de", p, budget=10_000, seed=seed).fun < 1e-5


@pytest.mark.parametrize("f, width", [(rastrigin, 5.12), (rosenbrock, 2.0)])
def test_beats_random_search(f, width):
    p = Problem(f, -width * np.ones(N), width * np.ones(N))
    for seed in (0, 1):
        ours = minimize("de", p, budget=5000, seed=seed).fun
        rs = minimize("random-search", p, budget=5000, seed=seed).fun
        assert ours < rs


def test_operators_against_a_loop():
    """Trial vectors: r1, r2, r3 distinct and != i, one forced crossover gene, bounce-back."""
    seen = []
    costs = []

    def f(X):
        seen.append(X.copy())
        F = ((X - 0.9) ** 2).sum(axis=1)
        costs.append(F)
        return F

    NP, n = 8, 3
    p = Problem(f, -np.ones(n), np.ones(n))
    minimize("de", p, budget=NP * 6, seed=2,
             params={"population": NP, "crossover": 0.0, "weight": 0.9})
    X, F = seen[0], costs[0]
    for g in range(1, 6):
        U = seen[g]
        assert U.min() >= -1 and U.max() <= 1
        for i in range(NP):
            # CR = 0: exactly one coordinate differs from the parent
            assert np.count_nonzero(U[i] != X[i]) <= 1
        better = costs[g] <= F
        X = np.where(better[:, None], U, X)
        F = np.where(better, costs[g], F)


def test_mutant_uses_three_distinct_others():
    # population of 4: each mutant uses the 3 other members; with CR = 1 and F = 1 the
    # trial is x_r1 + (x_r2 - x_r3), a combination of the others only
    seen = []

    def f(X):
        seen.append(X.copy())
        return np.zeros(len(X))

    p = Problem(f, -100 * np.ones(2), 100 * np.ones(2))
    minimize("de", p, budget=8, seed=0, params={"population": 4, "crossover": 1.0, "weight": 1.0})
    X, U = seen
    for i in range(4):
        others = [j for j in range(4) if j != i]
        cands = [X[a] + X[b] - X[c] for a in others for b in others for c in others
                 if len({a, b, c}) == 3]
        # bounce-back: a coordinate outside the box goes half-way to the violated bound
        cands = [np.where(c > 100, (X[i] + 100) / 2, np.where(c < -100, (X[i] - 100) / 2, c))
                 for c in cands]
        # x_r1 + F (x_r2 - x_r3) against x_r1 + x_r2 - x_r3: rounding ~1e-14 of coordinates up
        # to 100, another triple O(1): the allclose defaults sit far from both
        assert any(np.allclose(U[i], c) for c in cands)


def test_dither_changes_the_run_and_stays_deterministic():
    p = Problem(rastrigin, -5.12 * np.ones(N), 5.12 * np.ones(N))
    a = minimize("de", p, budget=3000, seed=0, params={"dither": True})
    b = minimize("de", p, budget=3000, seed=0, params={"dither": True})
    c = minimize("de", p, budget=3000, seed=0)
    assert a.fun == b.fun and a.fun != c.fun
    assert a.fun < minimize("random-search", p, budget=3000, seed=0).fun
