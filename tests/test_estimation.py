"""The estimation problem shared by identify and compare: search spaces, penalty, references.

Tolerances are modelling tolerances (fits, cost ratios), far above rounding, except where a
comment says otherwise.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from flexid import compare, identify
from flexid.config import (
    PAPER_SEARCH,
    ComparisonSpec,
    CostSpec,
    DataSpec,
    ModelSpec,
    OptimiserSpec,
    SearchSpec,
)
from flexid.costs.arx import ARXCost
from flexid.data import IOData, save
from flexid.errors import (
    ConfigError,
    FlexidDeprecationWarning,
    ModelOrderError,
    UnknownNameError,
)
from flexid.fit.estimation import build_problem, check_search, model_structure
from flexid.models.arx import ARXStructure
from flexid.models.stability import is_stable, max_pole_radius, pole_radius_batched

A_TRUE = np.array([-1.5, 0.7])  # poles 0.75 +- 0.37j, radius 0.84
B1, B2 = np.array([1.0, 0.5]), np.array([-0.4, 0.3])


def two_input_record(n: int = 900, seed: int = 0) -> IOData:
    """y = B1/A u1 + B2/A u2 + small white equation noise (an exact ARX(2, [2, 2], [1, 1]))."""
    rng = np.random.default_rng(seed)
    u = rng.uniform(-1, 1, (n, 2))
    y = np.zeros(n)
    e = 0.01 * rng.standard_normal(n)
    for t in range(2, n):
        y[t] = (
            -A_TRUE @ y[t - 2 : t][::-1]
            + B1 @ u[t - 2 : t, 0][::-1]
            + B2 @ u[t - 2 : t, 1][::-1]
            + e[t]
        )
    return IOData(u, y[:, None], dt=0.01, input_names=["u1", "u2"], output_names=["y"])


def test_model_structure_gives_every_input_the_default_orders():
    s = model_structure(3, None, 1, 2)
    assert s.nb == (3, 3) and s.nk == (1, 1)
    assert model_structure(2, 4, 0, 1).nb == (4,)
    with pytest.raises(ModelOrderError, match="2 input"):
        model_structure(2, [2, 2, 2], [1, 1, 1], 2)


def test_two_input_record_identifies_and_compares(tmp_path):
    data = two_input_record()
    ident = identify(data, 2, optimiser="de", budget=6000, seed=1)
    assert ident.model.structure.nb == (2, 2)
    assert ident.model.is_stable and ident.cost_value < 1.5 * ident.cost_ls
    path = save(data, tmp_path / "two.csv")
    spec = ComparisonSpec(
        name="two-input",
        data=DataSpec(file=str(path), inputs=["u1", "u2"], outputs=["y"]),
        model=ModelSpec(na=2),
        optimisers=(OptimiserSpec("de"),),
        runs=2,
        budget=6000,
    )
    result = compare(spec)
    for record in result.records["de"]:
        assert record["status"] == "ok", record.get("error")
        assert len(record["theta"]) == 6 and record["stable"]
        assert record["cost"] < 1.5 * result.reference_cost


@pytest.mark.parametrize("space", ["poles", "reflection", "coefficients"])
def test_every_search_space_reports_arx_coefficients(space):
    data = two_input_record()
    ident = identify(data, 2, optimiser="pso", budget=3000, seed=0, parametrisation=space)
    out = ident.to_dict()
    assert out["search"]["space"]["parametrisation"]["name"] == space
    assert len(out["model"]["theta"]) == 6  # a1, a2, b(u1), b(u2): ARX coefficients
    assert ident.model.is_stable
    assert space in ident.summary()


def test_stable_initial_population_in_the_coefficient_space():
    data = two_input_record()
    est = data.split()[0]
    s = model_structure(2, None, 1, 2)
    ep = build_problem(est, s, CostSpec(), SearchSpec(parametrisation="coefficients"))
    X = ep.problem.initial_population(500, 3)
    assert np.all(is_stable(X[:, :2]))
    assert np.all((X >= ep.problem.lower) & (X <= ep.problem.upper))
    paper = build_problem(est, s, CostSpec(), PAPER_SEARCH)
    # the paper's uniform box: the same draws as a plain uniform population
    Xp = paper.problem.initial_population(50, 3)
    r = np.random.default_rng(3).random((50, 6))
    np.testing.assert_array_equal(Xp, paper.problem.lower + r * paper.problem.width)


@pytest.mark.numerics
def test_graded_penalty_grows_with_the_pole_radius_and_flat_stays_the_papers():
    data = two_input_record()
    s = ARXStructure(2, [2, 2], [1, 1])
    graded = ARXCost(s, data, penalty_kind="graded")
    flat = ARXCost(s, data)
    theta = np.r_[A_TRUE, B1, B2]
    unstable = []
    for radius in (1.05, 1.2, 2.0):  # a pole pair at 0.75 +- 0.37j scaled out
        a = np.array([-1.5 * radius / 0.8385, 0.7 * (radius / 0.8385) ** 2])
        unstable.append(np.r_[a, B1, B2])
    X = np.vstack([theta, *unstable])
    g, f = graded(X), flat(X)
    assert g[0] == f[0]  # stable rows: the same cost, same code path
    assert np.all(g[1:] > 1e9) and np.all(np.diff(g[1:]) > 0)
    # graded = the paper's cost with the penalty scaled by the largest pole radius; radii by
    # two LAPACK routes agree to ~1e-12 relative here (well-separated roots), far below 1e-9
    rho = max_pole_radius(X[1:, :2])
    np.testing.assert_allclose(g[1:] - f[1:], 1e9 * (rho - 1), rtol=1e-6)
    assert np.all(f[1:] > 1e9)  # the paper's flat penalty
    sim = ARXCost(s, data, predictor="simulation", penalty_kind="graded")
    gs = sim(X)
    assert np.all(gs[1:] > 1e9) and np.all(np.diff(gs[1:]) > 0)
    with pytest.raises(UnknownNameError):
        ARXCost(s, data, penalty_kind="steep")


@pytest.mark.numerics
def test_batched_pole_radius_equals_roots():
    rng = np.random.default_rng(0)
    a = rng.uniform(-2, 2, (200, 5))
    # companion eigenvalues and np.roots are the same LAPACK problem; well-separated roots
    np.testing.assert_allclose(pole_radius_batched(a), max_pole_radius(a), rtol=1e-8)


def test_check_search_rejects_bad_settings():
    with pytest.raises(UnknownNameError):
        check_search(SearchSpec(parametrisation="zeros"))
    with pytest.raises(UnknownNameError):
        check_search(SearchSpec(init="lucky"))
    with pytest.raises(ConfigError):
        check_search(SearchSpec(r_max=1.0))


def test_seeded_hbcsd_ends_stable_in_the_default_setting():
    data = two_input_record(n=600, seed=4)
    ident = identify(data, 2, optimiser="hbcsd", budget=5000, seed=7)
    assert ident.model.is_stable
    # better than predicting zero (the least a stable model found by search should do)
    assert ident.cost_value < ident.cost._from_sse(np.array(ident.cost._sse_zero))


def test_output_error_in_identify_beats_least_squares_on_the_simulation_cost():
    rng = np.random.default_rng(2)
    n = 1200
    u = rng.uniform(-1, 1, (n, 1))
    y0 = ARXStructure(2, 2, 1).model(np.r_[A_TRUE, B1]).simulate(u)
    data = IOData(u, (y0 + 0.3 * rng.standard_normal(n))[:, None], dt=0.01)
    ls = identify(data, 2, 2, optimiser="ls", predictor="simulation")
    oe = identify(data, 2, 2, optimiser="pem", predictor="simulation")
    assert oe.model.is_stable and oe.cost_value <= ls.cost_value
    assert oe.nfev > 0 and "Levenberg-Marquardt" in oe.summary()
    # the one-step ARX cost's gradient reference is its exact optimum, least squares
    one_step = identify(data, 2, 2, optimiser="pem")
    np.testing.assert_array_equal(one_step.model.theta, identify(data, 2, 2).model.theta)


def test_the_old_reference_spelling_oe_warns_and_runs_pem():
    """``optimiser="oe"`` read as "an output-error model" and gave an ARX model: one name,
    one meaning now; the old spelling warns, says what to write, and runs ``"pem"``."""
    rng = np.random.default_rng(2)
    n = 600
    u = rng.uniform(-1, 1, (n, 1))
    y0 = ARXStructure(2, 2, 1).model(np.r_[A_TRUE, B1]).simulate(u)
    data = IOData(u, (y0 + 0.3 * rng.standard_normal(n))[:, None], dt=0.01)
    for kwargs in ({"predictor": "simulation"}, {"structure": "oe", "nb": 2, "nf": 2, "nk": 1}):
        orders = {} if "structure" in kwargs else {"na": 2, "nb": 2}
        with pytest.warns(FlexidDeprecationWarning, match="write 'pem'") as caught:
            old = identify(data, optimiser="oe", **orders, **kwargs)
        assert caught[0].filename == __file__  # the warning points at the caller's line
        new = identify(data, optimiser="pem", **orders, **kwargs)
        assert old.optimiser == "pem"
        np.testing.assert_array_equal(old.model.theta, new.model.theta)
        assert old.cost_value == new.cost_value


def test_simulation_comparison_uses_the_output_error_reference():
    spec = ComparisonSpec(
        name="oe-ref",
        data=DataSpec(plant="twin-rotor", preset="paper-twin-rotor", seed=0),
        model=ModelSpec(na=3, nb=3, nk=1),
        cost=CostSpec(predictor="simulation"),
        optimisers=(OptimiserSpec("de"),),
        runs=1,
        budget=500,
    )
    result = compare(spec)
    oe = result.reference["output_error"]
    assert oe["stable"] and oe["cost"] <= result.reference["cost"]
    assert result.reference_cost == oe["cost"]
    assert "output-error" in result.reference_note
    paper = compare(replace(spec, search=PAPER_SEARCH))
    assert paper.key != result.key  # the search space is part of what a result means
