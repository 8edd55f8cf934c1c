"""Tests of flexid.envs.manipulator (single and vector env) and the flexid.envs._render canvas."""

from __future__ import annotations

import math
import pickle
import warnings

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import flexid  # noqa: F401  (registers the environments)
from flexid.data.plants import get_plant
from flexid.envs import beam
from flexid.envs._render import Canvas
from flexid.envs.manipulator import FlexibleManipulatorEnv, FlexibleManipulatorVectorEnv
from flexid.errors import ActionError, PlantParameterError
from numerics import EPS, assert_close_to_terms, route_tolerance

ENV_ID = "flexid/FlexibleManipulator-v0"
SMALL = {"n_sections": 10}  # fast physics for rollout tests


# ---- API conformance -------------------------------------------------------------------------
def test_check_env_without_warnings():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        env = gymnasium.make(ENV_ID, payload_mass=0.02, noise_std=1e-3, render_mode="rgb_array")
        check_env(env.unwrapped)
        check_env(FlexibleManipulatorEnv(**SMALL), skip_render_check=True)
        # the made env (with its wrappers, including the passive checker) runs cleanly too
        env.reset(seed=0)
        for _ in range(5):
            env.step(env.action_space.sample())
        env.render()
        env.close()


def test_spaces_and_make_kwargs():
    env = gymnasium.make(ENV_ID, payload_mass=0.02, tau_max=0.5, noise_std=[0, 0, 1e-4, 0.1])
    u = env.unwrapped
    assert u.params.payload_mass == 0.02
    assert env.action_space == gymnasium.spaces.Box(-0.5, 0.5, (1,), np.float64)
    assert env.observation_space.shape == (5,) and env.observation_space.dtype == np.float64
    assert env.spec.max_episode_steps == 2000
    assert FlexibleManipulatorEnv.metadata["render_fps"] > 0


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"payload_mass": -1.0}, "payload_mass"),
        ({"n_sections": 2}, "n_sections"),
        ({"tau_max": 0.0}, "tau_max"),
        ({"dt": -1e-3}, "dt"),
        ({"noise_std": [0.1, 0.2]}, "noise_std"),
        ({"noise_std": -0.1}, "noise_std"),
        ({"target_angle": 5.0}, "target_angle"),
        ({"tip_weight": float("nan")}, "tip_weight"),
        ({"render_mode": "ansi"}, "render_mode"),
        ({"stiffness": 3.0}, "stiffness"),
    ],
)
def test_bad_kwargs_raise(kwargs, match):
    with pytest.raises(PlantParameterError, match=match):
        FlexibleManipulatorEnv(**kwargs)
    if "render_mode" not in kwargs:  # make() itself handles render modes
        with pytest.raises(PlantParameterError, match=match):
            gymnasium.make(ENV_ID, **kwargs)
    with pytest.raises(PlantParameterError, match=match):
        FlexibleManipulatorVectorEnv(2, **kwargs)


# ---- dynamics, reward, termination ----------------------------------------------------------
def test_env_follows_beam_simulate_and_reward_formula():
    ideal = beam.IDEAL_SENSORS
    env = FlexibleManipulatorEnv(payload_mass=0.01, tip_weight=50.0, torque_weight=0.1, **ideal)
    obs, info = env.reset(seed=3)
    np.testing.assert_array_equal(obs, [0, 0, 0, 0, 0.5])
    rng = np.random.default_rng(0)
    u = rng.uniform(-0.3, 0.3, 300)
    y = beam.simulate(u, beam.BeamParameters(payload_mass=0.01, **ideal))
    for k in range(299):
        obs, reward, terminated, truncated, info = env.step(np.array([u[k]]))
        scale = np.abs(y).max(axis=0)
        assert np.all(np.abs(obs[:4] - y[k + 1]) <= 1e-9 * scale)
        expected = -((obs[0] - 0.5) ** 2 + 50.0 * obs[2] ** 2 + 0.1 * (u[k] / 0.3) ** 2)
        assert reward == pytest.approx(expected, rel=1e-9, abs=1e-15)
        assert not terminated and not truncated
        assert info["applied_torque"] == u[k] and not info["clipped"]


def test_out_of_range_action_is_clipped_and_reported():
    a, b = FlexibleManipulatorEnv(**SMALL), FlexibleManipulatorEnv(**SMALL)
    a.reset(seed=0)
    b.reset(seed=0)
    oa, ra, *_, ia = a.step(np.array([2.0]))
    ob, rb, *_, ib = b.step(np.array([0.3]))
    np.testing.assert_array_equal(oa, ob)
    assert ra == rb and ia["applied_torque"] == 0.3 and ia["clipped"] and not ib["clipped"]
    _, _, _, _, ic = a.step(-7.0)  # a scalar is accepted
    assert ic["applied_torque"] == -0.3


@pytest.mark.parametrize(
    "action", [np.array([np.nan]), np.array([np.inf]), np.zeros(2), np.zeros((1, 1)), "x"]
)
def test_bad_actions_raise(action):
    env = FlexibleManipulatorEnv(**SMALL)
    env.reset(seed=0)
    with pytest.raises(ActionError):
        env.step(action)


def test_termination_when_hub_leaves_safe_range():
    env = FlexibleManipulatorEnv(angle_limit=0.2, target_angle=0.1, **SMALL)
    env.reset(seed=0)
    n_steps = 0
    for _ in range(2000):
        _, _, terminated, _, info = env.step(np.array([0.3]))
        n_steps += 1
        if terminated:
            break
        assert abs(info["outputs"][0]) <= 0.2
    assert terminated and abs(info["outputs"][0]) > 0.2
    # rigid-body estimate: theta = tau t^2 / (2 J) reaches 0.2 rad after ~0.256 s
    j = env.params.total_inertia
    assert n_steps * 1e-3 == pytest.approx(math.sqrt(2 * 0.2 * j / 0.3), rel=0.05)


def test_truncation_by_time_limit():
    env = gymnasium.make(ENV_ID, max_episode_steps=5, **SMALL)
    env.reset(seed=0)
    flags = [env.step(np.zeros(1))[3] for _ in range(5)]
    assert flags == [False] * 4 + [True]


def test_reset_is_reproducible_and_noise_depends_on_seed():
    def rollout(seed):
        env = FlexibleManipulatorEnv(noise_std=[1e-3, 1e-2, 1e-4, 0.1], **SMALL)
        obs = [env.reset(seed=seed, options={"random_target": True})[0]]
        obs += [env.step(np.array([0.1]))[0] for _ in range(100)]
        return np.array(obs)

    a, b, c = rollout(1), rollout(1), rollout(2)
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)
    assert a[0, 4] != c[0, 4] and abs(a[0, 4]) <= 1.0
    noise = a[1:, :4] - rollout_noise_free()
    np.testing.assert_allclose(noise.std(axis=0), [1e-3, 1e-2, 1e-4, 0.1], rtol=0.35)


def rollout_noise_free():
    env = FlexibleManipulatorEnv(**SMALL)
    env.reset(seed=0)
    return np.array([env.step(np.array([0.1]))[0][:4] for _ in range(100)])


def test_reset_options():
    env = FlexibleManipulatorEnv(**SMALL)
    assert env.reset(options={"target_angle": -0.3})[0][4] == -0.3
    assert env.reset()[0][4] == 0.5
    with pytest.raises(PlantParameterError, match="target_angle"):
        env.reset(options={"target_angle": 9.0})
    with pytest.raises(PlantParameterError, match="unknown reset option"):
        env.reset(options={"initial_angle": 0.1})


@pytest.mark.parametrize("chain", ["ideal", "lab"])
def test_coulomb_friction_env_matches_simulate(chain):
    # with the lab chain the friction acts at the hub, behind the actuator's lag
    sensors = beam.IDEAL_SENSORS if chain == "ideal" else {"tachometer_noise": 0.0}
    kw = {"hub_coulomb_friction": 0.02, **SMALL, **sensors}
    env = FlexibleManipulatorEnv(**kw)
    env.reset(seed=0)
    u = np.where(np.arange(200) < 100, 0.3, -0.3)
    p = beam.BeamParameters(**kw)
    y = beam.measure(beam.simulate(u, p), p)
    obs = np.array([env.step(np.array([t]))[0][:4] for t in u[:-1]])
    # the hub angle in encoder steps: a value on a step boundary may round either way
    # after the batched and the single-state routes' different summation orders
    step = p.encoder_step
    assert np.all(np.abs(obs[:, 0] - y[1:, 0]) <= step * (1 + 1e-9) + 1e-9 * np.abs(y[:, 0]).max())
    np.testing.assert_allclose(obs[:, 1:], y[1:, 1:], rtol=1e-7, atol=1e-9 * np.abs(y).max())


def test_env_reads_the_hub_angle_through_the_encoder_and_adds_tachometer_noise():
    env = FlexibleManipulatorEnv(**SMALL)
    env.reset(seed=0)
    obs = np.array([env.step(np.array([0.3]))[0][:4] for _ in range(100)])
    step = 2 * math.pi / 2048
    counts = obs[:, 0] / step
    np.testing.assert_allclose(counts, np.round(counts), atol=1e-9)
    assert len(np.unique(obs[:, 0])) > 5  # it moved through several counts
    quiet = FlexibleManipulatorEnv(**SMALL, tachometer_noise=0.0)
    quiet.reset(seed=0)
    ref = np.array([quiet.step(np.array([0.3]))[0][:4] for _ in range(100)])
    np.testing.assert_array_equal(obs[:, [0, 2, 3]], ref[:, [0, 2, 3]])
    noise = obs[:, 1] - ref[:, 1]
    assert 0.003 < noise.std() < 0.007  # 0.005 rad/s; 100 draws: within +-40 % w.p. > 1 - 1e-6


# ---- rendering ----------------------------------------------------------------------------------
def test_render_draws_the_beam_at_the_hub_angle():
    env = FlexibleManipulatorEnv(render_mode="rgb_array", **SMALL)
    env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (500, 500, 3) and frame.dtype == np.uint8
    beam_colour = np.array([30, 60, 160])
    # at rest the beam lies along +x from the hub centre (250, 250), 0.45 * 500 px long
    np.testing.assert_array_equal(frame[250, 400], beam_colour)
    assert not np.array_equal(frame[100, 250], beam_colour)
    # rotate the whole beam rigidly by 90 degrees: it now points up
    x = env.state.copy()
    x[0] = math.pi / 2
    x[1 : 11] = beam.node_positions(env.params)[1:] * math.pi / 2
    env.state = x
    up = env.render()
    np.testing.assert_array_equal(up[100, 250], beam_colour)
    assert not np.array_equal(up[250, 400], beam_colour)
    assert FlexibleManipulatorEnv(**SMALL).render() is None


def test_canvas_primitives():
    c = Canvas(20, 10, background=(0, 0, 0))
    img = c.frame()
    assert img.shape == (10, 20, 3) and img.dtype == np.uint8 and img.max() == 0
    c.line(2, 5, 17, 5, (255, 0, 0))
    img = c.frame()
    assert np.all(img[5, 2:18, 0] == 255) and img[4, 10, 0] == 0 and img[5, 19, 0] == 0
    c.fill((1, 2, 3)).circle(10, 5, 2, (0, 255, 0))
    img = c.frame()
    assert tuple(img[5, 10]) == (0, 255, 0) and tuple(img[5, 12]) == (0, 255, 0)
    assert tuple(img[5, 13]) == (1, 2, 3) and tuple(img[0, 0]) == (1, 2, 3)
    c.rectangle(0, 0, 3, 2, (9, 9, 9))
    assert tuple(c.frame()[2, 3]) == (9, 9, 9) and tuple(c.frame()[3, 3]) == (1, 2, 3)
    c.line(-50, -50, 100, 100, (7, 7, 7), thickness=3)  # clipped, no error
    px, py = c.to_pixels([1.0], [1.0], scale=2.0, origin=(10, 5))
    assert (px[0], py[0]) == (12.0, 3.0)
    with pytest.raises(ValueError):
        Canvas(0, 5)


# ---- vector env ---------------------------------------------------------------------------------
def _single_rollouts(n_envs, seed, actions, max_steps, options, **kw):
    """Reference: n single envs seeded seed + i, next-step autoreset done by hand.

    Also returns, per observation, the largest terms ``|C| |x|`` and ``|C| |A| |x|`` its
    outputs sum in the episode so far, and the outputs themselves (for the rounding bounds of
    the comparison).
    """
    obs_all, rew_all, term_all, trunc_all, terms_all, y_all = [], [], [], [], [], []
    for i in range(n_envs):
        env = FlexibleManipulatorEnv(**kw)
        model = env._cfg.stepper.model
        # |C| |x| and |C| |A| |x|: the terms of an output and of its one-step update
        c_abs = np.vstack([np.abs(model.C), np.abs(model.C) @ np.abs(model.A)])
        obs, _ = env.reset(seed=seed + i, options=options)
        os_, rs, ts, us = [obs], [], [], []
        terms, ys = [np.abs(env.state) @ c_abs.T], [env._cfg.outputs(env.state)]
        steps, done = 0, False
        for a in actions[:, i]:
            if done:
                obs, _ = env.reset(options=options)
                r, te, tr, steps, done = 0.0, False, False, 0, False
            else:
                obs, r, te, _, _ = env.step(np.array([a]))
                steps += 1
                tr = steps >= max_steps
                done = te or tr
            os_.append(obs)
            rs.append(r)
            ts.append(te)
            us.append(tr)
            terms.append(np.abs(env.state) @ c_abs.T)
            ys.append(env._cfg.outputs(env.state))
        obs_all.append(os_)
        rew_all.append(rs)
        term_all.append(ts)
        trunc_all.append(us)
        terms_all.append(terms)
        y_all.append(ys)
    t = lambda v: np.swapaxes(np.array(v), 0, 1)  # noqa: E731
    terms = t(terms_all)
    terms = np.maximum.accumulate(np.maximum(terms[..., :4], terms[..., 4:]), axis=0)
    return t(obs_all), t(rew_all), t(term_all), t(trunc_all), terms, t(y_all)


@pytest.mark.numerics
def test_vector_env_equals_single_envs_with_autoreset():
    n, seed, steps, max_steps = 4, 11, 220, 100
    kw = {"noise_std": [1e-3, 1e-2, 1e-4, 0.1], "angle_limit": 0.02, "target_range": 0.015,
          "target_angle": 0.0,
          "payload_mass": 0.01, **SMALL}  # fmt: skip
    options = {"random_target": True}
    rng = np.random.default_rng(5)
    actions = rng.uniform(-0.4, 0.4, (steps, n))
    actions[:, 0] = 0.3  # env 0 terminates (hub leaves +-0.02 rad), others truncate at 100
    venv = gymnasium.make_vec(
        ENV_ID, num_envs=n, vectorization_mode="vector_entry_point", max_episode_steps=max_steps,
        **kw,
    )  # fmt: skip
    assert venv.single_action_space == FlexibleManipulatorEnv(**kw).action_space
    assert venv.observation_space.shape == (n, 5)
    obs0, _ = venv.reset(seed=seed, options=options)
    vo, vr, vt, vu = [obs0], [], [], []
    for k in range(steps):
        o, r, te, tr, _ = venv.step(actions[k][:, None])
        vo.append(o)
        vr.append(r)
        vt.append(te)
        vu.append(tr)
    ro, rr, rt, ru, terms, y = _single_rollouts(n, seed, actions, max_steps, options, **kw)
    assert np.any(rt) and np.any(ru)  # the episode includes terminations and truncations
    np.testing.assert_array_equal(np.array(vt), rt)
    np.testing.assert_array_equal(np.array(vu), ru)
    vo = np.array(vo)
    # targets and noise draws are the same numbers from the same generators: exact
    np.testing.assert_array_equal(vo[..., 4], ro[..., 4])
    # Outputs: the batched and single state updates are two routes through at most max_steps
    # steps of an n_x-state recursion (an episode restarts from rest), so they differ by at
    # most max_steps n_x eps times the largest terms so far (tests/numerics.py); adding the same
    # noise draw rounds each to within eps/2 of the observation.
    n_x = beam.discrete_model(beam.BeamParameters(payload_mass=0.01, **SMALL)).n_states
    tol = route_tolerance(n_x, max_steps)
    delta = tol * terms + EPS * np.abs(ro[..., :4])
    assert_close_to_terms(vo[..., :4], ro[..., :4], delta, 1.0)
    # Reward -(w_a e^2 + w_t y_tip^2 + w_u u^2): first order in the output errors above, plus
    # the rounding of its own three terms.
    env = FlexibleManipulatorEnv(**kw)
    w_a, w_t = env._cfg.angle_weight, env._cfg.tip_weight
    err = np.abs(y[1:, :, 0]) + np.abs(ro[1:, :, 4])
    bound = 2 * w_a * err * delta[1:, :, 0] + 2 * w_t * np.abs(y[1:, :, 2]) * delta[1:, :, 2]
    bound += 4 * route_tolerance(3) * np.abs(rr)
    assert np.all(np.abs(np.array(vr) - rr) <= bound + 1e-300)


def test_vector_env_actions_and_errors():
    venv = FlexibleManipulatorVectorEnv(3, **SMALL)
    venv.reset(seed=0)
    _, _, _, _, info = venv.step(np.array([[0.1], [5.0], [-5.0]]))
    np.testing.assert_array_equal(info["applied_torque"], [0.1, 0.3, -0.3])
    np.testing.assert_array_equal(info["clipped"], [False, True, True])
    with pytest.raises(ActionError, match="finite"):
        venv.step(np.array([[0.1], [np.nan], [0.0]]))
    with pytest.raises(ActionError, match="shape"):
        venv.step(np.zeros((2, 1)))
    with pytest.raises(PlantParameterError, match="num_envs"):
        FlexibleManipulatorVectorEnv(0)
    with pytest.raises(PlantParameterError, match="seed"):
        venv.reset(seed=[1, 2])


def test_vector_render():
    venv = FlexibleManipulatorVectorEnv(2, render_mode="rgb_array", **SMALL)
    venv.reset(seed=0)
    frames = venv.render()
    assert len(frames) == 2 and frames[0].shape == (500, 500, 3)


# ---- pickling ---------------------------------------------------------------------------------
def test_envs_pickle_and_step_identically():
    env = gymnasium.make(ENV_ID, noise_std=1e-3, **SMALL).unwrapped
    env.reset(seed=4)
    env.step(np.array([0.2]))
    clone = pickle.loads(pickle.dumps(env))
    for _ in range(70):  # crosses a noise-chunk boundary
        np.testing.assert_array_equal(env.step(np.array([0.1]))[0], clone.step(np.array([0.1]))[0])
    venv = FlexibleManipulatorVectorEnv(3, noise_std=1e-3, **SMALL)
    venv.reset(seed=4)
    vclone = pickle.loads(pickle.dumps(venv))
    a = np.full((3, 1), 0.2)
    for _ in range(70):
        np.testing.assert_array_equal(venv.step(a)[0], vclone.step(a)[0])


@pytest.mark.numerics
@pytest.mark.parametrize("chain", ["lab", "ideal"])
def test_environments_step_the_plants_transition(chain):
    """The envs' steps (beam.Stepper on one state, or on the batch of the vector env) equal
    the plant's pure transition (the registry's PlantFunctions.transition) from the same
    state, and their outputs its output function at zero torque."""
    f = get_plant("manipulator").functions()
    assert f.transition is beam.step_states
    physics = {**SMALL, "payload_mass": 0.01, **(beam.IDEAL_SENSORS if chain == "ideal" else {})}
    env = FlexibleManipulatorEnv(**physics)
    venv = FlexibleManipulatorVectorEnv(3, angle_limit=10.0, **physics)
    p, dt = env.params, env.dt
    model = beam.discrete_model(p, dt)
    assert p.is_linear  # one exact step x A^T + tau B per sample
    n_x = model.n_states
    # Tolerance: a step is one (n_x + 1)-term sum per state, x A^T + tau B, computed by a
    # vector-matrix product (single env), a matrix product over the batch (vector env, the
    # transition): two routes, so route_tolerance(n_x + 1) times the terms |x| |A^T| + |tau|
    # |B| (tests/numerics.py), compared one step at a time from the same state.  The outputs
    # C x: route_tolerance(n_x) times |x| |C^T|.
    a_t, b, c_t = np.abs(model.A.T), np.abs(model.B[:, 0]), np.abs(model.C.T)
    np.testing.assert_array_equal(f.initial_state(p, dt), np.zeros(n_x))
    env.reset(seed=0)
    venv.reset(seed=0)
    rng = np.random.default_rng(2)
    for _ in range(200):
        tau = rng.uniform(-0.3, 0.3, 3)
        x = env.state.copy()
        env.step(np.array([tau[0]]))
        want = f.transition(x[None], tau[:1, None], p, dt)[0]
        assert_close_to_terms(env.state, want, np.abs(x) @ a_t + abs(tau[0]) * b,
                              route_tolerance(n_x + 1))  # fmt: skip
        xs = venv.state.copy()
        _, _, _, _, info = venv.step(tau[:, None])
        want = f.transition(xs, tau[:, None], p, dt)
        assert_close_to_terms(venv.state, want, np.abs(xs) @ a_t + np.abs(tau)[:, None] * b,
                              route_tolerance(n_x + 1))  # fmt: skip
        y = f.output(venv.state, np.zeros((3, 1)), p, dt)
        assert_close_to_terms(info["outputs"], y, np.abs(venv.state) @ c_t, route_tolerance(n_x))
