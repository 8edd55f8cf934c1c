"""Tests of flexid.arx: MATLAB convention, exact recovery, prediction, simulation, export."""

from __future__ import annotations

import control
import numpy as np
import pytest
from scipy import signal

from flexid.arx import ARX, ARXStructure
from flexid.data import IOData
from flexid.errors import DataError, ModelOrderError


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


def test_matlab_convention_by_hand():
    # ARX(1,1,1): y(t) = -a1 y(t-1) + b1 u(t-1)
    s = ARXStructure(1, 1, 1)
    m = s.model([-0.5, 2.0])
    u = np.array([1.0, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(m.simulate(u), [0.0, 2.0, 1.0, 0.5])
    # nk = 0: direct feed-through, y(t) = b1 u(t) + b2 u(t-1)
    m0 = ARXStructure(0, 2, 0).model([3.0, 1.0])
    np.testing.assert_allclose(m0.simulate(u), [3.0, 1.0, 0.0, 0.0])
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


@pytest.mark.parametrize(("na", "nb"), [(2, 2), (8, 8)])
def test_exact_recovery_noise_free(na, nb):
    rng = np.random.default_rng(na)
    a = stable_a(rng, na)
    b = rng.normal(size=nb)
    u = rng.uniform(-1, 1, 1500)
    y = simulate_arx(a, [b], [1], u)
    m = ARXStructure(na, nb, 1).least_squares(u, y)
    np.testing.assert_allclose(m.theta, np.r_[a, b], atol=1e-8)
    assert m.noise_variance < 1e-20
    np.testing.assert_allclose(m.simulate(u), y, atol=1e-8 * np.abs(y).max())


def test_two_inputs_recovered():
    rng = np.random.default_rng(5)
    a = stable_a(rng, 3)
    b1, b2 = rng.normal(size=2), rng.normal(size=3)
    u = rng.uniform(-1, 1, (800, 2))
    y = simulate_arx(a, [b1, b2], [1, 2], u)
    m = ARXStructure(3, [2, 3], [1, 2]).least_squares(u, y)
    np.testing.assert_allclose(m.theta, np.r_[a, b1, b2], atol=1e-8)
    np.testing.assert_allclose(m.b[1], b2, atol=1e-8)


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


def test_predict_and_simulate():
    rng = np.random.default_rng(3)
    a, b = stable_a(rng, 4), rng.normal(size=4)
    u = rng.uniform(-1, 1, 300)
    y = simulate_arx(a, [b], [1], u)
    m = ARXStructure(4, 4, 1).model(np.r_[a, b])
    np.testing.assert_allclose(m.predict(u, y), y, atol=1e-12)
    np.testing.assert_allclose(m.residuals(u, y), 0.0, atol=1e-12)
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
    np.testing.assert_allclose(sim, direct, atol=1e-10)
    assert np.abs(sim - ref).max() > 0


def test_iodata_input_and_multi_output_error():
    rng = np.random.default_rng(0)
    u = rng.uniform(-1, 1, 200)
    y = simulate_arx([-0.5], [[1.0]], [1], u)
    data = IOData(u, y, dt=0.5)
    m = ARXStructure(1, 1, 1).least_squares(data)
    assert m.dt == 0.5
    np.testing.assert_allclose(m.theta, [-0.5, 1.0], atol=1e-10)
    two = IOData(u, np.c_[y, y], dt=0.5)
    with pytest.raises(DataError, match="select"):
        ARXStructure(1, 1, 1).regressors(two)


def test_poles_zeros_stability_and_exports():
    rng = np.random.default_rng(4)
    a, b = stable_a(rng, 4), rng.normal(size=3)
    m = ARXStructure(4, 3, 1).model(np.r_[a, b], dt=0.01)
    np.testing.assert_allclose(np.sort_complex(m.poles()), np.sort_complex(np.roots(np.r_[1, a])))
    np.testing.assert_allclose(np.sort_complex(m.zeros()), np.sort_complex(np.roots(b)))
    assert m.is_stable and m.max_pole_radius < 1
    u = rng.uniform(-1, 1, 200)
    tf = m.to_control()
    assert tf.dt == 0.01
    resp = control.forced_response(tf, T=np.arange(200) * 0.01, U=u)
    np.testing.assert_allclose(resp.outputs, m.simulate(u), atol=1e-10)
    _, yd = signal.dlsim(m.to_dlti(), u)
    np.testing.assert_allclose(yd[:, 0], m.simulate(u), atol=1e-10)
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
