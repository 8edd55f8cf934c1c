"""Tests of flexid.report.plots: every figure of an identification and a comparison is drawn."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("matplotlib")

from flexid import compare, identify
from flexid.data import IOData
from flexid.report.plots import (
    comparison_figures,
    identification_figures,
    plot_correlations,
    plot_pole_zero,
)
from helpers import tiny_spec
from numerics import EPS


def _record(n=500, seed=0):
    rng = np.random.default_rng(seed)
    u = rng.uniform(-1, 1, n)
    y = np.zeros(n)
    for t in range(2, n):
        y[t] = 1.2 * y[t - 1] - 0.5 * y[t - 2] + u[t - 1] + 0.01 * rng.standard_normal()
    return IOData(u, y, dt=0.1)


def _is_png(path) -> bool:
    return path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and path.stat().st_size > 2000


def test_identification_figures_are_the_papers_set(tmp_path):
    ident = identify(_record(), 2, optimiser="sda", budget=800, seed=0)
    paths = identification_figures(ident, tmp_path)
    names = {p.name for p in paths}
    assert {"convergence.png", "spectra.png", "pole_zero.png", "correlations.png"} <= names
    assert {"validation_simulation.png", "validation_one_step.png"} <= names
    assert all(_is_png(p) for p in paths)


def test_least_squares_has_no_convergence_figure(tmp_path):
    ident = identify(_record(), 2, optimiser="ls")
    names = {p.name for p in identification_figures(ident, tmp_path, prefix="ls-")}
    assert "ls-convergence.png" not in names and "ls-pole_zero.png" in names


@pytest.mark.numerics
def test_pole_zero_map_draws_the_unit_circle_and_every_root():
    fig = plot_pole_zero(np.array([0.5 + 0.5j, 0.5 - 0.5j]), np.array([-0.3]))
    ax = fig.axes[0]
    circle = ax.lines[0].get_xydata()
    # cos and sin within 4 ulps (libm or NumPy's SIMD code), hypot within 1
    np.testing.assert_allclose(np.hypot(circle[:, 0], circle[:, 1]), 1.0, rtol=0, atol=8 * EPS)
    assert len(ax.lines[1].get_xdata()) == 2  # poles
    np.testing.assert_allclose(ax.lines[2].get_xdata(), [-0.3])  # zeros


def test_correlation_panels_show_the_bands():
    lags = np.arange(-5, 6)
    fig = plot_correlations([("r_ee", lags, np.zeros(11), 0.1), ("r_ue", lags, np.ones(11), 0.2)])
    assert len(fig.axes) == 2


def test_comparison_figures(tmp_path):
    result = compare(tiny_spec("fig"), progress=False)
    paths = comparison_figures(result, tmp_path, prefix="c-")
    assert [p.name for p in paths] == ["c-convergence.png", "c-fe_to_target_1.png", "c-bode.png"]
    assert all(_is_png(p) for p in paths)


def test_diverged_simulation_is_drawn_not_raised(tmp_path):
    from flexid.report.plots import plot_spectra, plot_time_response

    t = np.arange(100) * 0.1
    y = np.sin(t)
    yhat = np.r_[np.sin(t[:50]), np.geomspace(1.0, 1e300, 49), np.inf]
    fig = plot_time_response(t, y, yhat, title="unstable")
    assert "diverges from t = 5" in fig.axes[0].get_title()
    fig.savefig(tmp_path / "a.png")
    fig = plot_spectra(np.arange(5.0), {"model": np.array([1.0, np.inf, np.nan, 2.0, 3.0])})
    fig.savefig(tmp_path / "b.png")


def _legend_outside(fig) -> bool:
    """The legend's box lies right of the axes' box (so it covers no data)."""
    fig.canvas.draw()
    ax = fig.axes[0]
    renderer = fig.canvas.get_renderer()
    legend = ax.get_legend().get_window_extent(renderer)
    return legend.x0 >= ax.get_window_extent(renderer).x1


def test_comparison_figures_read_at_a_glance():
    # the convergence and FE-to-target figures: log FE axis from 1 to the budget, the cost
    # relative to the named reference (the line at 1), a legend outside the data, one curve
    # per optimiser that runs to the budget; with no run at the target, a sentence says so
    from flexid.report.plots import plot_comparison_convergence, plot_fe_to_target, reference_name

    result = compare(tiny_spec("glance"), progress=False)
    budget = result.spec.budget
    name = reference_name(result)
    assert name in ("least squares", "best stable run")
    fig = plot_comparison_convergence(result)
    ax = fig.axes[0]
    assert ax.get_xscale() == "log" and ax.get_yscale() == "log"
    assert ax.get_xlim() == (1, budget)
    assert ax.get_ylabel() == f"best cost / {name} [-]"
    assert any(line.get_label().startswith(name) for line in ax.lines)
    assert _legend_outside(fig)
    for target in result.spec.targets:
        fig = plot_fe_to_target(result, target)
        ax = fig.axes[0]
        assert ax.get_xscale() == "log" and _legend_outside(fig)
        curves = [line for line in ax.lines if not line.get_label().startswith("_")]
        assert curves and all(line.get_xdata()[-1] == budget for line in curves)
        reached = any(line.get_ydata()[-1] > 0 for line in curves)
        assert reached != any("no run reached" in t.get_text() for t in ax.texts)


def test_fe_to_target_says_when_no_run_reached_it():
    from flexid.report.plots import plot_fe_to_target

    result = compare(tiny_spec("none"), progress=False)
    target = result.spec.targets[0]
    for stats in result.stats.values():  # as if no run had reached the target
        stats["reach"][str(target)]["fe"] = [float("inf")] * len(stats["reach"][str(target)]["fe"])
    ax = plot_fe_to_target(result, target).axes[0]
    assert any("no run reached" in t.get_text() for t in ax.texts)


def test_identification_figures_name_the_channel_and_its_unit():
    from flexid.report.plots import plot_convergence, plot_spectra, plot_time_response

    t = np.arange(50) * 0.01
    fig = plot_time_response(t, np.sin(t), np.sin(t), output="tip_acceleration", unit="m/s^2")
    assert fig.axes[0].get_ylabel() == "tip_acceleration [m/s^2]"
    assert fig.axes[1].get_ylabel() == "error [m/s^2]"
    fig = plot_spectra(np.arange(1.0, 6.0), {"measured": np.ones(5)}, unit="m/s^2")
    assert fig.axes[0].get_ylabel() == "PSD [dB re 1 (m/s^2)^2/Hz]"
    fig = plot_convergence({"de": {"fe": [10, 20, 30], "best": [3.0, 2.0, 1.0]}}, reference=0.5,
                           reference_label="prediction-error reference")
    ax = fig.axes[0]
    assert ax.get_xscale() == "log" and ax.get_xlim() == (1, 30)
    assert any(line.get_label().startswith("prediction-error reference") for line in ax.lines)
    assert _legend_outside(fig)


def test_pole_zero_map_marks_repeated_roots():
    # a triple pole computed as three roots 1e-6 apart (what np.roots gives a cubed factor),
    # a double zero; a simple pair gets no label
    fig = plot_pole_zero(np.r_[0.5, 0.5 + 1e-6, 0.5 - 1e-6, 0.3 + 0.4j, 0.3 - 0.4j],
                         np.r_[-0.5, -0.5])
    labels = sorted(t.get_text() for t in fig.axes[0].texts)
    assert labels == ["2", "3"]


def test_figures_of_two_comparisons_with_one_name_do_not_replace_each_other(tmp_path):
    from flexid.report import figure_prefix

    first = compare(tiny_spec("twin rotor / ARX (5,5,1)"), progress=False)
    second = compare(tiny_spec("twin rotor / ARX (5,5,1)", budget=200), progress=False)
    a, b = figure_prefix(first), figure_prefix(second)
    assert a != b and "--" not in a and a.startswith("twin-rotor-arx-5-5-1-")
    names_a = {p.name for p in comparison_figures(first, tmp_path, prefix=a)}
    names_b = {p.name for p in comparison_figures(second, tmp_path, prefix=b)}
    assert not names_a & names_b


def test_pole_zero_map_keeps_the_unit_circle_readable_beside_a_far_zero():
    fig = plot_pole_zero([0.99 * np.exp(0.1j), 0.99 * np.exp(-0.1j)], [181.36, -0.5])
    ax = fig.axes[0]
    assert ax.get_xlim() == (-1.2, 1.2) and ax.get_ylim() == (-1.2, 1.2)
    assert any("zeros at 181.4" in t.get_text() for t in ax.texts)
