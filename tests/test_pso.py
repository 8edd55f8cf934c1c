"""Tests of flexid.optimisers.pso (global-best PSO with constriction).

Cost and distance thresholds are modelling tolerances, far above rounding.  Determinism,
FE-exactness, ask/tell and hyper-parameter validation of every optimiser are in
test_conformance.py.
"""

from __future__ import annotations

import numpy as np
import pytest

from flexid.optimisers import Problem, create, minimize
from flexid.optimisers.pso import ParticleSwarm
from objectives import rosenbrock, shifted_rastrigin, shifted_sphere

N = 10
SHIFT = np.linspace(-1.4, 1.4, N)
sphere = shifted_sphere(SHIFT)
rastrigin = shifted_rastrigin(SHIFT)


def test_registered_with_clerc_kennedy_defaults():
    opt = create("pso")
    assert isinstance(opt, ParticleSwarm)
    assert opt.inertia == pytest.approx(0.7298)
    assert opt.cognitive == pytest.approx(1.49618) and opt.social == pytest.approx(1.49618)


def test_shifted_sphere_10d_reaches_1e_6_in_10000_fe():
    p = Problem(sphere, -5 * np.ones(N), 5 * np.ones(N))
    for seed in (0, 1):
        r = minimize("pso", p, budget=10_000, seed=seed)
        assert r.fun < 1e-6
        np.testing.assert_allclose(r.x, SHIFT, atol=1e-2)


@pytest.mark.parametrize("f, width", [(rastrigin, 5.12), (rosenbrock, 2.0)])
def test_beats_random_search(f, width):
    p = Problem(f, -width * np.ones(N), width * np.ones(N))
    for seed in (0, 1):
        ours = minimize("pso", p, budget=5000, seed=seed).fun
        rs = minimize("random-search", p, budget=5000, seed=seed).fun
        assert ours < 0.5 * rs


def test_points_stay_in_box_with_optimum_on_a_face():
    seen = []

    def f(X):
        seen.append(X.copy())
        return ((X - 3.0) ** 2).sum(axis=1)  # optimum outside the box [-1, 1]^n

    p = Problem(f, -np.ones(4), np.ones(4))
    r = minimize("pso", p, budget=2000, seed=0)
    X = np.concatenate(seen)
    assert X.min() >= -1 and X.max() <= 1
    np.testing.assert_allclose(r.x, np.ones(4), atol=1e-9)  # absorbed on the face


def test_velocity_is_clamped():
    seen = []

    def f(X):
        seen.append(X.copy())
        return np.zeros(X.shape[0])  # flat: only the swarm dynamics move points

    p = Problem(f, -np.ones(3), np.ones(3))
    minimize("pso", p, budget=20 * 10, seed=0, params={"population": 10, "v_max": 0.05})
    steps = np.abs(np.diff(np.stack(seen), axis=0))
    assert steps.max() <= 0.05 * 2 + 1e-12
