"""Tests of flexid.objective: batched costs equal plain loops; least squares is the optimum."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from flexid.arx import ARXStructure
from flexid.data import IOData
from flexid.errors import DataError, UnknownNameError
from flexid.objective import ARXCost, simulate_population


def lightly_damped_record(n=1500, seed=0, noise=1e-3, na=8):
    rng = np.random.default_rng(seed)
    ang = np.linspace(0.1, 2.5, na // 2)
    poles = 0.97 * np.exp(1j * ang)
    a = np.poly(np.r_[poles, poles.conj()]).real
    b = rng.normal(size=na) * 0.1
    u = rng.uniform(-0.3, 0.3, n)
    y = signal.lfilter(np.r_[0.0, b], a, u) + noise * rng.standard_normal(n)
    return u, y


def loop_cost(cost: ARXCost, theta: np.ndarray) -> float:
    """Plain per-candidate reference: np.roots, then residuals by lfilter or regressors."""
    s = cost.structure
    na = s.na
    a = np.r_[1.0, theta[:na]]
    stable = np.abs(np.roots(a)).max() < 1 if na else True
    y = cost.y
    st = s.start
    target = y[st:]
    if cost.predictor == "one-step":
        phi, _ = s.regressors(cost.u, y)
        e = target - phi @ theta
    elif not stable:
        e = target  # the zero prediction
    else:
        b = np.r_[np.zeros(s.nk[0]), theta[na:]]
        forced = signal.lfilter(b, [1.0], cost.u[:, 0])
        if cost.initial == "measured":
            zi = signal.lfiltic([1.0], a, y[:st][::-1][:na])
            ysim = signal.lfilter([1.0], a, forced[st:], zi=zi)[0]
        else:
            ysim = signal.lfilter([1.0], a, forced)[st:]
        e = target - ysim
    sse = float(e @ e)
    k = target.size
    value = {
        "paper": cost.weight * np.sqrt(sse) / k,
        "rmse": np.sqrt(sse / k),
        "nrmse": np.sqrt(sse / k) / np.std(target),
        "sse": sse,
        "mse": sse / k,
    }[cost.metric]
    return value + (0.0 if stable else cost.penalty)


@pytest.mark.parametrize("predictor", ["one-step", "simulation"])
@pytest.mark.parametrize("metric", ["paper", "rmse", "nrmse", "sse", "mse"])
def test_batched_cost_equals_a_plain_loop(predictor, metric):
    u, y = lightly_damped_record()
    s = ARXStructure(8, 8, 1)
    cost = ARXCost(s, (u, y), metric=metric, predictor=predictor)
    rng = np.random.default_rng(1)
    X = cost.theta_ls + rng.normal(size=(40, 16)) * np.r_[np.full(8, 2e-3), np.full(8, 0.02)]
    X[:3, :8] = rng.uniform(-3, 3, (3, 8))  # some unstable candidates
    F = cost(X)
    ref = np.array([loop_cost(cost, x) for x in X])
    np.testing.assert_allclose(F, ref, rtol=1e-10)
    assert (F >= cost.penalty).sum() >= 1


def test_zero_initial_conditions_and_other_orders():
    u, y = lightly_damped_record(n=700, na=4, seed=3)
    for na, nb, nk in [(4, 4, 1), (2, 3, 2), (5, 1, 1)]:
        s = ARXStructure(na, nb, nk)
        for initial in ("measured", "zero"):
            cost = ARXCost(s, (u, y), predictor="simulation", initial=initial, metric="sse")
            rng = np.random.default_rng(na)
            X = cost.theta_ls + 1e-3 * rng.normal(size=(7, s.n_params))
            F = cost(X)
            ref = []
            for x in X:
                m = s.model(x)
                ysim = m.simulate(u, y_init=y[: s.start] if initial == "measured" else None)
                e = y[s.start :] - ysim[s.start :]
                stable = m.is_stable
                ref.append(e @ e if stable else y[s.start :] @ y[s.start :] + cost.penalty)
            np.testing.assert_allclose(F, ref, rtol=1e-10)


def test_least_squares_is_the_minimum_of_the_one_step_cost():
    u, y = lightly_damped_record(noise=0.01)
    cost = ARXCost(ARXStructure(8, 8, 1), IOData(u, y, dt=1e-3))
    assert cost.cost_ls == pytest.approx(cost(cost.theta_ls)[0], rel=1e-14)
    rng = np.random.default_rng(0)
    for scale in (1e-8, 1e-5, 1e-2):
        X = cost.theta_ls + scale * rng.normal(size=(200, 16))
        assert np.all(cost(X) >= cost.cost_ls * (1 - 1e-12))
    # numerical gradient ~ 0 at the optimum (SSE form)
    sse = ARXCost(ARXStructure(8, 8, 1), (u, y), metric="sse")
    h = 1e-6
    E = np.eye(16) * h
    grad = (sse(sse.theta_ls + E) - sse(sse.theta_ls - E)) / (2 * h)
    assert np.abs(grad).max() < 1e-6 * sse.cost_ls
    # equals the regression of numpy's lstsq
    phi, target = ARXStructure(8, 8, 1).regressors(u, y)
    ref = np.linalg.lstsq(phi, target, rcond=None)[0]
    np.testing.assert_allclose(cost.theta_ls, ref, rtol=1e-9, atol=1e-12)


def test_noise_free_data_cost_is_zero_at_least_squares():
    u, y = lightly_damped_record(noise=0.0, na=4, n=400)
    cost = ARXCost(ARXStructure(4, 4, 1), (u, y), metric="rmse")
    assert cost.cost_ls < 1e-12
    x = cost.theta_ls.copy()
    x[0] += 1e-3
    assert cost(x)[0] == pytest.approx(loop_cost(cost, x), rel=1e-8)


def test_simulate_population_matches_lfilter():
    rng = np.random.default_rng(2)
    for na in (1, 3, 8, 10, 12, 16):
        P, K = 6, 333
        A = np.array([np.poly(np.r_[r, r.conj()][:na]).real[1:] if na > 1 else [0.5] for r in
                      [0.95 * np.exp(1j * rng.uniform(0.1, 3, (na + 1) // 2)) for _ in range(P)]])
        f = rng.normal(size=(P, K))
        s0 = rng.normal(size=na)
        y = simulate_population(A, f, s0)
        for p in range(P):
            a = np.r_[1.0, A[p]]
            ref = signal.lfilter([1.0], a, f[p], zi=signal.lfiltic([1.0], a, s0))[0]
            np.testing.assert_allclose(y[p], ref, rtol=1e-9, atol=1e-9 * np.abs(ref).max())


def test_bad_input():
    u, y = lightly_damped_record(n=300, na=2)
    s = ARXStructure(2, 2, 1)
    with pytest.raises(UnknownNameError, match="metric"):
        ARXCost(s, (u, y), metric="l7")
    with pytest.raises(UnknownNameError, match="predictor"):
        ARXCost(s, (u, y), predictor="two-step")
    cost = ARXCost(s, (u, y))
    with pytest.raises(DataError, match=r"\(P, 4\)"):
        cost(np.zeros((3, 5)))
    X = np.zeros((3, 4))
    X[1, 2] = np.nan
    F = cost(X)
    assert np.isinf(F[1]) and np.isfinite(F[[0, 2]]).all()
    assert "K=298" in cost.describe()
    with pytest.raises(DataError):
        ARXCost(s, (u, y), weight=-1.0)
