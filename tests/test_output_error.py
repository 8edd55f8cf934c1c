"""Tests of the output-error reference (:mod:`flexid.fit.output_error`).

The plant is ``y = B(q)/A(q) u`` with ``A = 1 - 1.5 q^-1 + 0.7 q^-2`` (poles 0.75 +- 0.37j,
radius 0.84) and ``B = q^-1 + 0.5 q^-2``, driven by white noise, all generated here.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from flexid.costs.arx import METRICS, ARXCost
from flexid.errors import ConfigError, DataError
from flexid.fit.output_error import (
    OEResult,
    output_error,
    simulation_jacobian,
    simulation_residuals,
)
from flexid.models.arx import ARXStructure
from flexid.models.stability import is_stable, max_pole_radius, mirror_inside

A_TRUE = np.array([1.0, -1.5, 0.7])
B_TRUE = np.array([0.0, 1.0, 0.5])  # nk = 1
THETA_TRUE = np.array([-1.5, 0.7, 1.0, 0.5])
STRUCT = ARXStructure(2, 2, 1)


def _plant(n: int, seed: int, noise: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Input, output and noise-free output of the OE plant; white noise on the OUTPUT only."""
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(n)
    y0 = signal.lfilter(B_TRUE, A_TRUE, u)
    return u, y0 + noise * rng.standard_normal(n), y0


# ------------------------------------------------------------------------------ recovery
@pytest.mark.parametrize("initial", ["measured", "zero"])
def test_noise_free_recovery_from_every_start(initial: str) -> None:
    # Noise-free data make least squares exact as well, so the point here is that LM from
    # starts that are NOT the truth (random stable poles, a far x0) converges to it: the
    # simulation residual is zero only at the true parameters.
    u, y, _ = _plant(400, seed=1)
    cost = ARXCost(STRUCT, (u, y), predictor="simulation", initial=initial)
    x0 = np.array([0.5, 0.3, -1.0, 2.0])  # stable, every parameter off by >= 0.4
    res = output_error(cost, starts=5, x0=x0)
    assert [r.kind for r in res.runs] == [
        "least-squares",
        "steiglitz-mcbride",
        "perturbed",
        "random",
        "perturbed",
        "random",
        "x0",
    ]
    for run in res.runs:
        assert np.abs(run.theta - THETA_TRUE).max() < 1e-6, run.kind
    far = [r for r in res.runs if r.kind in ("random", "x0")]
    assert min(np.abs(r.theta0 - THETA_TRUE).max() for r in far) > 0.4
    assert np.abs(res.theta - THETA_TRUE).max() < 1e-6
    assert res.cost < 1e-6 * cost(np.zeros(4))[0]


def test_output_noise_ls_biased_oe_consistent() -> None:
    # White noise on the output makes the equation error A(q) v coloured, so least squares
    # is biased (here by ~0.5 on a1); OE is consistent.  Tolerance: 5 asymptotic standard
    # deviations sigma * sqrt(diag((J'J)^-1)) from the simulation Jacobian at the truth.
    sigma = 1.0
    u, y, _ = _plant(2000, seed=2, noise=sigma)
    cost = ARXCost(STRUCT, (u, y), metric="rmse", predictor="simulation")
    res = output_error(cost)
    _, jac = simulation_jacobian(cost, THETA_TRUE)
    std = sigma * np.sqrt(np.diag(np.linalg.inv(jac.T @ jac)))  # about 0.005 .. 0.03
    err_ls = np.abs(cost.theta_ls - THETA_TRUE)
    err_oe = np.abs(res.theta - THETA_TRUE)
    assert np.all(err_oe < 5 * std), (err_oe, std)
    assert err_ls.max() > 0.3  # the bias, far outside the statistical spread
    assert err_ls.max() > 10 * err_oe.max()
    assert res.cost < res.cost_ls


# ------------------------------------------------------------------------------ stability
def test_stable_when_ls_unstable_and_optimum_on_the_boundary() -> None:
    # A growing output disturbance 1.02^t: least squares fits a pole at 1.016, and the
    # unconstrained simulation optimum is unstable too, so the stable result sits next to
    # the unit circle.  It must stay strictly inside and beat the penalised LS cost.
    u, y, _ = _plant(300, seed=3)
    y = y + 1.02 ** np.arange(300)
    cost = ARXCost(STRUCT, (u, y), predictor="simulation")
    assert not is_stable(cost.theta_ls[:2])[0]
    res = output_error(cost, x0=[-2.5, 1.6, 1.0, 0.5])  # an unstable x0 is mirrored too
    assert not res.ls_stable and "mirrored" in res.message
    assert res.stable and max_pole_radius(res.theta[:2])[0] < 1.0
    for run in res.runs:
        assert is_stable(run.theta0[:2])[0] and is_stable(run.theta[:2])[0]
        if run.kind == "along the cap" or run.kind.startswith("pulled in"):
            continue  # the restarts of the best end on the circle start where it ended
        # every run moved a long way (>= 10 %) and ended against the circle: LM pushed
        # towards the unstable optimum and the rejected steps held it inside
        assert run.fun < 0.9 * run.fun0 and cost(run.x0)[0] < cost.penalty
        assert 1.0 - 1e-6 < max_pole_radius(run.theta[:2])[0] < 1.0
    assert res.cost < cost.penalty < res.cost_ls
    assert res.cost == pytest.approx(cost(res.theta)[0], rel=1e-12)


def test_lightly_damped_plant_stays_stable() -> None:
    # Poles at radius 0.995 with output noise: the optimum is near the boundary.
    a = np.real(np.poly(0.995 * np.exp([0.3j, -0.3j])))
    rng = np.random.default_rng(4)
    u = rng.standard_normal(600)
    y = signal.lfilter([0.0, 0.2, 0.1], a, u) + 0.3 * rng.standard_normal(600)
    cost = ARXCost(STRUCT, (u, y), predictor="simulation")
    res = output_error(cost)
    assert res.stable and all(is_stable(r.theta[:2])[0] for r in res.runs)
    assert res.cost <= res.cost_ls
    assert abs(max_pole_radius(res.theta[:2])[0] - 0.995) < 0.01


def test_mirror_keeps_magnitude_response() -> None:
    # pem-style reflection p -> 1/conj(p) with B / prod|p|: same |B/A| on the unit circle.
    theta = np.concatenate([np.real(np.poly([1.25, 0.5 + 0.2j, 0.5 - 0.2j]))[1:], [1.0, -0.3]])
    new = mirror_inside(theta, 3)
    assert is_stable(new[:3])[0]
    poles = np.sort_complex(np.roots(np.concatenate([[1.0], new[:3]])))
    assert np.allclose(poles, np.sort_complex(np.array([0.8, 0.5 + 0.2j, 0.5 - 0.2j])))
    w = np.linspace(0.01, np.pi, 50)
    _, h_old = signal.freqz(theta[3:], np.concatenate([[1.0], theta[:3]]), worN=w)
    _, h_new = signal.freqz(new[3:], np.concatenate([[1.0], new[:3]]), worN=w)
    assert np.allclose(np.abs(h_old), np.abs(h_new), rtol=1e-10)
    stable = np.array([-0.5, 0.1, 0.2, 1.0, 2.0])
    assert np.array_equal(mirror_inside(stable, 3), stable)


# ------------------------------------------------------------------------------ never worse than LS
@pytest.mark.parametrize("metric", METRICS)
@pytest.mark.parametrize("initial", ["measured", "zero"])
def test_never_worse_than_least_squares(metric: str, initial: str) -> None:
    u, y, _ = _plant(300, seed=5, noise=0.5)
    structure = ARXStructure(3, 2, 1)  # over-parameterised A: a harder, flatter problem
    cost = ARXCost(structure, (u, y), metric=metric, predictor="simulation", initial=initial)
    res = output_error(cost, starts=2, max_nfev=30)
    assert res.cost <= cost(cost.theta_ls)[0]
    assert res.cost == cost(res.theta)[0]
    assert res.fun == min(r.fun for r in res.runs)
    assert all(r.fun <= r.fun0 for r in res.runs)


# ------------------------------------------------------------------------------ residuals, Jacobian
def _multi_input_cost(initial: str) -> tuple[ARXCost, np.ndarray]:
    rng = np.random.default_rng(6)
    u = rng.standard_normal((250, 2))
    y = signal.lfilter([0.0, 0.5, 0.2], [1.0, -1.2, 0.5, -0.1], u[:, 0])
    y += signal.lfilter([0.0, 0.0, 0.3, -0.2, 0.1], [1.0, -1.2, 0.5, -0.1], u[:, 1])
    y += 0.1 * rng.standard_normal(250)
    structure = ARXStructure(3, [2, 3], [0, 2])
    cost = ARXCost(structure, (u, y), metric="sse", predictor="simulation", initial=initial)
    return cost, np.array([-1.1, 0.45, -0.08, 0.1, 0.4, 0.25, -0.15, 0.12])


@pytest.mark.parametrize("initial", ["measured", "zero"])
def test_residuals_match_the_cost(initial: str) -> None:
    cost, theta = _multi_input_cost(initial)
    X = theta + 0.01 * np.random.default_rng(7).standard_normal((5, theta.size))
    r = simulation_residuals(cost, X)
    assert r.shape == (5, cost.K)
    np.testing.assert_allclose(np.einsum("ij,ij->i", r, r), cost(X), rtol=1e-12)
    np.testing.assert_allclose(r[0], cost.residuals(X[0]), atol=1e-11)


@pytest.mark.parametrize("initial", ["measured", "zero"])
def test_analytic_jacobian_matches_finite_differences(initial: str) -> None:
    # Central differences with h = 1e-6: truncation O(h^2) and rounding eps/h both below
    # 1e-9 relative here, so 1e-7 (Frobenius, relative) leaves a wide margin yet would catch
    # any wrong sign, shift or initial-state term (those give O(1) errors).
    cost, theta = _multi_input_cost(initial)
    r, jac = simulation_jacobian(cost, theta)
    assert jac.shape == (cost.K, theta.size)
    np.testing.assert_allclose(r, simulation_residuals(cost, theta)[0], rtol=0, atol=1e-14)
    h = 1e-6
    steps = h * np.eye(theta.size)
    fd = (simulation_residuals(cost, theta + steps) - simulation_residuals(cost, theta - steps)).T
    fd /= 2 * h
    assert np.linalg.norm(jac - fd) / np.linalg.norm(fd) < 1e-7
    # every column matters (no parameter silently ignored)
    assert np.all(np.linalg.norm(jac, axis=0) > 1e-3)


# ------------------------------------------------------------------------------ determinism, effort
def test_deterministic_for_a_seed() -> None:
    u, y, _ = _plant(300, seed=8, noise=0.5)
    cost = ARXCost(ARXStructure(3, 2, 1), (u, y), predictor="simulation")
    one = output_error(cost, starts=4, seed=11)
    two = output_error(cost, starts=4, seed=11)
    assert np.array_equal(one.theta, two.theta)
    assert [r.fun for r in one.runs] == [r.fun for r in two.runs]
    assert [r.theta0.tolist() for r in one.runs] == [r.theta0.tolist() for r in two.runs]
    other = output_error(cost, starts=4, seed=12)
    # runs 0 and 1 (least squares, Steiglitz-McBride) do not depend on the seed
    assert np.array_equal(one.runs[1].theta0, other.runs[1].theta0)
    assert not np.array_equal(one.runs[2].theta0, other.runs[2].theta0)


def test_result_fields_and_effort() -> None:
    u, y, _ = _plant(300, seed=9, noise=0.2)
    cost = ARXCost(STRUCT, (u, y), predictor="simulation")
    res = output_error(cost, starts=3)
    assert isinstance(res, OEResult)
    # least squares, Steiglitz-McBride and two random starts
    assert res.theta.shape == (4,) and len(res.runs) == 4
    assert res.cost_ls == cost.cost_ls
    assert res.nfev >= sum(r.nfev for r in res.runs) > 0
    assert res.njev >= sum(r.njev for r in res.runs) > 0
    assert res.nfev_equivalent == res.nfev + res.njev * cost.n_params
    assert res.wall_time > 0 and isinstance(res.message, str)
    assert res.runs[res.best_start].fun == res.fun


def test_fir_model_is_least_squares() -> None:
    # na = 0: with measured initial conditions simulation and one-step errors coincide.
    u, y, _ = _plant(300, seed=10, noise=0.1)
    cost = ARXCost(ARXStructure(0, 4, 1), (u, y), predictor="simulation")
    res = output_error(cost, starts=3)
    assert len(res.runs) == 1  # no poles to vary, the random starts are skipped
    np.testing.assert_allclose(res.theta, cost.theta_ls, atol=1e-8)


# ------------------------------------------------------------------------------ errors
def test_errors() -> None:
    u, y, _ = _plant(200, seed=11)
    one_step = ARXCost(STRUCT, (u, y), predictor="one-step")
    with pytest.raises(ConfigError, match="simulation"):
        output_error(one_step)
    with pytest.raises(ConfigError, match="simulation"):
        simulation_jacobian(one_step, THETA_TRUE)
    with pytest.raises(ConfigError, match="ARXCost"):
        output_error(lambda X: X.sum(axis=1))
    cost = ARXCost(STRUCT, (u, y), predictor="simulation")
    for bad in (0, -1, 2.5, True):
        with pytest.raises(ConfigError, match="starts"):
            output_error(cost, starts=bad)
    with pytest.raises(ConfigError, match="max_nfev"):
        output_error(cost, max_nfev=0)
    with pytest.raises(ConfigError, match="tol"):
        output_error(cost, tol=0.0)
    with pytest.raises(DataError, match="x0"):
        output_error(cost, x0=[1.0, 2.0])
    with pytest.raises(DataError, match="x0"):
        output_error(cost, x0=[np.nan, 0.0, 1.0, 0.5])
    with pytest.raises(DataError, match="stable"):
        simulation_jacobian(cost, [-2.5, 1.6, 1.0, 0.5])
    with pytest.raises(DataError, match="stable"):
        simulation_residuals(cost, [[-2.5, 1.6, 1.0, 0.5]])


def test_result_is_an_optimize_result_at_a_verified_minimum() -> None:
    # Noise-free data of the true structure: the simulation optimum is THETA_TRUE with a zero
    # residual; with output noise the end is an interior minimum whose gradient test passes
    # (MINPACK stops with ||J'e|| / (||J|| ||e||) ~ 1e-9 at tol 1e-10, far below 1e-6).
    from scipy.optimize import OptimizeResult

    u, y, _ = _plant(400, seed=12, noise=0.3)
    cost = ARXCost(STRUCT, (u, y), predictor="simulation", metric="sse")
    res = output_error(cost, starts=2)
    assert isinstance(res, OptimizeResult)
    assert res.status == 0 and res.success and res.local_minimum and not res.on_cap
    assert res.optimality < 1e-6
    assert res.fun == pytest.approx(res.cost, rel=1e-12)  # the SSE metric is the SSE
    # standard errors against an independent route: central differences of the residuals
    # (error O(h^2) ~ 1e-12 relative in J) and a plain inverse of J'J
    h = 1e-6
    steps = h * np.eye(4)
    jac = (simulation_residuals(cost, res.x - steps) - simulation_residuals(cost, res.x + steps)).T
    jac /= 2 * h
    sigma2 = res.fun / (cost.K - 4)
    std = np.sqrt(np.diag(sigma2 * np.linalg.inv(jac.T @ jac)))
    np.testing.assert_allclose(res.std, std, rtol=1e-5)
    # and the true parameters lie within four of them
    assert np.all(np.abs(res.x - THETA_TRUE) < 4 * res.std)
