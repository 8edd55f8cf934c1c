"""The polynomial model family (flexid.models.polynomial), checked against independent routes.

The independent route is a cascade of ``scipy.signal.lfilter`` calls written from the model
equation ``A y = B/F u + C/D e``, and data made from a known innovation sequence ``e``: the
one-step prediction error of the true model is then ``e`` itself, and the ``k``-step error the
first ``k`` impulse-response terms of ``H = C/(A D)`` applied to ``e``.

Tolerances: every comparison is of two exact evaluations of the same linear filter in
float64 with stable filters whose poles are at most 0.9 in radius, so the outputs agree to a
few hundred ulps of the signals' magnitude (bounds 1e-10 relative to max|y|, far above
that and far below any modelling error).
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy import signal

from flexid.errors import DataError, ModelOrderError, UnknownNameError
from flexid.models.arx import ARXStructure
from flexid.models.polynomial import (
    STRUCTURES,
    PolynomialModel,
    PolynomialStructure,
    run_predictor,
    structure,
)

N = 800
RTOL = 1e-10  # see the module docstring


def _poly(roots) -> np.ndarray:
    return np.real(np.poly(roots))


# one model of each structure, SISO and two-input; poles and C roots within radius 0.9
A = _poly([0.7, 0.5 + 0.3j, 0.5 - 0.3j])
F = _poly([0.8 * np.exp(0.4j), 0.8 * np.exp(-0.4j)])
F2 = _poly([0.6])
C = _poly([-0.5, 0.3])
D = _poly([0.9])
B = np.array([0.5, -0.2, 0.1])
B2 = np.array([0.3, 0.2])

MODELS = {
    "arx": (PolynomialStructure.arx(3, 3, 1), np.r_[A[1:], B]),
    "armax": (PolynomialStructure.armax(3, 3, 2, 1), np.r_[A[1:], B, C[1:]]),
    "oe": (PolynomialStructure.oe(3, 2, 1), np.r_[B, F[1:]]),
    "bj": (PolynomialStructure.bj(3, 2, 1, 2, 2), np.r_[B, C[1:], D[1:], F[1:]]),
    "oe2": (PolynomialStructure.oe([3, 2], [2, 1], [1, 0]), np.r_[B, B2, F[1:], F2[1:]]),
    "bj2": (
        PolynomialStructure.bj([3, 2], 2, 1, [2, 1], [1, 0]),
        np.r_[B, B2, C[1:], D[1:], F[1:], F2[1:]],
    ),
}


def _data(model: PolynomialModel, seed: int = 0, noise: float = 0.1):
    """``(u, y, e)``: y made by lfilter from the model's own equation and a known ``e``."""
    rng = np.random.default_rng(seed)
    s = model.structure
    u = rng.standard_normal((N, s.n_inputs))
    e = noise * rng.standard_normal(N)
    y = signal.lfilter(model.c, np.convolve(model.a, model.d), e)
    for j in range(s.n_inputs):
        num = np.r_[np.zeros(s.nk[j]), model.b[j]]
        y = y + signal.lfilter(num, np.convolve(model.a, model.f[j]), u[:, j])
    return u, y, e


@pytest.fixture(params=sorted(MODELS))
def model(request) -> PolynomialModel:
    s, theta = MODELS[request.param]
    return s.model(theta, dt=0.01)


# ================================================================================ structures
def test_named_structures_take_matlab_orders_and_name_themselves():
    assert structure("oe", nb=16, nf=16, nk=1) == PolynomialStructure(nb=16, nf=16, nk=1)
    assert repr(structure("bj", nb=16, nc=2, nd=2, nf=16)) == (
        "BJ(nb=16, nc=2, nd=2, nf=16, nk=1)"
    )
    for name in STRUCTURES:
        orders = {k: 2 for k in STRUCTURES[name]}
        assert structure(name, **orders).kind == name
    # ARX: the same parameter order as ARXStructure
    assert structure("arx", na=2, nb=[2, 1], nk=[1, 0]).param_names == ARXStructure(
        2, [2, 1], [1, 0]
    ).param_names
    assert structure("bj", nb=2, nc=1, nd=1, nf=2).param_names == [
        "b1", "b2", "c1", "d1", "f1", "f2",
    ]


@pytest.mark.parametrize(
    ("name", "orders", "error", "words"),
    [
        ("oe", {"nb": 2, "nf": 2, "nc": 1}, ModelOrderError, "no order nc"),
        ("arx", {"na": 2, "nb": 2, "nf": 1}, ModelOrderError, "takes na, nb, nk"),
        ("bj", {"nb": 2, "nf": 2}, ModelOrderError, r"needs the order\(s\) nc, nd"),
        ("box-jenkins", {"nb": 2}, UnknownNameError, "armax, arx, bj, oe"),
        ("oe", {"nb": 2, "nf": -1}, ModelOrderError, "nf"),
        ("oe", {"nb": [2, 2], "nf": [1, 1, 1]}, ModelOrderError, "one per input"),
        ("oe", {"nb": 0, "nf": 2}, ModelOrderError, "no B coefficients"),
    ],
)
def test_bad_orders_get_a_typed_error_naming_them(name, orders, error, words):
    with pytest.raises(error, match=words):
        structure(name, **orders)


def test_structure_dictionary_round_trip_and_arx_dictionary_reads():
    s = MODELS["bj2"][0]
    assert PolynomialStructure.from_dict(json.loads(json.dumps(s.to_dict()))) == s
    arx = PolynomialStructure.from_dict({"na": 2, "nb": [3], "nk": [1]})
    assert arx.kind == "arx" and arx == structure("arx", na=2, nb=3, nk=1)


def test_too_short_a_record_is_refused():
    s = structure("oe", nb=16, nf=16)
    with pytest.raises(ModelOrderError, match="too few samples"):
        s.check_samples(40)


# ================================================================================ predictors
def test_one_step_error_of_the_true_model_is_the_innovation(model):
    """From rest, the true model's one-step error is exactly the ``e`` that made the data."""
    u, y, e = _data(model)
    err = y - model.predict(u, y, initial="zero")
    np.testing.assert_allclose(err, e, rtol=0, atol=RTOL * np.abs(y).max())


def test_one_step_predictor_equals_the_lfilter_cascade(model):
    """``e = D/C (A y - sum_j B_j/F_j u_j)`` for arbitrary data, against the combined filter."""
    rng = np.random.default_rng(3)
    u = rng.standard_normal((N, model.structure.n_inputs))
    y = rng.standard_normal(N)
    v = signal.lfilter(model.a, [1.0], y)
    for j in range(model.structure.n_inputs):
        num = np.r_[np.zeros(model.structure.nk[j]), model.b[j]]
        v = v - signal.lfilter(num, model.f[j], u[:, j])
    e = signal.lfilter(model.d, model.c, v)
    np.testing.assert_allclose(y - model.predict(u, y, initial="zero"), e, atol=RTOL * 10)


@pytest.mark.parametrize("k", [2, 5])
def test_k_step_error_is_the_first_k_noise_impulse_terms_applied_to_e(model, k):
    """``y - yhat(t|t-k) = sum_(i<k) h_i e(t-i)`` with ``h`` the impulse response of ``H``."""
    u, y, e = _data(model)
    impulse = np.zeros(k)
    impulse[0] = 1.0
    h = signal.lfilter(model.c, np.convolve(model.a, model.d), impulse)
    expected = signal.lfilter(h, [1.0], e)
    err = y - model.predict(u, y, k=k, initial="zero")
    np.testing.assert_allclose(err, expected, atol=RTOL * np.abs(y).max())


def test_simulation_is_b_over_af_and_infinite_horizon_prediction(model):
    u, y, e = _data(model)
    sim = model.simulate(u)
    expected = np.zeros(N)
    for j in range(model.structure.n_inputs):
        num = np.r_[np.zeros(model.structure.nk[j]), model.b[j]]
        expected += signal.lfilter(num, np.convolve(model.a, model.f[j]), u[:, j])
    np.testing.assert_allclose(sim, expected, atol=RTOL * np.abs(y).max())
    np.testing.assert_allclose(
        model.predict(u, y, k=np.inf, initial="zero"), sim, atol=RTOL * np.abs(y).max()
    )
    noise = signal.lfilter(model.c, np.convolve(model.a, model.d), e)
    np.testing.assert_allclose(y - sim, noise, atol=RTOL * np.abs(y).max())


def test_estimated_initial_state_removes_the_transient_of_a_record_cut_mid_run(model):
    """Noise-free data cut in the middle of a run: ``"estimate"`` reproduces it exactly,
    ``"zero"`` does not (its transient), and ``"measured"`` sits between."""
    rng = np.random.default_rng(5)
    s = model.structure
    u = rng.standard_normal((2 * N, s.n_inputs))
    full = model.simulate(u)
    u, y = u[N:], full[N:]
    errors = {}
    for rule in ("estimate", "zero", "measured"):
        r = (y - model.simulate(u, y, initial=rule))[s.start :]
        errors[rule] = float(np.sqrt(np.mean(r * r)))
    # the initial state is fitted by least squares over a 3-to-5 dimensional space whose
    # basis has condition number below 1e3 here: exact to ~1e-12 of the signal
    assert errors["estimate"] < 1e-9 * np.abs(y).max()
    assert errors["zero"] > 1e-3 * np.abs(y).max()


def test_measured_rule_matches_arx_simulate_from_measured_outputs():
    s, theta = MODELS["arx"]
    model = s.model(theta)
    arx = ARXStructure(3, 3, 1).model(theta)
    u, y, _ = _data(model)
    np.testing.assert_allclose(
        model.simulate(u, y, initial="measured"),
        arx.simulate(u[:, 0], y_init=y[: s.start]),
        atol=RTOL * np.abs(y).max(),
    )
    np.testing.assert_allclose(model.predict(u, y)[s.start :], arx.predict(u[:, 0], y)[s.start :])


def test_run_predictor_counts_from_the_first_sample_with_measured_data():
    den, num_y, nums = MODELS["bj"][0].model(MODELS["bj"][1]).predictor_polynomials(3)
    u, y, _ = _data(MODELS["bj"][0].model(MODELS["bj"][1]))
    out, x0 = run_predictor(den, num_y, nums, u, y, 0, "measured")
    start = max(den.size, num_y.size, *[n.size for n in nums]) - 1
    np.testing.assert_array_equal(out[:start], y[:start])
    assert x0.shape == (den.size - 1,)


# ================================================================================ exports
def test_control_and_dlti_exports_have_the_models_frequency_response(model):
    s = model.structure
    w = np.linspace(0.05, 3.0, 7)
    z = np.exp(1j * w)
    for j in range(s.n_inputs):
        num = np.r_[np.zeros(s.nk[j]), model.b[j]]
        den = np.convolve(model.a, model.f[j])
        expected = np.polyval(num[::-1], 1 / z) / np.polyval(den[::-1], 1 / z)
        _, h = model.to_dlti(j).freqresp(w)
        np.testing.assert_allclose(h, expected, rtol=1e-9)
        tf = model.to_control()
        got = tf(z)[0, j] if s.n_inputs > 1 else tf(z)
        np.testing.assert_allclose(np.ravel(got), expected, rtol=1e-9)
    expected = np.polyval(model.c[::-1], 1 / z) / np.polyval(
        np.convolve(model.a, model.d)[::-1], 1 / z
    )
    np.testing.assert_allclose(model.to_dlti(noise=True).freqresp(w)[1], expected, rtol=1e-9)
    np.testing.assert_allclose(np.ravel(model.to_control(noise=True)(z)), expected, rtol=1e-9)
    assert model.to_control().dt == model.dt


def test_poles_zeros_and_stability(model):
    expected = np.concatenate([np.roots(p) for p in (model.a, *model.f) if p.size > 1])
    np.testing.assert_allclose(np.sort_complex(model.poles()), np.sort_complex(expected))
    assert model.is_stable and model.predictor_stable
    assert model.max_pole_radius == pytest.approx(np.abs(expected).max())
    np.testing.assert_allclose(np.sort_complex(model.zeros(0)), np.sort_complex(np.roots(B)))
    unstable = model.structure.model(
        np.where(np.arange(model.theta.size) == model.structure.slices()["f"][0].start, -2.1,
                 model.theta)
    ) if model.structure.nf[0] else None
    if unstable is not None:
        assert not unstable.is_stable


def test_model_dictionary_and_json_round_trip(model):
    again = PolynomialModel.from_json(model.to_json())
    assert again.structure == model.structure
    np.testing.assert_array_equal(again.theta, model.theta)
    assert again.dt == model.dt
    with pytest.raises(DataError, match="theta"):
        PolynomialModel.from_dict({"na": 1, "nb": [1]})


def test_bad_model_input_gets_a_typed_error():
    s, theta = MODELS["oe"]
    with pytest.raises(DataError, match="theta has 2 values"):
        s.model([1.0, 2.0])
    m = s.model(theta)
    with pytest.raises(DataError, match="measured output y is needed"):
        m.simulate(np.zeros(50), initial="estimate")
    with pytest.raises(UnknownNameError, match="estimate, measured, zero"):
        m.simulate(np.zeros(50), initial="backcast")
    with pytest.raises(DataError, match="column"):
        m.simulate(np.zeros((50, 2)))
    with pytest.raises(DataError, match="prediction horizon"):
        m.predict(np.zeros(50), np.zeros(50), k=0)


def test_a_named_structure_keeps_its_name_with_a_zero_order():
    """ARMAX with nc = 0 is still ARMAX (and reads back as such); OE takes no A."""
    s = structure("armax", na=2, nb=2, nc=0)
    assert s.kind == "armax" and PolynomialStructure.from_dict(s.to_dict()).kind == "armax"
    with pytest.raises(ModelOrderError, match="the oe structure has no order na"):
        PolynomialStructure(na=1, nb=1, nf=1, kind="oe")
