"""The fitted numerator (variable projection): the best ``b`` of each denominator.

Both predictors are linear in ``b`` for a fixed ``A``, so :meth:`ARXCost.fit_numerator`
solves for ``b`` exactly.  The checks compare it with an independent route: regressors
built by :meth:`ARXModel.simulate` (``scipy.signal.lfilter``) and the first-order condition
of least squares, residual orthogonal to every regressor.
"""

from __future__ import annotations

import numpy as np
import pytest

from flexid import identify
from flexid.config import CostSpec, SearchSpec
from flexid.costs.arx import ARXCost
from flexid.errors import ConfigError, DataError, UnknownNameError
from flexid.fit.estimation import build_problem, check_search
from flexid.fit.output_error import output_error
from flexid.models.arx import ARXStructure
from flexid.models.stability import is_stable, pole_radius_batched
from flexid.optimisers import minimize
from numerics import EPS
from test_estimation import two_input_record

STRUCTURE = ARXStructure(2, [2, 3], [1, 1])
DENOMINATORS = np.array([[-1.4, 0.6], [-1.2, 0.5], [-1.5, 0.7], [0.3, 0.1]])


def _orthogonality(columns: np.ndarray, resid: np.ndarray) -> tuple[np.ndarray, float]:
    """``|F_j . e| / (|F_j| |e|)`` for every column, and the bound rounding allows.

    A backward-stable least-squares solve leaves a residual orthogonal to the columns to
    ``O(kappa K eps)`` relative (Higham, Accuracy and Stability, ch. 20); the independent
    route's columns and residual differ from the solver's by ``O(K eps)`` relative (stable
    recursions of ``K`` steps).  The factor 64 covers the constants of both.
    """
    k = columns.shape[0]
    sv = np.linalg.svd(columns, compute_uv=False)
    kappa = sv[0] / sv[-1]
    cos = np.abs(columns.T @ resid) / (np.linalg.norm(columns, axis=0) * np.linalg.norm(resid))
    return cos, 64 * kappa * k * EPS


@pytest.mark.numerics
@pytest.mark.parametrize("initial", ["measured", "zero"])
@pytest.mark.parametrize("predictor", ["one-step", "simulation"])
def test_fitted_numerator_is_the_least_squares_optimum(predictor, initial):
    data = two_input_record(600, seed=3)
    cost = ARXCost(STRUCTURE, data, predictor=predictor, initial=initial, metric="sse")
    theta = cost.fit_numerator(DENOMINATORS)
    assert theta.shape == (4, STRUCTURE.n_params)
    np.testing.assert_array_equal(theta[:, :2], DENOMINATORS)
    start = STRUCTURE.start
    for row in theta:
        resid = cost.residuals(row)
        if predictor == "one-step":
            phi, _ = STRUCTURE.regressors(data.u, data.y[:, 0])
            columns = phi[:, 2:]
        else:  # the response to each unit b, by lfilter: y_sim is affine in b
            y_init = data.y[:start, 0] if initial == "measured" else None
            base = np.concatenate([row[:2], np.zeros(5)])
            y0 = STRUCTURE.model(base).simulate(data.u, y_init=y_init)
            columns = np.empty((data.n_samples - start, 5))
            for j in range(5):
                unit = base.copy()
                unit[2 + j] = 1.0
                yj = STRUCTURE.model(unit).simulate(data.u, y_init=y_init)
                columns[:, j] = (yj - y0)[start:]
        cos, bound = _orthogonality(columns, resid)
        assert cos.max() <= bound, (cos.max(), bound)
        # and it is a minimum: any change of b costs more
        nudged = row.copy()
        nudged[2:] += 1e-3
        assert cost(nudged)[0] > cost(row)[0]


def test_fit_numerator_shapes_and_unstable_rows():
    data = two_input_record(300)
    cost = ARXCost(STRUCTURE, data, predictor="simulation")
    one = cost.fit_numerator(DENOMINATORS[0])
    assert one.shape == (STRUCTURE.n_params,)
    # an unstable denominator cannot be simulated: it keeps least squares' b
    out = cost.fit_numerator(np.array([[-2.5, 1.2], [-1.4, 0.6]]))
    np.testing.assert_array_equal(out[0, 2:], cost.theta_ls[2:])
    assert not np.array_equal(out[1, 2:], cost.theta_ls[2:])
    with pytest.raises(DataError, match="shape"):
        cost.fit_numerator(np.zeros((3, 5)))


@pytest.mark.parametrize("parametrisation", ["poles", "reflection", "coefficients"])
def test_fitted_numerator_searches_the_denominator_only(parametrisation):
    data = two_input_record(600)
    search = SearchSpec(parametrisation=parametrisation, numerator="fit")
    ep = build_problem(data, ARXStructure(2, [2, 2], [1, 1]), CostSpec(), search)
    assert ep.problem.dim == 2
    assert ep.to_dict()["numerator"] == "fit"
    assert "fitted" in ep.describe() and "b fitted" in ep.box_rule
    z = ep.problem.initial_population(8, np.random.default_rng(0))
    theta = ep.theta(z)
    assert theta.shape == (8, 6)
    np.testing.assert_array_equal(ep.problem.objective(z), ep.cost(theta))
    assert is_stable(theta[:, :2]).all()  # stable spaces; stable init in the coefficient box


def test_fitted_numerator_reaches_least_squares_on_the_one_step_cost():
    # the one-step cost reduced to A is a 2-D quadratic: DE lands on least squares
    data = two_input_record(600)
    ep = build_problem(
        data, ARXStructure(2, [2, 2], [1, 1]), CostSpec(), SearchSpec(numerator="fit")
    )
    r = minimize("de", ep.problem, 3000, seed=0)
    assert r.fun <= ep.cost_ls * (1 + 1e-6)
    np.testing.assert_allclose(ep.theta(r.x), ep.theta_ls, atol=1e-4)


def test_identify_and_bad_numerator_rule():
    ident = identify(
        two_input_record(600), na=2, nb=2, nk=1, optimiser="cmaes", budget=1500, seed=1,
        numerator="fit",
    )  # fmt: skip
    assert ident.model.theta.shape == (6,)
    assert ident.search["numerator"] == "fit"
    with pytest.raises(UnknownNameError, match="numerator"):
        check_search(SearchSpec(numerator="free"))
    with pytest.raises(ConfigError, match="na = 0"):
        build_problem(two_input_record(200), ARXStructure(0, [2, 2], [1, 1]), CostSpec(),
                      SearchSpec(numerator="fit"))  # fmt: skip


def _lightly_damped_record(n: int = 800, seed: int = 0):
    """Output error through poles of radius 0.995: y = B/A u + white noise."""
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(n)
    a = np.array([-2 * 0.995 * np.cos(0.3), 0.995**2])
    x = np.zeros(n)
    for t in range(2, n):
        x[t] = -a @ x[t - 2 : t][::-1] + u[t - 1] + 0.5 * u[t - 2]
    return u, x + 0.05 * rng.standard_normal(n)


def test_output_error_reference_respects_the_radius_cap():
    u, y = _lightly_damped_record()
    cost = ARXCost(ARXStructure(2, 2, 1), (u, y), predictor="simulation")
    free = output_error(cost, seed=0)
    capped = output_error(cost, seed=0, r_max=0.98)
    assert float(pole_radius_batched(free.theta[None, :2])[0]) > 0.98
    assert float(pole_radius_batched(capped.theta[None, :2])[0]) <= 0.98
    assert capped.cost >= free.cost
    with pytest.raises(ConfigError, match="r_max"):
        output_error(cost, r_max=1.5)


def test_compare_with_a_fitted_numerator_stores_arx_coefficients(tmp_path):
    from flexid import compare
    from flexid.config import ComparisonSpec, DataSpec, ModelSpec, OptimiserSpec
    from flexid.data import save

    path = save(two_input_record(), tmp_path / "two.csv")
    spec = ComparisonSpec(
        name="two-input-fit",
        data=DataSpec(file=str(path), inputs=["u1", "u2"], outputs=["y"]),
        model=ModelSpec(na=2),
        search=SearchSpec(numerator="fit"),
        optimisers=(OptimiserSpec("de"),),
        runs=2,
        budget=2000,
    )
    result = compare(spec, store=tmp_path / "r.sqlite")
    assert "b fitted" in result.summary()
    for record in result.records["de"]:
        assert record["status"] == "ok", record.get("error")
        assert len(record["theta"]) == 6 and record["stable"]
        assert record["cost"] <= result.reference_cost * (1 + 1e-4)  # 2,000 FE, 2-D search
