"""Tests of flexid.jobs.selection: the criteria, the shared-regressor ARX grid, the recommendation
on a known OE system and on the simulated manipulator, typed errors, and the figure."""

from __future__ import annotations

import json
import math
import time

import numpy as np
import pytest
from scipy import signal

import flexid
from flexid._table import LINE_WIDTH
from flexid.errors import ConfigError, DataError, ModelOrderError, UnknownNameError
from flexid.fit.estimation import structure_of
from flexid.jobs.selection import DEFAULT_GRIDS, Selection, arx_grid, select
from flexid.models.arx import ARXStructure
from flexid.models.polynomial import structure
from numerics import EPS, route_tolerance

# The known system: OE(2, 2, 1), y = (0.5 q^-1 + 0.3 q^-2) / (1 - 1.5 q^-1 + 0.7 q^-2) u + e,
# poles of radius sqrt(0.7) = 0.84, white Gaussian input and white measurement noise of 10 %
# of the noise-free output's standard deviation.
B_TRUE = [0.0, 0.5, 0.3]
F_TRUE = [1.0, -1.5, 0.7]
OE_GRID = {
    "arx": [{"na": n, "nb": n} for n in range(1, 11)],
    "oe": [{"nb": n, "nf": n} for n in (1, 2, 3, 4)],
}


def oe_record(seed: int = 0, n: int = 3000, noise: float = 0.1) -> flexid.IOData:
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(n)
    x = signal.lfilter(B_TRUE, F_TRUE, u)
    y = x + noise * x.std() * rng.standard_normal(n)
    return flexid.IOData(u, y, dt=0.01)


@pytest.fixture(scope="module")
def oe_selection() -> Selection:
    return select(oe_record(), ("arx", "oe"), OE_GRID)


# ------------------------------------------------------------------ 1. the criteria
def test_criteria_follow_their_formulas_from_independent_sses(oe_selection):
    """AIC, FPE and MDL recomputed from SSEs obtained by another route: ARX by
    ARXStructure.least_squares and its own regressors, OE by the model's lfilter predictor
    (PolynomialModel.residuals, initial state estimated) at the fitted theta.

    Tolerances.  SSE: each error sample is a stable recursion of at most n = 2 d + 2 terms
    run over K steps, so two routes differ by at most route_tolerance(n, K) of the terms
    (tests/numerics.py); the terms are about 10 times the error here (fits of ~90 %), and
    the SSE's relative error is twice the error's, hence 20 * route_tolerance(n, K) (about
    1e-10; the routes agree to 1e-16 in practice).  Criteria: a handful of operations on
    V, K and d, so within 100 eps of the largest term of each formula.
    """
    est, _ = oe_record().split()
    u, y = est.u[:, 0], est.y[:, 0]
    for c in oe_selection.candidates:
        s = c.structure
        if c.kind == "arx":
            arx = ARXStructure(s.na, s.nb, s.nk)
            phi, target = arx.regressors(u, y)
            e = target - phi @ arx.least_squares(u, y).theta
        else:
            # the rule PEM minimises: the direct form's state at start
            e = c.model.residuals(u, y, initial="estimate", from_start=True)[s.start :]
        sse = float(e @ e)
        k = y.size - s.start
        assert c.K == k == e.size
        assert c.sse == pytest.approx(sse, rel=20 * route_tolerance(2 * s.n_params + 2, k))
        v, d = c.sse / k, s.n_params  # the criteria of the candidate's own SSE
        terms = abs(k * math.log(v)) + 2 * d + d * math.log(k)
        assert abs(c.aic - (k * math.log(v) + 2 * d)) <= 100 * EPS * terms
        assert abs(c.mdl - (k * math.log(v) + d * math.log(k))) <= 100 * EPS * terms
        assert abs(c.aic_normalized - (math.log(v) + 2 * d / k)) <= 100 * EPS * terms / k
        assert abs(c.mdl_normalized - (math.log(v) + d * math.log(k) / k)) <= 100 * EPS * terms / k
        assert c.fpe == pytest.approx(v * (1 + d / k) / (1 - d / k), rel=100 * EPS)
        assert c.loss == v
        # the normalized criteria are the raw ones per error sample
        assert c.aic_normalized == pytest.approx(c.aic / k, rel=100 * EPS)


def test_ranking_by_aic_is_the_order_of_the_normalized_aic(oe_selection):
    ranked = oe_selection.ranked("aic")
    values = [c.aic_normalized for c in ranked]
    assert values == sorted(values)
    assert oe_selection.ranked("bic") == oe_selection.ranked("mdl")
    fits = [c.fit_simulation for c in oe_selection.ranked()]  # criterion "simulation"
    assert fits == sorted(fits, reverse=True)


# ------------------------------------------------------------------ 2. the ARX grid
def test_shared_regressor_grid_equals_per_order_least_squares():
    """Every order of the grid (delays 0..2, na = 0, two inputs) against its own
    ARXStructure.least_squares.

    Both solve the same least-squares problem (the same regressors over the same rows) by
    Householder QR, which is backward stable: each solution is exact for data perturbed by a
    few eps, so they differ by at most ~ cond(Phi) * n eps * |theta| (Higham, ch. 20).  The
    bound used is 10 * cond(Phi) * n_params * eps * ||theta||, computed per order.
    """
    rng = np.random.default_rng(3)
    n = 600
    u = rng.standard_normal((n, 2))
    y = signal.lfilter([0, 1.0, 0.4], [1, -1.2, 0.5], u[:, 0])
    y += signal.lfilter([0, 0, 0.7], [1, -0.6], u[:, 1]) + 0.05 * rng.standard_normal(n)
    orders = [
        (1, [1, 1], [1, 1]),
        (2, [2, 3], [0, 2]),
        (0, [4, 2], [1, 1]),
        (5, [3, 3], [2, 0]),
        (8, [8, 8], [1, 1]),
    ]
    structures = [structure("arx", na=na, nb=nb, nk=nk) for na, nb, nk in orders]
    models = arx_grid(u, y, structures, dt=0.5)
    for (na, nb, nk), model in zip(orders, models):
        ref_structure = ARXStructure(na, nb, nk)
        ref = ref_structure.least_squares(u, y, dt=0.5)
        phi, _ = ref_structure.regressors(u, y)
        bound = 10 * np.linalg.cond(phi) * ref_structure.n_params * EPS
        scale = np.linalg.norm(ref.theta)
        assert np.max(np.abs(model.theta - ref.theta)) <= bound * scale
        assert model.noise_variance == pytest.approx(ref.noise_variance, rel=bound)
        np.testing.assert_allclose(model.param_std, ref.param_std, rtol=bound)
        assert model.dt == 0.5 and model.structure.param_names == ref_structure.param_names


def test_arx_grid_takes_only_arx_structures():
    u = np.random.default_rng(0).standard_normal(100)
    with pytest.raises(ModelOrderError, match="ARX structures only"):
        arx_grid(u, u, [structure("oe", nb=2, nf=2)])


# ------------------------------------------------------------------ 3. a known OE system
def test_recommends_the_true_oe_order_and_low_arx_fails(oe_selection):
    """On OE(2, 2, 1) data with white measurement noise the equation error of an ARX model is
    A v, coloured: low ARX orders fail the whiteness test, and the recommendation is OE with
    nb = nf = 2, the smallest OE order that passes (OE(3, 3) and OE(4, 4) pass too, with
    held-out errors within 1 % of it: parsimony picks the smallest)."""
    sel = oe_selection
    by_label = {c.label: c for c in sel.candidates}
    for n in (1, 2, 3):
        arx = by_label[f"ARX(na={n}, nb={n}, nk=1)"]
        assert not arx.passed and not arx.report.test("auto e").passed
    passing_oe = [c for c in sel.candidates if c.kind == "oe" and c.passed and c.stable]
    smallest = min(passing_oe, key=lambda c: c.n_params)
    assert sel.best is smallest
    assert sel.best.orders == {"nb": 2, "nf": 2, "nk": 1}
    assert sel.best_model is sel.best.model
    # the estimate is close to the truth: the simulated fit is at the noise level (~90 %)
    assert sel.best.fit_simulation > 85.0
    np.testing.assert_allclose(sel.best_model.f[0], F_TRUE, atol=0.02)
    assert sel.note.startswith("Recommended OE(nb=2, nf=2, nk=1)")
    # AIC alone over-fits: its minimum (OE(4, 4) here, 0.015 below OE(2, 2) in normalized AIC,
    # far beyond rounding) has more parameters than the recommendation, and the note says so
    by_aic = sel.ranked("aic")[0]
    assert by_aic.n_params > sel.best.n_params
    assert f"AIC alone would pick {by_aic.label}" in sel.note


def test_table_summary_json_and_html(oe_selection):
    sel = oe_selection
    table = sel.table()
    lines = table.splitlines()
    assert lines[0].split()[:3] == ["rank", "candidate", "d"]
    marked = [line for line in lines if "<- recommended" in line]
    assert len(marked) == 1 and "OE(nb=2, nf=2, nk=1)" in marked[0]
    assert len(lines) == 2 + len(sel.candidates)
    summary = sel.summary()  # the note wrapped and the table in blocks at a terminal's width
    assert " ".join(sel.note.split()) in " ".join(summary.split())
    assert sel.table(LINE_WIDTH) in summary
    assert max(len(line) for line in sel.table(LINE_WIDTH).splitlines()) <= LINE_WIDTH
    d = sel.to_dict()
    text = json.dumps(d, allow_nan=False)
    assert json.loads(text)["candidates"][d["best"]]["label"] == sel.best.label
    assert d["best_model"]["theta"] == sel.best_model.theta.tolist()
    assert sorted(d["ranking"]) == list(range(len(sel.candidates)))
    html = sel._repr_html_()
    assert "<table" in html and "&lt;- recommended" in html


def test_falls_back_with_a_note_when_no_candidate_passes():
    sel = select(oe_record(), "arx", [{"na": 1, "nb": 1}, {"na": 2, "nb": 2}], criterion="fpe")
    assert not any(c.passed for c in sel.candidates)
    assert sel.best is min(sel.candidates, key=lambda c: c.fpe)
    assert sel.note.startswith("NO CANDIDATE PASSES")
    assert "fpe" in sel.note and sel.best.label in sel.note


def test_grids_as_a_product_a_mapping_and_structure_objects():
    data = oe_record(n=900)
    sel = select(data, "arx", {"na": [1, 2], "nb": range(1, 4), "nk": [1, 2]})
    assert len(sel.candidates) == 2 * 3 * 2
    sel = select(
        data,
        ["ARX", structure("oe", nb=2, nf=2)],
        {"arx": [{"na": 2, "nb": 2}, {"na": 2, "nb": 2}]},  # the duplicate is fitted once
    )
    assert [c.label for c in sel.candidates] == ["ARX(na=2, nb=2, nk=1)", "OE(nb=2, nf=2, nk=1)"]
    # two inputs, a (u, y) tuple: one value of nb, nf or nk is every input's; progress calls
    rng = np.random.default_rng(1)
    u = rng.standard_normal((900, 2))
    y = signal.lfilter([0, 1.0], [1, -0.5], u[:, 0]) + signal.lfilter([0, 0, 0.5], [1], u[:, 1])
    y += 0.1 * rng.standard_normal(y.size)  # white measurement noise
    seen = []
    grid = {"arx": [{"na": 1, "nb": 2}], "oe": [{"nb": 2, "nf": 1, "nk": [1, 2]}]}
    sel = select((u, y), ("arx", "oe"), grid, progress=seen.append)
    # nk="auto": the grid at nk = 1 and at the estimated delays, here the true [1, 2]
    # (an entry's own nk stays)
    assert [c.label for c in sel.candidates] == [
        "ARX(na=1, nb=[2, 2], nk=[1, 1])",
        "OE(nb=[2, 2], nf=[1, 1], nk=[1, 2])",
        "ARX(na=1, nb=[2, 2], nk=[1, 2])",
    ]
    assert sel.delay.startswith("nk = 1, 2 (MATLAB delayest and the prewhitened")
    assert seen == sel.candidates
    assert sel.best.kind == "oe" and sel.best.passed  # it holds the true system


def test_default_grids_are_documented_and_small():
    assert [e["na"] for e in DEFAULT_GRIDS["arx"]] == list(range(1, 21))
    assert [e["nf"] for e in DEFAULT_GRIDS["oe"]] == [1, 2, 3, 4, 6, 8, 16]
    assert len(DEFAULT_GRIDS["armax"]) == len(DEFAULT_GRIDS["bj"]) == 16
    for name, grid in DEFAULT_GRIDS.items():
        for entry in grid:  # every entry is a valid structure
            if name == "ss":
                structure_of(name, 1, **entry)
            else:
                structure(name, **entry)


# ------------------------------------------------------------------ 4. the manipulator
@pytest.mark.slow
def test_manipulator_recommendation_passes_every_test():
    """OE(16, 16, 1) passes every validation test on this plant (seed 0) and OE(8, 8, 1) does
    not: the recommendation is OE(16, 16, 1).  About 5-10 s (OE(8, 8) is the slow fit)."""
    data = flexid.generate("manipulator", preset="paper-manipulator", seed=0)
    t0 = time.perf_counter()
    sel = select(data, ("oe",), [{"nb": 8, "nf": 8}, {"nb": 16, "nf": 16}], nk=1)
    elapsed = time.perf_counter() - t0
    low, high = sel.candidates
    assert not low.passed
    assert sel.best is high and high.orders == {"nb": 16, "nf": 16, "nk": 1}
    report = sel.best.report
    assert report.passed and report.linear_passed and report.nonlinear_passed
    assert report.stability.stable and sel.best.stable
    assert sel.best.fit_simulation > 98.0
    assert elapsed < 120  # a guard against a pathological slowdown, not a benchmark


# ------------------------------------------------------------------ 5. bad input
def test_bad_input_is_a_typed_error_naming_the_argument(monkeypatch):
    data = oe_record(n=600)

    def no_fit(*args, **kwargs):
        raise AssertionError("a fit ran before the grid was checked")

    monkeypatch.setattr("flexid.fit.prediction_error.pem", no_fit)
    monkeypatch.setattr("flexid.jobs.selection._arx_fits", no_fit)
    with pytest.raises(UnknownNameError, match=r"structures 'ox'; known: armax, arx, bj, oe"):
        select(data, ("arx", "ox"))
    with pytest.raises(UnknownNameError, match=r"criterion 'best'.*aic.*simulation"):
        select(data, criterion="best")
    with pytest.raises(UnknownNameError, match=r"initial.*'rest'.*estimate"):
        select(data, initial="rest")
    # an order OE does not have, in the last entry: raised before any fit
    grid = [{"nb": 2, "nf": 2}, {"nb": 2, "nf": 2, "nc": 1}]
    with pytest.raises(ModelOrderError, match=r"entry 1 of oe.*no order nc.*nb, nf, nk"):
        select(data, ("oe",), grid)
    with pytest.raises(ModelOrderError, match=r"needs the order\(s\) nf"):
        select(data, ("oe",), [{"nb": 2}])
    with pytest.raises(ModelOrderError, match=r"model order nb must be an integer >= 0"):
        select(data, ("oe",), [{"nb": -1, "nf": 2}])
    with pytest.raises(ModelOrderError, match="too few samples"):
        select(data, ("oe",), [{"nb": 2, "nf": 2}, {"nb": 300, "nf": 300}])
    with pytest.raises(ModelOrderError, match=r"validation part \(60 samples\).*max_lag=25"):
        select(data, ("oe",), [{"nb": 10, "nf": 10}], split=0.9)
    with pytest.raises(ModelOrderError, match="2 input"):
        select(data, ("oe",), [{"nb": [2, 2], "nf": [1, 1]}])
    with pytest.raises(ModelOrderError, match=r"unknown order name.*'nq'"):
        select(data, ("oe",), {"nb": [2], "nq": [1]})
    with pytest.raises(ModelOrderError, match=r"grid for 'bj'.*not in structures"):
        select(data, ("oe",), {"bj": [{"nb": 1, "nc": 1, "nd": 1, "nf": 1}]})
    with pytest.raises(ModelOrderError, match="mixes structure names and order names"):
        select(data, ("oe",), {"oe": [{"nb": 1, "nf": 1}], "nb": [1]})
    with pytest.raises(ModelOrderError, match=r"orders\[0\] must be a dict"):
        select(data, ("oe",), [3])
    with pytest.raises(ConfigError, match="structures is empty"):
        select(data, ())
    with pytest.raises(DataError, match="the estimation range must be a sample range"):
        select(data, split=0.5, validation=data)  # with a validation record: one range
    with pytest.raises(ConfigError, match="max_lag"):
        select(data, max_lag=0)
    with pytest.raises(ConfigError, match="parsimony"):
        select(data, parsimony=-0.1)


# ------------------------------------------------------------------ 6. the figure
def test_selection_figure_writes_a_png(oe_selection, tmp_path):
    pytest.importorskip("matplotlib")
    from flexid.report.plots import selection_figure

    path = selection_figure(oe_selection, tmp_path / "selection.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and path.stat().st_size > 20_000
    fig = selection_figure(oe_selection, criterion=False)
    assert len(fig.axes) == 1


def test_select_and_identify_give_one_model_for_one_structure():
    """A candidate of select is the model identify's reference finds for that structure (the
    same Levenberg-Marquardt starts, flexid.config.REFERENCE_STARTS), with the same fit."""
    data = oe_record(n=600)
    sel = select(data, "bj", [{"nb": 2, "nc": 1, "nd": 1, "nf": 2}], nk=1)
    ident = flexid.identify(data, structure="bj", nb=2, nc=1, nd=1, nf=2, nk=1)
    np.testing.assert_array_equal(sel.best.model.theta, ident.model.theta)
    assert sel.best.fit_simulation == ident.validation.fit_simulation
    assert sel.best.fit_one_step == ident.validation.fit_one_step
