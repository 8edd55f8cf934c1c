"""Tests of flexid.jobs.statistics.

Values are checked against scipy or hand computations to pytest's default 1e-6 (far above
rounding of a few operations); the Holm p-value is the same product as the hand value.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from flexid.jobs.statistics import (
    best_at,
    convergence_band,
    fe_to_target,
    holm,
    rank_sum_against_best,
    summarise,
)


def test_best_at_is_a_step_function():
    h = {"fe": [10, 20, 50], "best": [5.0, 3.0, 1.0]}
    np.testing.assert_array_equal(
        best_at(h, [0, 9, 10, 15, 20, 49, 50, 1000]), [np.inf, np.inf, 5, 5, 3, 3, 1, 1]
    )
    assert fe_to_target(h, 3.0) == 20
    assert fe_to_target(h, 4.0) == 20
    assert math.isnan(fe_to_target(h, 0.5))


def test_holm_against_hand_computation():
    p = [0.01, 0.04, 0.03, 0.005]
    # sorted: 0.005*4=0.02, 0.01*3=0.03, 0.03*2=0.06, 0.04*1=0.04 -> monotone 0.06
    np.testing.assert_allclose(holm(p), [0.03, 0.06, 0.06, 0.02])
    assert holm([0.9, 0.8]).max() <= 1.0
    assert holm([]).size == 0


def test_rank_sum_against_best():
    rng = np.random.default_rng(0)
    costs = {
        "good": rng.normal(1.0, 0.1, 20),
        "same": rng.normal(1.0, 0.1, 20),
        "bad": rng.normal(2.0, 0.1, 20),
        "one": [5.0],
    }
    out = rank_sum_against_best(costs)
    best = [k for k, v in out.items() if v["best"]]
    assert len(best) == 1 and best[0] in ("good", "same")
    other = "same" if best[0] == "good" else "good"
    assert not out[other]["significant"]
    assert out["bad"]["significant"]
    raw = stats.mannwhitneyu(costs[best[0]], costs["bad"], alternative="two-sided").pvalue
    assert out["bad"]["p"] == pytest.approx(raw)
    assert (
        out["bad"]["p_holm"] == pytest.approx(min(1.0, 2 * raw), rel=1e-12)
        or out["bad"]["p_holm"] >= raw
    )
    assert math.isnan(out["one"]["p"])


def _rec(cost, hist, status="ok", **v):
    return {
        "status": status,
        "cost": cost,
        "history": hist,
        "nfev": hist["fe"][-1],
        "wall_time": 0.5,
        "stable": True,
        "validation": v,
    }


def test_summarise():
    recs = [
        _rec(
            1.0, {"fe": [10, 100], "best": [3.0, 1.0]}, fit_one_step=90.0, correlation_passed=True
        ),
        _rec(
            2.0, {"fe": [10, 100], "best": [3.0, 2.0]}, fit_one_step=80.0, correlation_passed=False
        ),
        _rec(1.05, {"fe": [10, 60, 100], "best": [3.0, 1.05, 1.05]}, fit_one_step=85.0),
        {"status": "failed", "error": "RuntimeError: x"},
    ]
    s = summarise(recs, reference=1.0, targets=[0.1, 0.01])
    assert (s["runs"], s["ok"], s["failed"]) == (4, 3, 1)
    assert s["median"] == 1.05 and s["best"] == 1.0
    assert s["reach"]["0.1"]["success"] == pytest.approx(2 / 3)
    assert s["reach"]["0.1"]["median_fe"] == 80.0
    assert s["reach"]["0.01"]["success"] == pytest.approx(1 / 3)
    assert s["fit_one_step"] == 85.0
    assert s["correlation_pass_rate"] == 0.5
    assert s["errors"] == ["RuntimeError: x"]


def test_convergence_band():
    hs = [{"fe": [10, 50], "best": [4.0, 2.0]}, {"fe": [10, 50], "best": [6.0, 1.0]}]
    band = convergence_band(hs, 100, points=11)
    i = np.searchsorted(band["fe"], 50)
    assert band["median"][i] == pytest.approx(1.5)
    assert np.isnan(band["median"][0])
