"""Tests of flexid.optimisers.cmaes_restarts (BIPOP/IPOP-CMA-ES with a box transformation).

The cost thresholds are modelling tolerances with the margins measured here stated next to
them; the transformation checks are exact or at a few ulps of the values involved.
"""

from __future__ import annotations

import numpy as np
import pytest

from flexid.optimisers import available, describe, minimize
from flexid.optimisers.cmaes_restarts import (
    CMAESRestarts,
    box_transform,
    box_transform_inverse,
)
from helpers import assert_absorbed_on_a_face, assert_defaults
from numerics import EPS
from objectives import Recorder, box

D = 5
SHIFT = np.linspace(-4.0, 3.5, D)  # inside [-5, 5]^5, not symmetric about the centre
COND = 10.0 ** (6 * np.arange(D) / (D - 1))  # the BBOB ellipsoid's scaling, condition 1e6


def sphere(X):
    return np.sum((X - SHIFT) ** 2, axis=1)


def ellipsoid(X):
    return np.sum(COND * (X - SHIFT) ** 2, axis=1)


def test_registered_defaults_and_ipop_variant():
    assert {"cmaes", "cmaes-bipop", "cmaes-ipop"} <= set(available())
    assert_defaults(
        "cmaes-bipop", CMAESRestarts, population=None, sigma0=0.3, bipop=True, active=True
    )
    assert_defaults("cmaes-ipop", CMAESRestarts, bipop=False)
    assert describe("cmaes-ipop")["variant_of"] == "cmaes-bipop"


# ------------------------------------------------------------------------ the transform
def test_box_transform_maps_into_the_box_smoothly_and_periodically():
    a = 0.05
    g = np.linspace(-7.3, 8.1, 20_001)
    x = box_transform(g, a)
    assert x.min() >= 0.0 and x.max() <= 1.0
    inside = (g >= a) & (g <= 1 - a)
    np.testing.assert_array_equal(x[inside], g[inside])  # the identity inside the layers
    # period 2 (1 + 2a); shifting by it changes g by rounding (|g| <= 10: a few ulps)
    np.testing.assert_allclose(box_transform(g + 2 * (1 + 2 * a), a), x, rtol=0, atol=64 * EPS)
    # continuous with slope at most 1: |dx| <= |dg| on the grid, up to rounding of the values
    assert np.all(np.abs(np.diff(x)) <= np.diff(g) + 16 * EPS)
    # the layers meet the identity with equal value and slope 1 (C^1): one-sided differences
    # of the quadratic at g = a differ from 1 by h / (4a)
    h = 1e-6
    for at in (a, 1 - a):
        left = (box_transform(np.array([at]), a) - box_transform(np.array([at - h]), a)) / h
        assert left[0] == pytest.approx(1.0, abs=h / (4 * a) + 1e-9)
    # the faces are reached (the point -a maps to 0, 1 + a to 1)
    assert box_transform(np.array([-a, 1 + a]), a).tolist() == [0.0, 1.0]


def test_box_transform_inverse():
    X = np.random.default_rng(0).random((500, 3))
    X[:5] = [
        [0.0, 1.0, 0.01],
        [0.049, 0.951, 0.5],
        [1e-9, 1 - 1e-9, 0.3],
        [0.05, 0.95, 0.2],
        [0.0, 0.0, 1.0],
    ]
    # sqrt and square each round to half an ulp; the result is within a few ulps of X
    np.testing.assert_allclose(box_transform(box_transform_inverse(X)), X, rtol=0, atol=8 * EPS)


# ------------------------------------------------------------------------- convergence
@pytest.mark.parametrize("objective", [sphere, ellipsoid])
def test_solves_shifted_sphere_and_ellipsoid_to_1e_8(objective):
    """5,000 FE at d = 5 (BBOB's 1,000 d); measured: below 3e-14 for every seed in 0..9, so
    1e-8 leaves five decades for other BLAS builds and platforms."""
    for seed in (0, 1):
        assert minimize("cmaes-bipop", box(objective, D, half=5.0), 5000, seed=seed).fun < 1e-8


def test_converges_just_inside_a_face_where_plain_cmaes_stalls():
    """Sphere with its optimum 0.01 inside the lower face of [-5, 5]^10 (0.1 % of the side).

    Measured at 10,000 FE, seeds 0..4: ``cmaes-bipop`` below 1e-13 for each; ``cmaes``
    (clipping + penalty) between 3e-4 and 4e-4, coordinates stuck on the face where sigma
    collapsed.  The thresholds 1e-8 and 1e-5 leave five and one decades to spare.
    """
    n, budget = 10, 10_000

    def near_face(X):
        return np.sum((X + 4.99) ** 2, axis=1)

    for seed in (0, 1, 2):
        assert minimize("cmaes-bipop", box(near_face, n, half=5.0), budget, seed=seed).fun < 1e-8
        assert minimize("cmaes", box(near_face, n, half=5.0), budget, seed=seed).fun > 1e-5


def test_converges_on_a_face_and_stays_in_the_box():
    """Optimum on the face x_i = -5 (quartic through the transform: f ~ (g - g*)^4), and
    optimum outside the box (the corner is the answer).  Measured over seeds 0..9: cost
    below 3e-17 on the face and the corner within 3e-15: 1e-8 and 1e-6 have decades to
    spare."""

    def on_face(X):
        return np.sum((X + 5.0) ** 2, axis=1)

    rec = Recorder(on_face)
    r = minimize("cmaes-bipop", box(rec, D, half=5.0), 5000, seed=0)
    assert r.fun < 1e-8
    assert rec.points.min() >= -5.0 and rec.points.max() <= 5.0
    assert_absorbed_on_a_face("cmaes-bipop", 4, 3000, atol=1e-6)


# ----------------------------------------------------------------- restarts and budget
def test_ipop_doubles_the_population_and_the_budget_is_exact():
    """On a sphere tolfun ends each run (ranges below 1e-11), so a 5,000-FE run restarts;
    every restart of IPOP doubles pycma's unrounded population size ``p_0 = 4 + 3 ln n``
    (lambda = floor(2^k p_0): 8, 17, 35 at n = 5, where doubling the rounded 8 gave 16, 32),
    and the last batch is cut at the budget."""
    rec = Recorder(sphere)
    budget = 4999  # not a sum of whole generations
    r = minimize("cmaes-ipop", box(rec, D, half=5.0), budget, seed=0)
    assert r.nfev == rec.rows == budget
    p0 = 4 + 3 * np.log(D)  # 8.83
    sizes = rec.sizes
    assert sizes[0] == 50
    distinct = list(dict.fromkeys(sizes[1:-1]))
    assert distinct[:3] == [int(p0), int(2 * p0), int(4 * p0)] == [8, 17, 35], distinct
    assert sizes[-1] <= distinct[-1]


def test_bipop_interleaves_small_and_large_runs():
    """The first restart is a large one (the first run counts on the small budget); later
    runs alternate between doubled populations and small ones, whose lambda lies between
    lambda_def and the last large lambda (pycma's ``p_0 2^(large runs)^(U^2)``; it was capped
    at half the last large lambda before, which no small run here could exceed).  The budget
    is exact."""
    above_half = 0
    for seed in (0, 1):  # measured lambdas: 8 17 8 35 13 8 70 23 20; 8 17 9 35 18 28 70 9 8 11
        rec = Recorder(sphere)
        r = minimize("cmaes-bipop", box(rec, D, half=5.0), 20_000, seed=seed)
        assert r.nfev == rec.rows == 20_000
        above_half += _check_bipop_runs(rec.sizes)
    assert above_half >= 1


def _check_bipop_runs(sizes: list[int]) -> int:
    """Check the lambdas of a BIPOP run's batches; returns the number of small runs whose
    lambda exceeds half the last large one."""
    p0 = 4 + 3 * np.log(D)  # pycma's popsize before rounding, 8.83
    lam = int(p0)
    sizes = np.array(sizes[1:-1])
    starts = np.concatenate(([0], np.flatnonzero(np.diff(sizes)) + 1))
    runs = [int(sizes[i]) for i in starts]  # lambda of each run (equal neighbours merge)
    assert runs[:2] == [lam, int(2 * p0)] and lam <= runs[2] <= runs[1], runs
    large, k, small, above_half = lam, 0, 0, 0
    for size in runs[1:]:
        if size == int(p0 * 2 ** (k + 1)):
            large, k = size, k + 1
        else:
            assert lam <= size <= large, runs
            small += 1
            above_half += size > large // 2
    assert large >= 8 * lam and small >= 3, runs
    return above_half


def test_reproducible_from_the_seed():
    runs = []
    for seed in (3, 3, 4):
        rec = Recorder(ellipsoid)
        runs.append((minimize("cmaes-bipop", box(rec, D, half=5.0), 3000, seed=seed), rec))
    (a, ra), (b, rb), (_, rc) = runs
    np.testing.assert_array_equal(ra.points, rb.points)
    assert a.fun == b.fun and a.nit == b.nit
    assert ra.points.shape != rc.points.shape or not np.array_equal(ra.points, rc.points)


def test_mean_starts_at_the_best_initial_point():
    """With a tiny sigma0 the first generation sits on the best shared initial point (the
    transformation is the identity away from the faces, and its inverse round-trips)."""
    rec = Recorder(sphere)
    minimize("cmaes-bipop", box(rec, D, half=5.0), 58, seed=0, params={"sigma0": 1e-9})
    first, second = rec.batches
    best = first[np.argmin(sphere(first))]
    # steps of sigma0 x side = 1e-8 per coordinate: 1e-6 is a hundred standard deviations
    np.testing.assert_allclose(second, np.tile(best, (8, 1)), atol=1e-6)


def test_nan_costs_do_not_break_it():
    def f(X):
        F = sphere(X)
        F[X[:, 0] > 2] = np.nan
        return F

    r = minimize("cmaes-bipop", box(f, D, half=5.0), 3000, seed=0)
    assert np.isfinite(r.fun) and r.fun < 1e-6  # measured: below 5e-14 for seeds 0..9
