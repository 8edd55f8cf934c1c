"""Tests of flexid.optimisers.cmaes (numpy CMA-ES).

Cost thresholds and the distances to the optimum are modelling tolerances; the eigen-
decomposition check uses the backward error of LAPACK's symmetric eigensolver.
"""

from __future__ import annotations

import numpy as np
import pytest

from flexid.optimisers import AskTell, Problem, create, minimize
from flexid.optimisers.cmaes import CMAES
from numerics import EPS
from objectives import rosenbrock, shifted_rastrigin, shifted_sphere

N = 10
SHIFT = np.linspace(-1.4, 1.4, N)
sphere = shifted_sphere(SHIFT)
rastrigin = shifted_rastrigin(SHIFT)


def test_registered_defaults():
    opt = create("cmaes")
    assert isinstance(opt, CMAES)
    assert opt.population is None and opt.sigma0 == 0.3


def test_default_lambda_and_fe_exact():
    sizes = []

    def f(X):
        sizes.append(len(X))
        return sphere(X)

    p = Problem(f, -5 * np.ones(N), 5 * np.ones(N))
    r = minimize("cmaes", p, budget=50 + 10 * 7 + 3, seed=0)
    lam = 4 + int(np.floor(3 * np.log(N)))  # = 10
    assert sizes == [50] + [lam] * 7 + [3]
    assert r.nfev == sum(sizes)


def test_shifted_sphere_10d_reaches_1e_12_in_5000_fe():
    p = Problem(sphere, -5 * np.ones(N), 5 * np.ones(N))
    for seed in (0, 1):
        assert minimize("cmaes", p, budget=5000, seed=seed).fun < 1e-12


def test_rosenbrock_solved_and_rastrigin_beats_random_search():
    ros = Problem(rosenbrock, -2 * np.ones(N), 2 * np.ones(N))
    ras = Problem(rastrigin, -5.12 * np.ones(N), 5.12 * np.ones(N))
    for seed in (0, 1):
        assert minimize("cmaes", ros, budget=10_000, seed=seed).fun < 1e-8
        ours = minimize("cmaes", ras, budget=5000, seed=seed).fun
        assert ours < 0.5 * minimize("random-search", ras, budget=5000, seed=seed).fun


def test_mean_starts_at_best_initial_point():
    seen = []

    def f(X):
        seen.append(X.copy())
        return sphere(X)

    p = Problem(f, -5 * np.ones(N), 5 * np.ones(N))
    minimize("cmaes", p, budget=60, seed=0, params={"sigma0": 1e-9})
    x_best = seen[0][np.argmin(sphere(seen[0]))]
    np.testing.assert_allclose(seen[1], np.tile(x_best, (10, 1)), atol=1e-6)


@pytest.mark.numerics
def test_internal_invariants_during_a_run():
    """Weights sum to 1 and decrease; C stays symmetric positive definite; B, D match C."""
    p = Problem(rosenbrock, -2 * np.ones(N), 2 * np.ones(N))
    at = AskTell("cmaes", p, budget=3000, seed=1)
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
    seen = []

    def f(X):
        seen.append(X.copy())
        return ((X - 3.0) ** 2).sum(axis=1)

    p = Problem(f, -np.ones(4), np.ones(4))
    r = minimize("cmaes", p, budget=3000, seed=0)
    X = np.concatenate(seen)
    assert X.min() >= -1 and X.max() <= 1
    np.testing.assert_allclose(r.x, np.ones(4), atol=1e-6)


def test_nan_costs_do_not_break_it():
    def f(X):
        F = sphere(X)
        F[X[:, 0] > 2] = np.nan
        return F

    p = Problem(f, -5 * np.ones(N), 5 * np.ones(N))
    r = minimize("cmaes", p, budget=3000, seed=0)
    assert np.isfinite(r.fun) and r.fun < 1e-3
