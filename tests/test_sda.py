"""Tests of the spiral dynamics algorithm.

Against the reference, every recorded batch is compared with one reference step from the
batch before it (its centre chosen by the reference rule from the recorded costs): the
rounding of one step (GEMM with the swept rotation against a dense product and a
matrix-vector product, tests/route_bounds.py) is then the whole tolerance, on any machine,
and never accumulates over the run.  Reaching 1e-8 on the sphere and beating random search
are modelling thresholds.
"""

from __future__ import annotations

import numpy as np
import pytest

from flexid.optimisers import create, get, minimize
from flexid.optimisers.rotation import plane_rotation
from helpers import assert_median_beats_random_search
from numerics import EPS, assert_close_to_terms
from objectives import Recorder, box, rosenbrock, shifted_problems
from route_bounds import spiral_step_bound

SHIFT, sphere, rastrigin = shifted_problems(0.5)


def reference_sda(batches, f, r, theta):
    """Straightforward SDA with explicit dense plane rotations (no shared code).

    One step from each recorded batch: returns the best point and cost, and for every batch
    but the last the centre used and the next batch the reference predicts.
    """
    n = batches[0].shape[1]
    R = np.eye(n)
    for i in range(1, n):
        for j in range(1, i + 1):
            R = R @ plane_rotation(n, n - i, n + 1 - j, theta)
    xs = fs = None
    steps = []
    for k, X in enumerate(batches):
        F = f(X)
        b = int(np.argmin(F))
        if fs is None or F[b] < fs:
            xs, fs = X[b].copy(), F[b]
        if k + 1 < len(batches):
            steps.append((xs.copy(), np.array([xs + r * R @ (x - xs) for x in X])))
    return xs, fs, steps


@pytest.mark.numerics
def test_matches_reference_implementation():
    rec = Recorder(sphere)
    res = minimize("sda", box(rec), budget=10_000, seed=4,
                   params=dict(population=8, radius=0.9, angle=0.5, k_max=30))
    xs, fs, steps = reference_sda(rec.batches, sphere, 0.9, 0.5)
    assert res.nfev == 8 * 31 == rec.rows
    assert res.stop == "converged"
    assert len(steps) == 30
    for (centre, want), before, got in zip(steps, rec.batches[:-1], rec.batches[1:], strict=True):
        bound = spiral_step_bound(centre, 0.9, before - centre, lower=-2.0)
        assert_close_to_terms(got, want, bound, 1.0)
    # the best of the recorded costs, by the same function on the same rows: exact
    assert res.fun == fs
    np.testing.assert_array_equal(res.x, xs)


def test_r1_theta0_moves_nothing():
    rec = Recorder(sphere)
    minimize("sda", box(rec), budget=60, seed=0, params=dict(population=6, radius=1.0, angle=0.0))
    assert len(rec.batches) == 10
    # R = I exactly (cos 0, sin 0), so a step is (z - zs) + zs in the unit box: two
    # roundings, within u (|z - zs| + |z|) <= 2 u of z, adding up over the steps; the
    # objective sees -2 + 4 z, rounded once more (on any machine: elementwise IEEE
    # operations and a GEMM with the identity, which is exact)
    x0 = rec.batches[0]
    for k, batch in enumerate(rec.batches[1:], start=1):
        bound = EPS / 2 * (2 * k * 4 + np.abs(x0) + np.abs(x0 + 2)) * (1 + EPS)
        assert_close_to_terms(batch, x0, bound, 1.0)


def test_centre_point_is_fixed_and_reevaluated():
    rec = Recorder(sphere)
    minimize("sda", box(rec), budget=5 * 4, seed=2, params=dict(population=5))
    b = int(np.argmin(sphere(rec.batches[0])))
    # the best point is the centre: it stays put and is evaluated every iteration; its
    # displacement is zero and rotates to zero, so xs + r 0 = xs exactly
    for batch in rec.batches[1:]:
        np.testing.assert_array_equal(batch[b], rec.batches[0][b])


def test_one_iteration_is_one_population():
    # FE-exactness at any budget: test_conformance.py
    res = minimize("sda", box(sphere), 777, seed=1)
    np.testing.assert_array_equal(res.history.fe, [*range(50, 777, 50), 777])
    np.testing.assert_array_equal(res.history.iteration, np.arange(16))


def test_k_max_limits_iterations():
    res = minimize("sda", box(sphere), 100_000, seed=1, params=dict(population=10, k_max=25))
    assert res.nfev == 10 * 26
    assert res.nit == 25
    assert res.stop == "converged"


def test_best_is_non_increasing_and_matches_recorded_costs():
    rec = Recorder(rastrigin)
    res = minimize("sda", box(rec, half=5.12), 4_000, seed=3)
    assert np.all(np.diff(res.history.best) <= 0)
    assert res.fun == pytest.approx(min(rastrigin(b).min() for b in rec.batches))


def test_clip_keeps_points_in_box():
    rec = Recorder(sphere)
    # a large angle with r close to 1 throws points out of the box without clip
    minimize("sda", box(rec), 2_000, seed=5, params=dict(radius=0.99, angle=2.0, clip=True))
    allx = np.concatenate(rec.batches)
    assert allx.min() >= -2.0 and allx.max() <= 2.0
    rec2 = Recorder(sphere)
    minimize("sda", box(rec2), 2_000, seed=5, params=dict(radius=0.99, angle=2.0))
    assert np.abs(np.concatenate(rec2.batches)).max() > 2.0


def test_reaches_tolerance_on_shifted_sphere():
    # 10-D shifted sphere, box [-2, 2]^10: cost < 1e-8 within 20,000 FE for every seed
    for seed in range(3):
        assert minimize("sda", box(sphere), 20_000, seed=seed).fun < 1e-8


@pytest.mark.parametrize(
    "f, half", [(rastrigin, 5.12), (rosenbrock, 2.0)], ids=["rastrigin", "rosenbrock"]
)
def test_clearly_better_than_random_search(f, half):
    assert_median_beats_random_search("sda", box(f, half=half), 20_000, range(5), factor=0.6)


def test_paper_variants():
    man = create("sda-paper-manipulator")
    assert (man.radius, man.angle, man.population, man.k_max) == (0.99, 0.381, 50, 1000)
    trs = create("sda-paper-trs")
    assert (trs.radius, trs.angle, trs.population, trs.k_max) == (0.98, 0.72, 10, 200)
    assert issubclass(get("sda-paper-trs"), get("sda"))
    # TRS schedule: m (1 + k_max) = 2,010 FE
    assert minimize("sda-paper-trs", box(sphere), 10**6, seed=0).nfev == 2_010
