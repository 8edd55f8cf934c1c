"""Tests of flexid.models.arx: MATLAB convention, exact recovery, prediction, simulation, export.

Noise-free data are made by a plain loop (``simulate_arx``), so "exact" recovery,
prediction and simulation agree with them up to rounding only: those comparisons use the
bounds of tests/numerics.py and tests/route_bounds.py and carry the ``numerics`` mark.  The
Monte-Carlo test has a statistical tolerance (far above rounding).
"""

from __future__ import annotations

import control
import numpy as np
import pytest
from scipy import signal

from flexid.data import IOData
from flexid.errors import DataError, ModelOrderError
from flexid.models.arx import ARX, ARXStructure
from numerics import assert_close_to_terms, route_tolerance
from route_bounds import ar_route_bound, lstsq_error, propagate, recovery_error


def simulate_arx(a, bs, nks, u, noise=None):
    """Direct time loop of A(q) y = sum B_i(q) u_i(t - nk_i) + e (zero pre-history)."""
    u = np.atleast_2d(np.asarray(u, float).T).T
    n = u.shape[0]
    y = np.zeros(n)
    for t in range(n):
        acc = 0.0 if noise is None else noise[t]
        for i, ai in enumerate(a, start=1):
            if t - i >= 0:
                acc -= ai * y[t - i]
        for j, (b, nk) in enumerate(zip(bs, nks)):
            for i, bi in enumerate(b):
                if t - nk - i >= 0:
                    acc += bi * u[t - nk - i, j]
        y[t] = acc
    return y


def stable_a(rng, na, rmax=0.95):
    pairs = na // 2
    z = rng.uniform(0.5, rmax, pairs) * np.exp(1j * rng.uniform(0.1, 3.0, pairs))
    roots = np.r_[z, z.conj(), rng.uniform(-rmax, rmax, na - 2 * pairs)]
    return np.poly(roots).real[1:]


def loop_terms(phi: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Magnitudes ``|phi(t)| |theta|`` the loop summed for each sample."""
    return np.abs(phi) @ np.abs(theta)


def simulation_bound(m: ARX, u: np.ndarray, y: np.ndarray, theta_err: float = 0.0):
    """Bound on ``m.simulate(u)`` (zero initial state) minus a loop simulation of the model.

    Per step: the rounding of the two routes (``na + nb + 1`` terms, tests/route_bounds.py)
    and, when the loop ran the true parameters, ``|phi(t)|_2 theta_err``; both filtered by
    ``1 / A(q)``.
    """
    s = m.structure
    phi = s._phi_padded(np.asarray(u, float).reshape(len(y), -1), y)
    na, nb = s.na, phi.shape[1] - s.na
    forced_terms = np.abs(phi[:, na:]) @ np.abs(m.theta[na:])
    bound = ar_route_bound(m.theta[None, :na], forced_terms[None], np.zeros(na), y[None],
                           forced_terms[None], nb + 1)[0]  # fmt: skip
    if theta_err:
        bound += propagate(m.theta[None, :na], np.linalg.norm(phi, axis=1)[None] * theta_err)[0]
    return bound


def state_space_bound(A, B, C, D, u):
    """Rounding of ``x(k+1) = A x(k) + B u(k)``, ``y = C x + D u`` run from rest (one route).

    Each state update and output is an ``n + 1``-term sum (tests/numerics.py); the state
    errors reach the output through ``C A^j``, so ``|dy(k)| <= sum_j |C A^j| delta(k-1-j)``
    plus the output's own rounding.
    """
    A, B, C, D = (np.atleast_2d(np.asarray(v, float)) for v in (A, B, C, D))
    n, k = A.shape[0], len(u)
    x = np.zeros(n)
    states = np.empty((k, n))
    for t in range(k):
        states[t] = x
        x = A @ x + B[:, 0] * u[t]
    tol = route_tolerance(n + 1)
    delta = tol * (np.abs(states) @ np.abs(A).T + np.abs(u)[:, None] * np.abs(B[:, 0]))
    gains = np.empty((k, n))
    g = C[0].copy()
    for j in range(k):
        gains[j] = np.abs(g)
        g = g @ A
    out = tol * (np.abs(states) @ np.abs(C[0]) + abs(D[0, 0]) * np.abs(u))
    for t in range(1, k):
        out[t] += np.sum(gains[:t][::-1] * delta[:t])
    return out


def test_matlab_convention_by_hand():
    # ARX(1,1,1): y(t) = -a1 y(t-1) + b1 u(t-1); dyadic numbers, so every product and sum
    # is exact in any order: exact on every machine
    s = ARXStructure(1, 1, 1)
    m = s.model([-0.5, 2.0])
    u = np.array([1.0, 0.0, 0.0, 0.0])
    np.testing.assert_array_equal(m.simulate(u), [0.0, 2.0, 1.0, 0.5])
    # nk = 0: direct feed-through, y(t) = b1 u(t) + b2 u(t-1)
    m0 = ARXStructure(0, 2, 0).model([3.0, 1.0])
    np.testing.assert_array_equal(m0.simulate(u), [3.0, 1.0, 0.0, 0.0])
    assert ARXStructure(2, 3, 2).start == 4
    assert ARXStructure(2, [2, 1], [1, 3]).param_names == ["a1", "a2", "b1[u1]", "b2[u1]", "b1[u2]"]


def test_regressor_layout():
    s = ARXStructure(2, 2, 1)
    u = np.arange(10.0)
    y = np.arange(10.0) * 10
    phi, target = s.regressors(u, y)
    assert phi.shape == (8, 4)
    # row for t = 2: [-y(1), -y(0), u(1), u(0)]
    np.testing.assert_array_equal(phi[0], [-10.0, 0.0, 1.0, 0.0])
    np.testing.assert_array_equal(target, y[2:])


@pytest.mark.numerics
@pytest.mark.parametrize(("na", "nb"), [(2, 2), (8, 8)])
def test_exact_recovery_noise_free(na, nb):
    rng = np.random.default_rng(na)
    a = stable_a(rng, na)
    b = rng.normal(size=nb)
    u = rng.uniform(-1, 1, 1500)
    y = simulate_arx(a, [b], [1], u)
    s = ARXStructure(na, nb, 1)
    m = s.least_squares(u, y)
    theta = np.r_[a, b]
    # exact up to the loop's rounding of y (na + nb terms a sample) and the QR solver's
    # (tests/route_bounds.py)
    phi, target = s.regressors(u, y)
    err = recovery_error(phi, theta, loop_terms(phi, theta), na + nb)
    np.testing.assert_allclose(m.theta, theta, rtol=0, atol=err)
    # residual of theta_ls: at most that of theta (the loop's rounding) plus phi (theta_ls -
    # theta*) and its own rounding (n + 1 terms); the K-term sum of squares
    rho = np.linalg.norm(route_tolerance(na + nb + 1) * loop_terms(phi, theta))
    sigma_max = np.linalg.svd(phi, compute_uv=False)[0]
    resid = 2 * rho + sigma_max * lstsq_error(phi, m.theta, rho)
    k = target.size
    assert m.noise_variance <= resid**2 / (k - na - nb) * (1 + route_tolerance(k + 3))
    # free run from the estimate against the loop's data: both rounding and the
    # parameter error, filtered by 1/A
    bound = simulation_bound(m, u, y, err)
    assert_close_to_terms(m.simulate(u), y, bound, 1.0)
    assert bound.max() < 1e-4 * np.abs(y).max()  # not vacuous


@pytest.mark.numerics
def test_two_inputs_recovered():
    rng = np.random.default_rng(5)
    a = stable_a(rng, 3)
    b1, b2 = rng.normal(size=2), rng.normal(size=3)
    u = rng.uniform(-1, 1, (800, 2))
    y = simulate_arx(a, [b1, b2], [1, 2], u)
    s = ARXStructure(3, [2, 3], [1, 2])
    m = s.least_squares(u, y)
    theta = np.r_[a, b1, b2]
    phi, _ = s.regressors(u, y)
    err = recovery_error(phi, theta, loop_terms(phi, theta), 8)  # as in the test above
    np.testing.assert_allclose(m.theta, theta, rtol=0, atol=err)
    np.testing.assert_allclose(m.b[1], b2, rtol=0, atol=err)


def test_parameter_std_matches_monte_carlo_scale():
    rng = np.random.default_rng(1)
    a, b = [-1.2, 0.5], [1.0, 0.3]
    stds = []
    estimates = []
    for _ in range(60):
        u = rng.uniform(-1, 1, 600)
        e = 0.1 * rng.standard_normal(600)
        y = simulate_arx(a, [b], [1], u, noise=e)
        m = ARXStructure(2, 2, 1).least_squares(u, y)
        estimates.append(m.theta)
        stds.append(m.param_std)
        assert m.noise_variance == pytest.approx(0.01, rel=0.25)
    empirical = np.std(estimates, axis=0)
    np.testing.assert_allclose(np.mean(stds, axis=0), empirical, rtol=0.35)


@pytest.mark.numerics
def test_predict_and_simulate():
    rng = np.random.default_rng(3)
    a, b = stable_a(rng, 4), rng.normal(size=4)
    u = rng.uniform(-1, 1, 300)
    y = simulate_arx(a, [b], [1], u)
    m = ARXStructure(4, 4, 1).model(np.r_[a, b])
    # the prediction phi(t) theta (one GEMV) and the loop sum the same 8 products: within
    # 8 eps of their magnitudes; the residual subtracts once more (9 terms)
    terms = loop_terms(m.structure._phi_padded(u[:, None], y), m.theta)
    assert_close_to_terms(m.predict(u, y), y, terms, route_tolerance(8))
    assert_close_to_terms(m.residuals(u, y), 0.0, terms, route_tolerance(9))
    # measured initial conditions: first `start` samples are the measured ones
    y_noisy = y + 0.01 * rng.standard_normal(300)
    sim = m.simulate(u, y_init=y_noisy[:4])
    np.testing.assert_array_equal(sim[:4], y_noisy[:4])
    ref = simulate_arx(a, [b], [1], u)  # check the recursion after start by a loop
    direct = np.zeros(300)
    direct[:4] = y_noisy[:4]
    for t in range(4, 300):
        lags = [t - 1, t - 2, t - 3, t - 4]
        direct[t] = -np.dot(a, direct[lags]) + np.dot(b, u[lags])
    # two routes (lfilter for B and 1/A from y_init, and two dot products a step) through
    # the recursion from t = 4 on (tests/route_bounds.py)
    phi_u = m.structure._phi_padded(u[:, None], direct)[4:, 4:]
    forced_terms = np.abs(phi_u) @ np.abs(b)
    bound = ar_route_bound(a[None], forced_terms[None], y_noisy[3::-1], direct[None, 4:],
                           forced_terms[None], 4 + 1)[0]  # fmt: skip
    assert_close_to_terms(sim[4:], direct[4:], bound, 1.0)
    assert np.abs(sim - ref).max() > 1e3 * bound.max()  # the initial conditions do matter


@pytest.mark.numerics
def test_iodata_input_and_multi_output_error():
    rng = np.random.default_rng(0)
    u = rng.uniform(-1, 1, 200)
    y = simulate_arx([-0.5], [[1.0]], [1], u)
    data = IOData(u, y, dt=0.5)
    s = ARXStructure(1, 1, 1)
    m = s.least_squares(data)
    assert m.dt == 0.5
    phi, _ = s.regressors(data)
    err = recovery_error(phi, np.array([-0.5, 1.0]), loop_terms(phi, np.array([-0.5, 1.0])), 2)
    np.testing.assert_allclose(m.theta, [-0.5, 1.0], rtol=0, atol=err)
    two = IOData(u, np.c_[y, y], dt=0.5)
    with pytest.raises(DataError, match="select"):
        ARXStructure(1, 1, 1).regressors(two)


@pytest.mark.numerics
def test_poles_zeros_stability_and_exports():
    rng = np.random.default_rng(4)
    a, b = stable_a(rng, 4), rng.normal(size=3)
    m = ARXStructure(4, 3, 1).model(np.r_[a, b], dt=0.01)
    # np.roots of the same coefficients (no leading zero in b): the same call, exact
    poles = np.sort_complex(np.roots(np.r_[1, a]))
    np.testing.assert_array_equal(np.sort_complex(m.poles()), poles)
    np.testing.assert_array_equal(np.sort_complex(m.zeros()), np.sort_complex(np.roots(b)))
    assert m.is_stable and m.max_pole_radius < 1
    u = rng.uniform(-1, 1, 200)
    tf = m.to_control()
    assert tf.dt == 0.01
    # python-control and scipy simulate a state-space realization (x+ = A x + B u): each is
    # within its state-space rounding bound, m.simulate within the recursion's
    sim = m.simulate(u)
    bound = simulation_bound(m, u, sim)
    resp = control.forced_response(tf, T=np.arange(200) * 0.01, U=u)
    ss = control.ss(tf)
    ss_bound = state_space_bound(ss.A, ss.B, ss.C, ss.D, u)
    assert_close_to_terms(resp.outputs, sim, bound + ss_bound, 1.0)
    dlti = m.to_dlti()
    _, yd = signal.dlsim(dlti, u)
    abcd = signal.tf2ss(dlti.num, dlti.den)
    assert_close_to_terms(yd[:, 0], sim, bound + state_space_bound(*abcd, u), 1.0)
    # the paper's printed form for nk = 1: b1 z^(n-1) + ... over z^n + a1 z^(n-1) + ...
    num = np.asarray(tf.num[0][0], float)
    den = np.asarray(tf.den[0][0], float)
    np.testing.assert_allclose(den, np.r_[1, a])
    np.testing.assert_allclose(num[-4:], np.r_[b, 0.0][-4:] if num.size < 5 else num[-4:])
    unstable = ARXStructure(1, 1, 1).model([-1.01, 1.0])
    assert not unstable.is_stable and unstable.max_pole_radius == pytest.approx(1.01)


def test_json_round_trip_is_exact():
    rng = np.random.default_rng(8)
    u = rng.uniform(-1, 1, 300)
    y = simulate_arx([-0.7, 0.1], [[0.3, 0.2]], [1], u, noise=0.01 * rng.standard_normal(300))
    m = ARXStructure(2, 2, 1).least_squares(u, y, dt=0.1)
    back = ARX.from_json(m.to_json())
    np.testing.assert_array_equal(back.theta, m.theta)
    np.testing.assert_array_equal(back.param_std, m.param_std)
    assert back.dt == m.dt and back.noise_variance == m.noise_variance
    assert back.structure == m.structure
    assert "a1" in m.summary() and "stable" in m.summary()
    with pytest.raises(DataError):
        ARX.from_json("{not json")


def test_bad_input():
    s = ARXStructure(2, 2, 1)
    with pytest.raises(ModelOrderError, match="too few samples"):
        s.regressors(np.ones(5), np.ones(5))
    with pytest.raises(ModelOrderError):
        ARXStructure(-1, 2)
    with pytest.raises(ModelOrderError):
        ARXStructure(0, 0)
    with pytest.raises(ModelOrderError):
        ARXStructure(2, [2, 2], [1, 1, 1])
    with pytest.raises(ModelOrderError):
        ARXStructure(2.5, 2)
    y = np.ones(50)
    y[17] = np.nan
    with pytest.raises(DataError, match="17"):
        s.regressors(np.ones(50), y)
    with pytest.raises(DataError, match="50 samples but y has 49"):
        s.regressors(np.ones(50), np.ones(49))
    with pytest.raises(DataError, match="input"):
        s.regressors(np.ones((50, 2)), np.ones(50))
    with pytest.raises(DataError):
        s.model([1.0, 2.0])
