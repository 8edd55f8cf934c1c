"""Tests of flexid.costs.arx: batched costs equal plain loops; least squares is the optimum.

The batched costs (GEMMs, the compiled or NumPy recursion, the QR form of the one-step SSE)
and the plain loops are two routes to one number: they are compared within the rounding
bounds of tests/numerics.py and tests/route_bounds.py, and carry the ``numerics`` mark.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from flexid.costs.arx import METRICS, ARXCost, simulate_population
from flexid.data import IOData
from flexid.errors import DataError, UnknownNameError
from flexid.models.arx import ARXStructure
from numerics import EPS, assert_close_to_terms, route_tolerance
from route_bounds import ar_route_bound, lstsq_error, sse_route_bound


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


def one_step_sse_bound(cost: ARXCost, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """SSE of each row and a bound on batched minus loop SSE (one-step predictor).

    Batched: ``sse_ls + |R (theta - theta_ls)|^2`` with the QR factor ``R`` and the computed
    ``theta_ls`` (off the exact optimum ``theta*`` by ``delta``); loop: ``|target - phi
    theta|^2``.  Exactly, ``sse(theta) = sse(theta_ls) + |phi d|^2 + 2 (phi d).(phi delta)``
    with ``d = theta - theta_ls``; the bound adds up, each against the exact value:

    * the loop's and ``sse_ls``'s residuals, ``n + 1`` terms a sample, and their ``K``-term sums;
    * ``R`` is the factor of ``phi + dphi``, ``|dphi e_j| <= gamma_mn |phi e_j|`` (Householder
      QR, Higham Thm 19.4), so ``|R d|`` is ``|phi d|`` within ``g = gamma_mn sum_j |phi e_j|
      |d_j|``; ``d`` and ``|R d|^2`` are ``n + 1``- and ``n``-term sums;
    * ``|phi delta| <= gamma_mn (|target| + sum_j |phi e_j| |theta_j| + sqrt(n) kappa |r|)``
      (the LS perturbation theorem, Higham Thm 20.1, for that backward error);
    * the last addition.
    """
    phi, target = cost.structure.regressors(cost.u, cost.y)
    m, n = phi.shape
    tol = route_tolerance(n + 1)
    gamma = m * n * EPS / 2
    col = np.linalg.norm(phi, axis=0)
    sv = np.linalg.svd(phi, compute_uv=False)

    def residual_part(theta):
        e = target - phi @ theta
        rho = tol * (np.abs(target) + np.abs(phi) @ np.abs(theta))
        return e @ e, 2 * np.abs(e) @ rho + rho @ rho + route_tolerance(m) * (e @ e)

    sse_ls, b_ls = residual_part(cost.theta_ls)
    r_norm = np.sqrt(sse_ls)
    phi_delta = gamma * (np.linalg.norm(target) + col @ np.abs(cost.theta_ls)
                         + np.sqrt(n) * sv[0] / sv[-1] * r_norm)  # fmt: skip
    sse, bound = np.empty(len(X)), np.empty(len(X))
    for i, theta in enumerate(X):
        sse[i], b_loop = residual_part(theta)
        d = theta - cost.theta_ls
        phi_d = np.linalg.norm(phi @ d)
        g = gamma * col @ np.abs(d)
        rd = cost._r @ d
        dd = tol * (np.abs(cost._r) @ np.abs(d))
        b_r = 2 * phi_d * g + g * g + 2 * np.abs(rd) @ dd + dd @ dd + route_tolerance(n) * (rd @ rd)
        bound[i] = b_loop + b_ls + b_r + 2 * phi_d * phi_delta + EPS * sse[i]
    return sse, bound


def cost_bound(cost: ARXCost, F: np.ndarray, sse: np.ndarray, dsse: np.ndarray) -> np.ndarray:
    """Allowed ``|F_batched - F_loop|`` from the SSE bound: the square-root metrics halve the
    relative error; the two formulas (``w sqrt(sse) / K`` or ``w / K sqrt(sse)``, the penalty)
    round up to 4 times more."""
    power = 1.0 if cost.metric in ("sse", "mse") else 0.5
    return power * dsse / sse * np.abs(F) + 4 * EPS * np.abs(F)


def simulation_sse_bound(cost: ARXCost, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """SSE of each row and a bound on batched minus loop SSE (simulation predictor).

    Routes: forced term by one GEMM or ``lfilter`` (``nb`` terms a sample), the recursion by
    the kernel or ``lfilter`` (tests/route_bounds.py), then the SSE.
    """
    s = cost.structure
    na, st = s.na, s.start
    phi_u = s._phi_padded(cost.u, cost.y)[:, na:]  # every sample, zero before t = 0
    b = X[:, na:]
    forced = b @ phi_u.T
    terms = np.abs(b) @ np.abs(phi_u).T
    if cost.initial == "measured":
        forced, terms = forced[:, st:], terms[:, st:]
        state = cost.y[st - na : st][::-1] if na else np.zeros(0)
    else:
        state = np.zeros(na)
    y = np.array([lfilter_state(X[i, :na], forced[i], state) for i in range(len(X))])
    dy = ar_route_bound(X[:, :na], forced, state, y, terms, b.shape[1])
    if cost.initial == "zero":
        y, dy = y[:, st:], dy[:, st:]
    e = cost.y[st:] - y
    return (e * e).sum(axis=1), sse_route_bound(e, dy)


def lfilter_state(a, forced, state):
    """``y(t) = f(t) - sum_i a_i y(t - i)`` from ``[y(-1), .., y(-na)] = state``."""
    if not len(a):
        return np.array(forced, dtype=float)
    den = np.r_[1.0, a]
    return signal.lfilter([1.0], den, forced, zi=signal.lfiltic([1.0], den, state))[0]


@pytest.mark.numerics
@pytest.mark.parametrize("predictor", ["one-step", "simulation"])
@pytest.mark.parametrize("metric", METRICS)  # a new metric needs its formula in the reference
def test_batched_cost_equals_a_plain_loop(predictor, metric):
    u, y = lightly_damped_record()
    s = ARXStructure(8, 8, 1)
    cost = ARXCost(s, (u, y), metric=metric, predictor=predictor)
    rng = np.random.default_rng(1)
    X = cost.theta_ls + rng.normal(size=(40, 16)) * np.r_[np.full(8, 2e-3), np.full(8, 0.02)]
    X[:3, :8] = rng.uniform(-3, 3, (3, 8))  # some unstable candidates
    F = cost(X)
    ref = np.array([loop_cost(cost, x) for x in X])
    stable = F < cost.penalty
    assert (~stable).sum() >= 1
    if predictor == "one-step":
        # every row: its one-step SSE (plus the penalty if unstable)
        sse, dsse = one_step_sse_bound(cost, X)
        assert_close_to_terms(F, ref, cost_bound(cost, ref, sse, dsse), 1.0)
        return
    # unstable rows: the SSE of the zero prediction (a K-term dot product on each route),
    # the penalty; stable rows: the simulations
    zero = ref[~stable]
    k = cost.K
    assert_close_to_terms(F[~stable], zero, cost_bound(cost, zero, 1.0, route_tolerance(k)), 1.0)
    sse, dsse = simulation_sse_bound(cost, X[stable])
    assert_close_to_terms(F[stable], ref[stable], cost_bound(cost, ref[stable], sse, dsse), 1.0)


@pytest.mark.numerics
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
                assert m.is_stable
                ref.append(e @ e)
            # the model's simulation (lfilter for B and for 1/A) against the batched routes
            sse, dsse = simulation_sse_bound(cost, X)
            assert_close_to_terms(F, ref, dsse + 2 * EPS * sse, 1.0)


@pytest.mark.numerics
def test_least_squares_is_the_minimum_of_the_one_step_cost():
    u, y = lightly_damped_record(noise=0.01)
    cost = ARXCost(ARXStructure(8, 8, 1), IOData(u, y, dt=1e-3))
    # cost_ls is this very call (same code, same input): exact
    assert cost.cost_ls == cost(cost.theta_ls)[0]
    rng = np.random.default_rng(0)
    for scale in (1e-8, 1e-5, 1e-2):
        X = cost.theta_ls + scale * rng.normal(size=(200, 16))
        # w sqrt(sse_ls + |R d|^2) / K with |R d|^2 >= 0 and monotone rounding: exact
        assert np.all(cost(X) >= cost.cost_ls)
    # every metric is a monotone function of the SSE, so least squares minimises each one
    # (the promise the reference rows of a comparison rest on)
    for metric in METRICS:
        other = ARXCost(ARXStructure(8, 8, 1), IOData(u, y, dt=1e-3), metric=metric)
        X = other.theta_ls + 1e-3 * rng.normal(size=(200, 16))
        assert np.all(other(X) >= other.cost_ls), metric
    # numerical gradient ~ 0 at the optimum (SSE form): sse_ls + h^2 |R e_j|^2 on both
    # sides, so the difference is rounding only: each value within (n + 3) u of its size,
    # and theta_ls +- h - theta_ls within u |theta_ls| of h
    sse = ARXCost(ARXStructure(8, 8, 1), (u, y), metric="sse")
    h = 1e-6
    E = np.eye(16) * h
    plus, minus = sse(sse.theta_ls + E), sse(sse.theta_ls - E)
    grad = (plus - minus) / (2 * h)
    phi, target = ARXStructure(8, 8, 1).regressors(u, y)
    col2 = np.linalg.norm(phi, axis=0) ** 2
    bound = (route_tolerance(16 + 3) * (plus + minus) / (2 * h)
             + 4 * EPS * (np.abs(sse.theta_ls) + h) * col2)  # fmt: skip
    assert_close_to_terms(grad, 0.0, bound, 1.0)
    assert bound.max() < 1e-6 * sse.cost_ls  # and that bound is a gradient of ~0
    # equals the regression of numpy's lstsq (SVD): two backward-stable solvers, each within
    # the LS perturbation bound (tests/route_bounds.py) of the exact solution
    ref = np.linalg.lstsq(phi, target, rcond=None)[0]
    resid = np.linalg.norm(target - phi @ ref)
    tol = 2 * lstsq_error(phi, ref, resid)
    assert np.linalg.norm(cost.theta_ls - ref) <= tol
    assert tol < 1e-3 * np.linalg.norm(ref)  # not vacuous


@pytest.mark.numerics
def test_noise_free_data_cost_is_zero_at_least_squares():
    u, y = lightly_damped_record(noise=0.0, na=4, n=400)
    s = ARXStructure(4, 4, 1)
    cost = ARXCost(s, (u, y), metric="rmse")
    # rounding only: lfilter made each sample from 9 terms, so the true theta leaves a
    # residual rho of at most 9 eps terms; theta_ls is off the exact LS solution (whose
    # residual is at most |rho|) by the LS error bound, and the residual is itself a sum
    phi, target = s.regressors(u, y)
    k = target.size
    # |rho| and the residual's own rounding, both 9-term sums of these magnitudes
    terms = np.abs(target) + np.abs(phi) @ np.abs(cost.theta_ls)
    rho = np.linalg.norm(route_tolerance(9) * terms)
    sigma_max = np.linalg.svd(phi, compute_uv=False)[0]
    resid = 2 * rho + sigma_max * lstsq_error(phi, cost.theta_ls, rho)
    bound = resid / np.sqrt(k) * (1 + route_tolerance(k + 3))  # the K-term sum, sqrt, / K
    assert cost.cost_ls <= bound
    x = cost.theta_ls.copy()
    x[0] += 1e-3
    sse, dsse = one_step_sse_bound(cost, x[None])
    assert abs(cost(x)[0] - loop_cost(cost, x)) <= cost_bound(cost, cost(x), sse, dsse)[0]


@pytest.mark.numerics
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
            # two routes through the recursion (tests/route_bounds.py)
            bound = ar_route_bound(A[p], f[p], s0, ref)[0]
            assert_close_to_terms(y[p], ref, bound, 1.0)


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
    assert "K = 298 samples" in cost.describe()
    with pytest.raises(DataError):
        ARXCost(s, (u, y), weight=-1.0)
