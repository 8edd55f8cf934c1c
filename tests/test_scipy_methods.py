"""Tests of flexid.optimisers.scipy_methods (scipy.optimize.minimize adapters).

The first local run is compared exactly with plain scipy: the same scipy code on the same
numbers (the objective sees the same rows).  Cost and distance thresholds are modelling
tolerances, far above rounding.
"""

from __future__ import annotations

import threading

import numpy as np
import pytest
from scipy import optimize

from flexid.optimisers import AskTell, Problem, create, describe, minimize
from helpers import assert_absorbed_on_a_face
from objectives import Recorder, box, rosenbrock, shifted_sphere

N = 5
SHIFT = np.linspace(-1.4, 1.4, N)
METHODS = ["nelder-mead", "powell", "l-bfgs-b"]
sphere = shifted_sphere(SHIFT)


@pytest.mark.parametrize("name, method", list(zip(METHODS, ["Nelder-Mead", "Powell", "L-BFGS-B"])))
def test_variants_registered(name, method):
    assert create(name).method == method
    assert describe(name)["variant_of"] == "scipy"


@pytest.mark.parametrize("name", METHODS)
def test_threads_cleaned_up(name):
    # FE-exactness and determinism: test_conformance.py
    before = threading.active_count()
    p = box(sphere, N, half=5.0)
    for seed in (2, 3):
        assert minimize(name, p, budget=400, seed=seed).nfev == 400
    assert threading.active_count() == before


@pytest.mark.parametrize("name, tol", [("nelder-mead", 1e-6), ("powell", 1e-10),
                                       ("l-bfgs-b", 1e-10)])
def test_shifted_sphere_5d(name, tol):
    p = box(sphere, N, half=5.0)
    assert minimize(name, p, budget=1500, seed=0).fun < tol


@pytest.mark.parametrize("method", ["Nelder-Mead", "Powell"])
@pytest.mark.parametrize("start", ["x0", "best-initial"])
def test_first_run_matches_plain_scipy(method, start):
    """The first local run evaluates exactly the points plain scipy evaluates."""
    seen = []

    def f(X):
        seen.append(X.copy())
        return rosenbrock(X)

    x0 = np.array([0.5, -0.3, 1.2, 0.1, -1.0])
    lo, width = -2 * np.ones(N), 4 * np.ones(N)
    p = Problem(f, lo, lo + width, x0=x0)
    r = minimize("scipy", p, budget=300, seed=0,
                 params={"method": method, "start": start, "restarts": False})
    if start == "best-initial":
        X0 = seen.pop(0)
        assert len(X0) == 50
        x0 = X0[np.argmin(rosenbrock(X0))]
    ref = []

    # scipy runs in the unit box the driver hands every optimiser; the points it evaluates
    # are mapped to the problem's box by the same expression, hence the same bits
    def g(z):
        x = lo + np.clip(z, 0, 1) * width
        ref.append(x)
        return float(rosenbrock(x[None])[0])

    bounds = optimize.Bounds(np.zeros(N), np.ones(N))
    res = optimize.minimize(g, (x0 - lo) / width, method=method, bounds=bounds)
    ours = np.concatenate(seen)
    assert all(len(X) == 1 for X in seen)
    k = min(len(ours), len(ref))
    np.testing.assert_array_equal(ours[:k], np.array(ref[:k]))
    if res.nfev < 300 - (50 if start == "best-initial" else 0):
        # scipy stopped first: without restarts the run ends with scipy
        assert r.stop == "converged" and len(ours) == len(ref)
        assert r.fun == pytest.approx(res.fun)


def test_lbfgsb_matches_scipy_with_same_gradient():
    """L-BFGS-B path equals scipy driven by the same forward-difference gradient."""
    seen = []

    def f(X):
        seen.append(X.copy())
        return rosenbrock(X)

    lo, hi = -2 * np.ones(N), 2 * np.ones(N)
    p = Problem(f, lo, hi)
    r = minimize("l-bfgs-b", p, budget=50_000, seed=0, params={"restarts": False})
    z0 = Problem(f, lo, hi).initial_unit(1, np.random.SeedSequence(0).spawn(2)[0])[0]

    # in the unit box the driver hands the optimiser (box width 1)
    def fg(z):
        z = np.clip(z, 0, 1)
        h = 1e-7 * np.maximum(np.abs(z), 1e-3)
        h = np.where(z + h > 1, -h, h)
        F = rosenbrock(lo + np.vstack([z, z + np.diag(h)]) * (hi - lo))
        return F[0], (F[1:] - F[0]) / h

    res = optimize.minimize(fg, z0, jac=True, method="L-BFGS-B",
                            bounds=optimize.Bounds(np.zeros(N), np.ones(N)))
    assert r.stop == "converged" and r.nfev == res.nfev * (N + 1)
    # flexid's best also counts the difference points, so it may be slightly lower
    assert r.fun <= res.fun and r.fun == pytest.approx(res.fun, rel=1e-2)
    assert res.fun < 1e-7  # scipy's own convergence (FACTR) on this start


def test_lbfgsb_gradient_is_one_batch_of_n_plus_1():
    rec = Recorder(sphere)
    minimize("l-bfgs-b", box(rec, N, half=5.0), budget=6 * 10, seed=0)
    assert rec.sizes == [N + 1] * 10


@pytest.mark.parametrize("name", METHODS)
def test_restarts_use_the_budget(name):
    """On a sphere scipy converges quickly; restarts keep spending the budget."""
    p = box(sphere, N, half=5.0)
    r = minimize(name, p, budget=1500, seed=1)
    assert r.nfev == 1500 and r.stop == "budget"


@pytest.mark.parametrize("name", METHODS)
def test_points_stay_in_box(name):
    assert_absorbed_on_a_face(name, 3, 600, atol=1e-3)


def test_abandoned_ask_tell_run_ends_its_thread():
    # ask/tell equals minimize: test_conformance.py
    p = box(rosenbrock, N)
    before = threading.active_count()
    at = AskTell("nelder-mead", p, seed=4)
    for _ in range(5):
        at.tell(rosenbrock(at.ask()))
    at.result()  # closes the generator mid-run
    assert threading.active_count() == before


def test_objective_error_propagates():
    def f(X):
        if len(X) == 1:
            raise RuntimeError("plant exploded")
        return sphere(X)

    p = Problem(f, -np.ones(N), np.ones(N))
    before = threading.active_count()
    with pytest.raises(RuntimeError, match="plant exploded"):
        minimize("nelder-mead", p, budget=500, seed=0)
    assert threading.active_count() == before
