"""Tests of flexid.envs.beam: exact frequencies, FD model, ZOH exactness, simulate."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from flexid.envs import beam
from flexid.envs.beam import BeamParameters
from flexid.errors import PlantParameterError
from numerics import assert_close_to_terms, route_tolerance

# exact modes (Hz) of the hub-inertia beam: roots of the frequency equation, two root-finders
EXACT_NO_PAYLOAD = [11.853, 32.238, 58.491, 102.571]
EXACT_20G = [10.206, 29.434, 53.660, 93.871]
CLAMPED_FREE_BETA_L = [1.87510, 4.69409, 7.85476]
PINNED_FREE_BETA_L = [3.92660, 7.06858, 10.21018]


def _closed_form(lam, mu_h, mu_p):
    """Closed-form frequency equation for J_p = 0 (independent of the 4x4 determinant)."""
    s, c, sh, ch = np.sin(lam), np.cos(lam), np.sinh(lam), np.cosh(lam)
    return (s * ch - c * sh) + 2 * mu_p * lam * s * sh + mu_h * lam**3 * (
        1 + c * ch + mu_p * lam * (c * sh - s * ch)
    )


def _lam(p: BeamParameters, f):
    return np.sqrt(2 * np.pi * np.asarray(f) / math.sqrt(
        p.flexural_rigidity / (p.mass_per_length * p.length**4)
    ))


def _close(actual, desired, rel):
    """Equal up to ``rel`` times the largest magnitude of each output channel."""
    scale = np.abs(desired).reshape(-1, 4).max(axis=0)
    err = np.abs(np.asarray(actual) - desired).reshape(-1, 4).max(axis=0)
    assert np.all(err <= rel * scale), (err, scale)


# ---- parameters ---------------------------------------------------------------------------
def test_derived_quantities_match_plants_md():
    p = BeamParameters()
    assert p.flexural_rigidity == pytest.approx(3.686602, rel=1e-6)
    assert p.mass_per_length == pytest.approx(0.164858, rel=1e-5)
    assert p.beam_inertia == pytest.approx(0.048619, rel=1e-5)
    assert p.total_inertia == pytest.approx(0.049205, rel=1e-5)
    q = BeamParameters(payload_mass=0.02, payload_inertia=1e-5)
    assert q.total_inertia == pytest.approx(p.total_inertia + 0.02 * 0.96**2 + 1e-5)


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"length": -1.0}, "length"),
        ({"width": 0.0}, "width"),
        ({"youngs_modulus": float("nan")}, "youngs_modulus"),
        ({"hub_inertia": "big"}, "hub_inertia"),
        ({"payload_mass": -0.01}, "payload_mass"),
        ({"hub_coulomb_friction": float("inf")}, "hub_coulomb_friction"),
        ({"damping_ratios": (0.02, 1.0)}, "damping_ratios"),
        ({"damping_ratios": ()}, "damping_ratios"),
        ({"n_sections": 3}, "n_sections"),
        ({"n_sections": 40.0}, "n_sections"),
        ({"n_sections": True}, "n_sections"),
    ],
)
def test_bad_parameters_raise_naming_the_parameter(kwargs, name):
    with pytest.raises(PlantParameterError, match=name):
        BeamParameters(**kwargs)


def test_parameters_are_hashable_and_normalised():
    a = BeamParameters(damping_ratios=[0.02, 0.03], payload_mass=1)
    b = BeamParameters(damping_ratios=(0.02, 0.03), payload_mass=1.0)
    assert a == b and hash(a) == hash(b)
    assert a.damping_ratio(1) == 0.02
    assert a.replace(damping_law="constant").damping_ratio(7) == 0.03
    assert BeamParameters(damping_ratios=0.05).damping_ratios == (0.05,)


# ---- exact frequencies ---------------------------------------------------------------------
@pytest.mark.parametrize("payload, table", [(0.0, EXACT_NO_PAYLOAD), (0.02, EXACT_20G)])
def test_exact_frequencies_reproduce_table(payload, table):
    f = beam.exact_frequencies(BeamParameters(payload_mass=payload), n_modes=4)
    np.testing.assert_allclose(f, table, atol=1e-3)


@pytest.mark.parametrize("payload", [0.0, 0.01, 0.05, 0.1])
def test_exact_frequencies_are_roots_of_the_closed_form(payload):
    p = BeamParameters(payload_mass=payload)
    lam = _lam(p, beam.exact_frequencies(p, n_modes=4))
    mu_h = p.hub_inertia / (p.mass_per_length * p.length**3)
    mu_p = payload / (p.mass_per_length * p.length)
    # a sign change of the independent closed form within +-1e-7 of each root
    lo = _closed_form(lam - 1e-7, mu_h, mu_p)
    hi = _closed_form(lam + 1e-7, mu_h, mu_p)
    assert np.all(lo * hi < 0)


def test_exact_frequencies_limits():
    stiff_hub = BeamParameters(hub_inertia=1e6)
    np.testing.assert_allclose(
        _lam(stiff_hub, beam.exact_frequencies(stiff_hub)), CLAMPED_FREE_BETA_L, atol=2e-5
    )
    light_hub = BeamParameters(hub_inertia=1e-14)
    np.testing.assert_allclose(
        _lam(light_hub, beam.exact_frequencies(light_hub)), PINNED_FREE_BETA_L, atol=2e-5
    )


def test_exact_frequencies_bad_n_modes():
    with pytest.raises(PlantParameterError, match="n_modes"):
        beam.exact_frequencies(None, 0)


# ---- finite-difference model ---------------------------------------------------------------
def test_fd_matrices_structure():
    p = BeamParameters(n_sections=10, payload_mass=0.03, payload_inertia=1e-4)
    m, k, b = beam.fd_matrices(p)
    assert m.shape == k.shape == (11, 11) and b.shape == (11,)
    np.testing.assert_allclose(m, m.T)
    np.testing.assert_allclose(k, k.T, atol=1e-9 * np.abs(k).max())
    assert np.all(np.linalg.eigvalsh(m) > 0)
    # rigid rotation y_i = x_i theta is the stiffness null vector
    rigid = np.concatenate([[1.0], beam.node_positions(p)[1:]])
    assert np.abs(k @ rigid).max() < 1e-9 * np.abs(k).max()
    # total rigid inertia of the lumped model: I_h + sum m_i x_i^2 (+ J_p)
    assert rigid @ m @ rigid == pytest.approx(p.total_inertia, rel=0.01)
    np.testing.assert_array_equal(b, np.eye(11)[0])


@pytest.mark.parametrize("payload, table", [(0.0, EXACT_NO_PAYLOAD), (0.02, EXACT_20G)])
def test_fd_frequencies_within_one_percent(payload, table):
    p = BeamParameters(payload_mass=payload)
    f_fd = beam.natural_frequencies(p, 3)
    np.testing.assert_allclose(f_fd, table[:3], rtol=0.01)
    assert np.all(f_fd < np.array(table[:3]))  # the FD model converges from below


def test_fd_frequencies_converge_with_sections():
    exact = beam.exact_frequencies(None, 3)
    errors = [
        np.abs(beam.natural_frequencies(BeamParameters(n_sections=n), 3) / exact - 1).max()
        for n in (10, 20, 40)
    ]
    assert errors[0] > errors[1] > errors[2]
    assert errors[1] / errors[2] == pytest.approx(4.0, rel=0.25)  # O(dx^2)


def test_payload_inertia_lowers_frequencies_like_the_exact_solution():
    p = BeamParameters(payload_mass=0.02, payload_inertia=5e-5)
    np.testing.assert_allclose(
        beam.natural_frequencies(p, 3), beam.exact_frequencies(p, 3), rtol=0.01
    )
    assert np.all(beam.exact_frequencies(p, 3) < np.array(EXACT_20G[:3]))


def test_collocated_pole_zero_interlacing():
    p = BeamParameters()
    m, k, _ = beam.fd_matrices(p)
    poles = beam.natural_frequencies(p, 4)
    w2 = np.sort(np.linalg.eigvals(np.linalg.solve(m[1:, 1:], k[1:, 1:])).real)
    zeros = np.sqrt(w2[:4]) / (2 * np.pi)
    # zeros of tau -> theta are the locked-hub (clamped-free) frequencies 2.871, 17.994, 50.385
    np.testing.assert_allclose(zeros[:3], [2.871, 17.994, 50.385], rtol=0.01)
    assert zeros[0] < poles[0] < zeros[1] < poles[1] < zeros[2] < poles[2] < zeros[3] < poles[3]

    # and they are zeros of the undamped frequency response e' (K - w^2 M)^-1 e
    def g(f):
        w = 2 * np.pi * f
        return np.linalg.solve(k - w**2 * m, np.eye(len(m))[0])[0]

    for z in zeros[:3]:
        assert abs(g(z)) < 1e-6 * abs(g(0.9 * z))


# ---- discretisation and simulation ---------------------------------------------------------
def _bang_bang(n=2000, dt=1e-3, tau=0.3, width=0.3):
    t = np.arange(n) * dt
    return np.where(t < width, tau, np.where(t < 2 * width, -tau, 0.0))


@pytest.mark.parametrize("payload", [0.0, 0.02])
def test_rigid_body_final_angle_of_bang_bang(payload):
    p = BeamParameters(payload_mass=payload)
    y = beam.simulate(_bang_bang(), p)
    expected = 0.3 * 0.3**2 / p.total_inertia
    if payload == 0.0:
        assert expected == pytest.approx(0.5487, abs=1e-4)
    assert y[1000:, 0].mean() == pytest.approx(expected, rel=0.01)
    assert abs(y[-300:, 1]).max() < 0.1 * abs(y[:, 1]).max()  # hub at rest apart from ringing


def test_bang_bang_regression_numbers_plants_md():
    y = beam.simulate(_bang_bang())
    assert abs(y[:, 0]).max() == pytest.approx(0.5767, rel=0.01)
    assert abs(y[:, 2]).max() == pytest.approx(0.06075, rel=0.03)
    assert abs(y[:, 3]).max() == pytest.approx(126.0, rel=0.05)


@pytest.mark.parametrize("chain", ["ideal", "lab"])
def test_zoh_matches_fine_step_integration(chain):
    # the lab chain's model integrated independently: actuator, accelerometer and the
    # anti-aliasing filter act on the continuous signals, before the sampler
    ideal = beam.IDEAL_SENSORS if chain == "ideal" else {}
    p = BeamParameters(n_sections=8, damping_ratios=(0.02, 0.03, 0.05), **ideal)
    dt, n = 2e-3, 60
    rng = np.random.default_rng(1)
    u = rng.uniform(-0.3, 0.3, n)
    a, b, c, d = beam.measured_model(p, dt)
    if chain == "ideal":
        np.testing.assert_array_equal(a, beam.continuous_model(p)[0])
    x = np.zeros(a.shape[0])
    ref = np.empty((n, 4))
    for i in range(n):
        ref[i] = c @ x + d[:, 0] * u[i]
        sol = solve_ivp(
            lambda t, s, ui=u[i]: a @ s + b[:, 0] * ui,
            (0.0, dt), x, method="DOP853", rtol=1e-11, atol=1e-14,
        )  # fmt: skip
        x = sol.y[:, -1]
    y = beam.measure(beam.simulate(u, p, dt=dt), p)
    ref[:, 0] = beam.measure(ref, p)[:, 0]
    scale = np.abs(ref).max(axis=0)
    np.testing.assert_allclose(y / scale, ref / scale, atol=1e-8)


def test_simulate_equals_state_space_recursion_with_x0_and_batch():
    p = BeamParameters(payload_mass=0.01, hub_viscous_friction=0.002)
    model = beam.discrete_model(p, 1e-3)
    rng = np.random.default_rng(7)
    u = rng.uniform(-0.3, 0.3, (3, 500))
    x0 = rng.normal(0, 1e-3, (3, model.n_states))
    y = beam.simulate(u, p, x0=x0)
    assert y.shape == (3, 500, 4)
    x = x0.copy()
    for k in range(500):
        ref = x @ model.C.T + u[:, k : k + 1] * model.D[:, 0]
        np.testing.assert_allclose(y[:, k], ref, rtol=1e-7, atol=1e-9 * np.abs(ref).max())
        x = x @ model.A.T + u[:, k : k + 1] * model.B[:, 0]
    # a single run equals its row of the batch; a shared x0 broadcasts
    _close(beam.simulate(u[1], p, x0=x0[1]), y[1], 1e-10)
    yb = beam.simulate(u, p, x0=x0[0])
    _close(yb[0], y[0], 1e-10)


def test_hub_viscous_friction_gives_analytic_terminal_velocity():
    c_h, tau = 0.05, 0.1
    p = BeamParameters(hub_viscous_friction=c_h)
    y = beam.simulate(np.full(8000, tau), p)
    # rigid-body time constant J / c_h ~ 1 s; after 8 s the velocity is tau / c_h (1 - e^-8)
    assert y[-1, 1] == pytest.approx(tau / c_h * (1 - math.exp(-8000e-3 * c_h / p.total_inertia)),
                                     rel=2e-3)  # fmt: skip


def _states(u, p):
    """States x[k] of one run stepped sample by sample, shape (N, n_x)."""
    stepper = beam.Stepper(p)
    x = np.zeros((1, stepper.n_states))
    out = np.empty((u.size, stepper.n_states))
    for k in range(u.size):
        out[k] = x[0]
        x = stepper.step(x, u[k : k + 1])
    return out


def _output_terms(u, p):
    """Largest terms of each output over a run: max_k of |C| |x[k]| and |C| |A| |x[k]|.

    The first is what the output sums, the second what its one-step update sums.
    """
    model = beam.discrete_model(p)
    c_abs = np.abs(model.C)
    x = np.abs(_states(u, p))
    return np.maximum(x @ c_abs.T, x @ (c_abs @ np.abs(model.A)).T).max(axis=0)


@pytest.mark.numerics
def test_coulomb_friction_nonlinear_path():
    u = _bang_bang(1500)
    lin = beam.simulate(u)
    p0 = BeamParameters()
    n_x = beam.discrete_model(p0).n_states
    # Two routes through 1500 steps of an n_x-state stable recursion (FFT convolution of the
    # impulse response, and the stepped path; a batch of two and single runs): they differ by
    # at most N n_x eps times the terms |C| |x| (tests/numerics.py).  The tip acceleration's
    # terms are ~1e6 times its value (C row ~ M^-1 K), so it is compared to its terms.
    tol = route_tolerance(n_x, u.size)
    # the stepped path with zero friction is the same linear model
    stepped = beam._simulate_coulomb(u[None], p0, beam.discrete_model(p0), None)[0]
    assert_close_to_terms(stepped, lin, _output_terms(u, p0), tol)
    pf = BeamParameters(hub_coulomb_friction=0.05)
    fr = beam.simulate(u, pf)
    assert 0 < fr[-1, 0] < lin[-1, 0]
    # friction larger than the torque: the hub creeps at the smoothed-Coulomb equilibrium
    # velocity v_s atanh(tau / tau_c) (substeps keep the explicit friction update stable)
    stuck = beam.simulate(np.full(2000, 0.05), BeamParameters(hub_coulomb_friction=0.2))
    free = beam.simulate(np.full(2000, 0.05))
    assert abs(stuck[-1, 0]) < 0.1 * abs(free[-1, 0])
    assert stuck[-100:, 1].mean() == pytest.approx(0.05 * math.atanh(0.25), rel=0.01)
    assert beam.Stepper(BeamParameters(hub_coulomb_friction=0.2)).n_substeps == 7
    # batched nonlinear simulation equals single runs; the friction update is dissipative
    # (substeps keep it inside its stability limit), so errors add per step as above, with
    # n_substeps steps per sample
    both = beam.simulate(np.stack([u, -u]), pf)
    terms = _output_terms(u, pf)
    tol_f = route_tolerance(n_x, u.size * beam.Stepper(pf).n_substeps)
    assert_close_to_terms(both[0], fr, terms, tol_f)
    assert_close_to_terms(both[1], -fr, terms, tol_f)
    # the bound is not vacuous: a one-sample shift of the input breaks it
    shifted = beam.simulate(np.concatenate([[0.0], u[:-1]]), pf)
    with pytest.raises(AssertionError):
        assert_close_to_terms(shifted, fr, terms, tol_f)


def test_discrete_model_is_cached_and_read_only():
    m1 = beam.discrete_model(BeamParameters(payload_mass=0.02), 1e-3)
    m2 = beam.discrete_model(BeamParameters(payload_mass=0.02), 0.001)
    assert m1 is m2
    assert m1 is not beam.discrete_model(BeamParameters(payload_mass=0.02), 5e-4)
    with pytest.raises(ValueError):
        m1.A[0, 0] = 1.0


def test_output_metadata():
    assert beam.OUTPUT_NAMES == ("hub_angle", "hub_velocity", "tip_deflection", "tip_acceleration")
    assert beam.OUTPUT_UNITS == ("rad", "rad/s", "m", "m/s^2")
    assert beam.simulate(np.zeros(3)).shape == (3, 4)
    assert beam.simulate([0.3]).shape == (1, 4)


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: beam.simulate(np.array([0.1, np.nan])), "torque"),
        (lambda: beam.simulate(np.zeros((2, 3, 4))), "shape"),
        (lambda: beam.simulate(np.zeros(0)), "shape"),
        (lambda: beam.simulate(np.zeros(5), dt=0.0), "dt"),
        (lambda: beam.simulate(np.zeros(5), x0=np.zeros(3)), "x0"),
        (lambda: beam.simulate(np.zeros(5), params={"length": 1}), "params"),
        (lambda: beam.natural_frequencies(None, 41), "n_modes"),
    ],
)
def test_bad_simulation_input_raises(call, match):
    with pytest.raises(PlantParameterError, match=match):
        call()


def test_blockwise_powers_equal_recursion(monkeypatch):
    monkeypatch.setattr(beam, "_BLOCK_ELEMENTS", 7 * 22)  # blocks of 7 (1 run) or 2 (3 runs)
    p = BeamParameters(n_sections=10, payload_mass=0.013)
    model = beam.BeamModel(p, 1e-3)
    rng = np.random.default_rng(3)
    x0 = rng.normal(0, 1e-3, (3, model.n_states))
    got = model.projected_powers(x0, 50, model.C)
    h = model.markov_parameters(50)
    x, v = x0.copy(), model.B[:, 0].copy()
    for k in range(50):
        _close(got[k], x @ model.C.T, 1e-10)
        if k:
            _close(h[k], model.C @ v, 1e-10)
            v = model.A @ v
        x = x @ model.A.T
