"""Tests of flexid.identify: one-call identification, least squares, search box, held-out checks.

Fit thresholds (99.999 %, 1 % of the cost, 0.05 on parameters) are modelling tolerances far
above rounding; the noise-free recovery is exact up to rounding, bounded as in
tests/route_bounds.py.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from flexid import identify, search_box
from flexid.data import IOData
from flexid.errors import ConfigError, DataError, ModelOrderError, UnknownNameError
from flexid.models.arx import ARXStructure
from flexid.models.stability import is_stable
from numerics import EPS
from route_bounds import recovery_error

A_TRUE = [-1.5, 0.7]
B_TRUE = [0.5, 0.25]


def arx_record(n=600, seed=0, noise=0.0, dt=0.01) -> IOData:
    rng = np.random.default_rng(seed)
    u = rng.uniform(-1, 1, n)
    e = noise * rng.standard_normal(n)
    y = np.zeros(n)
    for t in range(2, n):
        y[t] = (
            -A_TRUE[0] * y[t - 1]
            - A_TRUE[1] * y[t - 2]
            + B_TRUE[0] * u[t - 1]
            + B_TRUE[1] * u[t - 2]
            + e[t]
        )
    return IOData(u, y, dt=dt, input_names=["u"], output_names=["y"])


@pytest.mark.numerics
def test_least_squares_recovers_the_system_and_validates_on_held_out_data():
    ident = identify(arx_record(), 2, 2, 1, optimiser="ls")
    # noise-free: exact up to the loop's rounding (5 terms a sample) and the QR solver's
    theta = np.array(A_TRUE + B_TRUE)
    phi, _ = ident.model.structure.regressors(ident.cost.u, ident.cost.y)
    err = recovery_error(phi, theta, np.abs(phi) @ np.abs(theta), 5)
    np.testing.assert_allclose(ident.model.theta, theta, rtol=0, atol=err)
    assert ident.result is None and ident.nfev == 0
    assert ident.cost_value == ident.cost_ls  # the least-squares value itself
    assert ident.validation.fit_one_step > 99.999
    assert ident.validation.fit_simulation > 99.999
    assert ident.model.is_stable
    # the held-out record is the last third of the samples
    assert ident.data_info["n_validation"] == 200
    text = ident.summary()
    assert "fit" in text.lower() and "ls" in text


def test_optimiser_gets_close_to_least_squares_within_its_budget():
    data = arx_record(noise=0.02, seed=3)
    ls = identify(data, 2, 2, 1, optimiser="ls")
    ident = identify(data, 2, 2, 1, optimiser="de", budget=6000, seed=1)
    assert ident.nfev == 6000
    # least squares is the optimum: w sqrt(sse_ls + |R d|^2) / K with |R d|^2 >= 0 and
    # monotone rounding, from the same data by the same code: exact
    assert ident.cost_value >= ls.cost_value
    assert ident.cost_value <= ls.cost_value * 1.01
    assert ident.history.fe[-1] == 6000
    np.testing.assert_allclose(ident.model.theta, ls.model.theta, atol=0.05)


def test_same_seed_same_numbers_and_json_is_complete():
    data = arx_record(noise=0.01, seed=2)
    a = identify(data, 2, optimiser="sda", budget=1500, seed=7)
    b = identify(data, 2, optimiser="sda", budget=1500, seed=7)
    assert a.cost_value == b.cost_value
    np.testing.assert_array_equal(a.model.theta, b.model.theta)
    d = json.loads(json.dumps(a.to_dict()))
    assert d["search"]["nfev"] == 1500
    assert d["search"]["box"]["rule"].startswith("auto")
    assert set(d["cost"]) == {"description", "value", "search_value", "least_squares"}
    assert d["cost"]["search_value"] is None  # a well-conditioned model is not rescored
    assert "fit_simulation" in d["validation"]


@pytest.mark.numerics
def test_auto_box_contains_every_stable_denominator_and_the_ls_estimate():
    s = ARXStructure(4, 4, 1)
    theta_ls = np.array([0.1, -0.2, 0.05, 0.0, 0.3, -0.02, 0.01, 0.2])
    box = search_box(s, "auto", theta_ls)
    assert np.all(box.lower <= theta_ls) and np.all(theta_ls <= box.upper)
    np.testing.assert_allclose(box.upper[:4], [4, 6, 4, 1])
    assert box.upper[4] == pytest.approx(0.6)
    # random stable polynomials (roots in the unit disc) all lie in the box
    rng = np.random.default_rng(0)
    r = rng.uniform(0, 1, (2000, 2)) ** 0.5
    ang = rng.uniform(0, np.pi, (2000, 2))
    roots = np.concatenate([r * np.exp(1j * ang), r * np.exp(-1j * ang)], axis=1)
    coeffs = np.array([np.poly(z).real[1:] for z in roots])
    assert is_stable(coeffs).all()
    # |a_k| <= C(4, k) exactly; np.poly rounds the coefficients of four linear factors of
    # magnitude <= 2 (complex products: 4 roundings each) within 16 eps 2^4
    assert np.all(np.abs(coeffs) <= box.upper[:4] + 16 * EPS * 2**4)


def test_explicit_boxes_are_recorded():
    s = ARXStructure(2, 2, 1)
    box = search_box(s, 2.0)
    np.testing.assert_array_equal(box.upper, [2, 2, 2, 2])
    box = search_box(s, (-1.0, 3.0))
    np.testing.assert_array_equal(box.lower, [-1, -1, -1, -1])
    box = search_box(s, {"a": 3.0, "b": 0.5})
    np.testing.assert_array_equal(box.upper, [3, 3, 0.5, 0.5])
    with pytest.raises(ConfigError):
        search_box(s, (3.0, -1.0))
    with pytest.raises(ConfigError):
        search_box(s, "big")


def test_simulation_predictor_and_other_metrics_run():
    data = arx_record(noise=0.01, seed=5)
    ident = identify(data, 2, optimiser="pso", predictor="simulation", cost="nrmse",
                     budget=2000, seed=0)
    assert np.isfinite(ident.cost_value)
    assert ident.model.is_stable
    assert "simulation" in ident.cost.describe()


def test_bad_input_raises_typed_errors(tmp_path):
    data = arx_record(n=60)
    with pytest.raises(ModelOrderError):
        identify(data, 40, optimiser="ls")
    with pytest.raises(ModelOrderError):
        identify(data, -1, optimiser="ls")
    with pytest.raises(UnknownNameError):
        identify(data, 2, optimiser="no-such")
    with pytest.raises(UnknownNameError):
        identify(data, 2, optimiser="ls", cost="l7")
    with pytest.raises(DataError):
        identify(tmp_path / "missing.csv", 2, optimiser="ls")
    y = data.y.copy()
    y[10, 0] = np.nan
    with pytest.raises(DataError, match="10"):
        identify(IOData(data.u, y, dt=0.01), 2, optimiser="ls")


def test_the_record_channel_names_reach_the_model_and_its_exports():
    rng = np.random.default_rng(4)
    data = IOData(rng.normal(size=(400, 2)), rng.normal(size=400),
                         input_names=["torque", "u2"], output_names="tip")  # fmt: skip
    for kw in ({"na": 2, "nb": 2, "nk": 1}, {"structure": "oe", "nb": 1, "nf": 1, "nk": 1}):
        model = identify(data, optimiser="ls", **kw).model
        sys = model.to_control()
        assert sys.input_labels == ["torque", "u2"] and sys.output_labels == ["tip"]
        again = type(model).from_dict(json.loads(json.dumps(model.to_dict())))
        assert again.input_names == ("torque", "u2") and again.output_name == "tip"
        old = {k: v for k, v in model.to_dict().items() if k not in ("input_names", "output_name")}
        assert type(model).from_dict(old).input_names == ("u1", "u2")  # older dictionaries
    noise = identify(data, structure="oe", nb=1, nf=1, nk=1, optimiser="ls").model
    assert noise.to_control(noise=True).input_labels == ["e"]
