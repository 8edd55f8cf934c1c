"""The measurement and actuation chain against analytic responses.

Frequency responses are evaluated from the state space by one linear solve of a
well-conditioned system (filters of order <= 8 whose poles lie on a circle of the cutoff's
radius); 1e-9 relative covers the solve's rounding many times over.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from flexid.envs import beam, sensors, twin_rotor_physics
from flexid.errors import PlantParameterError


def response(system, f_hz: float, out: int = 0) -> complex:
    a, b, c, d = system
    s = 2j * math.pi * f_hz
    x = np.linalg.solve(s * np.eye(a.shape[0]) - a, b[:, 0])
    return complex(c[out] @ x + d[out, 0])


@pytest.mark.parametrize("order", [1, 2, 3, 4, 7])
def test_butterworth_magnitude_is_maximally_flat(order):
    fc = 200.0
    filt = sensors.butterworth(order, fc)
    assert filt[0].shape == (order, order)
    for f in [0.0, 10.0, 100.0, 200.0, 350.0, 1000.0]:
        expected = 1.0 / math.sqrt(1.0 + (f / fc) ** (2 * order))
        assert abs(response(filt, f)) == pytest.approx(expected, rel=1e-9)
    assert np.all(np.linalg.eigvals(filt[0]).real < 0)


def test_first_and_second_order_sections():
    lag = sensors.first_order_lag(50.0)
    w = 2 * math.pi * 50.0
    for f in [0.0, 5.0, 50.0, 500.0]:
        assert response(lag, f) == pytest.approx(w / (2j * math.pi * f + w), rel=1e-12)
    acc = sensors.second_order_lowpass(1000.0)
    assert abs(response(acc, 1000.0)) == pytest.approx(1 / math.sqrt(2), rel=1e-12)
    assert response(acc, 0.0) == pytest.approx(1.0, rel=1e-12)
    # step response of the lag: 1 - exp(-w t), from the exact matrix exponential
    import scipy.linalg

    a, b, c, _ = lag
    t = 3e-3
    x = scipy.linalg.solve(a, (scipy.linalg.expm(a * t) - np.eye(1)) @ b)
    assert (c @ x)[0, 0] == pytest.approx(1 - math.exp(-w * t), rel=1e-12)


def test_series_and_output_filters_multiply_responses():
    lag, acc = sensors.first_order_lag(30.0), sensors.second_order_lowpass(80.0)
    both = sensors.series(lag, acc)
    for f in [1.0, 30.0, 120.0]:
        assert response(both, f) == pytest.approx(response(lag, f) * response(acc, f), rel=1e-9)
    # two outputs of one system, the second filtered: the first is untouched
    a = np.array([[-3.0]])
    system = (a, np.array([[1.0]]), np.array([[1.0], [2.0]]), np.array([[0.0], [0.5]]))
    filtered = sensors.filter_outputs(system, [None, acc])
    for f in [0.5, 10.0, 90.0]:
        g = 1.0 / (2j * math.pi * f + 3.0)
        assert response(filtered, f, 0) == pytest.approx(g, rel=1e-9)
        assert response(filtered, f, 1) == pytest.approx((2 * g + 0.5) * response(acc, f), rel=1e-9)


def test_beam_through_its_chain_is_the_product_of_the_blocks():
    p = beam.BeamParameters(n_sections=12)
    dt = 1e-3
    chain = beam.measured_model(p, dt)
    plant = beam.continuous_model(p)
    act = sensors.first_order_lag(p.actuator_bandwidth)
    aa = sensors.butterworth(p.anti_alias_order, p.anti_alias_fraction / dt)
    acc = sensors.second_order_lowpass(p.accelerometer_bandwidth)
    for f in [3.0, 11.0, 47.0, 180.0, 450.0]:
        base = response(act, f)
        assert response(chain, f, 0) == pytest.approx(base * response(plant, f, 0), rel=1e-7)
        for out in (1, 2):
            want = base * response(plant, f, out) * response(aa, f)
            assert response(chain, f, out) == pytest.approx(want, rel=1e-7)
        want = base * response(plant, f, 3) * response(acc, f) * response(aa, f)
        assert response(chain, f, 3) == pytest.approx(want, rel=1e-7)


def test_chain_leaves_the_modal_frequencies_and_damps_higher_modes_more():
    lab = beam.BeamParameters()
    ideal = beam.BeamParameters(**beam.IDEAL_SENSORS)
    freqs = beam.natural_frequencies(lab, 6)
    np.testing.assert_array_equal(freqs, beam.natural_frequencies(ideal, 6))
    omega = 2 * math.pi * np.concatenate([[0.0], beam.natural_frequencies(lab, 6)])
    assert lab.damping_ratio(3) == ideal.damping_ratio(3) == 0.04
    assert ideal.damping_ratio(6) == 0.04
    assert lab.damping_ratio(6, omega) == pytest.approx(0.04 * omega[6] / omega[3], rel=1e-12)
    assert lab.damping_ratio(6) == pytest.approx(lab.damping_ratio(6, omega), rel=1e-12)


def test_encoder_steps_are_two_pi_over_counts():
    p = beam.BeamParameters()
    assert p.encoder_step == 2 * math.pi / 2048
    y = np.zeros((5, 4))
    y[:, 0] = [0.0, 0.4 * p.encoder_step, 0.6 * p.encoder_step, -2.6 * p.encoder_step, 1.0]
    got = beam.measure(y, p)[:, 0] / p.encoder_step
    np.testing.assert_allclose(got, [0, 0, 1, -3, round(1.0 / p.encoder_step)], atol=1e-12)
    ideal = beam.BeamParameters(**beam.IDEAL_SENSORS)
    np.testing.assert_array_equal(beam.measure(y, ideal), y)
    t = twin_rotor_physics.TwinRotorParameters()
    ang = np.array([[0.0123, -0.0456, 0.7, 0.8]])
    seen = twin_rotor_physics.measure(ang, t)
    np.testing.assert_allclose(seen[0, :2] / t.encoder_step, np.round(ang[0, :2] / t.encoder_step),
                               atol=1e-9)
    np.testing.assert_array_equal(seen[0, 2:], ang[0, 2:])


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"damping_law": "viscous"}, "damping_law"),
        ({"actuator_bandwidth": -1.0}, "actuator_bandwidth"),
        ({"anti_alias_fraction": 0.5}, "anti_alias_fraction"),
        ({"anti_alias_order": 0}, "anti_alias_order"),
        ({"encoder_counts": True}, "encoder_counts"),
        ({"tachometer_noise": float("nan")}, "tachometer_noise"),
    ],
)
def test_bad_chain_parameters_name_the_parameter(kwargs, name):
    with pytest.raises(PlantParameterError, match=name):
        beam.BeamParameters(**kwargs)
    with pytest.raises(PlantParameterError, match="encoder_counts"):
        twin_rotor_physics.TwinRotorParameters(encoder_counts=0)
