"""The table of cost metrics is the one place they are defined, and it is read everywhere."""

from __future__ import annotations

import numpy as np
import pytest

from flexid.config import CostSpec
from flexid.costs import metrics
from flexid.costs.metrics import METRIC_TABLE, METRICS, metric_from_sse
from flexid.errors import UnknownNameError


def test_each_metric_is_its_formula_on_the_errors():
    rng = np.random.default_rng(0)
    e = rng.normal(size=(3, 200))
    y = rng.normal(2.0, 1.5, size=200)
    sse = np.einsum("pk,pk->p", e, e)
    direct = {  # written from the errors, not from the SSE
        "paper": 1e3 * np.sqrt((e**2).sum(axis=1)) / 200,
        "rmse": np.sqrt((e**2).mean(axis=1)),
        "nrmse": np.sqrt((e**2).mean(axis=1)) / y.std(),
        "sse": (e**2).sum(axis=1),
        "mse": (e**2).mean(axis=1),
    }
    assert set(direct) == set(METRICS)
    for name, want in direct.items():
        # a few roundings apart: sums in another order
        np.testing.assert_allclose(metric_from_sse(name, sse, 200, 1e3, y.std()), want,
                                   rtol=1e-13)


def test_an_unknown_metric_raises_and_the_table_is_read_everywhere():
    known = "known: mse, nrmse, paper, rmse, sse"
    with pytest.raises(UnknownNameError, match=f"unknown cost metric 'rms'; {known}"):
        metric_from_sse("rms", np.ones(2), 10, 1e3, 1.0)
    assert METRICS == tuple(METRIC_TABLE) and CostSpec().metric == METRICS[0]
    from flexid.cli import _COST_HELP

    for m in METRIC_TABLE.values():
        assert m.name in _COST_HELP
        assert f"``{m.formula}``" in metrics.__doc__ and m.description in metrics.__doc__
