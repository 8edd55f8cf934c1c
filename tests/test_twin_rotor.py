"""Tests of flexid.envs.twin_rotor: the physics checks of plants.md 2.1 and the environments."""

from __future__ import annotations

import pickle
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from scipy import signal

import flexid  # noqa: F401  (registers the environments)
from flexid.envs.twin_rotor import (
    TwinRotorEnv,
    TwinRotorParameters,
    TwinRotorVectorEnv,
    pitch_linear_mode,
    simulate,
    step_states,
)
from flexid.errors import ActionError, DataError, PlantParameterError


def test_linearised_pitch_resonance_and_damping():
    f, zeta = pitch_linear_mode()
    assert f == pytest.approx(0.3453, rel=0.01)
    assert zeta == pytest.approx(0.020, abs=0.002)
    # the simulated small-amplitude free oscillation has that frequency
    p = TwinRotorParameters(lock_yaw=True, B2psi=0.0)
    x0 = np.zeros(7)
    x0[0] = 0.01
    y = simulate(np.zeros(600), p, x0=x0)
    crossings = np.flatnonzero(np.diff(np.sign(y[:, 0])) != 0)
    period = 2 * np.mean(np.diff(crossings)) * 0.1
    assert 1 / period == pytest.approx(f * np.sqrt(1 - zeta**2), rel=0.01)


@pytest.mark.parametrize("lock_yaw", [True, False])
def test_random_input_gives_the_pitch_resonance_peak(lock_yaw):
    rng = np.random.default_rng(0)
    u = rng.uniform(-1, 1, 3000)  # +-1 V held 0.1 s for 300 s on the main rotor
    y = simulate(u, TwinRotorParameters(lock_yaw=lock_yaw))
    f, p = signal.welch(y[:, 0], fs=10.0, nperseg=1024)
    assert 0.33 <= f[np.argmax(p)] <= 0.37
    if lock_yaw:
        assert np.all(y[:, 1] == 0) and np.all(y[:, 3] == 0)


def test_unit_step_settles_to_the_documented_pitch_and_yaw_rate():
    y = simulate(np.ones(600), TwinRotorParameters())
    assert y[-1, 0] == pytest.approx(0.339, rel=0.05)
    assert y[-1, 3] == pytest.approx(2.1, rel=0.05)
    locked = simulate(np.ones(600), TwinRotorParameters(lock_yaw=True))
    m1 = 0.0135 * 1.1**2 + 0.0924 * 1.1
    assert locked[-1, 0] == pytest.approx(np.arcsin(m1 / 0.32), rel=0.01)


def test_thrust_laws_and_input_clipping():
    neg = -np.ones(400)
    signed = simulate(neg, TwinRotorParameters(lock_yaw=True))
    square = simulate(neg, TwinRotorParameters(lock_yaw=True, thrust_law="square"))
    assert signed[-1, 0] < 0 and square[-1, 0] != signed[-1, 0]
    big = simulate(np.full(300, 10.0), TwinRotorParameters(lock_yaw=True))
    clipped = simulate(np.full(300, 2.5), TwinRotorParameters(lock_yaw=True))
    np.testing.assert_array_equal(big, clipped)


def test_scalar_and_batched_integrators_agree():
    rng = np.random.default_rng(1)
    u = rng.uniform(-2, 2, (150, 2))
    p = TwinRotorParameters()
    y = simulate(u, p)
    x = np.zeros((1, 7))
    for k in range(150):
        np.testing.assert_allclose(x[0, [0, 2, 1, 3]], y[k], atol=1e-12)
        x = step_states(x, u[k : k + 1], p, 0.1)


def test_bad_parameters_and_inputs():
    with pytest.raises(PlantParameterError, match="thrust_law"):
        TwinRotorParameters(thrust_law="cubic")
    with pytest.raises(PlantParameterError, match="I1"):
        TwinRotorParameters(I1=-1.0)
    with pytest.raises(DataError, match="shape"):
        simulate(np.zeros((10, 3)))
    u = np.zeros(20)
    u[7] = np.inf
    with pytest.raises(DataError, match="7"):
        simulate(u)
    with pytest.raises(PlantParameterError, match="unknown"):
        TwinRotorEnv(rotor_colour="red")


def test_environment_passes_the_checker_and_is_reproducible():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        env = gym.make("flexid/TwinRotor-v0", render_mode="rgb_array", lock_yaw=True)
        check_env(env.unwrapped)
        check_env(TwinRotorEnv(noise_std=0.01), skip_render_check=True)
    assert env.observation_space.dtype == np.float64 and env.spec.max_episode_steps == 600
    _obs, _ = env.reset(seed=3)
    frame = env.render()
    assert frame.shape == (400, 800, 3) and frame.dtype == np.uint8
    a = TwinRotorEnv(noise_std=0.01)
    b = TwinRotorEnv(noise_std=0.01)
    _oa, _ = a.reset(seed=5)
    _ob, _ = b.reset(seed=5)
    for _ in range(20):
        ra = a.step(np.array([0.5, -0.2]))
        rb = b.step(np.array([0.5, -0.2]))
        np.testing.assert_array_equal(ra[0], rb[0])
    c = pickle.loads(pickle.dumps(a))
    np.testing.assert_array_equal(c.step(np.array([0.1, 0.1]))[0], a.step(np.array([0.1, 0.1]))[0])


def test_actions_out_of_range_are_clipped_non_finite_raise():
    env = TwinRotorEnv()
    env.reset(seed=0)
    _, _, _, _, info = env.step(np.array([3.0, -7.0]))
    np.testing.assert_allclose(info["applied_voltage"], [2.5, -2.5])
    with pytest.raises(ActionError):
        env.step(np.array([np.nan, 0.0]))
    with pytest.raises(ActionError):
        env.step(np.array([0.1]))


def test_vector_env_equals_single_envs():
    n = 3
    vec = TwinRotorVectorEnv(n, noise_std=0.005, max_episode_steps=40)
    singles = [TwinRotorEnv(noise_std=0.005) for _ in range(n)]
    obs_v, _ = vec.reset(seed=10)
    obs_s = [e.reset(seed=10 + i)[0] for i, e in enumerate(singles)]
    np.testing.assert_allclose(obs_v, np.stack(obs_s))
    rng = np.random.default_rng(0)
    for _ in range(35):
        act = rng.uniform(-1, 1, (n, 2))
        ov, rv, tv, _, _ = vec.step(act)
        for i, e in enumerate(singles):
            o, r, t, _, _ = e.step(act[i])
            np.testing.assert_allclose(ov[i], o, atol=1e-12)
            assert rv[i] == pytest.approx(r) and tv[i] == t
    env = gym.make_vec("flexid/TwinRotor-v0", num_envs=2, vectorization_mode="vector_entry_point")
    assert env.reset(seed=0)[0].shape == (2, 6)
    pickle.loads(pickle.dumps(vec))
