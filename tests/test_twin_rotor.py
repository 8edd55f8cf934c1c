"""Tests of flexid.envs.twin_rotor: the physics of the 33-949S model and the environments.

Physics checks (1-5 % of documented values) are modelling tolerances.  The reference route
(:func:`derivatives` stepped by :func:`step_states`, batched NumPy), the fast scalar route
(``ScalarStepper``: Python ``math``, behind ``simulate`` and the single environment) and the
fast batched route (``BatchStepper``, behind the vector environment) are routes to one RK4
trajectory, the plant's pure transition (``step_states``, the registry's
``PlantFunctions.transition``) stepped sample by sample (``plant_trajectory``).  NumPy's
sin/cos/tanh may be SIMD code on one CPU and libm on another, and the fast routes order and
group the same operations differently, so they are compared within a rounding bound
propagated along the trajectory (``trajectory_bound``), and carry the ``numerics`` mark.
What the locked yaw axis holds at 0 is compared exactly.
"""

from __future__ import annotations

import pickle
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from scipy import signal

import flexid  # noqa: F401  (registers the environments)
from flexid.data.plants import get_plant
from flexid.envs import twin_rotor_physics, twin_rotor_steppers
from flexid.envs.twin_rotor import TwinRotorEnv, TwinRotorVectorEnv
from flexid.envs.twin_rotor_physics import (
    THRUST_LAWS,
    TwinRotorParameters,
    derivatives,
    pitch_linear_mode,
    reference_trajectory,
    step_states,
)
from flexid.envs.twin_rotor_steppers import (
    BatchStepper,
    CompiledBatchStepper,
    CompiledScalarStepper,
    ScalarStepper,
    simulate,
)
from flexid.errors import ActionError, DataError, PlantParameterError
from numerics import EPS, assert_close_to_terms

PLANT_FUNCTIONS = get_plant("twin-rotor").functions()


def plant_trajectory(u, p: TwinRotorParameters, dt: float = 0.1, x0=None) -> np.ndarray:
    """States (K + 1, 7) from ``x0`` (default the plant's initial state) under the voltages
    ``u`` (K, 2), by the plant's pure transition one sample at a time: the reference."""
    f = PLANT_FUNCTIONS
    x = (f.initial_state(p, dt) if x0 is None else np.asarray(x0, dtype=float))[None]
    out = [x[0]]
    for k in range(len(u)):
        x = f.transition(x, np.asarray(u, dtype=float)[k : k + 1], p, dt)
        out.append(x[0])
    return np.array(out)


def derivative_terms(x: np.ndarray, u: np.ndarray, p: TwinRotorParameters) -> np.ndarray:
    """Magnitudes of the terms each state derivative sums (sin, cos, tanh bounded by 1), (B, 7)."""
    _, dpsi, _, dphi, t1, t2, mr = np.abs(x).T
    u1, u2 = np.abs(u).T
    m1 = abs(p.a1) * t1 * t1 + abs(p.b1) * t1
    m2 = abs(p.a2) * t2 * t2 + abs(p.b2) * t2
    dt1 = (abs(p.k1) * u1 + abs(p.T10) * t1) / abs(p.T11)
    dt2 = (abs(p.k2) * u2 + abs(p.T20) * t2) / abs(p.T21)
    dmr = (mr + abs(p.kc) * (abs(p.T0) * dt1 + t1)) / abs(p.Tp)
    ddpsi = (m1 + abs(p.Mg) + abs(p.B1psi) * dpsi + abs(p.B2psi)
             + abs(p.Kgy) * m1 * dphi) / abs(p.I1)  # fmt: skip
    ddphi = (m2 + abs(p.B1phi) * dphi + abs(p.B2phi) + mr) / abs(p.I2)
    if p.lock_yaw:
        ddphi, dphi = 0 * ddphi, 0 * dphi
    return np.stack([dpsi, ddpsi, dphi, ddphi, dt1, dt2, dmr], axis=1)


def trajectory_bound(x0: np.ndarray, u: np.ndarray, p: TwinRotorParameters, dt: float):
    """Bound on two routes through the sampled RK4 trajectory from ``x0``, shape (K + 1, 7).

    Per sample and route: each derivative sums at most ~10 rounded terms and one sin, cos or
    tanh (a few ulps on any libm or SIMD code): 16 eps of its term magnitudes; each RK4 stage
    input and the update round twice or five times the magnitudes they add: 8 eps of those.
    Errors carried from earlier samples move by the samples' Jacobians (central differences,
    first order): an error made in sample ``j`` reaches sample ``k`` through ``T = J(k-1) ..
    J(j+1)``, so ``|e(k)| <= sum_j |T| 2 delta(j)`` for two routes (the product before the
    absolute value: the pitch oscillation rotates errors, it does not grow them).
    """
    n_sub = max(1, round(dt / p.substep))
    h = dt / n_sub
    x = np.array(x0, dtype=float)[None, :]
    out = [np.zeros(7)]
    transfer = np.zeros((0, 7, 7))  # from the errors of earlier samples to the current state
    deltas = np.zeros((0, 7))
    for k in range(len(u)):
        uk = u[k : k + 1]
        delta = np.zeros(7)
        xs = x
        for _ in range(n_sub):
            k1 = derivatives(xs, uk, p)
            k2 = derivatives(xs + 0.5 * h * k1, uk, p)
            k3 = derivatives(xs + 0.5 * h * k2, uk, p)
            k4 = derivatives(xs + h * k3, uk, p)
            ks = np.abs(k1) + 2 * np.abs(k2) + 2 * np.abs(k3) + np.abs(k4)
            terms = sum(w * derivative_terms(y, uk, p) for w, y in (
                (1, xs), (2, xs + 0.5 * h * k1), (2, xs + 0.5 * h * k2), (1, xs + h * k3)))
            delta += (8 * EPS * (np.abs(xs) + h * ks) + 16 * EPS * h * terms)[0]
            xs = xs + (h / 6.0) * (k1 + 2 * k2 + 2 * k3 + k4)
        steps = 1e-6 * np.maximum(1.0, np.abs(x[0]))
        probe = np.concatenate([x + np.diag(steps), x - np.diag(steps)])
        moved = step_states(probe, np.repeat(uk, 14, axis=0), p, dt)
        jac = (moved[:7] - moved[7:]).T / (2 * steps)
        transfer = np.concatenate([np.einsum("ij,kjl->kil", jac, transfer), np.eye(7)[None]])
        deltas = np.concatenate([deltas, 2 * delta[None]])
        out.append(np.einsum("kij,kj->i", np.abs(transfer), deltas) * (1 + 1e-3))
        x = xs
    return np.array(out)


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


def _random_record(rng: np.random.Generator, n: int, lock_yaw: bool):
    """Voltages (n, 2) over the whole +-2.5 V range on both rotors and a start away from rest
    (its yaw rate 0 when the yaw is locked)."""
    u = rng.uniform(-2.5, 2.5, (n, 2))
    x0 = rng.normal(0.0, [0.3, 0.5, 1.0, 1.0, 1.0, 1.0, 0.1])
    if lock_yaw:
        x0[3] = 0.0
    return u, x0


@pytest.mark.numerics
@pytest.mark.parametrize("route", ["python", "compiled"])
@pytest.mark.parametrize("thrust_law", THRUST_LAWS)
@pytest.mark.parametrize("lock_yaw", [False, True])
def test_fast_routes_equal_the_reference(lock_yaw, thrust_law, route):
    # Tolerance: trajectory_bound, the rounding of two routes through the RK4 trajectory
    # (per derivative 16 eps of its term magnitudes, per stage point and update 8 eps),
    # carried along the trajectory by the sample Jacobians.  The fast routes round
    # differently but not more: the rotor states and reaction torque at the stages come from
    # a 5-term product with coefficients from the reference recursion, the constants are
    # divided out beforehand, the Coulomb rates are held scaled by 1 / eps, the batched cosine
    # is sin(psi + pi/2): each a few eps of the same magnitudes.  On the machine these tests
    # were written on the routes use at most 2 % of the bound; an error in a coefficient or a
    # term (1e-6 relative or more) exceeds it by orders of magnitude.  The compiled route
    # runs the reference's equations in C with the constants divided out once (possibly with
    # FMA) and sin, cos and tanh within a few eps of the exact values: rounding only.
    if route == "compiled":
        if twin_rotor_steppers._compiled() is None:
            pytest.skip("the compiled kernels are not running")
        scalar_cls, batch_cls = CompiledScalarStepper, CompiledBatchStepper
    else:
        scalar_cls, batch_cls = ScalarStepper, BatchStepper
    rng = np.random.default_rng(21)
    n = 150
    p = TwinRotorParameters(lock_yaw=lock_yaw, thrust_law=thrust_law)
    u, x0 = _random_record(rng, n, lock_yaw)
    ref = plant_trajectory(u, p, 0.1, x0)
    bound = trajectory_bound(x0, u, p, 0.1)
    assert bound.max() < 1e-9  # the bound is not vacuous
    scalar = scalar_cls(p, 0.1)
    assert_close_to_terms(scalar.run(u, x0), ref, bound, 1.0)
    x = tuple(x0)
    stepped = [x]
    for u1, u2 in u.tolist():
        x = scalar.step(x, u1, u2)
        stepped.append(x)
    assert_close_to_terms(np.array(stepped), ref, bound, 1.0)
    # row 1 is the record; rows 0 and 2 run other records beside it (a row leaking into
    # another would show as a difference)
    batch = batch_cls(p, 0.1, 3)
    other_u, other_x0 = _random_record(rng, n, lock_yaw)
    batch.state = np.stack([other_x0, x0, -other_x0])
    assert_close_to_terms(batch.state[1], x0, EPS * np.abs(x0), 2.0)  # scaled and unscaled
    for k in range(n):
        batch.advance(np.stack([other_u[k], u[k], -other_u[k]]))
        assert_close_to_terms(batch.state[1], ref[k + 1], bound[k + 1], 1.0)
    y = simulate(u, p, x0=x0)
    assert_close_to_terms(y, ref[:-1, [0, 2, 1, 3]], bound[:-1, [0, 2, 1, 3]], 1.0)


@pytest.mark.numerics
@pytest.mark.parametrize("thrust_law", THRUST_LAWS)
@pytest.mark.parametrize("lock_yaw", [False, True])
def test_compiled_batch_rows_equal_the_reference(lock_yaw, thrust_law):
    # The compiled route steps 4 rotors per SIMD vector: 11 rotors fill two vectors, then
    # three lanes of a third (its last lane runs a rotor at rest).  Each row runs its own
    # record from a start in another quadrant of the pitch (sin and cos are reduced by
    # multiples of pi / 2), one of them 3e5 rad, where the library's sin and cos take over;
    # one starts near rest without input, so that its rates stay below the Coulomb velocity,
    # where tanh is not saturated.
    # Tolerance: trajectory_bound, as in test_fast_routes_equal_the_reference; the compiled
    # sin, cos and tanh are within a few eps of the exact values (absolute), inside the 16 eps
    # per derivative the bound gives the terms they multiply.  A row computed with another
    # row's input, state or constants, or a wrong quadrant, is off by orders of magnitude.
    if twin_rotor_steppers._compiled() is None:
        pytest.skip("the compiled kernels are not running")
    rng = np.random.default_rng(33)
    n, rows = 30, 11
    p = TwinRotorParameters(lock_yaw=lock_yaw, thrust_law=thrust_law)
    records = [_random_record(rng, n, lock_yaw) for _ in range(rows)]
    x0 = np.array([x for _, x in records])
    x0[:, 0] += 0.5 * np.pi * np.arange(-5, rows - 5)
    x0[-1, 0] = 3e5
    x0[1] = [0.0, 0.01, 0.0, 0.0 if lock_yaw else -0.02, 0.0, 0.0, 0.0]
    u = np.stack([v for v, _ in records], axis=1)  # (n, rows, 2)
    u[:, 1] = 0.0
    batch = CompiledBatchStepper(p, 0.1, rows)
    batch.state = x0
    states = [batch.state]
    for k in range(n):
        batch.advance(u[k])
        states.append(batch.state)
    states = np.array(states)
    for i in range(rows):
        ref = plant_trajectory(u[:, i], p, 0.1, x0[i])
        bound = trajectory_bound(x0[i], u[:, i], p, 0.1)
        assert_close_to_terms(states[:, i], ref, bound, 1.0)


def test_the_plants_pure_functions_are_the_models():
    f = PLANT_FUNCTIONS
    assert f.transition is step_states
    rng = np.random.default_rng(3)
    p = TwinRotorParameters()
    u, x0 = _random_record(rng, 40, False)
    # the same function on the same numbers in the same order: the same trajectory
    x = plant_trajectory(u, p, 0.1, x0)
    np.testing.assert_array_equal(x, reference_trajectory(u, p, 0.1, x0))
    np.testing.assert_array_equal(f.output(x, np.zeros((len(x), 2)), p, 0.1), x[:, [0, 2, 1, 3]])
    np.testing.assert_array_equal(f.initial_state(p, 0.1), np.zeros(7))
    low, high = f.input_limits(TwinRotorParameters(u_max=2.0))
    np.testing.assert_array_equal(low, [-2.0, -2.0])
    np.testing.assert_array_equal(high, [2.0, 2.0])


@pytest.mark.numerics
def test_environments_equal_the_reference():
    # The single environment steps the scalar route, the vector environment the batch route;
    # tolerance: trajectory_bound, as in test_fast_routes_equal_the_reference.
    rng = np.random.default_rng(8)
    n = 60
    actions = rng.uniform(-1.3, 1.3, (n, 2))  # some out of the box: clipped
    volts = np.clip(actions, -1.0, 1.0) * 2.5
    env = TwinRotorEnv()
    p = env.params
    env.reset(seed=0)
    ref = plant_trajectory(volts, p, 0.1)
    bound = trajectory_bound(np.zeros(7), volts, p, 0.1)
    for k in range(n):
        obs, reward, terminated, truncated, info = env.step(actions[k])
        np.testing.assert_array_equal(info["applied_voltage"], volts[k])
        x = info["state"]
        np.testing.assert_array_equal(x, env.state)
        assert_close_to_terms(x, ref[k + 1], bound[k + 1], 1.0)
        # observation and reward are read from that state, noise-free: exact; the angles
        # in encoder counts
        seen = twin_rotor_physics.measure(x[[0, 2, 1, 3]], p)
        np.testing.assert_array_equal(obs, [*seen, 0.2, 0.0])
        np.testing.assert_allclose(seen[:2], x[[0, 2]], rtol=0, atol=p.encoder_step / 2)
        q = volts[k] / 2.5
        assert type(reward) is float
        assert reward == -((x[0] - 0.2) ** 2 + x[2] ** 2 + 0.01 * (q[0] ** 2 + q[1] ** 2))
        assert terminated is bool(abs(x[0]) > 1.2) and truncated is False

    # the vector environment, through a truncation and its autoreset: two episodes per env
    horizon, m = 25, 2
    vec = TwinRotorVectorEnv(m, max_episode_steps=horizon)
    vec.reset(seed=1)
    acts = rng.uniform(-1.0, 1.0, (2 * horizon + 1, m, 2))
    volts = acts * 2.5
    episodes = []  # per env: (states of episode 1, states of episode 2) and their bounds
    for i in range(m):
        first, second = volts[:horizon, i], volts[horizon + 1 :, i]
        episodes.append([
            (plant_trajectory(first, p), trajectory_bound(np.zeros(7), first, p, 0.1)),
            (plant_trajectory(second, p), trajectory_bound(np.zeros(7), second, p, 0.1)),
        ])  # fmt: skip
    for k in range(2 * horizon + 1):
        obs, reward, terminated, truncated, _ = vec.step(acts[k])
        for i in range(m):
            if k == horizon:  # the autoreset step: the action is ignored
                np.testing.assert_array_equal(vec.state[i], np.zeros(7))
                np.testing.assert_array_equal(obs[i], [0, 0, 0, 0, 0.2, 0.0])
                assert reward[i] == 0 and not terminated[i] and not truncated[i]
                continue
            states, bound = episodes[i][k > horizon]
            j = k + 1 if k < horizon else k - horizon
            x = vec.state[i]
            assert_close_to_terms(x, states[j], bound[j], 1.0)
            seen = twin_rotor_physics.measure(x[[0, 2, 1, 3]], p)
            assert_close_to_terms(obs[i, :4], seen, EPS * np.abs(seen), 1.0)
            assert truncated[i] == (k in (horizon - 1, 2 * horizon))


def test_locked_yaw_holds_yaw_at_zero_on_every_route():
    rng = np.random.default_rng(4)
    u = rng.uniform(-2.5, 2.5, (200, 2))  # the tail rotor driven too
    p = TwinRotorParameters(lock_yaw=True)
    ref = reference_trajectory(u, p)
    np.testing.assert_array_equal(ref[:, 2:4], 0.0)
    assert np.all(ref[1:, 5] != 0)  # the tail rotor state moves, it does not act
    y = simulate(u, p)
    np.testing.assert_array_equal(y[:, [1, 3]], 0.0)
    env = TwinRotorEnv(lock_yaw=True)
    vec = TwinRotorVectorEnv(3, lock_yaw=True, max_episode_steps=None)
    env.reset(seed=0)
    vec.reset(seed=0)
    for k in range(200):
        obs, *_ = env.step(u[k] / 2.5)
        np.testing.assert_array_equal(env.state[2:4], 0.0)
        np.testing.assert_array_equal(obs[[1, 3]], 0.0)
        obs, *_ = vec.step(np.stack([u[k], -u[k], u[-k]]) / 2.5)
        np.testing.assert_array_equal(vec.state[:, 2:4], 0.0)
        np.testing.assert_array_equal(obs[:, [1, 3]], 0.0)
    with pytest.raises(DataError, match="yaw rate"):
        simulate(u, p, x0=[0, 0, 0, 0.1, 0, 0, 0])


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


@pytest.mark.numerics
def test_vector_env_equals_single_envs():
    n = 3
    vec = TwinRotorVectorEnv(n, noise_std=0.005, max_episode_steps=40)
    singles = [TwinRotorEnv(noise_std=0.005) for _ in range(n)]
    obs_v, _ = vec.reset(seed=10)
    obs_s = [e.reset(seed=10 + i)[0] for i, e in enumerate(singles)]
    # the same draws from the same generators, added to the same initial state: exact
    np.testing.assert_array_equal(obs_v, np.stack(obs_s))
    rng = np.random.default_rng(0)
    acts = rng.uniform(-1, 1, (35, n, 2))
    # a batch of 3 and batches of 1 through step_states: NumPy may take another SIMD or
    # libm path for strided or short arrays, so the states may differ by rounding, bounded
    # along each trajectory; the observations add the same noise draw (rounding u |y|)
    p = singles[0].params
    bounds = [trajectory_bound(singles[i].state, acts[:, i] * p.u_max, p, 0.1) for i in range(n)]
    for k in range(35):
        ov, rv, tv, _, _ = vec.step(acts[k])
        for i, e in enumerate(singles):
            o, r, t, _, _ = e.step(acts[k, i])
            dx = bounds[i][k + 1]
            dy = dx[[0, 2, 1, 3]] + EPS * np.abs(o[:4])
            assert_close_to_terms(ov[i, :4], o[:4], dy, 1.0)
            np.testing.assert_array_equal(ov[i, 4:], o[4:])  # the set point
            # reward -(e_psi^2 + e_phi^2 + w |u|^2): first order in the state errors, plus
            # its own rounding
            sp = e._cfg.setpoint
            dr = 2 * abs(e.state[0] - sp[0]) * dx[0] + 2 * abs(e.state[2] - sp[1]) * dx[2]
            assert abs(rv[i] - r) <= dr + 8 * EPS * abs(r)
            assert tv[i] == t
    env = gym.make_vec("flexid/TwinRotor-v0", num_envs=2, vectorization_mode="vector_entry_point")
    assert env.reset(seed=0)[0].shape == (2, 6)
    # a copy steps on its own state, as the original does (the stepper's views are rebuilt)
    copy = pickle.loads(pickle.dumps(vec))
    a = np.full((n, 2), 0.3)
    np.testing.assert_array_equal(copy.step(a)[0], vec.step(a)[0])
    np.testing.assert_array_equal(copy.step(-a)[0], vec.step(-a)[0])
