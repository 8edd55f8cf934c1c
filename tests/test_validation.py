"""Tests of flexid.validation against exact values, brute-force loops and known statistics.

Statistical checks (false-alarm rates, Parseval within 5 %, spectral peaks within a bin)
and fits within 1e-10 % or 1e-6 of a percent of the same formula are far above rounding.
The FFT correlation against the brute-force loop, and the pole maps, are two routes whose
difference is rounding only: their tolerances are derived below and the tests carry the
``numerics`` mark.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import fft as sfft
from scipy.signal import lfilter

from flexid.data import IOData
from flexid.errors import DataError, ModelOrderError
from flexid.validation import stability_report, validate
from flexid.validation.diagnostics import (
    billings_voon_tests,
    correlation_bound,
    error_range,
    fit_percent,
    psd,
    residual_tests,
    rmse,
    xcorr,
)
from numerics import EPS


# ---------------------------------------------------------------- a small independent ARX model
@dataclass
class _Structure:
    na: int
    nb: tuple
    nk: tuple
    start: int
    n_params: int


class LoopARX:
    """Reference ARX written with plain loops: A(q) y(t) = sum_i B_i(q) u_i(t - nk_i).

    ``a = [1, a1, .., a_na]``, ``b[i] = [b0, .., b_{nb-1}]`` acting on u_i(t - nk_i - j).
    Independent of flexid.models.arx, duck-typed to its API.
    """

    def __init__(self, a, b, nk, dt=1.0):
        self.a = np.asarray(a, float)
        self.b = [np.asarray(bi, float) for bi in b]
        self.nk = tuple(nk)
        na = self.a.size - 1
        nb = tuple(bi.size for bi in self.b)
        start = max([na] + [k + n - 1 for k, n in zip(self.nk, nb)])
        self.structure = _Structure(na, nb, self.nk, start, na + sum(nb))
        self.dt = dt

    def _u(self, u):
        u = np.asarray(u, float)
        return u[:, None] if u.ndim == 1 else u

    def _input_part(self, u, t):
        s = 0.0
        for i, bi in enumerate(self.b):
            for j, bj in enumerate(bi):
                k = t - self.nk[i] - j
                if k >= 0:
                    s += bj * u[k, i]
        return s

    def _output(self, u, t, past):
        """y(t) from the inputs and the outputs ``past`` (measured, or the model's own)."""
        s = self._input_part(u, t)
        for i in range(1, self.a.size):
            if t - i >= 0:
                s -= self.a[i] * past[t - i]
        return s

    def predict(self, u, y):
        u = self._u(u)
        y = np.asarray(y, float)
        out = np.zeros(y.size)
        for t in range(y.size):
            out[t] = self._output(u, t, y)
        return out

    def simulate(self, u, y_init=None):
        u = self._u(u)
        n = u.shape[0]
        out = np.zeros(n)
        t0 = 0
        if y_init is not None:
            t0 = self.structure.start
            out[:t0] = np.asarray(y_init, float)[:t0]
        with np.errstate(over="ignore", invalid="ignore"):  # unstable models may overflow
            for t in range(t0, n):
                out[t] = self._output(u, t, out)
        return out

    def residuals(self, u, y):
        return np.asarray(y, float) - self.predict(u, y)

    def poles(self):
        return np.roots(self.a)

    def zeros(self, input=0):
        return np.roots(self.b[input])


def _simulate_arx(a, b, nk, u, e):
    """Data from A(q) y = B(q) u(t - nk) + e (single input), loop reference."""
    n = u.size
    y = np.zeros(n)
    for t in range(n):
        s = e[t]
        for j, bj in enumerate(b):
            if t - nk - j >= 0:
                s += bj * u[t - nk - j]
        for i in range(1, len(a)):
            if t - i >= 0:
                s -= a[i] * y[t - i]
        y[t] = s
    return y


def _fit_arx(u, y, na, nb, nk):
    """Least-squares ARX over t >= start (plain regressor build, independent of flexid)."""
    start = max(na, nk + nb - 1)
    rows = []
    for t in range(start, y.size):
        rows.append([-y[t - i] for i in range(1, na + 1)] + [u[t - nk - j] for j in range(nb)])
    theta, *_ = np.linalg.lstsq(np.array(rows), y[start:], rcond=None)
    return LoopARX(np.r_[1.0, theta[:na]], [theta[na:]], [nk])


# ---------------------------------------------------------------- fit numbers
def test_fit_percent_exact_cases():
    rng = np.random.default_rng(1)
    y = rng.normal(size=50)
    assert fit_percent(y, y) == 100.0
    # y - yhat is the very array y - mean(y) of the scale: exactly 0
    assert fit_percent(y, np.full_like(y, y.mean())) == 0.0
    # hand example: ||y - yhat|| = 1, ||y - mean|| = sqrt(2)
    assert fit_percent([1, 2, 3], [1, 2, 4]) == pytest.approx(100 * (1 - 1 / math.sqrt(2)))
    assert fit_percent([1, 2, 3], [3, 2, 1]) == pytest.approx(100 * (1 - math.sqrt(8 / 2)))


def test_rmse_and_error_range_by_hand():
    y = [1.0, 2.0, 3.0, 4.0]
    yhat = [1.5, 2.0, 2.0, 4.0]
    assert rmse(y, yhat) == pytest.approx(math.sqrt((0.25 + 1.0) / 4))
    assert error_range(y, yhat) == (-0.5, 1.0)


@pytest.mark.parametrize(
    "y, yhat, match",
    [
        ([1.0, np.nan, 2.0], [1.0, 2.0, 3.0], "non-finite"),
        ([1.0, 2.0, 3.0], [1.0, np.inf, 3.0], "non-finite"),
        ([1.0, 2.0, 3.0], [1.0, 2.0], "different lengths"),
        ([2.0, 2.0, 2.0], [1.0, 2.0, 3.0], "constant"),
    ],
)
def test_fit_bad_input(y, yhat, match):
    with pytest.raises(DataError, match=match):
        fit_percent(y, yhat)


# ---------------------------------------------------------------- xcorr
def _xcorr_loop(a, b, max_lag):
    a = np.asarray(a, float) - np.mean(a)
    b = np.asarray(b, float) - np.mean(b)
    n = a.size
    scale = math.sqrt(sum(v * v for v in a) * sum(v * v for v in b))
    out = []
    for tau in range(-max_lag, max_lag + 1):
        s = 0.0
        for t in range(n):
            if 0 <= t - tau < n:
                s += a[t] * b[t - tau]
        out.append(s / scale)
    return np.array(out)


def fft_tolerance(n: int, max_lag: int) -> float:
    """Bound on the rounding of ``xcorr``'s FFT correlation, relative to ``|a| |b|``.

    A radix-2 FFT of length N is within ``log2(N) eta |x|`` of the exact transform in the
    2-norm, ``eta = mu + gamma_4 (sqrt 2 + mu) ~ 3.4 eps`` (Higham, *Accuracy and Stability
    of Numerical Algorithms*, Thm 24.2).  Two forward transforms, the product (``|B|_inf <=
    |b|_1 <= sqrt(n) |b|``) and the inverse give at most ``(3 x 3.4 log2 N + 1.5) sqrt(n)
    eps |a| |b|`` in each lag.
    """
    nfft = sfft.next_fast_len(n + max_lag, real=True)
    return (11 * math.log2(nfft) + 2) * math.sqrt(n) * EPS


def xcorr_tolerance(n: int, max_lag: int) -> float:
    """``xcorr`` (FFT) against ``_xcorr_loop``: the FFT bound, plus the loop's ``n``-term sums
    and both normalisations (``n`` eps relative each), in units of the normalised ``r``."""
    return fft_tolerance(n, max_lag) + 2 * n * EPS


@pytest.mark.numerics
@pytest.mark.parametrize("n, max_lag", [(7, 6), (64, 10), (257, 40), (1000, 25)])
def test_xcorr_equals_brute_force(n, max_lag):
    rng = np.random.default_rng(n)
    a = rng.normal(size=n) + 3.0
    b = rng.normal(size=n) * 2 - 1.0
    lags, r = xcorr(a, b, max_lag)
    np.testing.assert_array_equal(lags, np.arange(-max_lag, max_lag + 1))
    # the same centred signals (np.mean both times); two routes to the sums
    np.testing.assert_allclose(r, _xcorr_loop(a, b, max_lag), rtol=0,
                               atol=xcorr_tolerance(n, max_lag))  # fmt: skip


@pytest.mark.numerics
def test_xcorr_sign_convention_and_autocorrelation():
    rng = np.random.default_rng(3)
    b = rng.normal(size=500)
    a = np.r_[np.zeros(3), b[:-3]]  # a(t) = b(t - 3): a correlates with b at lag +3
    lags, r = xcorr(a, b, 5)
    assert lags[np.argmax(r)] == 3
    lags, r = xcorr(b, b, 5)
    assert r[lags == 0][0] == pytest.approx(1.0)
    # symmetric exactly; the FFT rounds lags +k and -k differently
    np.testing.assert_allclose(r, r[::-1], rtol=0, atol=2 * fft_tolerance(500, 5))
    assert np.all(xcorr(np.ones(10), b[:10], 3)[1] == 0.0)


@pytest.mark.numerics
def test_xcorr_of_a_diverging_signal_is_not_zero():
    """A residual that grows to 1e200 (an unstable predictor) has the correlations of its
    shape: the sums must not overflow to inf and every coefficient to 0 (which passes every
    test)."""
    rng = np.random.default_rng(5)
    u = rng.normal(size=400)
    e = np.r_[0.0, u[:-1]] * 1.05 ** np.arange(400) * 1e190  # grows past 1e200
    lags, r = xcorr(e, u, 5)
    _, r_small = xcorr(e / 1e190, u, 5)
    np.testing.assert_allclose(r, r_small, rtol=0, atol=1e-12)  # the scale cancels
    assert abs(r[lags == 1][0]) > 0.05
    auto, cross = residual_tests(e, u[:, None], 5)
    assert not (auto.passed and cross[0].passed)


def test_xcorr_bad_input():
    with pytest.raises(DataError, match="different lengths"):
        xcorr(np.ones(5), np.ones(6), 2)
    with pytest.raises(DataError, match="max_lag"):
        xcorr(np.arange(5.0), np.arange(5.0), 5)
    with pytest.raises(DataError, match="non-finite"):
        xcorr(np.array([1.0, np.nan, 2.0]), np.ones(3), 1)


# ---------------------------------------------------------------- false-alarm rate
def test_bound_is_1_96_over_sqrt_n():
    assert correlation_bound(1000) == pytest.approx(1.959964 / math.sqrt(1000), rel=1e-6)


@pytest.mark.slow
def test_false_alarm_rate_on_white_noise():
    rng = np.random.default_rng(2024)
    draws, n, lags = 400, 1000, 20
    auto_out = cross_out = auto_fail = cross_fail = 0
    sysidentpy_out = 0
    for _ in range(draws):
        e = rng.normal(size=n)
        u = rng.normal(size=n)
        auto, cross = residual_tests(e, u, lags)
        auto_out += auto.n_outside
        cross_out += cross.n_outside
        auto_fail += not auto.passed
        cross_fail += not cross.passed
        assert auto.n_lags == lags and cross.n_lags == 2 * lags + 1
        r = auto.values[auto.counted]
        sysidentpy_out += int(np.sum(np.abs(r) > 1.96 / math.sqrt(2 * n - 1)))
    auto_rate = auto_out / (draws * lags)
    cross_rate = cross_out / (draws * (2 * lags + 1))
    assert 0.035 <= auto_rate <= 0.065, auto_rate
    assert 0.035 <= cross_rate <= 0.065, cross_rate
    # the narrower sqrt(2N-1) band flags far more (about 16 %): the check can tell them apart
    assert sysidentpy_out / (draws * lags) > 0.12
    # each test alone rejects a valid residual at its level, 5 %: 400 draws give a binomial
    # standard deviation of 1.1 %, so [1.5, 9] % is more than three of them either side
    assert 0.015 <= auto_fail / draws <= 0.09 and 0.015 <= cross_fail / draws <= 0.09


@pytest.mark.slow
def test_false_alarm_rate_billings_voon_on_white_noise():
    rng = np.random.default_rng(77)
    draws, n, lags = 200, 1000, 20
    outside = np.zeros(3)
    counted = np.zeros(3)
    for _ in range(draws):
        tests = billings_voon_tests(rng.normal(size=n), rng.normal(size=n), lags)
        outside += [t.n_outside for t in tests]
        counted += [t.n_lags for t in tests]
    rates = outside / counted
    assert np.all((rates > 0.03) & (rates < 0.075)), rates


# ---------------------------------------------------------------- tests detect what they should
def _arx_221_data(n=2000, seed=5):
    rng = np.random.default_rng(seed)
    u = rng.normal(size=n)
    e = 0.05 * rng.normal(size=n)
    a, b = [1.0, -1.5, 0.7], [1.0, 0.5]
    return u, _simulate_arx(a, b, 1, u, e)


def test_under_ordered_model_fails_autocorrelation_correct_order_passes():
    u, y = _arx_221_data()
    low = validate(_fit_arx(u, y, 1, 1, 1), (u, y), max_lag=20)
    right = validate(_fit_arx(u, y, 2, 2, 1), (u, y), max_lag=20)
    assert not low.test("auto e").passed
    assert not low.passed
    assert right.test("auto e").passed
    assert right.linear_passed
    assert right.fit_one_step > low.fit_one_step


def test_billings_voon_flags_unmodelled_nonlinearity():
    rng = np.random.default_rng(11)
    n = 3000
    u = rng.normal(size=n)
    x = _simulate_arx([1.0, -0.6], [1.0], 1, u, np.zeros(n))
    noise = 0.05 * rng.normal(size=n)
    y_lin = x + noise
    y_nl = x + 0.5 * x**2 + noise  # Wiener-type y + 0.5 y^2 output nonlinearity
    lin = validate(_fit_arx(u, y_lin, 1, 1, 1), (u, y_lin), max_lag=15)
    nl = validate(_fit_arx(u, y_nl, 1, 1, 1), (u, y_nl), max_lag=15)
    assert lin.nonlinear_passed
    assert not nl.nonlinear_passed
    assert not nl.test("BV u2'-e").passed
    assert not nl.passed


@pytest.mark.numerics
def test_billings_voon_definitions_by_brute_force():
    rng = np.random.default_rng(8)
    n, lag = 300, 6
    e = rng.normal(size=n)
    u = rng.normal(size=n)
    eu, u2 = e * u, u * u
    t_eeu, t_u2e, t_u2e2 = billings_voon_tests(e, u, lag)
    # e(eu): corr(e(t), e(t-1-tau) u(t-1-tau)), tau = 0..lag-1
    full = _xcorr_loop(e, eu, lag)
    np.testing.assert_array_equal(t_eeu.lags, np.arange(lag))
    tol = xcorr_tolerance(n, lag)  # the same products e u, u^2, e^2; FFT against the loop
    np.testing.assert_allclose(t_eeu.values, full[lag + 1 :], rtol=0, atol=tol)
    np.testing.assert_allclose(t_u2e.values, _xcorr_loop(e, u2, lag), rtol=0, atol=tol)
    np.testing.assert_allclose(t_u2e2.values, _xcorr_loop(e * e, u2, lag), rtol=0, atol=tol)


# ---------------------------------------------------------------- spectra
def test_psd_peak_on_sinusoid_and_parseval():
    dt, f0, n = 1e-3, 37.5, 8192
    t = np.arange(n) * dt
    rng = np.random.default_rng(0)
    x = 2.0 * np.sin(2 * np.pi * f0 * t) + 0.1 * rng.normal(size=n)
    f, p = psd(x, dt)
    assert f[-1] == pytest.approx(0.5 / dt)
    df = f[1] - f[0]
    assert abs(f[np.argmax(p)] - f0) <= df
    # integral of the one-sided PSD is the variance (2^2 / 2 + 0.1^2)
    assert np.sum(p) * df == pytest.approx(2.0 + 0.01, rel=0.05)
    f2, _ = psd(x, dt, nperseg=1000)
    assert f2.size == 501


def test_psd_bad_input():
    with pytest.raises(DataError, match="dt"):
        psd(np.ones(100), 0.0)
    with pytest.raises(DataError, match="non-finite"):
        psd(np.r_[np.ones(10), np.nan], 1.0)


# ---------------------------------------------------------------- stability
def pole_map_tolerances(dz: float, wn: float, zeta: float, dt: float) -> tuple[float, float]:
    """Relative tolerances of ``f_n`` and ``zeta`` mapped from a pole known within ``dz |z|``.

    ``s = log(z) / dt`` moves by ``dz / dt`` (plus ``log``'s own few ulps, ``|s| dt`` relative),
    so ``|s| = w_n`` by ``dz / (w_n dt)`` relative and ``zeta = -Re(s) / |s|`` by ``1 / zeta``
    times that; ``/ (2 pi)``, ``abs`` and the division add a few eps.
    """
    rel_s = (dz + 4 * EPS * wn * dt) / (wn * dt)
    return rel_s + 4 * EPS, (rel_s + 4 * EPS) * 2 / zeta


@pytest.mark.numerics
def test_stability_report_maps_known_continuous_poles():
    dt, fn, zeta = 0.01, 5.0, 0.05
    wn = 2 * np.pi * fn
    s = -zeta * wn + 1j * wn * math.sqrt(1 - zeta**2)
    z = np.exp(s * dt)
    rep = stability_report([z, np.conj(z), 0.5, 0.0], [2.0, 0.3], dt)
    # z = exp(s dt) is within 8 eps (exp, cos, sin and the products, ~2 ulp each) of exact
    rtol_f, rtol_zeta = pole_map_tolerances(8 * EPS, wn, zeta, dt)
    np.testing.assert_allclose(rep.natural_frequency[:2], fn, rtol=rtol_f)
    np.testing.assert_allclose(rep.damping[:2], zeta, rtol=rtol_zeta)
    np.testing.assert_allclose(rep.radius[:2], math.exp(-zeta * wn * dt), rtol=16 * EPS)
    # real pole 0.5: s = ln(0.5)/dt, damping 1, f = |s|/(2 pi)
    assert rep.damping[2] == pytest.approx(1.0)
    assert rep.natural_frequency[2] == pytest.approx(-math.log(0.5) / dt / (2 * np.pi))
    assert math.isinf(rep.natural_frequency[3])
    assert rep.stable and rep.max_pole_radius == pytest.approx(math.exp(-zeta * wn * dt))
    assert rep.non_minimum_phase and rep.max_zero_radius == 2.0
    json.dumps(rep.to_dict(), allow_nan=False)
    assert not stability_report([1.01, 0.2], [], dt).stable
    assert not stability_report([0.5], [[0.5], [-0.9]], dt).non_minimum_phase


@pytest.mark.numerics
def test_validate_stability_of_model_with_known_poles():
    dt, fn, zeta = 0.002, 12.0, 0.1
    wn = 2 * np.pi * fn
    z = np.exp((-zeta * wn + 1j * wn * math.sqrt(1 - zeta**2)) * dt)
    a = np.real(np.poly([z, np.conj(z)]))
    model = LoopARX(a, [[0.01, -0.03]], [1], dt=dt)  # zero at 3: non-minimum phase
    rng = np.random.default_rng(4)
    u = rng.normal(size=4000)
    y = model.simulate(u) + 1e-4 * rng.normal(size=4000)
    rep = validate(model, IOData(u, y, dt=dt), max_lag=10)
    # z (8 eps), a = np.poly (4 eps of 1 + |a|), np.roots (companion eigenvalues, backward
    # error 4 eps of 1 + |a|, LAPACK): a simple root moves by that over |A'(z)| = |z - conj z|
    dz = 8 * EPS + 8 * EPS * np.abs(a).sum() / abs(z - np.conj(z))
    rtol_f, rtol_zeta = pole_map_tolerances(dz, wn, zeta, dt)
    np.testing.assert_allclose(rep.stability.natural_frequency, fn, rtol=rtol_f)
    np.testing.assert_allclose(rep.stability.damping, zeta, rtol=rtol_zeta)
    assert rep.stability.stable and rep.stability.non_minimum_phase
    assert rep.dt == dt
    # the lightly damped mode dominates both spectra
    df = rep.psd_frequency[1] - rep.psd_frequency[0]
    assert abs(rep.peak_model - fn) <= 2 * df
    assert abs(rep.peak_measured - fn) <= 2 * df


# ---------------------------------------------------------------- validate
def test_validate_numbers_match_independent_computation():
    u, y = _arx_221_data(n=600, seed=9)
    model = _fit_arx(u, y, 2, 2, 1)
    start = model.structure.start
    rep = validate(
        model, IOData(u, y, dt=0.01, input_names="torque"), max_lag=10, initial="measured"
    )
    y1 = model.predict(u, y)
    ys = model.simulate(u, y_init=y[:start])
    assert rep.start == start == 2
    ref1 = 100 * (1 - np.linalg.norm(y[start:] - y1[start:]) / np.linalg.norm(
        y[start:] - y[start:].mean()
    ))
    assert rep.fit_one_step == pytest.approx(ref1, abs=1e-10)
    assert rep.fit_simulation == pytest.approx(fit_percent(y[start:], ys[start:]), abs=1e-10)
    assert rep.rmse_one_step == pytest.approx(np.sqrt(np.mean((y - y1)[start:] ** 2)))
    assert rep.error_range_simulation == error_range(y[start:], ys[start:])
    assert [t.name for t in rep.correlation_tests] == ["auto e", "cross torque-e"]
    assert rep.correlation_tests[0].bound == pytest.approx(1.96 / math.sqrt(600 - 2), rel=1e-4)
    np.testing.assert_allclose(rep.arrays()["time"], np.arange(2, 600) * 0.01)
    # zero initial conditions: a different simulation, over every sample (MATLAB's)
    rep0 = validate(model, (u, y), max_lag=10, initial="zero")
    assert rep0.start == 0
    assert rep0.fit_simulation == pytest.approx(fit_percent(y, model.simulate(u)), abs=1e-10)
    # split: only the second part is used
    reps = validate(model, IOData(u, y, dt=0.01), max_lag=10, split=0.5)
    assert reps.n_samples == 300


def test_validate_noise_free_is_perfect():
    rng = np.random.default_rng(2)
    model = LoopARX([1.0, -0.8, 0.2], [[0.5, 0.1]], [2])
    u = rng.normal(size=400)
    y = model.simulate(u)
    rep = validate(model, (u, y), max_lag=10, initial="measured")
    # the prediction and the free run are the loop that made y (same operations in the same
    # order on the same numbers): exact on any machine
    assert rep.fit_one_step == 100.0
    assert rep.fit_simulation == 100.0
    assert rep.rmse_simulation == 0.0


def test_validate_multi_input_one_cross_test_per_input():
    rng = np.random.default_rng(6)
    n = 1500
    u = rng.normal(size=(n, 2))
    model = LoopARX([1.0, -0.5], [[1.0], [0.3, -0.2]], [1, 2])
    # equation error: A y = B u + e  <=>  y = (B/A) u + e / A
    y = model.simulate(u) + lfilter([1.0], model.a, 0.05 * rng.normal(size=n))
    wrong = LoopARX([1.0, -0.5], [[1.0], [0.0, 0.0]], [1, 2])  # ignores input 2
    data = IOData(u, y, input_names=["motor", "disturbance"])
    good = validate(model, data, max_lag=10)
    bad = validate(wrong, data, max_lag=10)
    names = [t.name for t in good.correlation_tests]
    assert names == ["auto e", "cross motor-e", "cross disturbance-e"]
    assert len(good.nonlinear_tests) == 6
    assert good.linear_passed
    assert bad.test("cross motor-e").passed
    assert not bad.test("cross disturbance-e").passed


def test_summary_and_to_dict():
    u, y = _arx_221_data(n=800, seed=3)
    rep = validate(_fit_arx(u, y, 2, 2, 1), IOData(u, y, dt=0.01), max_lag=12)
    text = rep.summary()
    assert f"{rep.fit_one_step:9.2f} %" in text
    assert f"{rep.fit_simulation:9.2f} %" in text
    assert "one-step" in text and "simulation (free run)" in text
    auto = rep.correlation_tests[0]
    assert f"{auto.n_outside} of 12" in text and f"{auto.statistic:8.1f}   12" in text
    assert f"PASS at 5 % (Holm over {len(rep.all_tests)} tests)" in text or "FAIL at 5 %" in text
    assert f"{rep.stability.max_pole_radius:.5f}" in text
    assert "Hz" in text and "[initial state estimated by least squares]" in text
    d = rep.to_dict()
    json.dumps(d, allow_nan=False)
    assert "arrays" not in d and "values" not in d["correlation_tests"][0]
    assert d["fit_one_step"] == rep.fit_one_step and d["passed"] == rep.passed
    d = rep.to_dict(arrays=True)
    json.dumps(d, allow_nan=False)
    assert len(d["arrays"]["y"]) == 800  # the estimated initial state: every sample
    assert len(d["correlation_tests"][0]["values"]) == 25
    panels = rep.correlation_panels()
    assert len(panels) == 2 and panels[0][3] == rep.correlation_tests[0].bound


def test_validate_bad_input():
    u, y = _arx_221_data(n=200, seed=1)
    model = _fit_arx(u, y, 2, 2, 1)
    y_nan = y.copy()
    y_nan[17] = np.nan
    with pytest.raises(DataError, match="non-finite"):
        validate(model, (u, y_nan))
    with pytest.raises(DataError, match="different lengths"):
        validate(model, (u, y[:-1]))
    with pytest.raises(DataError, match="too short for max_lag=120"):
        validate(model, (u, y), max_lag=120)
    with pytest.raises(DataError, match="initial"):
        validate(model, (u, y), initial="steady")
    with pytest.raises(DataError, match="single-output"):
        validate(model, IOData(u, np.c_[y, y]))
    with pytest.raises(DataError, match="IOData"):
        validate(model, y)
    with pytest.raises(ModelOrderError, match="start"):
        validate(LoopARX(np.r_[1.0, np.zeros(5)], [[1.0]], [1]), (u[:4], y[:4]), max_lag=1)
    with pytest.raises(ModelOrderError, match="input"):
        validate(model, (np.c_[u, u], y))
    with pytest.raises(DataError, match="max_lag"):
        residual_tests(np.ones(50), np.ones(50), max_lag=0)


def test_unstable_model_divergence_is_reported_not_raised():
    rng = np.random.default_rng(12)
    n = 3000
    u = rng.normal(size=n)
    y = _simulate_arx([1.0, -0.5], [1.0], 1, u, 0.1 * rng.normal(size=n))
    unstable = LoopARX([1.0, -1.5], [[1.0]], [1])  # pole at 1.5: 1.5**3000 overflows
    rep = validate(unstable, (u, y), max_lag=10)
    assert rep.simulation_diverged
    assert rep.fit_simulation == -np.inf and not rep.stability.stable
    assert rep.stability.max_pole_radius == pytest.approx(1.5)
    assert np.isfinite(rep.fit_one_step)
    d = rep.to_dict(arrays=True)
    json.dumps(d, allow_nan=False)
    assert d["fit_simulation"] is None and d["simulation_diverged"]
    assert "DIVERGED" in rep.summary() and "UNSTABLE" in rep.summary()
    # a stable model on the same data does not diverge
    assert not validate(_fit_arx(u, y, 1, 1, 1), (u, y), max_lag=10).simulation_diverged


@pytest.mark.numerics
def test_xcorr_swap_mirrors_lags_and_fit_is_affine_invariant():
    rng = np.random.default_rng(21)
    a, b = rng.normal(size=300), rng.normal(size=300)
    _, r_ab = xcorr(a, b, 30)
    _, r_ba = xcorr(b, a, 30)
    # two FFT correlations (the same normalisation): twice the FFT bound
    np.testing.assert_allclose(r_ab, r_ba[::-1], rtol=0, atol=2 * fft_tolerance(300, 30))
    _, r_scaled = xcorr(5.0 * a - 2.0, -3.0 * b + 7.0, 30)
    # the affine maps and the re-centring round each sample within 3 eps of |5 a| + 2 +
    # |mean| (so the centred signals within that relative to their norms), then as above
    # plus both normalisations
    centring = 0.0
    for k, c, x in ((5.0, -2.0, a), (-3.0, 7.0, b)):
        size = np.abs(k * x) + abs(c) + abs(np.mean(k * x + c))
        centring += 3 * EPS * np.linalg.norm(size) / np.linalg.norm(k * (x - x.mean()))
    tol = 2 * fft_tolerance(300, 30) + 2 * centring + 2 * 300 * EPS
    np.testing.assert_allclose(r_scaled, -r_ab, rtol=0, atol=tol)
    y, yhat = rng.normal(size=100), rng.normal(size=100)
    assert fit_percent(4 * y + 1, 4 * yhat + 1) == pytest.approx(fit_percent(y, yhat))


def test_binary_input_marks_u_squared_tests_not_applicable():
    rng = np.random.default_rng(31)
    n = 1000
    u = np.where(rng.random(n) < 0.5, -2.0, 2.0)  # PRBS-like: u^2 = 4 everywhere
    e = rng.normal(size=n)
    t_eeu, t_u2e, t_u2e2 = billings_voon_tests(e, u, 10)
    assert t_eeu.applicable
    assert not t_u2e.applicable and not t_u2e2.applicable
    assert t_u2e.passed and t_u2e2.passed
    assert "n/a" in t_u2e.verdict()
    # a non-binary input keeps them applicable
    assert all(t.applicable for t in billings_voon_tests(e, rng.normal(size=n), 10))
    # two levels with an offset (a PRBS between 1 and 3): u^2 = 4 u - 3 repeats the input
    # cross-correlation test, which the battery would otherwise count twice; e^2 against it
    # still asks whether the residual's size follows the input
    shifted = u / 2 + 2
    _, t_u2e, t_u2e2 = billings_voon_tests(e, shifted, 10)
    (cross,) = residual_tests(e, shifted, 10)[1:]
    assert not t_u2e.applicable and t_u2e2.applicable
    assert t_u2e.statistic == pytest.approx(cross.statistic, rel=1e-9)


@pytest.mark.numerics
@settings(max_examples=40, deadline=None)
@given(
    n=st.integers(min_value=2, max_value=60),
    lag_share=st.floats(min_value=0.0, max_value=1.0),
    seed=st.integers(min_value=0, max_value=2**32 - 1),
)
def test_xcorr_matches_loop_for_any_length_and_lag(n, lag_share, seed):
    rng = np.random.default_rng(seed)
    a, b = rng.normal(size=n) * 10.0, rng.normal(size=n)
    max_lag = round(lag_share * (n - 1))
    lags, r = xcorr(a, b, max_lag)
    assert lags.size == 2 * max_lag + 1
    tol = xcorr_tolerance(n, max_lag)
    np.testing.assert_allclose(r, _xcorr_loop(a, b, max_lag), rtol=0, atol=tol)
    assert np.all(np.abs(r) <= 1.0 + tol)  # Cauchy-Schwarz, up to the same rounding
