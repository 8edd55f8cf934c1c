"""Subspace identification (:func:`flexid.fit.subspace.n4sid`) on a known two-input two-output
system made with ``scipy.signal``: its order read from the singular values, its frequency
response (which does not depend on the state coordinates) and its modes recovered."""

from __future__ import annotations

import numpy as np
import pytest

import flexid
from flexid.errors import ConfigError, DataError, ModelOrderError
from flexid.fit.subspace import n4sid
from test_statespace_model import DT, MODES, _model

F = np.linspace(0.2, 40.0, 80)  # Hz, below Nyquist (50 Hz)


def _record(seed: int, noise: float, n: int = 4000) -> tuple[flexid.IOData, np.ndarray]:
    true = _model()
    rng = np.random.default_rng(seed)
    u = rng.standard_normal((n, 2))
    y0 = true.simulate(u)
    y = y0 + noise * y0.std(axis=0) * rng.standard_normal(y0.shape)
    return flexid.IOData(u, y, dt=DT), true.frequency_response(F)


def test_noise_free_data_give_the_system_exactly():
    data, G0 = _record(0, 0.0, n=1500)
    res = n4sid(data, feedthrough=True)
    assert res.order_chosen and res.order == 5  # two pairs and a real pole
    sv = res.singular_values / res.singular_values[0]
    assert sv[4] > 1e-3 and sv[5] < 1e-10  # the drop the order is read at
    G = res.model.frequency_response(F)
    # exact up to rounding of the LQ, SVD and least squares (condition ~1e4 here)
    np.testing.assert_allclose(G, G0, rtol=0, atol=1e-8 * np.abs(G0).max())
    np.testing.assert_allclose(res.model.simulate(data.u), data.y, atol=1e-9 * np.abs(data.y).max())
    assert res.model.output_names == data.output_names and res.model.dt == DT


def test_output_noise_leaves_the_response_and_the_modes_close():
    # 5 % output noise, 4,000 samples: over seeds 0-2 the largest error of any entry of G is
    # at most 1.5 % of that entry's peak, frequencies within 0.1 %, damping within 10 %;
    # the bounds are about three times those
    data, G0 = _record(1, 0.05)
    res = n4sid(data, feedthrough=True)
    assert res.order == 5
    G = res.model.frequency_response(F)
    err = np.abs(G - G0) / np.abs(G0).max(axis=0, keepdims=True)
    assert err.max() < 0.05
    pairs = [m for m in res.model.modes() if m.kind == "pair"]
    for m, (f, zeta) in zip(pairs, MODES):
        assert m.frequency == pytest.approx(f, rel=3e-3)
        assert m.damping == pytest.approx(zeta, rel=0.3)


def test_a_given_order_and_its_limits():
    data, _ = _record(2, 0.0, n=1500)
    res = n4sid(data, order=3, block_rows=6)
    assert res.order == 3 and not res.order_chosen and res.block_rows == 6
    assert res.model.order == 3 and res.model.n_outputs == 2
    with pytest.raises(ModelOrderError, match="needs more than 2 block rows"):
        n4sid(data, order=4, block_rows=2)
    with pytest.raises(ModelOrderError, match="too few"):
        n4sid((data.u[:60], data.y[:60]), order=3)
    with pytest.raises(ConfigError, match="order"):
        n4sid(data, order=0)
    with pytest.raises(DataError, match="same number of samples"):
        n4sid((data.u, data.y[:-1]))
    bad = data.y.copy()
    bad[3, 0] = np.nan
    with pytest.raises(DataError, match="non-finite"):
        n4sid((data.u, bad))


def test_the_singular_value_figure_marks_the_order():
    pytest.importorskip("matplotlib")
    from flexid.report.plots import plot_singular_values

    data, _ = _record(0, 0.0, n=1500)
    res = n4sid(data)
    fig = plot_singular_values(res)
    ax = fig.axes[0]
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert legend == ["singular values", "order 5 (read from the largest drop)"]
    marked = ax.lines[1].get_xdata()
    assert list(marked) == [5]
    assert all(float(t).is_integer() for t in ax.get_xticks())
