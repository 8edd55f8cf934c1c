"""One rule for non-finite numbers in every JSON flexid writes: NaN, inf and -inf become None."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from flexid._json import jsonable

NON_FINITE = [math.nan, math.inf, -math.inf]


def dumps(value):
    # strict JSON: raises ValueError on a NaN or an infinity that slipped through
    return json.dumps(value, allow_nan=False)


@pytest.mark.parametrize("value", NON_FINITE, ids=["nan", "inf", "-inf"])
def test_non_finite_python_floats_become_none(value):
    assert jsonable(value) is None


@pytest.mark.parametrize("value", NON_FINITE, ids=["nan", "inf", "-inf"])
@pytest.mark.parametrize("dtype", [np.float64, np.float32, np.float16])
def test_non_finite_numpy_scalars_become_none(value, dtype):
    assert jsonable(dtype(value)) is None


def test_finite_numpy_scalars_become_python_types():
    out = [jsonable(np.float64(1.5)), jsonable(np.int64(7)), jsonable(np.bool_(True))]
    assert out == [1.5, 7, True]
    assert [type(v) for v in out] == [float, int, bool]


def test_finite_values_pass_unchanged():
    assert jsonable(0.1) == 0.1 and type(jsonable(0.1)) is float
    assert jsonable(-3) == -3 and jsonable("inf") == "inf" and jsonable(None) is None
    assert jsonable(1e308) == 1e308


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_arrays_become_nested_lists_with_none(dtype):
    a = np.array([[1.0, np.nan], [np.inf, -np.inf]], dtype=dtype)
    out = jsonable(a)
    assert out == [[1.0, None], [None, None]]
    assert type(out[0][0]) is float
    assert jsonable(np.array(np.nan)) is None  # a 0-d array is a scalar
    assert jsonable(np.arange(3)) == [0, 1, 2]
    assert jsonable(np.array([True, False])) == [True, False]
    assert jsonable(np.empty((0, 2))) == []


def test_nested_dicts_and_lists():
    value = {
        "cost": np.float64(np.inf),
        "fits": (98.5, np.nan, [np.float32(-np.inf), {"deep": np.array([2.0, np.nan])}]),
        3: {"path": Path("a") / "b.csv", "n": np.int32(4)},
    }
    out = jsonable(value)
    assert out == {
        "cost": None,
        "fits": [98.5, None, [None, {"deep": [2.0, None]}]],
        "3": {"path": str(Path("a") / "b.csv"), "n": 4},
    }
    assert json.loads(dumps(out)) == out


def test_input_is_not_modified():
    a = np.array([1.0, np.nan])
    d = {"a": a, "b": [math.inf]}
    jsonable(d)
    assert np.isnan(a[1]) and d["b"] == [math.inf]


def test_results_follow_the_rule():
    from flexid.validation import stability_report

    # a pole at z = 0 has an infinite natural frequency
    rep = stability_report([0.5, 0.0], [], dt=0.01)
    assert math.isinf(rep.natural_frequency[-1])
    d = rep.to_dict()
    assert d["natural_frequency"][-1] is None
    dumps(d)


def test_record_metadata_follows_the_rule(tmp_path):
    from flexid.data import IOData, load

    d = IOData(np.zeros(5), np.arange(5.0), dt=0.1, metadata={"gain": np.inf, "x": [np.nan, 1]})
    back = load(d.save(tmp_path / "r.csv"))
    assert back.metadata["gain"] is None and back.metadata["x"] == [None, 1]
