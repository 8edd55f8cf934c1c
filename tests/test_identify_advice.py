"""The one line an identification adds when its model should not be trusted."""

from __future__ import annotations

import numpy as np

from flexid import identify
from flexid.data import IOData


def _arx_record(n: int = 600, seed: int = 0) -> IOData:
    # y = 1.5 y(t-1) - 0.7 y(t-2) + u(t-1) + 0.5 u(t-2) + e: ARX(2, 2, 1) exactly
    rng = np.random.default_rng(seed)
    u = rng.uniform(-1, 1, n)
    e = 0.05 * rng.standard_normal(n)
    y = np.zeros(n)
    for t in range(2, n):
        y[t] = 1.5 * y[t - 1] - 0.7 * y[t - 2] + u[t - 1] + 0.5 * u[t - 2] + e[t]
    return IOData(u, y, dt=0.1)


def test_a_valid_model_gets_no_warning():
    ident = identify(_arx_record(), 2, 2, 1, optimiser="ls")
    assert ident.advice() is None
    assert "warning:" not in ident.summary()


def test_a_poor_search_is_named_with_what_to_try():
    # random search with 60 evaluations ends far above the least-squares optimum of the
    # one-step cost; the line says so and points to the reference
    ident = identify(_arx_record(), 2, 2, 1, optimiser="random-search", budget=60, seed=0)
    advice = ident.advice()
    assert advice.startswith("warning: the final cost is")
    assert "optimiser='ls'" in advice
    # the last paragraph of the summary, wrapped to the terminal's width
    assert " ".join(ident.summary().split()).endswith(" ".join(advice.split()))


def test_a_structure_that_cannot_describe_the_data_is_named():
    # ARX(1, 1, 1) of a second-order system: the residual is coloured
    ident = identify(_arx_record(), 1, 1, 1, optimiser="ls")
    assert "correlation tests fail" in ident.advice()
    assert "another structure or higher orders" in ident.advice()


def test_an_assumed_sample_time_is_said(tmp_path):
    data = _arx_record()
    path = tmp_path / "no_time.csv"
    rows = "\n".join(f"{u!r},{y!r}" for u, y in zip(data.u[:, 0].tolist(), data.y[:, 0].tolist()))
    path.write_text("u,y\n" + rows + "\n")
    said = identify(str(path), 2, 2, 1, optimiser="ls").data_info["description"]
    assert "dt 1 s (ASSUMED" in said
    given = identify(str(path), 2, 2, 1, optimiser="ls", load_options={"dt": 0.1})
    assert "ASSUMED" not in given.data_info["description"]
