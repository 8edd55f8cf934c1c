"""Tests of flexid.optimisers.pso (global-best PSO with constriction).

Cost and distance thresholds are modelling tolerances, far above rounding.  Determinism,
FE-exactness, ask/tell and hyper-parameter validation of every optimiser are in
test_conformance.py.
"""

from __future__ import annotations

import numpy as np
import pytest

from flexid.optimisers import minimize
from flexid.optimisers.pso import ParticleSwarm
from helpers import assert_absorbed_on_a_face, assert_beats_random_search, assert_defaults
from objectives import Recorder, box, flat, rosenbrock, shifted_problems

SHIFT, sphere, rastrigin = shifted_problems(1.4)


def test_registered_with_clerc_kennedy_defaults():
    assert_defaults("pso", ParticleSwarm, inertia=pytest.approx(0.7298),
                    cognitive=pytest.approx(1.49618), social=pytest.approx(1.49618))


def test_shifted_sphere_10d_reaches_1e_6_in_10000_fe():
    p = box(sphere, half=5.0)
    for seed in (0, 1):
        r = minimize("pso", p, budget=10_000, seed=seed)
        assert r.fun < 1e-6
        np.testing.assert_allclose(r.x, SHIFT, atol=1e-2)


@pytest.mark.parametrize("f, width", [(rastrigin, 5.12), (rosenbrock, 2.0)])
def test_beats_random_search(f, width):
    assert_beats_random_search("pso", box(f, half=width), 5000, seeds=(0, 1), factor=0.5)


def test_points_stay_in_box_with_optimum_on_a_face():
    # particles leaving the box are absorbed on its face: the corner is reached exactly
    assert_absorbed_on_a_face("pso", 4, 2000, atol=1e-9)


def test_velocity_is_clamped():
    rec = Recorder(flat)  # only the swarm dynamics move points
    minimize("pso", box(rec, 3, half=1.0), budget=20 * 10, seed=0,
             params={"population": 10, "v_max": 0.05})
    steps = np.abs(np.diff(np.stack(rec.batches), axis=0))
    assert steps.max() <= 0.05 * 2 + 1e-12
