"""Tests of flexid.optimisers.lshade (L-SHADE, Tanabe & Fukunaga, CEC 2014).

The cost thresholds are modelling tolerances with the margins measured here stated next to
them; the memory update and the population schedule are checked exactly (the same few
floating-point operations in the same order, or integers).
"""

from __future__ import annotations

import numpy as np
import pytest

from flexid.optimisers import available, minimize
from flexid.optimisers.lshade import (
    LSHADE,
    memory_update,
    planned_population,
    weighted_lehmer_mean,
)
from helpers import assert_absorbed_on_a_face, assert_defaults
from objectives import Recorder, box

SHIFT = np.linspace(-4.0, 3.5, 10)  # inside [-5, 5]^n, not symmetric about the centre


def sphere(X):
    return np.sum((X - SHIFT[: X.shape[1]]) ** 2, axis=1)


def rosenbrock(X):
    Z = X - SHIFT[: X.shape[1]] + 1.0  # minimum 0 at X = SHIFT
    return np.sum(100.0 * (Z[:, 1:] - Z[:, :-1] ** 2) ** 2 + (1.0 - Z[:, :-1]) ** 2, axis=1)


def test_registered_with_the_papers_settings():
    assert "lshade" in available()
    assert_defaults("lshade", LSHADE, population=None, min_population=4, memory=6,
                    pbest=0.11, archive_rate=2.6)


# ------------------------------------------------------------------------- convergence
def test_solves_a_shifted_sphere_and_rosenbrock():
    """Sphere, d = 10, 20,000 FE: measured below 6e-19 for seeds 0..9; Rosenbrock, d = 5,
    25,000 FE: 2e-29 for seeds 0..9.  1e-8 leaves ten decades for other platforms."""
    for seed in (0, 1):
        assert minimize("lshade", box(sphere, 10, half=5.0), 20_000, seed=seed).fun < 1e-8
        assert minimize("lshade", box(rosenbrock, 5, half=5.0), 25_000, seed=seed).fun < 1e-8


# ---------------------------------------------------------------- population reduction
@pytest.mark.parametrize("budget", [5000, 4321])
def test_population_shrinks_linearly_to_n_min_at_the_budget(budget):
    """The first generation has N_init members (the paper reduces after a generation); each
    later one has the schedule's size at the FE spent before it (integers: exact); the
    schedule reaches N_min = 4 exactly at the budget, and the last batch is cut there."""
    rec = Recorder(sphere)
    r = minimize("lshade", box(rec, 5, half=5.0), budget, seed=0)
    assert r.nfev == rec.rows == budget
    n_init = 90  # round(18 x 5)
    sizes = rec.sizes
    assert sizes[0] == sizes[1] == n_init
    spent = np.cumsum(sizes)
    for before, size in zip(spent[1:-2], sizes[2:-1]):
        assert size == planned_population(int(before), budget, n_init, 4)
    assert sizes[-1] <= planned_population(int(spent[-2]), budget, n_init, 4)
    assert np.all(np.diff(sizes[:-1]) <= 0)
    assert planned_population(budget, budget, n_init, 4) == 4
    # the last generations run at (or next to) N_min: the schedule falls by 86 / budget per
    # FE, less than one member per generation of fewer than 50 members
    assert sizes[-2] <= 5


def test_planned_population_is_linear_and_rounded_half_up():
    assert planned_population(0, 1000, 100, 4) == 100
    assert planned_population(1000, 1000, 100, 4) == 4
    assert planned_population(500, 1000, 100, 4) == 52  # 100 - 48
    assert planned_population(125, 1000, 12, 4) == 11  # 11.0
    assert planned_population(1250, 10_000, 8, 4) == 8  # 7.5 rounds up, as C's round
    assert planned_population(2000, 1000, 100, 4) == 4  # never below N_min


# ----------------------------------------------------------------------- memory update
def test_memory_update_equals_a_hand_computation():
    """Weighted Lehmer means with weights delta / sum(delta), by hand:
    w = (0.5, 0.25, 0.25); S_F = (0.5, 1, 0.2): sum w F^2 = 0.125 + 0.25 + 0.01 = 0.385,
    sum w F = 0.25 + 0.25 + 0.05 = 0.55, mean 0.7; S_CR = (0.4, 0.8, 0.6):
    sum w CR^2 = 0.08 + 0.16 + 0.09 = 0.33, sum w CR = 0.2 + 0.2 + 0.15 = 0.55, mean 0.6.
    The computed values differ from these decimals by rounding only (a few ulps)."""
    M_CR, M_F = np.full(3, 0.5), np.full(3, 0.5)
    delta = np.array([2.0, 1.0, 1.0])
    k = memory_update(M_CR, M_F, 2, np.array([0.4, 0.8, 0.6]), np.array([0.5, 1.0, 0.2]), delta)
    assert k == 0  # (2 + 1) mod H
    assert M_F[2] == pytest.approx(0.7, rel=1e-15, abs=0)
    assert M_CR[2] == pytest.approx(0.6, rel=1e-15, abs=0)
    assert M_F[:2].tolist() == M_CR[:2].tolist() == [0.5, 0.5]
    # every successful CR is 0: the slot becomes terminal (NaN), and stays terminal
    k = memory_update(M_CR, M_F, 0, np.zeros(2), np.array([0.3, 0.3]), np.ones(2))
    assert k == 1 and np.isnan(M_CR[0]) and M_F[0] == pytest.approx(0.3, rel=1e-15, abs=0)
    memory_update(M_CR, M_F, 0, np.array([0.9]), np.array([0.4]), np.ones(1))
    assert np.isnan(M_CR[0]) and M_F[0] == pytest.approx(0.4, rel=1e-15, abs=0)  # one value
    # no success: nothing changes, the slot stays
    before = M_F.copy()
    assert memory_update(M_CR, M_F, 1, np.empty(0), np.empty(0), np.empty(0)) == 1
    assert M_F.tolist() == before.tolist()
    assert weighted_lehmer_mean(np.array([0.0, 0.0]), np.array([0.5, 0.5])) == 0.0


# ----------------------------------------------------------------------------- bounds
def test_never_leaves_the_box_and_converges_to_a_corner():
    """The optimum (3, ..., 3) lies outside [-1, 1]^4: the midpoint repair halves the distance
    to the face each time, so the corner is approached geometrically (measured: within 5e-16
    for seeds 0..9 at 3,000 FE); every evaluated point stays in the box (exact comparisons)."""
    assert_absorbed_on_a_face("lshade", 4, 3000, atol=1e-8)
    rec = Recorder(sphere)
    minimize("lshade", box(rec, 6, half=1.0), 4000, seed=1)  # the shift's ends lie outside
    assert rec.points.min() >= -1.0 and rec.points.max() <= 1.0


# ------------------------------------------------------------------------- reproducible
def test_reproducible_from_the_seed():
    runs = []
    for seed in (3, 3, 4):
        rec = Recorder(rosenbrock)
        runs.append((minimize("lshade", box(rec, 5, half=5.0), 3000, seed=seed), rec))
    (a, ra), (b, rb), (_, rc) = runs
    np.testing.assert_array_equal(ra.points, rb.points)
    assert a.fun == b.fun and a.nit == b.nit
    assert not np.array_equal(ra.points, rc.points)


def test_population_below_min_population_is_refused():
    from flexid.errors import HyperParameterError

    with pytest.raises(HyperParameterError, match="min_population"):
        LSHADE(population=5, min_population=6)
