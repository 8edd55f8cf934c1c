"""Tests of flexid.data.signals: the defining property of each excitation signal.

Frequency and amplitude checks (10-15 %) are modelling tolerances; the multisine's
out-of-band energy is rounding only and is bounded by the FFT's error analysis.
"""

from __future__ import annotations

import numpy as np
import pytest

from flexid.data.signals import (
    SIGNALS,
    aprbs,
    bang_bang,
    chirp,
    crest_factor,
    describe_signals,
    make_signal,
    multisine,
    prbs,
    random_binary,
    uniform,
)
from flexid.errors import DataError, UnknownNameError
from numerics import EPS


@pytest.mark.parametrize("order", [2, 3, 5, 7, 8, 10, 12, 16])
def test_prbs_is_maximum_length_and_balanced(order):
    period = 2**order - 1
    x = prbs(2 * period + 5, order, low=-1.0, high=1.0, rng=order)
    np.testing.assert_array_equal(x[:period], x[period : 2 * period])
    # no shorter period (a shorter one would divide the period)
    for d in range(1, period):
        if period % d == 0:
            assert not np.array_equal(x[: period - d], x[d:period])
    one = x[:period]
    assert (one == 1).sum() == 2 ** (order - 1) and (one == -1).sum() == 2 ** (order - 1) - 1
    if order >= 5:  # two-level circular autocorrelation: N at lag 0, -1 elsewhere
        r = np.array([np.dot(one, np.roll(one, k)) for k in range(period)])
        assert r[0] == period and np.all(r[1:] == -1)


def test_prbs_clock_and_levels():
    x = prbs(60, 3, clock=4, low=0.0, high=5.0)
    assert set(np.unique(x)) == {0.0, 5.0}
    np.testing.assert_array_equal(x[:28], x[28:56])
    assert np.all(x[0:4] == x[0])


def test_random_signals_bounded_and_reproducible():
    for fn in (random_binary, uniform):
        a = fn(1000, low=-0.3, high=0.3, hold=5, rng=np.random.default_rng(1))
        b = fn(1000, low=-0.3, high=0.3, hold=5, rng=np.random.default_rng(1))
        c = fn(1000, low=-0.3, high=0.3, hold=5, rng=np.random.default_rng(2))
        np.testing.assert_array_equal(a, b)
        assert not np.array_equal(a, c)
        assert a.min() >= -0.3 and a.max() <= 0.3
        assert np.all(a.reshape(-1, 5) == a.reshape(-1, 5)[:, :1])
    x = aprbs(2000, low=-1, high=2, min_hold=3, max_hold=10, rng=0)
    assert x.min() >= -1 and x.max() <= 2
    runs = np.diff(np.flatnonzero(np.diff(x) != 0))
    assert runs.min() >= 3 and runs.max() <= 10


@pytest.mark.numerics
def test_multisine_band_and_crest_factor():
    n, dt = 2000, 0.01
    x = multisine(n, dt, band=(2.0, 10.0), amplitude=0.5)
    assert np.abs(x).max() == pytest.approx(0.5)
    spec = np.abs(np.fft.rfft(x)) ** 2
    f = np.fft.rfftfreq(n, dt)
    inside = (f >= 2.0) & (f <= 10.0)
    # out of band there is rounding only: an FFT (irfft, the scaling, rfft) is within
    # c log2(n) eps of exact in the 2-norm (Higham Thm 24.2, c ~ 3.4 per radix-2 transform;
    # c = 20 covers two mixed-radix transforms), so the leaked energy is below that squared
    assert spec[~inside].sum() < (20 * np.log2(n) * EPS) ** 2 * spec[inside].sum()
    assert np.all(spec[inside] > 0.5 * spec[inside].max())
    random_cf = [crest_factor(multisine(n, dt, band=(2, 10), phases="random", rng=s))
                 for s in range(25)]
    assert crest_factor(x) < np.median(random_cf)


def test_chirp_instantaneous_frequency():
    dt, n = 0.001, 50000  # a slow sweep, so half periods measure the frequency
    for method in ("linear", "logarithmic"):
        x = chirp(n, dt, f0=2.0, f1=40.0, amplitude=2.0, method=method)
        assert np.abs(x).max() <= 2.0 + 1e-12
        zc = np.flatnonzero(np.diff(np.sign(x)) != 0)
        start = 1 / (2 * (zc[0] + 1) * dt)  # first half period (the signal starts at 0)
        end = 1 / (2 * np.mean(np.diff(zc[-6:])) * dt)
        assert start == pytest.approx(2.0, rel=0.15)
        assert end == pytest.approx(40.0, rel=0.1)


def test_bang_bang_pulse():
    x = bang_bang(1000, 1e-3, amplitude=0.3, width=0.3)
    assert np.all(x[:300] == 0.3) and np.all(x[300:600] == -0.3) and np.all(x[600:] == 0)


def test_registry_and_errors():
    assert set(SIGNALS) >= {"prbs", "random", "uniform", "aprbs", "multisine", "chirp", "bang_bang"}
    assert "prbs" in describe_signals()
    x = make_signal("uniform", 100, 0.1, rng=np.random.default_rng(0), amplitude=2.0)
    assert x.min() >= -2 and x.max() <= 2
    assert make_signal("bang-bang", 10, 0.1).shape == (10,)
    with pytest.raises(UnknownNameError, match="jazz"):
        make_signal("jazz", 10)
    with pytest.raises(DataError):
        make_signal("prbs", 10, colour=3)
    with pytest.raises(DataError):
        prbs(10, 30)
    with pytest.raises(DataError):
        uniform(10, low=1.0, high=-1.0)
    with pytest.raises(DataError):
        uniform(0)
    with pytest.raises(DataError):
        multisine(100, 0.01, band=(60.0, 70.0))
