"""Tests that look at every figure type of flexid.report.plots as a reader does, on the
matplotlib objects.

Each figure is drawn (Agg) from a small real identification, comparison or selection, and
checked for what an engineer reads at a glance: every axis labelled, physical quantities with
their unit (the channel's name and unit from the record), the legend clear of the data (outside
the axes, or over no drawn point), a log FE axis wherever function evaluations are plotted,
log-axis tick labels that are plain numbers or decades (no ``8.9x10^1``), and no empty axes.
(tests/test_plots.py checks the contents: the reference line, the curves' ends, the texts.)
"""

from __future__ import annotations

import shutil

import numpy as np
import pytest

pytest.importorskip("matplotlib")

import matplotlib.pyplot as plt
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.image import AxesImage
from matplotlib.patches import Rectangle

import flexid
from flexid import compare, identify
from flexid.jobs.selection import select
from flexid.report import comparison_ecdf, plots
from helpers import tiny_spec


# ============================================================================ what a reader sees
def _in_data_coords(artist, ax) -> bool:
    """Drawn at data coordinates (not a reference line across the axes, axhline/axvline)."""
    return artist.get_transform().contains_branch(ax.transData)


def _data_points(ax) -> np.ndarray:
    """Display coordinates (px) of every drawn data point of the axes, shape (M, 2)."""
    pts = []
    for line in ax.lines:
        if line.get_visible() and _in_data_coords(line, ax):
            xy = np.asarray(line.get_xydata(), float).reshape(-1, 2)
            xy = xy[np.isfinite(xy).all(axis=1)]
            if xy.size:
                pts.append(line.get_transform().transform(xy))
    for coll in ax.collections:
        if not coll.get_visible():
            continue
        for path in coll.get_paths():
            xy = np.asarray(path.vertices, float).reshape(-1, 2)
            xy = xy[np.isfinite(xy).all(axis=1)]
            if xy.size:
                pts.append(coll.get_transform().transform(xy))
    return np.concatenate(pts) if pts else np.empty((0, 2))


def _has_data(ax) -> bool:
    """At least one artist with data: a line or collection with a finite point, an image, a
    bar; text alone (a "no run reached the target" sentence) counts when it is all there is
    to say."""
    if _data_points(ax).size:
        return True
    if any(isinstance(a, AxesImage) for a in ax.get_children()):
        return True
    if any(isinstance(p, Rectangle) and p.get_height() for p in ax.patches):
        return True
    return False


def assert_no_empty_axes(fig, *, text_ok: bool = False) -> None:
    for ax in fig.axes:
        if not ax.get_visible():
            continue
        label = ax.get_title() or ax.get_ylabel() or "axes"
        if text_ok and any(t.get_text().strip() for t in ax.texts):
            continue
        assert _has_data(ax), f"empty axes: {label!r}"


def _draw(fig):
    """Draw the figure (on an Agg canvas: a closed figure has lost its own) and return the
    renderer."""
    if not hasattr(fig.canvas, "get_renderer"):
        FigureCanvasAgg(fig)
    fig.canvas.draw()
    return fig.canvas.get_renderer()


def assert_legend_clear_of_data(fig) -> None:
    """Every legend lies outside its axes, or no drawn data point falls inside its box."""
    renderer = _draw(fig)
    for ax in fig.axes:
        legend = ax.get_legend()
        if legend is None or not legend.get_visible():
            continue
        box = legend.get_window_extent(renderer)
        frame = ax.get_window_extent(renderer)
        if box.x0 >= frame.x1 or box.x1 <= frame.x0 or box.y0 >= frame.y1 or box.y1 <= frame.y0:
            continue  # outside the axes
        pts = _data_points(ax)
        inside = ((pts[:, 0] > box.x0) & (pts[:, 0] < box.x1)
                  & (pts[:, 1] > box.y0) & (pts[:, 1] < box.y1))
        assert not inside.any(), (
            f"the legend of {ax.get_title()!r} covers {int(inside.sum())} data point(s)"
        )


def assert_readable_log_ticks(fig) -> None:
    """Every log axis has tick labels, all of them decades or plain numbers."""
    _draw(fig)
    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis):
            if axis.get_scale() != "log":
                continue
            lo, hi = sorted(axis.get_view_interval())
            labels = []
            for locs, fmt in ((axis.get_majorticklocs(), axis.get_major_formatter()),
                              (axis.get_minorticklocs(), axis.get_minor_formatter())):
                locs = [x for x in locs if lo * (1 - 1e-9) <= x <= hi * (1 + 1e-9)]
                fmt.set_locs(locs)
                labels += [fmt(x, i) for i, x in enumerate(locs)]
            labels = [s for s in labels if s]
            assert labels, f"log axis of {ax.get_title()!r} without a tick label"
            assert not [s for s in labels if "\\times" in s], labels


def assert_log_fe_axis(ax, budget: int) -> None:
    assert ax.get_xlabel() == "function evaluations"
    assert ax.get_xscale() == "log"
    assert ax.get_xlim()[0] == 1 and ax.get_xlim()[1] >= budget


def assert_looks_right(fig, *, text_ok: bool = False) -> None:
    assert_no_empty_axes(fig, text_ok=text_ok)
    assert_legend_clear_of_data(fig)
    assert_readable_log_ticks(fig)
    for ax in fig.axes:
        if ax.get_visible() and ax.get_xlabel():
            assert ax.get_ylabel() or ax.get_title(), "an axes with neither y label nor title"


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


# ============================================================================ the data
@pytest.fixture(scope="module")
def ident():
    """An SDA identification on a short simulated manipulator record (tip acceleration)."""
    data = flexid.generate("manipulator", preset="paper-manipulator", seed=0, n_samples=600)
    return identify(data, na=4, nb=4, nk=1, optimiser="sda", budget=400, seed=0)


@pytest.fixture(scope="module")
def result():
    return compare(tiny_spec("look"), progress=False)


@pytest.fixture(scope="module")
def identification_set(ident, tmp_path_factory):
    """The figures identification_figures writes, kept instead of saved."""
    figures = {}

    def keep(fig, name):
        figures[name.removesuffix(".png")] = fig
        return name, b""

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(plots, "_drawn", keep)
        plots.identification_figures(ident, tmp_path_factory.mktemp("figures"))
    return figures


# ============================================================================ identification
def test_identification_writes_the_expected_figure_set(identification_set, tmp_path):
    assert set(identification_set) == {
        "convergence", "estimation_simulation", "estimation_one_step", "validation_simulation",
        "validation_one_step", "spectra", "pole_zero", "correlations", "bode",
    }


def test_convergence_of_an_identification(identification_set, ident):
    fig = identification_set["convergence"]
    ax = fig.axes[0]
    assert_log_fe_axis(ax, ident.nfev)
    # the paper's cost of the tip acceleration carries the output's unit
    assert ax.get_yscale() == "log"
    assert ax.get_ylabel() == "best paper cost, w sqrt(SSE) / K [m/s^2]"
    assert_looks_right(fig)


def test_every_axis_of_an_identification_states_its_unit(identification_set):
    """A reader never guesses a unit: counts (function evaluations) are the one label
    without brackets."""
    for name, fig in identification_set.items():
        for ax in fig.axes:
            for label in (ax.get_xlabel(), ax.get_ylabel()):
                if label and label != "function evaluations":
                    assert "[" in label and label.endswith("]"), (name, label)


@pytest.mark.parametrize("name", ["estimation_simulation", "estimation_one_step",
                                  "validation_simulation", "validation_one_step"])
def test_time_responses_name_the_channel_and_keep_the_legend_off_the_data(
    identification_set, name
):
    fig = identification_set[name]
    top, bottom = fig.axes
    assert top.get_ylabel() == "tip_acceleration [m/s^2]"
    assert bottom.get_ylabel() == "error [m/s^2]"
    assert bottom.get_xlabel() == "time [s]"
    assert_looks_right(fig)


def test_spectra_state_the_decibel_reference(identification_set):
    fig = identification_set["spectra"]
    ax = fig.axes[0]
    assert ax.get_xlabel() == "frequency [Hz]"
    assert ax.get_ylabel() == "PSD [dB re 1 (m/s^2)^2/Hz]"
    assert "tip_acceleration" in ax.get_title()
    assert_looks_right(fig)


def test_the_bode_figure_states_its_units_and_the_verdict(identification_set):
    fig = identification_set["bode"]
    magnitude, phase, coherence = fig.axes
    assert magnitude.get_ylabel() == "magnitude [dB re 1 m/s^2/N m]"
    assert phase.get_ylabel() == "phase [deg]" and coherence.get_ylabel() == "coherence [-]"
    assert coherence.get_xlabel() == "frequency [Hz]" and magnitude.get_xscale() == "log"
    # 200 validation samples: too few for a coherence of 0.9, and the title says so
    assert fig.get_suptitle() == "tip_acceleration (validation): no frequency with coherence >= 0.9"
    labels = magnitude.get_legend_handles_labels()[1]
    assert labels[:3] == ["95 % band", "estimate, coherence < 0.9", "estimate (tfestimate)"]
    assert_looks_right(fig)


def test_pole_zero_map(identification_set):
    fig = identification_set["pole_zero"]
    ax = fig.axes[0]
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("Re z [-]", "Im z [-]")  # the z-plane
    assert_looks_right(fig)


def test_correlation_tests(identification_set):
    fig = identification_set["correlations"]
    assert len(fig.axes) >= 2
    assert fig.axes[-1].get_xlabel() == "lag [samples]"
    assert all(ax.get_title() for ax in fig.axes)  # each panel names its test
    assert_looks_right(fig)


# ============================================================================ comparison
def test_comparison_convergence(result):
    fig = plots.plot_comparison_convergence(result)
    ax = fig.axes[0]
    assert_log_fe_axis(ax, result.spec.budget)
    assert ax.get_yscale() == "log" and ax.get_ylabel().startswith("best cost")
    assert_looks_right(fig)


def test_fe_to_target(result):
    for target in result.spec.targets:
        fig = plots.plot_fe_to_target(result, target)
        ax = fig.axes[0]
        assert_log_fe_axis(ax, result.spec.budget)
        assert ax.get_ylabel() == "fraction of runs at target [-]"
        assert_looks_right(fig, text_ok=True)


def test_fe_to_target_with_no_run_at_the_target_is_not_an_empty_plot(result):
    fig = plots.plot_fe_to_target(result, 1e-12)  # no statistics for it: no curve at all
    ax = fig.axes[0]
    assert any("no run reached" in t.get_text() for t in ax.texts)
    assert_looks_right(fig, text_ok=True)


def test_ecdf(result):
    fig = plots.plot_ecdf(comparison_ecdf(result))
    ax = fig.axes[0]
    assert_log_fe_axis(ax, 1)
    assert ax.get_ylabel().startswith("fraction of")
    assert_looks_right(fig)


def test_comparison_figures_are_these_three_kinds(result, tmp_path):
    names = [p.name for p in plots.comparison_figures(result, tmp_path)]
    assert names == ["convergence.png"] + [
        f"fe_to_target_{t:g}.png" for t in result.spec.targets] + ["bode.png"]  # fmt: skip


def test_the_comparison_s_bode_figure_draws_the_reference_and_each_best_run(result):
    fig = plots.comparison_bode(result)
    labels = fig.axes[0].get_legend_handles_labels()[1]
    # ARX on its one-step cost: least squares is the reference
    assert labels[3:] == ["least squares", "sda (best of 2)", "random-search (best of 2)"]
    assert_looks_right(fig)


# ============================================================================ selection
def test_selection_figure():
    rng = np.random.default_rng(0)
    u = rng.standard_normal(800)
    y = np.zeros(800)
    for t in range(2, 800):
        y[t] = 1.5 * y[t - 1] - 0.7 * y[t - 2] + 0.5 * u[t - 1] + 0.05 * rng.standard_normal()
    grid = {"arx": [{"na": n, "nb": n} for n in (1, 2, 3, 4)],
            "oe": [{"nb": n, "nf": n} for n in (1, 2)]}
    selection = select(flexid.IOData(u, y, dt=0.01), ("arx", "oe"), grid)
    fig = plots.selection_figure(selection)
    fit, aic = fig.axes
    assert fit.get_ylabel() == "held-out simulation fit [%]"
    assert fit.get_xlabel() == aic.get_xlabel() == "number of parameters d"
    assert aic.get_ylabel().startswith("normalized AIC")
    assert_looks_right(fig)


# ============================================================================ docs/check_site.py
# The site checker's own checks, on small hand-made pages and scripts: no documentation build,
# and Chromium only where it is installed.
def _check_site():
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "docs" / "check_site.py"
    spec = importlib.util.spec_from_file_location("check_site", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _page(body: str) -> str:
    return f"<html><head></head><body><article>{body}</article></body></html>"


def test_site_check_finds_stray_reprs_and_a_bare_index(tmp_path):
    cs = _check_site()
    (tmp_path / "auto_examples").mkdir()
    (tmp_path / "auto_examples" / "plot_a.html").write_text(_page(
        "<pre>&lt;Figure size 640x400 with 1 Axes&gt;</pre>"
        "<pre>&lt;matplotlib.legend.Legend object at 0x7f00aa&gt;</pre>"))
    (tmp_path / "auto_examples" / "plot_b.html").write_text(_page("<pre>cost 0.1</pre>"))
    (tmp_path / "index.html").write_text(_page("<p>no figure, no tutorial</p>"))
    problems = cs.check_reprs(tmp_path)
    assert len(problems) == 1 and "plot_a.html: 2 stray" in problems[0]
    assert "<Figure size 640x400 with 1 Axes>" in problems[0]
    assert [p.split(":")[1].strip().split(" ")[0] for p in cs.check_index(tmp_path)] == ["no", "no"]
    (tmp_path / "_images").mkdir()
    (tmp_path / "_images" / "f.png").write_bytes(b"\x89PNG")
    (tmp_path / "index.html").write_text(_page(
        '<img src="_images/f.png"><a href="guide/tutorial.html">tutorial</a>'))
    assert cs.check_index(tmp_path) == []


def test_site_check_finds_scientific_log_ticks_and_cut_off_legends(tmp_path):
    cs = _check_site()
    script = tmp_path / "plot_bad.py"
    script.write_text(
        "import matplotlib.pyplot as plt\n"
        "fig, ax = plt.subplots(figsize=(6.4, 4.0))\n"
        "ax.plot([1, 10, 100], [1, 2, 3], label='a long legend entry')\n"
        "ax.set_xscale('log'); ax.set_yscale('log'); ax.set_ylim(1, 5)\n"
        "ax.legend(loc='upper left', bbox_to_anchor=(1.02, 1.0))\n"
    )
    problems = cs.check_figures([script])
    assert len(problems) == 2
    assert "drawn beyond its edges" in problems[0] and "right" in problems[0]
    assert "y axis (log): tick labels in scientific form, e.g. 2x10^0" in problems[1]
    # the same figure drawn by flexid.report.plots reads plainly and keeps its legend inside
    script.write_text(
        "from flexid.report.plots import plot_convergence\n"
        "plot_convergence({'a': {'fe': [1, 10, 100], 'best': [5.0, 2.0, 1.0]}})\n"
    )
    assert cs.check_figures([script]) == []


@pytest.mark.skipif(
    not (shutil.which("chromium") or shutil.which("chromium-browser")),
    reason="no chromium on the PATH",
)
def test_site_check_measures_code_cut_off_in_chromium(tmp_path):
    cs = _check_site()
    (tmp_path / "auto_examples").mkdir()
    long = "x = " + "1 + " * 200 + "1"
    (tmp_path / "index.html").write_text(_page(f'<pre style="width:300px;overflow:auto">{long}'
                                               "</pre><pre>short</pre>"))
    problems = cs.check_in_browser(tmp_path, ["index.html"], tmp_path / "shots", 1000)
    assert len(problems) == 1 and "code block cut off at the right" in problems[0]
    assert (tmp_path / "shots" / "index.png").read_bytes()[:4] == b"\x89PNG"
    assert not list(tmp_path.glob("_flexid-site-check_*"))  # the measured copy is removed
