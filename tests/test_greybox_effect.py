"""A grey-box model's estimate in its residual tests (the estimation error on a held-out record).

The gradient of the simulation error is checked against an independent route: a first-order
lag ``T x' = K u - x`` sampled with the input held is exactly ``x(k+1) = a x(k) + K (1 - a)
u(k)``, ``a = exp(-dt/T)``, whose sensitivities a complex step gives to rounding; the model's
RK4 simulation differs from that recursion by its truncation error only.
"""

from __future__ import annotations

import numpy as np
import pytest

import flexid
from flexid.data.records import IOData
from flexid.errors import DataError
from flexid.fit.greybox_family import _parameter_effect, _simulation_gradient
from flexid.models.greybox import GreyBoxModel, GreyParameter

DT = 0.05


def _lag(K: float = 2.0, T: float = 0.4, substeps: int = 20) -> GreyBoxModel:
    return GreyBoxModel(
        "first-order lag",
        lambda x, u, p: ((p.K * u[:, 0] - x[:, 0]) / p.T)[:, None],
        lambda x, u, p: x[:, :1],
        states=("x",),
        inputs=("u",),
        outputs=("y",),
        parameters=(GreyParameter("K", K, 0.1, 10.0), GreyParameter("T", T, 0.05, 5.0, "s")),
        substep=DT / substeps,
    )


def _exact(K: complex, T: complex, u: np.ndarray) -> np.ndarray:
    """The lag's sampled response with the input held (complex-safe)."""
    a = np.exp(-DT / T)
    x, out = 0.0 * K, []
    for uk in u:
        out.append(x)
        x = a * x + K * (1 - a) * uk
    return np.array(out)


def test_the_simulation_gradient_is_the_exact_sensitivity():
    # Tolerance: the central differences' truncation (step 1e-6 of the parameter, squared)
    # and rounding (eps / 1e-6) are below 1e-9 of the response; RK4 with 20 substeps of a
    # time constant 16 substeps long has a global error near 1e-9 of the response, in the
    # response and in its sensitivities alike. 1e-7 of the largest sensitivity holds both.
    model = _lag()
    u = np.random.default_rng(0).uniform(-1, 1, 400)
    g = _simulation_gradient(model, u, DT)[:, 0, :]
    h = 1e-30
    dK = _exact(2.0 + 1j * h, 0.4, u).imag / h
    dT = _exact(2.0, 0.4 + 1j * h, u).imag / h
    np.testing.assert_allclose(-g[:, 0], dK, rtol=0, atol=1e-7 * np.abs(dK).max())
    np.testing.assert_allclose(-g[:, 1], dT, rtol=0, atol=1e-7 * np.abs(dT).max())


def _fitted(seed: int = 1):
    # two RK4 substeps a sample: the record's truth and the fitted model share the integrator
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(900)
    truth = _lag(substeps=2)
    y = truth.simulate(truth.nominal, u, DT)[0, :, 0] + 0.05 * rng.standard_normal(u.size)
    data = IOData(u, y, dt=DT, input_names=["u"], output_names=["y"])
    start = _lag(K=1.5, T=0.6, substeps=2)
    return flexid.identify(data, structure=start, optimiser="pem", seed=0), data


def test_identify_adds_the_estimation_error_to_the_held_out_null():
    ident, data = _fitted()
    assert ident.validation.parameters == "the estimation error of 2 parameters added to the " \
        "tests' null"
    assert ident.estimation.parameters == "the estimate of 2 parameters partialled out of the " \
        "tests"
    known = flexid.validate(ident.model, data, split=2 / 3)
    assert "taken as known" in known.parameters
    # the estimate's error is a covariance added to the null: no test's statistic grows
    for with_error, as_known in zip(ident.validation.all_tests, known.all_tests):
        assert with_error.name == as_known.name
        assert with_error.p_value >= as_known.p_value - 1e-12
    cross = next(t for t in ident.validation.all_tests if t.name.startswith("cross"))
    assert cross.p_value > next(t for t in known.all_tests if t.name == cross.name).p_value


def test_the_effect_is_none_where_nothing_is_estimated_and_a_bad_argument_is_named():
    model = _lag().fixing("K", "T")
    u = np.zeros(50)
    assert _parameter_effect(model, u, DT, 0, 10, "same") is None
    assert _parameter_effect(_lag(), u, DT, 0, 10, None) is None
    with pytest.raises(DataError, match="estimated_on"):
        _parameter_effect(_lag(), u, DT, 0, 10, "elsewhere")


def test_several_outputs_weigh_each_output_by_its_noise():
    # two sensors of one state, the second with twice the noise: the estimate's information
    # in the first output's noise is g'g (1 + 1/4), g the first output's gradient
    model = GreyBoxModel(
        "lag on two sensors",
        lambda x, u, p: ((p.K * u[:, 0] - x[:, 0]) / p.T)[:, None],
        lambda x, u, p: np.column_stack([x[:, 0], x[:, 0]]),
        states=("x",),
        inputs=("u",),
        outputs=("y1", "y2"),
        parameters=(GreyParameter("K", 2.0, 0.1, 10.0), GreyParameter("T", 0.4, 0.05, 5.0)),
        substep=DT / 2,
    )
    rng = np.random.default_rng(2)
    u = rng.standard_normal(600)
    clean = model.simulate(model.nominal, u, DT)[0]
    noise = rng.standard_normal(clean.shape) * [0.05, 0.1]
    noise -= noise.mean(axis=0)
    noise *= [0.05, 0.1] / noise.std(axis=0)  # residual deviations exactly 0.05 and 0.1
    est = IOData(u, clean + noise, dt=DT, input_names=["u"], output_names=["y1", "y2"])
    effect = _parameter_effect(model, u, DT, 0, 100, est)
    g = _simulation_gradient(model, u, DT)[:, 0, :]
    expected = g.T @ g * 1.25
    np.testing.assert_allclose(effect.root.T @ effect.root, expected, rtol=1e-10)
    np.testing.assert_array_equal(effect.gradient, g[100:])
    # on the estimation record the joint estimate is orthogonal to no one output's gradient
    assert _parameter_effect(model, u, DT, 0, 0, "same") is None
