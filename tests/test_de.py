"""Tests of flexid.optimisers.de (DE/rand/1/bin).

Cost thresholds are modelling tolerances, far above rounding.  Determinism, FE-exactness,
ask/tell and hyper-parameter validation of every optimiser are in test_conformance.py.
"""

from __future__ import annotations

import numpy as np
import pytest

from flexid.optimisers import Problem, minimize
from flexid.optimisers.de import DifferentialEvolution
from helpers import assert_beats_random_search, assert_defaults
from objectives import Recorder, box, flat, rosenbrock, shifted_problems

SHIFT, sphere, rastrigin = shifted_problems(1.4)


def test_registered_defaults():
    assert_defaults("de", DifferentialEvolution, weight=0.5, crossover=0.9, population=50)


def test_shifted_sphere_10d_reaches_1e_5_in_10000_fe():
    p = box(sphere, half=5.0)
    for seed in (0, 1):
        assert minimize("de", p, budget=10_000, seed=seed).fun < 1e-5


@pytest.mark.parametrize("f, width", [(rastrigin, 5.12), (rosenbrock, 2.0)])
def test_beats_random_search(f, width):
    assert_beats_random_search("de", box(f, half=width), 5000, seeds=(0, 1))


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
    rec = Recorder(flat)
    minimize("de", box(rec, 2, half=100.0), budget=8, seed=0,
             params={"population": 4, "crossover": 1.0, "weight": 1.0})
    X, U = rec.batches
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
    p = box(rastrigin, half=5.12)
    a = minimize("de", p, budget=3000, seed=0, params={"dither": True})
    b = minimize("de", p, budget=3000, seed=0, params={"dither": True})
    c = minimize("de", p, budget=3000, seed=0)
    assert a.fun == b.fun and a.fun != c.fun
    assert a.fun < minimize("random-search", p, budget=3000, seed=0).fun
