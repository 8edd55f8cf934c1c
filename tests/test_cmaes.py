"""Tests of flexid.optimisers.cmaes (numpy CMA-ES).

Cost thresholds and the distances to the optimum are modelling tolerances; the eigen-
decomposition check uses the backward error of LAPACK's symmetric eigensolver.
"""

from __future__ import annotations

import numpy as np
import pytest

from flexid.optimisers import AskTell, minimize
from flexid.optimisers.cmaes import CMAES
from helpers import assert_absorbed_on_a_face, assert_beats_random_search, assert_defaults
from numerics import EPS
from objectives import N, Recorder, box, rosenbrock, shifted_problems

SHIFT, sphere, rastrigin = shifted_problems(1.4)


def test_registered_defaults():
    assert_defaults("cmaes", CMAES, population=None, sigma0=0.3)


def test_default_lambda_and_fe_exact():
    rec = Recorder(sphere)
    r = minimize("cmaes", box(rec, half=5.0), budget=50 + 10 * 7 + 3, seed=0)
    lam = 4 + int(np.floor(3 * np.log(N)))  # = 10
    assert rec.sizes == [50] + [lam] * 7 + [3]
    assert r.nfev == rec.rows


def test_shifted_sphere_10d_reaches_1e_12_in_5000_fe():
    for seed in (0, 1):
        assert minimize("cmaes", box(sphere, half=5.0), budget=5000, seed=seed).fun < 1e-12


def test_rosenbrock_solved_and_rastrigin_beats_random_search():
    for seed in (0, 1):
        assert minimize("cmaes", box(rosenbrock), budget=10_000, seed=seed).fun < 1e-8
    assert_beats_random_search("cmaes", box(rastrigin, half=5.12), 5000, (0, 1), factor=0.5)


def test_mean_starts_at_best_initial_point():
    rec = Recorder(sphere)
    minimize("cmaes", box(rec, half=5.0), budget=60, seed=0, params={"sigma0": 1e-9})
    first, second = rec.batches
    x_best = first[np.argmin(sphere(first))]
    np.testing.assert_allclose(second, np.tile(x_best, (10, 1)), atol=1e-6)


@pytest.mark.numerics
def test_internal_invariants_during_a_run():
    """Weights sum to 1 and decrease; C stays symmetric positive definite; B, D match C."""
    at = AskTell("cmaes", box(rosenbrock), budget=3000, seed=1)
    checked = 0
    while not at.done:
        X = at.ask()
        at.tell(rosenbrock(X))
        if at.done:
            break
        loc = at._generator.gi_frame.f_locals
        if "C" not in loc:
            continue
        w, C, B, D = loc["w"], loc["C"], loc["B"], loc["D"]
        assert w.sum() == pytest.approx(1.0)
        assert np.all(np.diff(w) < 0) and np.all(w > 0)
        np.testing.assert_array_equal(C, C.T)  # C = (C + C') / 2: a + b == b + a exactly
        assert np.linalg.eigvalsh(C).min() > 0
        # eigh is exact for C + E, |E|_2 <= p(n) u |C|_2 (LAPACK, p(n) <= n); B is orthogonal
        # within n u; D^2 rounds sqrt and square (3 u); the product sums n terms of at most
        # lambda_max |B_ik B_jk|: (n + 2 n + 3) u lambda_max in all, bounded by 4 n eps
        lam_max = np.linalg.eigvalsh(C).max()
        np.testing.assert_allclose((B * D**2) @ B.T, C, rtol=0, atol=4 * N * EPS * lam_max)
        assert loc["sigma"] > 0
        checked += 1
    assert checked > 100


def test_bounds_clipped_when_optimum_outside():
    assert_absorbed_on_a_face("cmaes", 4, 3000, atol=1e-6)


def test_nan_costs_do_not_break_it():
    def f(X):
        F = sphere(X)
        F[X[:, 0] > 2] = np.nan
        return F

    r = minimize("cmaes", box(f, half=5.0), budget=3000, seed=0)
    assert np.isfinite(r.fun) and r.fun < 1e-3
