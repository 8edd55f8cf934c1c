"""The state-space model and the modes of discrete poles, against independent routes:
``scipy.signal.dlsim`` and ``dfreqresp``, python-control, and modes built from their
frequency and damping by the exact discretisation ``z = exp(s dt)``."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import linalg, signal

from flexid.errors import DataError, ModelOrderError
from flexid.models.modes import modes
from flexid.models.statespace import StateSpaceModel

DT = 0.01
# Two lightly damped modes (3 Hz at 2 %, 11 Hz at 5 %) and a real pole, two inputs, two
# outputs: a continuous model discretised exactly (zero-order hold), as a beam's modes are.
MODES = ((3.0, 0.02), (11.0, 0.05))
REAL_POLE = -4.0  # rad/s


def _continuous() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    blocks = []
    for f, zeta in MODES:
        w = 2 * np.pi * f
        blocks.append(np.array([[0.0, 1.0], [-w * w, -2 * zeta * w]]))
    blocks.append(np.array([[REAL_POLE]]))
    a = linalg.block_diag(*blocks)
    rng = np.random.default_rng(0)
    b = rng.standard_normal((5, 2))
    c = rng.standard_normal((2, 5))
    d = np.array([[0.1, 0.0], [0.0, -0.2]])
    return a, b, c, d


def _model(**kwargs) -> StateSpaceModel:
    a, b, c, d = _continuous()
    A, B, C, D, _ = signal.cont2discrete((a, b, c, d), DT, method="zoh")
    return StateSpaceModel(A, B, C, D, dt=DT, **kwargs)


def test_simulation_equals_dlsim():
    model = _model(x0=np.arange(5) * 0.1)
    u = np.random.default_rng(1).standard_normal((400, 2))
    y = model.simulate(u)
    _, y_ref, _ = signal.dlsim((model.A, model.B, model.C, model.D, DT), u, x0=model.x0)
    # the same arithmetic in another order: rounding of a stable recursion, ~1e-15 relative
    np.testing.assert_allclose(y, y_ref, rtol=1e-10, atol=1e-12)
    assert y.shape == (400, 2)


def test_one_step_prediction_is_the_innovations_form():
    # the predictor is itself a state-space system driven by (u, y): dlsim of it is the
    # independent route
    rng = np.random.default_rng(2)
    K = 0.01 * rng.standard_normal((5, 2))  # small enough for A - K C to be stable here
    model = _model(K=K)
    assert model.predictor_stable
    u = rng.standard_normal((300, 2))
    y = model.simulate(u) + 0.1 * rng.standard_normal((300, 2))
    yh = model.predict(u, y)
    F = model.A - K @ model.C
    G = np.hstack([model.B - K @ model.D, K])
    J = np.hstack([model.D, np.zeros((2, 2))])
    _, ref, _ = signal.dlsim((F, G, model.C, J, DT), np.hstack([u, y]))
    np.testing.assert_allclose(yh, ref, rtol=1e-10, atol=1e-12)
    # K = 0: the prediction is the simulation
    free = _model()
    np.testing.assert_allclose(free.predict(u, y), free.simulate(u), rtol=0, atol=1e-12)


def test_modes_recover_the_continuous_frequencies_and_damping():
    model = _model()
    found = model.modes()
    assert [m.kind for m in found] == ["real", "pair", "pair"]
    # z = exp(s dt) is exact, so log(z) / dt returns s to rounding (~1e-12 relative)
    for m, (f, zeta) in zip(found[1:], MODES):
        assert m.frequency == pytest.approx(f, rel=1e-9)
        assert m.damping == pytest.approx(zeta, rel=1e-7)
    assert found[0].frequency == pytest.approx(-REAL_POLE / (2 * np.pi), rel=1e-9)
    assert found[0].damping == pytest.approx(1.0, rel=1e-12)
    assert model.is_stable
    text = model.summary()
    assert "order 5" in text and "3" in text and "pair" in text


def test_modes_of_special_poles_and_bad_ones():
    kinds = {m.kind: m for m in modes([1.0, 0.0, -0.5, 0.5], dt=0.1)}
    assert set(kinds) == {"integrator", "delay", "negative real", "real"}
    assert kinds["integrator"].frequency == 0.0 and math.isnan(kinds["integrator"].damping)
    assert kinds["delay"].frequency == math.inf
    # a negative real pole is a "mode" at the Nyquist frequency's side, as MATLAB damp says
    s = complex(np.log(-0.5 + 0j)) / 0.1
    assert kinds["negative real"].frequency == pytest.approx(abs(s) / (2 * np.pi))
    assert kinds["real"].damping == pytest.approx(1.0)
    with pytest.raises(DataError, match="conjugate"):
        modes([0.5 + 0.5j], dt=0.1)
    with pytest.raises(DataError, match="dt"):
        modes([0.5], dt=0.0)


def test_frequency_response_equals_scipy_and_python_control():
    import control

    model = _model()
    f = np.linspace(0.1, 49.0, 37)
    G = model.frequency_response(f)
    assert G.shape == (37, 2, 2)
    w = 2 * np.pi * f * DT  # rad/sample
    for j in range(2):
        sys = signal.dlti(*signal.ss2tf(model.A, model.B, model.C, model.D, input=j), dt=DT)
        for o in range(2):
            num = sys.num[o] if np.ndim(sys.num) == 2 else sys.num
            _, H = signal.freqz(num, sys.den, worN=w)
            # the transfer function's direct form loses ~1e-9 on these lightly damped poles
            np.testing.assert_allclose(G[:, o, j], H, rtol=1e-6, atol=1e-9)
    H = control.frequency_response(model.to_control(), 2 * np.pi * f)
    np.testing.assert_allclose(np.moveaxis(H.complex, -1, 0), G, rtol=1e-10, atol=1e-12)


def test_exports_carry_the_matrices_and_dt():
    import control

    model = _model(input_names=["torque", "load"], output_names=["hub", "tip"])
    sys = model.to_control()
    assert sys.dt == DT and sys.input_labels == ["torque", "load"]
    np.testing.assert_array_equal(sys.A, model.A)
    u = np.random.default_rng(3).standard_normal((200, 2))
    resp = control.forced_response(sys, U=u.T)
    np.testing.assert_allclose(resp.outputs.T, model.simulate(u), rtol=1e-10, atol=1e-12)
    dlti = model.to_dlti()
    assert dlti.dt == DT and np.array_equal(dlti.C, model.C)
    d = model.to_dict()
    assert d["outputs"] == ["hub", "tip"] and len(d["modes"]) == 3


def test_bad_matrices_and_inputs_are_named():
    a, b, c, _ = _continuous()
    with pytest.raises(DataError, match=r"B must have shape \(5, 2\)"):
        StateSpaceModel(a, b[:4], c)
    with pytest.raises(DataError, match=r"D must have shape \(2, 2\)"):
        StateSpaceModel(a, b, c, D=np.zeros((2, 3)))
    with pytest.raises(DataError, match="K has non-finite"):
        StateSpaceModel(a, b, c, K=np.full((5, 2), np.nan))
    with pytest.raises(DataError, match="dt must be a positive"):
        StateSpaceModel(a, b, c, dt=-1.0)
    with pytest.raises(ModelOrderError, match=r"2 input\(s\)"):
        _model().simulate(np.zeros((10, 3)))
