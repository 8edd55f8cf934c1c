"""Offsets, drift and delay: detrending rules, the offset warning, the delay estimate."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy import signal

import flexid
from flexid.config import DataSpec
from flexid.data import IOData, prepare_data
from flexid.errors import ConfigError, DataError, DataWarning, UnknownNameError
from flexid.fit.delay import estimate_delay


def delayed_record(nk=3, n=1200, seed=0, n_inputs=1):
    """``y = sum_j q^-nk_j 0.5/(1 - 0.7 q^-1) u_j`` plus white noise (SNR about 10)."""
    rng = np.random.default_rng(seed)
    u = np.sign(rng.normal(size=(n, n_inputs)))
    delays = np.atleast_1d(nk) * np.ones(n_inputs, dtype=int)
    y = np.zeros(n)
    for j, k in enumerate(delays):
        y += signal.lfilter(np.r_[np.zeros(k), 0.5], [1.0, -0.7], u[:, j])
    y += 0.1 * np.std(y) * rng.normal(size=n)
    return IOData(u, y, dt=0.1)


@pytest.mark.parametrize("method", ["arx", "correlation"])
@pytest.mark.parametrize("nk", [0, 1, 3, 7])
def test_both_methods_find_a_known_delay(method, nk):
    found = estimate_delay(delayed_record(nk), method=method)
    assert found.nk == (nk,)
    assert found.nk_range == (0, 20) and found.scores[0].shape == (21,)
    assert f"nk = {nk} " in found.describe()


def test_each_input_gets_its_own_delay():
    found = estimate_delay(delayed_record(nk=[1, 4], n_inputs=2))
    assert found.nk == (1, 4)
    assert estimate_delay(delayed_record(nk=[1, 4], n_inputs=2), method="correlation").nk == (1, 4)


def test_the_arx_losses_are_compared_over_the_same_samples():
    """The loss of every delay is over one set of samples (from the largest start): a delay
    that only shortens the sum cannot win."""
    data = delayed_record(nk=2)
    found = estimate_delay(data, nk_min=0, nk_max=5)
    loss = found.scores[0]
    # nk = 1 with two b coefficients still reaches lag 2, the others do not
    assert np.argmin(loss) == 2 and np.all(loss[[0, 3, 4, 5]] > 10 * loss[2])


def test_bad_requests_say_what_is_wrong():
    data = delayed_record()
    with pytest.raises(UnknownNameError, match="delay estimation method"):
        estimate_delay(data, method="impulse")
    with pytest.raises(ConfigError, match="nk_max"):
        estimate_delay(data, nk_min=5, nk_max=2)
    with pytest.raises(DataError, match="too short"):
        estimate_delay(data.split(index=40)[0], nk_max=30)
    with pytest.raises(DataError, match="single-output"):
        estimate_delay(IOData(data.u, np.column_stack([data.y, data.y])))


def test_identify_estimates_the_delay_when_asked_and_says_so():
    ident = flexid.identify(delayed_record(nk=3), 1, 1, "auto", optimiser="ls")
    assert list(ident.model.structure.nk) == [3]
    assert "nk = 3 (MATLAB delayest" in ident.summary()
    with pytest.raises(ConfigError, match="'auto'"):
        flexid.identify(delayed_record(), 1, 1, "guess", optimiser="ls")


def test_select_tries_nk_1_and_the_estimated_delay():
    sel = flexid.select(delayed_record(nk=3), "arx", [{"na": 1, "nb": 1}])
    assert [c.label for c in sel.candidates] == ["ARX(na=1, nb=1, nk=1)", "ARX(na=1, nb=1, nk=3)"]
    assert sel.best.label == "ARX(na=1, nb=1, nk=3)"
    assert sel.delay.startswith("nk = 3 (MATLAB delayest and the prewhitened")
    assert sel.to_dict()["delay"] == sel.delay
    given = flexid.select(delayed_record(nk=3), "arx", [{"na": 1, "nb": 1}], nk=2)
    assert [c.label for c in given.candidates] == ["ARX(na=1, nb=1, nk=2)"] and not given.delay


# ------------------------------------------------------------------ detrending
def offset_record(n=900, seed=1):
    rng = np.random.default_rng(seed)
    u = np.sign(rng.normal(size=n))
    y = signal.lfilter([0, 0.5], [1, -0.7], u) + 0.05 * rng.normal(size=n)
    return u, y


def test_linear_detrend_removes_the_estimation_line_from_both_parts():
    u, y = offset_record()
    t = np.arange(y.size)
    data = IOData(u + 3.0, y + 20.0 + 0.01 * t, dt=0.1)
    est, val = prepare_data(data, detrend="linear")
    n_est = est.n_samples
    # the line is the estimation part's least squares: its residual has zero mean and no slope
    for x in (est.y[:, 0], est.u[:, 0]):
        assert abs(x.mean()) < 1e-9 and abs(np.polyfit(np.arange(n_est), x, 1)[0]) < 1e-12
    # the validation part loses the same line, extended (no validation sample used)
    c1, c0 = np.polyfit(np.arange(n_est), data.y[:n_est, 0], 1)
    expected = data.y[n_est:, 0] - (c0 + c1 * np.arange(n_est, data.n_samples))
    np.testing.assert_allclose(val.y[:, 0], expected, rtol=0, atol=1e-9)
    assert est.metadata["detrend"]["kind"] == "linear"
    # the constant rule, True and "constant" alike
    a = prepare_data(data, detrend=True)[1].y
    b = prepare_data(data, detrend="constant")[1].y
    np.testing.assert_array_equal(a, b)
    with pytest.raises(UnknownNameError, match="detrend rule"):
        prepare_data(data, detrend="quadratic")


def test_a_separate_validation_record_loses_its_own_line():
    u, y = offset_record()
    est_rec = IOData(u, y + 0.02 * np.arange(y.size), dt=0.1)
    val_rec = IOData(u[::-1].copy(), y[::-1] + 5.0 - 0.03 * np.arange(y.size), dt=0.1)
    _, val = prepare_data(est_rec, validation=val_rec, detrend="linear")
    np.testing.assert_allclose(val.y[:, 0], signal.detrend(val_rec.y[:, 0]), atol=1e-9)


def test_an_offset_or_a_drift_that_dwarfs_the_variation_warns_once():
    u, y = offset_record()
    with pytest.warns(DataWarning, match=r"output 'y' has mean 20.*--detrend constant"):
        prepare_data(IOData(u, y + 20.0, dt=0.1))
    with pytest.warns(DataWarning, match=r"output 'y' drifts by .*--detrend linear"):
        prepare_data(IOData(u, y + 0.01 * np.arange(y.size), dt=0.1))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        prepare_data(IOData(u, y, dt=0.1))  # zero-mean, no drift: silent
        prepare_data(IOData(u, y + 20.0, dt=0.1), detrend="constant")  # asked for: silent


def test_the_detrend_rule_reaches_identify_select_and_the_configs():
    u, y = offset_record()
    data = IOData(u + 2.0, y + 20.0 + 0.002 * np.arange(y.size), dt=0.1)
    lin = flexid.identify(data, 1, 1, 1, optimiser="ls", detrend="linear")
    const = flexid.identify(data, 1, 1, 1, optimiser="ls", detrend="constant")
    assert lin.validation.fit_simulation > const.validation.fit_simulation
    sel = flexid.select(data, "arx", [{"na": 1, "nb": 1}], nk=1, detrend="linear")
    assert sel.best.report.fit_simulation == pytest.approx(lin.validation.fit_simulation)
    assert DataSpec(file="x.csv", detrend="linear").detrend == "linear"
    for bad in ("quadratic", 3, 1.5):
        with pytest.raises(ConfigError, match="detrend"):
            DataSpec(file="x.csv", detrend=bad)


def test_a_drift_the_input_drives_is_the_plants_and_is_not_detrended():
    # a hub angle: a double integrator of a zero-mean torque drifts as a random walk's sum
    rng = np.random.default_rng(3)
    torque = rng.standard_normal(2000)
    angle = signal.lfilter([0.0, 1e-4], [1.0, -2.0, 1.0], torque)
    with pytest.warns(DataWarning, match=r"output 'y' drifts by .*the plant's own motion") as got:
        prepare_data(IOData(torque, angle, dt=0.01))
    assert not any("--detrend linear" in str(w.message) for w in got)
    # the same plant's stable response under a sensor's drift: the line is the advice
    response = signal.lfilter([0.0, 0.5], [1.0, -0.8], torque)
    with pytest.warns(DataWarning, match=r"output 'y' drifts by .*--detrend linear") as got:
        prepare_data(IOData(torque, response + 0.01 * np.arange(2000), dt=0.01))
    assert not any("plant's own motion" in str(w.message) for w in got)
