"""The residual tests' statistics: equal to statsmodels' Breusch-Godfrey test, their level on
valid residuals (coloured inputs, estimated parameters), Holm's correction, and a report's
verdict at a stated level."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import linalg, signal

import flexid
from flexid.errors import ConfigError, DataError
from flexid.validation.diagnostics import judged, residual_tests
from flexid.validation.portmanteau import ParameterEffect, estimation_root, holm, portmanteau

A, B = [1.0, -1.5, 0.7], [0.0, 1.0, 0.5]  # a lightly damped second-order ARX system


def _arx_record(n, rng, colour=0.0, noise=0.5):
    u = signal.lfilter([1.0], [1.0, -colour], rng.standard_normal(n))
    y = signal.lfilter(B, A, u) + signal.lfilter([1.0], A, noise * rng.standard_normal(n))
    return u, y


def _arx_ls(u, y, rows=slice(None)):
    """ARX(2,2,1) by least squares: its regressors, residual and parameters."""
    phi = np.column_stack([-y[1:-1], -y[:-2], u[1:-1], u[:-2]])
    target = y[2:]
    theta = np.linalg.lstsq(phi[rows], target[rows], rcond=None)[0]
    return phi, target - phi @ theta


@pytest.mark.numerics
def test_whiteness_statistic_equals_statsmodels_breusch_godfrey():
    """On an OLS fit the statistic with the regressors partialled out is the Breusch-Godfrey
    LM statistic and its F-form p-value; the two routes share only the definition, so they
    agree to the rounding of solving a 15-column regression (1e-9 relative is a thousand
    times that)."""
    sm = pytest.importorskip("statsmodels.api")
    from statsmodels.stats.diagnostic import acorr_breusch_godfrey

    rng = np.random.default_rng(0)
    u, y = _arx_record(800, rng)
    phi, _ = _arx_ls(u, y)
    x = np.column_stack([np.ones(len(phi)), phi])  # with a constant, as the test's regression
    fit = sm.OLS(y[2:], x).fit()
    lm, _, _, f_p = acorr_breusch_godfrey(fit, nlags=10, result_object=False)
    ours = portmanteau(fit.resid, fit.resid, np.arange(1, 11), ParameterEffect(-x))
    assert ours.statistic == pytest.approx(lm, rel=1e-9)
    assert ours.p_value == pytest.approx(f_p, rel=1e-6)
    assert ours.dof == 10


def test_a_lag_that_is_a_parameters_regressor_is_not_counted():
    """A finite impulse response fitted on u(t-1), u(t-2) (the record starting from rest, as
    the tests' lag matrix does) makes the residual orthogonal to exactly those two lags: the
    cross test has 2L + 1 - 2 degrees of freedom."""
    rng = np.random.default_rng(1)
    n, lag = 1000, 10
    u = rng.standard_normal(n)
    u -= u.mean()  # the tests centre u before lagging it: then its lags are the regressors
    y = signal.lfilter([0.0, 1.0, 0.5], [1.0], u) + 0.3 * rng.standard_normal(n)
    phi = np.column_stack([np.r_[0.0, u[:-1]], np.r_[0.0, 0.0, u[:-2]]])
    e = y - phi @ np.linalg.lstsq(phi, y, rcond=None)[0]
    _, cross = residual_tests(e, u, lag, effect=ParameterEffect(-phi))
    assert cross.dof == 2 * lag + 1 - 2
    _, known = residual_tests(e, u, lag)
    assert known.dof == 2 * lag + 1


def test_the_held_out_spread_survives_an_ill_conditioned_gradient():
    """Each direction of theta adds about N_held-out / N_estimation to the statistic however
    weakly the estimate determines it: with a gradient whose columns are nearly dependent
    (condition 1e9, as OE(16,16,1) of the manipulator) the triangular factor keeps every
    direction, where the normal equations J'J (condition 1e18) lose the weakest."""
    rng = np.random.default_rng(9)
    n, p = 3000, 6
    base = rng.standard_normal((n, p))
    mix = np.linalg.qr(rng.standard_normal((p, p)))[0] @ np.diag(np.logspace(0, -9, p))
    j = base @ mix  # singular values 1 .. 1e-9 times sqrt(n)
    est, val = j[: 2 * n // 3], j[2 * n // 3 :]
    root = estimation_root([est])
    x = linalg.solve_triangular(root, val.T, trans="T").T
    # the trace of J_v P J_v' is about p N_v / N_e = 3 (the columns' statistics are alike)
    assert 2.0 < float(np.sum(x**2)) < 4.5
    np.testing.assert_allclose(root.T @ root, est.T @ est, rtol=1e-12, atol=1e-12 * n)


def _rejections(draw, draws=300):
    return np.mean([draw() < 0.05 for _ in range(draws)])


@pytest.mark.numerics
def test_a_test_against_a_fixed_signal_is_an_exact_f_test_for_gaussian_noise():
    """For a white Gaussian residual and a fixed signal (here the centred square of a held
    uniform input, as the Billings-Voon ``u^2'-e`` test takes it: strongly coloured) the
    statistic is the regression F test, exact at any record length: its p-values are uniform.
    The draws are fixed by the seed; a Kolmogorov-Smirnov p-value above 1e-3 has a margin far
    above any rounding of the p-values (about 1e-12)."""
    from scipy import stats

    rng = np.random.default_rng(7)
    n, lags = 400, np.arange(-10, 11)
    u = np.repeat(rng.uniform(-1.0, 1.0, n // 5), 5)
    x = u**2 - np.mean(u**2)
    p = np.array([portmanteau(rng.standard_normal(n), x, lags).p_value for _ in range(2000)])
    assert stats.kstest(p, "uniform").pvalue > 1e-3
    assert 0.035 <= np.mean(p < 0.05) <= 0.065  # 5 % within 3 binomial deviations (0.5 %)


@pytest.mark.slow
def test_cross_test_holds_its_level_for_a_narrow_band_input():
    """The lags of a narrow-band input carry the same information many times over: the sum of
    squared correlations (Box-Pierce) rejects a valid residual far too often; the statistic
    whitened by the input's own correlation rejects at its level.  300 draws give a binomial
    standard deviation of 1.3 % at 5 %."""
    rng = np.random.default_rng(2)
    n, lag = 1000, 15
    lags = np.arange(-lag, lag + 1)

    def whitened():
        e, u = rng.standard_normal(n), signal.lfilter([1.0], [1.0, -0.95], rng.standard_normal(n))
        return portmanteau(e, u, lags).p_value

    def plain():
        e, u = rng.standard_normal(n), signal.lfilter([1.0], [1.0, -0.95], rng.standard_normal(n))
        (test,) = residual_tests(e, u, lag)[1:]
        from scipy import stats

        return stats.chi2.sf(n * np.sum(test.values**2), lags.size)

    assert 0.01 <= _rejections(whitened) <= 0.095
    assert _rejections(plain) > 0.15


@pytest.mark.slow
def test_estimation_on_the_record_and_held_out_are_both_accounted_for():
    """ARX(2,2,1) by least squares on a coloured input: on the estimation record the estimate
    shrinks the cross-correlations (taken as known, the test rejects too seldom), on the held
    out third its error inflates them (too often); with the estimate's effect both reject at
    their level.  Rates over 300 records each (binomial sd 1.3 %)."""
    rng = np.random.default_rng(3)
    n, lag = 1500, 25
    lags = np.arange(-lag, lag + 1)
    rates = {"same": [], "same_known": [], "held": [], "held_known": []}
    for _ in range(300):
        u, y = _arx_record(n, rng, colour=0.7)
        k = 2 * (n - 2) // 3
        phi, e = _arx_ls(u, y, slice(0, k))
        _, e_all = _arx_ls(u, y)
        ut = u[2:]
        rates["same"].append(portmanteau(e_all, ut, lags, ParameterEffect(-phi)).p_value)
        rates["same_known"].append(portmanteau(e_all, ut, lags).p_value)
        effect = ParameterEffect(-phi[k:], estimation_root([-phi[:k]]))
        rates["held"].append(portmanteau(e[k:], ut[k:], lags, effect).p_value)
        rates["held_known"].append(portmanteau(e[k:], ut[k:], lags).p_value)
    rate = {key: float(np.mean(np.array(v) < 0.05)) for key, v in rates.items()}
    assert 0.015 <= rate["same"] <= 0.09, rate
    assert 0.015 <= rate["held"] <= 0.09, rate
    assert rate["same_known"] < rate["same"] and rate["held_known"] > rate["held"], rate


def test_holm_step_down_by_hand():
    p = [0.01, 0.04, 0.03, 0.005]
    # sorted 0.005, 0.01, 0.03, 0.04 times 4, 3, 2, 1 -> 0.02, 0.03, 0.06, 0.04 -> running max
    np.testing.assert_allclose(holm(p), [0.03, 0.06, 0.06, 0.02])
    assert holm([0.9, 0.8]).max() == 1.0
    sm = pytest.importorskip("statsmodels.stats.multitest")
    rng = np.random.default_rng(4)
    q = rng.uniform(size=12) ** 3
    np.testing.assert_allclose(holm(q), sm.multipletests(q, method="holm")[1], rtol=1e-14)


def test_a_battery_is_judged_at_its_level():
    rng = np.random.default_rng(5)
    e, u = rng.standard_normal(600), rng.standard_normal(600)
    e[1:] += 0.12 * e[:-1]  # a mildly coloured residual: its own p-value is small
    tests = residual_tests(e, u, 10)
    loose, strict = judged(tests, 0.2), judged(tests, 1e-6)
    assert [t.adjusted_p for t in loose] == [t.adjusted_p for t in strict]
    assert loose[0].adjusted_p == pytest.approx(min(1.0, 2 * tests[0].p_value))
    assert not loose[0].passed and strict[0].passed
    with pytest.raises(DataError, match="alpha"):
        judged(tests, 1.5)


def test_validate_at_a_level_and_on_its_estimation_record():
    rng = np.random.default_rng(6)
    u, y = _arx_record(3000, rng, colour=0.5)
    data = flexid.IOData(u, y, dt=0.01)
    est, val = data.split(2 / 3)
    ident = flexid.identify(est, na=2, nb=2, nk=1, optimiser="ls", validation=val)
    report = ident.validation
    assert report.alpha == 0.05
    assert "partialled out" in ident.estimation.parameters
    assert "estimation error" in report.parameters
    assert "taken as known" in flexid.validate(ident.model, val).parameters
    assert report.passed and "PASS at 5 %" in report.verdict()
    assert all(t.adjusted_p >= t.p_value for t in report.all_tests)
    # the same report at another level: only the verdict's level changes
    loose = report.at_level(0.5)
    assert [t.p_value for t in loose.all_tests] == [t.p_value for t in report.all_tests]
    assert loose.alpha == 0.5
    under = flexid.identify(est, na=1, nb=1, nk=1, optimiser="ls", validation=val).validation
    assert not under.passed
    assert under.verdict().startswith("FAIL at 5 %: ") and "auto e" in under.verdict()
    assert "p < 1e-16" in under.verdict() and "lag" in under.verdict()
    assert "how to read a failure" in under.summary()
    with pytest.raises(ConfigError, match="alpha"):
        flexid.identify(est, na=2, optimiser="ls", alpha=0.0)
    with pytest.raises(DataError, match="estimated_on"):
        flexid.validate(ident.model, val, estimated_on="elsewhere")


def test_a_multi_output_verdict_is_one_battery_at_the_level():
    """Two outputs' reports judged together: Holm over all their tests, so each adjusted
    p-value is at least its own report's, and the joint verdict fails when any does."""
    from flexid.validation import joint_tests, joint_verdict

    rng = np.random.default_rng(7)
    reports = []
    for name, order in (("hub", 2), ("tip", 1)):  # the tip's model misses a pole
        u, y = _arx_record(1200, rng)
        data = flexid.IOData(u, y, dt=0.01, output_names=[name])
        reports.append(flexid.identify(data, na=order, optimiser="ls").validation)
    tests = joint_tests(reports)
    assert len(tests) == sum(len(r.all_tests) for r in reports)
    assert [t.name for t in tests][:2] == ["hub: auto e", "hub: cross u-e"]
    own = [t for r in reports for t in r.all_tests]
    assert all(j.adjusted_p >= o.adjusted_p for j, o in zip(tests, own, strict=True))
    assert reports[0].passed and not reports[1].passed
    worst = min(tests, key=lambda t: t.adjusted_p)
    assert worst.name.startswith("tip: ")
    assert joint_verdict(tests).startswith(f"FAIL at 5 %: {worst.name}")
    assert joint_verdict(joint_tests(reports[:1])).startswith("PASS at 5 %")
