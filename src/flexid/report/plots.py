"""Figures: the paper's identification figures and comparison figures (matplotlib, optional).

Install the ``plot`` extra (``pip install 'flexid[plot]'``) to use this module.  Every
function draws on a given ``Axes`` or a new figure and returns the figure; the ``*_figures``
functions write PNG files and return their paths.  The Agg backend is used, so no display is
needed.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..costs.metrics import cost_label
from ..errors import FlexidError
from ..jobs.statistics import convergence_band

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from ..jobs._comparison_result import ComparisonResult
    from ..jobs._identify import Identification
    from ..jobs.selection import Selection

__all__ = [
    "PlottingUnavailable",
    "comparison_bode",
    "comparison_figures",
    "identification_figures",
    "notebook_figures",
    "plot_bode",
    "plot_comparison_convergence",
    "plot_convergence",
    "plot_correlations",
    "plot_ecdf",
    "plot_fe_to_target",
    "plot_pole_zero",
    "plot_singular_values",
    "plot_spectra",
    "plot_time_response",
    "reference_name",
    "selection_bode",
    "selection_figure",
    "stabilisation_diagram",
    "suite_figure",
]


class PlottingUnavailable(FlexidError, ImportError):
    """matplotlib is not installed."""


def _plt():
    try:
        import matplotlib
    except ImportError:
        raise PlottingUnavailable("figures need matplotlib: pip install 'flexid[plot]'") from None
    if matplotlib.get_backend().lower() not in ("agg", "module://matplotlib_inline.backend_inline"):
        matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def _axes(ax, **fig_kw):
    plt = _plt()
    if ax is None:  # constrained: a legend outside the axes stays inside the saved figure
        fig, ax = plt.subplots(layout="constrained", **fig_kw)
        return fig, ax
    return ax.figure, ax


def _image(fig, fmt: str = "png", dpi: int = 110) -> bytes:
    """The figure as the bytes of an image file (then closed): drawn whole before any write."""
    import io

    buffer = io.BytesIO()
    fig.savefig(buffer, format=fmt, dpi=dpi, bbox_inches="tight")
    _plt().close(fig)
    return buffer.getvalue()


def _drawn(fig, name: str) -> tuple[str, bytes]:
    """A figure of a set as its file name and PNG bytes, to be written with the others."""
    return name, _image(fig)


def _save(fig, path: Path) -> Path:
    from ..data._files import write_bytes

    path = Path(path)
    write_bytes(path, _image(fig, path.suffix[1:].lower() or "png"))  # whole or not at all
    return path


# Okabe & Ito's colour-blind-safe palette (black last), each colour with its own line style
# so that curves stay apart in grey print and where they cross
_PALETTE = ("#0072B2", "#E69F00", "#009E73", "#CC79A7", "#56B4E9", "#D55E00", "#F0E442", "#000000")
_STYLES = ("-", "--", "-.", ":")


def _with_unit(name: str, unit: str) -> str:
    return f"{name} [{unit}]" if unit else name


def _style(i: int) -> dict[str, Any]:
    # past the palette's 8 colours, each colour comes back with another line style
    k = len(_PALETTE)
    return {"color": _PALETTE[i % k], "ls": _STYLES[(i // k + (i % k) // 2) % len(_STYLES)]}


_LOG_FORMATTER: type | None = None


def _readable_log_ticks(ax) -> None:
    """Label the log axes of ``ax`` with decades as ``10^k`` and other ticks as plain numbers.

    matplotlib labels the minor ticks of a log axis that spans a decade or two in scientific
    form (``2x10^1``, ``8.9x10^1``); an engineer reads ``20`` and ``89`` at a glance.  Which
    ticks carry a label is matplotlib's choice, unchanged.
    """
    global _LOG_FORMATTER
    if _LOG_FORMATTER is None:
        from matplotlib.ticker import LogFormatterSciNotation

        class _PlainLogFormatter(LogFormatterSciNotation):
            def __call__(self, x, pos=None):
                label = super().__call__(x, pos)
                return f"{x:.3g}" if "\\times" in label else label

        _LOG_FORMATTER = _PlainLogFormatter
    for axis in (ax.xaxis, ax.yaxis):
        if axis.get_scale() == "log":
            axis.set_major_formatter(_LOG_FORMATTER())
            axis.set_minor_formatter(_LOG_FORMATTER(labelOnlyBase=False))


def _outside_legend(ax) -> None:
    """The legend right of the axes, so that it never covers data (none without entries)."""
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0,
                  frameon=False)


# ============================================================================ identification
def _cost_unit(cost: Any, unit: str) -> str:
    """The unit of a cost's errors: the output's, or its standard deviations where a cost
    of several outputs divides each output's error by its own."""
    y = getattr(cost, "y", None)
    if y is not None and np.ndim(y) == 2 and np.shape(y)[1] > 1:
        return "output std"
    return unit


def plot_convergence(
    histories: dict[str, Any],
    *,
    ax=None,
    reference: float | None = None,
    reference_label: str = "least squares",
    cost: str = "cost",
) -> Figure:
    """Best cost against function evaluations (log axis), one line per run/optimiser.

    Parameters
    ----------
    histories : dict
        ``label -> History`` (or ``{"fe": [...], "best": [...]}``); rows with a
        non-finite best cost are not drawn.
    ax : matplotlib.axes.Axes, optional
        Axes to draw on (default: a new figure).
    reference : float, optional
        A horizontal line (the reference's cost); not drawn when NaN or infinite.
    reference_label : str
        What the reference is, for the legend.
    cost : str, optional
        The cost with its unit, for the axis (:func:`flexid.costs.metrics.cost_label`).

    Returns
    -------
    matplotlib.figure.Figure
        The figure drawn on.
    """
    fig, ax = _axes(ax, figsize=(8.0, 4.0))
    last = 1.0
    for i, (label, h) in enumerate(histories.items()):
        fe = np.asarray(h["fe"] if isinstance(h, dict) else h.fe, float)
        best = np.asarray(h["best"] if isinstance(h, dict) else h.best, float)
        finite = np.isfinite(best)
        ax.step(fe[finite], best[finite], where="post", label=label, lw=1.6, **_style(i))
        last = max(last, float(fe.max(initial=1.0)))
    if reference is not None and math.isfinite(reference):
        label = f"{reference_label} ({reference:.4g})"
        ax.axhline(reference, color="k", ls="--", lw=1, label=label)
    ax.set_xscale("log")
    ax.set_xlim(1, last)
    ax.set_yscale("log")
    ax.set_xlabel("function evaluations")
    ax.set_ylabel(f"best {cost}")
    ax.set_title("Convergence", fontsize=10)
    _readable_log_ticks(ax)
    ax.grid(True, which="both", alpha=0.3)
    _outside_legend(ax)
    return fig


def plot_time_response(
    t, y, yhat, *, title: str = "", label: str = "model", axes=None, output: str = "output",
    unit: str = "",
) -> Figure:
    """Measured and model output (top) and the modelling error (bottom).

    Parameters
    ----------
    t : ndarray, shape (N,)
        Time in seconds.
    y, yhat : ndarray, shape (N,)
        Measured and model output (output units).  Model samples that are non-finite or
        beyond 1000 times the largest ``|y|`` (a diverging free run) are not drawn, and the
        title says where the divergence starts.
    title : str, optional
        Title of the top panel.
    label : str, optional
        Legend label of the model line (default ``"model"``).
    axes : sequence of two matplotlib.axes.Axes, optional
        Top and bottom axes to draw on (default: a new figure).
    output, unit : str, optional
        The output channel's name and unit, for the axis labels (``tip_acceleration
        [m/s^2]``).

    Returns
    -------
    matplotlib.figure.Figure
        The figure drawn on.
    """
    plt = _plt()
    if axes is None:
        fig, axes = plt.subplots(2, 1, sharex=True, figsize=(7.0, 4.8), height_ratios=[2, 1],
                                 layout="constrained")
    else:
        fig = axes[0].figure
    y = np.asarray(y, dtype=float)
    yhat = np.asarray(yhat, dtype=float)
    limit = 1e3 * max(float(np.nanmax(np.abs(y))) if y.size else 1.0, 1e-300)
    diverged = ~np.isfinite(yhat) | (np.abs(np.nan_to_num(yhat, nan=np.inf)) > limit)
    if diverged.any():  # an unstable model's free run: show where it leaves the plot
        yhat = np.where(diverged, np.nan, yhat)
        first = float(np.asarray(t)[np.argmax(diverged)])
        title = f"{title} (model output diverges from t = {first:.3g} s)"
    axes[0].plot(t, y, lw=1, label="measured")
    axes[0].plot(t, yhat, lw=1, ls="--", label=label)
    axes[0].set_ylabel(_with_unit(output, unit))
    _outside_legend(axes[0])
    axes[0].set_title(title)
    axes[1].plot(t, y - yhat, lw=0.8, color="tab:red")
    axes[1].set_ylabel(_with_unit("error", unit))
    axes[1].set_xlabel("time [s]")
    for ax in axes:
        ax.grid(True, alpha=0.3)
    return fig


def plot_spectra(
    freq, spectra: dict[str, np.ndarray], *, ax=None, title: str = "Power spectral density",
    unit: str = "",
) -> Figure:
    """Power spectra in dB against frequency in Hz, one line per signal.

    Parameters
    ----------
    freq : array_like, shape (F,)
        Frequencies in Hz.
    spectra : dict of str to ndarray
        ``label -> PSD`` (shape (F,), linear units, e.g. from Welch's method), drawn as
        ``10 log10(PSD)``; non-finite values are not drawn.
    ax : matplotlib.axes.Axes, optional
        Axes to draw on (default: a new figure).
    title : str, optional
        Axes title.
    unit : str, optional
        The signal's unit: the PSD is in ``unit^2/Hz`` and drawn in dB re 1 ``unit^2/Hz``.

    Returns
    -------
    matplotlib.figure.Figure
        The figure drawn on.
    """
    fig, ax = _axes(ax, figsize=(6.4, 4.0))
    for label, p in spectra.items():
        p = np.asarray(p, float)
        p = np.where(np.isfinite(p), p, np.nan)  # a diverged simulation has no spectrum
        ax.plot(freq, 10 * np.log10(np.maximum(p, 1e-300)), lw=1, label=label)
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel(f"PSD [dB re 1 ({unit})^2/Hz]" if unit else "PSD [dB re 1 unit^2/Hz]")
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend()
    return fig


def _model_modes(model: Any) -> list[float]:
    """The natural frequencies (Hz) of a model's lightly damped pairs, for marking."""
    if not hasattr(model, "poles") or not hasattr(model, "dt"):
        return []
    from ..models.modes import model_modes

    try:
        found = model_modes(model)
    except FlexidError:
        return []
    return [m.frequency for m in found if m.kind == "pair" and 0 < m.damping < 1]


_BODE_POINTS = 1500  # a model's response: log-spaced frequencies across the estimate's


def _agreement_words(agreement: Any) -> str:
    share, judged = float(agreement.share[0]), int(agreement.judged[0])
    if judged == 0:
        return f"no frequency with coherence >= {agreement.coherence:g}"
    return f"model inside the band at {100 * share:.0f} % of {judged} trusted frequencies"


def plot_bode(
    estimate: Any, models: Mapping[str, Any] | None = None, *, title: str = "",
    coherence: float | None = None, modes: Mapping[str, Sequence[float]] | None = None,
) -> Figure:
    """Bode figure of a record's frequency-response estimate and models, with coherence.

    For every input-output pair, three panels share a log frequency axis in Hz: magnitude
    in dB (the estimate, its confidence band shaded, the models; each model's modes marked
    by a triangle on the top edge in its colour), phase in degrees (the estimate's band
    shaded) and the output's coherence with the inputs.  The estimate is drawn black where
    the coherence reaches ``coherence`` and grey where the record cannot be trusted.

    Parameters
    ----------
    estimate : FrequencyResponseEstimate
        From :func:`flexid.frf`.
    models : mapping of str to model, callable or ndarray, optional
        ``label -> model`` (anything with ``frequency_response(f)``, shape (F, ny, nu), such
        as every linear flexid model; its ``poles()`` give the marked modes), ``label ->
        response(f)`` (a function of frequencies in Hz), both drawn on a fine grid, or
        ``label -> response`` at the estimate's frequencies, shape (F, ny, nu).
    title : str, optional
        Figure title.
    coherence : float, optional
        The coherence a frequency needs to be drawn as trusted (default
        :data:`flexid.validation.frequency.COHERENCE_LEVEL`).
    modes : mapping of str to sequence of float, optional
        ``label -> natural frequencies`` (Hz) to mark for a model given as a response
        (default: a model's own lightly damped modes, none for a response).

    Returns
    -------
    matplotlib.figure.Figure
        Rows of three panels per output, one column per input.
    """
    from ..validation.frequency import COHERENCE_LEVEL

    plt = _plt()
    level = COHERENCE_LEVEL if coherence is None else float(coherence)
    f = estimate.frequency
    ny, nu = estimate.n_outputs, estimate.n_inputs
    fig, axes = plt.subplots(
        3 * ny, nu, sharex=True, squeeze=False, figsize=(6.4 * nu + 2.2, 5.6 * ny),
        height_ratios=[3.0, 2.0, 1.2] * ny, layout="constrained",
    )  # fmt: skip
    # a model is drawn on a fine grid of its own: its resonances sharper than the estimate's
    dense = np.geomspace(f[0], f[-1], _BODE_POINTS)
    curves = _bode_curves(models, modes, f, dense, ny, nu)
    mag_db = estimate.magnitude_db()
    phase = estimate.phase_deg()
    lower, upper = estimate.band()
    half = estimate.phase_band()
    with np.errstate(divide="ignore"):
        low_db, high_db = 20 * np.log10(lower), 20 * np.log10(upper)
    for j in range(ny):
        trusted = estimate.coherence[:, j] >= level
        for i in range(nu):
            ax_m, ax_p, ax_c = axes[3 * j, i], axes[3 * j + 1, i], axes[3 * j + 2, i]
            finite = mag_db[:, j, i][np.isfinite(mag_db[:, j, i])]
            floor = (finite.min() if finite.size else 0.0) - 20.0
            ax_m.fill_between(f, np.maximum(low_db[:, j, i], floor), high_db[:, j, i],
                              color="0.6", alpha=0.3, lw=0,
                              label=f"{100 * estimate.level:.0f} % band")  # fmt: skip
            ax_m.plot(f, mag_db[:, j, i], color="0.7", lw=1,
                      label=f"estimate, coherence < {level:g}")  # fmt: skip
            # the estimate over the models, thinner: both stay visible where they agree
            ax_m.plot(f, np.where(trusted, mag_db[:, j, i], np.nan), color="k", lw=1.0,
                      zorder=3, label=f"estimate ({estimate.method})")  # fmt: skip
            ax_p.fill_between(f, phase[:, j, i] - half[:, j, i], phase[:, j, i] + half[:, j, i],
                              color="0.6", alpha=0.3, lw=0)  # fmt: skip
            ax_p.plot(f, phase[:, j, i], color="0.7", lw=1)
            ax_p.plot(f, np.where(trusted, phase[:, j, i], np.nan), color="k", lw=1.0, zorder=3)
            for curve in curves:
                _bode_model_lines(ax_m, ax_p, curve, j, i, f, trusted, phase)
            ax_c.plot(f, estimate.coherence[:, j], color="k", lw=1)
            ax_c.axhline(level, color="0.4", ls=":", lw=1)
            ax_c.set_ylim(0.0, 1.05)
            _bode_labels(ax_m, ax_p, ax_c, estimate, j, i)
            if j == ny - 1:
                ax_c.set_xlabel("frequency [Hz]")
    axes[0, 0].set_xlim(f[0], f[-1])
    _outside_legend(axes[0, -1])
    if title:
        fig.suptitle(title)
    return fig


def _bode_curves(
    models: Mapping[str, Any] | None, modes: Mapping[str, Sequence[float]] | None,
    f: np.ndarray, dense: np.ndarray, ny: int, nu: int,
) -> list[tuple[str, np.ndarray, np.ndarray, list, dict]]:
    """The models of :func:`plot_bode` as ``(label, grid, response, modes, style)``: a model
    or a function on the fine grid ``dense``, a response at the estimate's frequencies."""
    curves = []
    for i, (label, model) in enumerate((models or {}).items()):
        if hasattr(model, "frequency_response"):
            grid, g = dense, model.frequency_response(dense)
        elif callable(model):
            grid, g = dense, model(dense)
        else:
            grid, g = f, model
        marked = (modes or {}).get(label)
        curves.append((label, grid, np.asarray(g, dtype=complex).reshape(grid.size, ny, nu),
                       _model_modes(model) if marked is None else list(marked),
                       _style(i)))  # fmt: skip
    return curves


def _bode_model_lines(
    ax_m: Any, ax_p: Any, curve: tuple[str, np.ndarray, np.ndarray, list, dict], j: int, i: int,
    f: np.ndarray, trusted: np.ndarray, phase: np.ndarray,
) -> None:
    """One model's magnitude, phase and marked modes on the panels of pair ``(j, i)``."""
    label, grid, g, mode_f, style = curve
    gji = g[:, j, i]
    with np.errstate(divide="ignore"):
        ax_m.plot(grid, 20 * np.log10(np.abs(gji)), lw=1.2, label=label, **style)
    ph = np.degrees(np.unwrap(np.angle(gji)))
    # the same branch as the estimate's phase where the record is trusted
    at = int(np.argmax(trusted)) if trusted.any() else 0
    near = int(np.argmin(np.abs(grid - f[at])))
    ph -= 360.0 * np.round((ph[near] - phase[at, j, i]) / 360.0)
    ax_p.plot(grid, ph, lw=1.2, **style)
    shown = [m for m in mode_f if f[0] <= m <= f[-1]]
    if shown:  # an empty line off the axes' clip box collapses the layout
        ax_m.plot(shown, np.ones(len(shown)), ls="none", marker="v", ms=7,
                  color=style["color"], transform=ax_m.get_xaxis_transform(),
                  clip_on=False)  # fmt: skip


def _bode_labels(ax_m: Any, ax_p: Any, ax_c: Any, estimate: Any, j: int, i: int) -> None:
    """Titles, axis labels, log scales and grids of the panels of pair ``(j, i)``."""
    unit_in = estimate.input_units[i] if estimate.input_units else ""
    unit_out = estimate.output_units[j] if estimate.output_units else ""
    gain_unit = f"{unit_out or '1'}/{unit_in or '1'}" if unit_in or unit_out else ""
    ax_m.set_title(f"{estimate.input_names[i]} \u2192 {estimate.output_names[j]}",
                   pad=12)  # fmt: skip
    ax_m.set_ylabel(_with_unit("magnitude", f"dB re 1 {gain_unit}" if gain_unit
                               else "dB"))  # fmt: skip
    ax_p.set_ylabel("phase [deg]")
    ax_c.set_ylabel("coherence [-]")
    for ax in (ax_m, ax_p, ax_c):
        ax.set_xscale("log")
        ax.grid(True, which="both", alpha=0.3)
    _readable_log_ticks(ax_c)


# Roots closer than this (relative to max(1, |root|)) are drawn as one repeated root: a root
# of multiplicity k is computed as k roots spread by about eps^(1/k) (1e-5 for k = 3).
_REPEATED = 1e-4


def _repeated(roots: np.ndarray) -> list[tuple[complex, int]]:
    """Clusters of (numerically) repeated roots: ``(mean root, multiplicity)``, k >= 2."""
    roots = np.asarray(roots, dtype=complex).ravel()
    left = list(range(roots.size))
    out = []
    while left:
        i = left.pop(0)
        near = [j for j in left if abs(roots[j] - roots[i]) <= _REPEATED * max(1.0, abs(roots[i]))]
        if near:
            left = [j for j in left if j not in near]
            out.append((complex(roots[[i, *near]].mean()), len(near) + 1))
    return out


def _root_text(root: complex) -> str:
    root = complex(root)
    return f"{root.real:.4g}" if root.imag == 0 else f"{root.real:.4g}{root.imag:+.4g}j"


#: Roots beyond this radius are named rather than drawn in the pole-zero map.
_VIEW_RADIUS = 3.0


def plot_pole_zero(
    poles: Any, zeros: Any, *, ax: Axes | None = None, title: str = "Pole-zero map"
) -> Figure:
    """Poles (x) and zeros (o) in the z-plane with the unit circle (dotted).

    A root that occurs several times (within a relative ``1e-4``) is labelled with its
    multiplicity.  The view holds the unit circle and the roots within radius 3; farther
    roots (a non-minimum-phase zero at 181, say) are named in a line of text instead.

    Parameters
    ----------
    poles : array_like of complex, shape (n_p,)
        Poles.
    zeros : array_like of complex, shape (n_z,)
        Zeros (may be empty).
    ax : matplotlib.axes.Axes, optional
        Axes to draw on (default: a new figure).
    title : str, optional
        Axes title.

    Returns
    -------
    matplotlib.figure.Figure
        The figure drawn on.
    """
    fig, ax = _axes(ax, figsize=(4.8, 4.8))
    theta = np.linspace(0, 2 * np.pi, 400)
    ax.plot(np.cos(theta), np.sin(theta), "k:", lw=1)
    poles = np.asarray(poles)
    zeros = np.asarray(zeros)
    ax.plot(poles.real, poles.imag, "x", ms=8, mew=2, label="poles")
    if zeros.size:
        ax.plot(zeros.real, zeros.imag, "o", ms=7, mfc="none", mew=1.5, label="zeros")
    for roots in (poles, zeros):  # a repeated root is one marker: its multiplicity beside it
        for root, count in _repeated(roots):
            ax.annotate(f"{count}", (root.real, root.imag), xytext=(5, 5),
                        textcoords="offset points", fontsize=9)
    ax.axhline(0, color="0.7", lw=0.5)
    ax.axvline(0, color="0.7", lw=0.5)
    # a far root (a zero at 181, say) would shrink the unit circle to a dot: the view holds
    # the roots within radius 3 and names the others
    radii = np.abs(np.concatenate([poles, zeros]).astype(complex))
    near = radii[radii <= _VIEW_RADIUS]
    lim = max(1.2, 1.1 * float(near.max())) if near.size else 1.2
    far = [f"{name} at {', '.join(map(_root_text, roots[np.abs(roots) > lim]))}"
           for name, roots in (("poles", poles), ("zeros", zeros))
           if np.any(np.abs(roots) > lim)]  # fmt: skip
    if far:
        ax.text(0.02, 0.02, "outside the view: " + "; ".join(far), transform=ax.transAxes,
                fontsize=8, va="bottom", wrap=True)
    ax.set_xlim(-lim, lim)
    ax.set_ylim(-lim, lim)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("Re z [-]")
    ax.set_ylabel("Im z [-]")
    ax.set_title(title)
    _outside_legend(ax)
    return fig


def plot_singular_values(result: Any, *, ax: Axes | None = None) -> Figure:
    """The singular values subspace identification reads the order from, the order marked.

    Parameters
    ----------
    result : SubspaceResult
        From :func:`flexid.fit.subspace.n4sid`.
    ax : matplotlib.axes.Axes, optional
        Axes to draw on (default: a new figure).

    Returns
    -------
    matplotlib.figure.Figure
        Logarithmic singular values relative to the largest against their index (the
        candidate order), the model's order a filled marker and a vertical line.
    """
    fig, ax = _axes(ax, figsize=(6.4, 3.8))
    sv = np.asarray(result.singular_values, dtype=float)
    rel = sv / sv[0] if sv.size and sv[0] > 0 else sv
    index = np.arange(1, rel.size + 1)
    floor = np.finfo(float).eps
    ax.semilogy(index, np.maximum(rel, floor), "o-", color="0.35", markerfacecolor="white",
                label="singular values")  # fmt: skip
    n = int(result.order)
    how = "read from the largest drop" if result.order_chosen else "given"
    ax.semilogy([n], [max(rel[n - 1], floor)], "o", color="#D55E00", markersize=9,
                label=f"order {n} ({how})")  # fmt: skip
    ax.axvline(n + 0.5, color="#D55E00", linestyle="--", linewidth=1)
    ax.set_xlabel("index (candidate order)")
    ax.set_ylabel("singular value / largest")
    ax.set_xlim(0.5, rel.size + 0.5)
    from matplotlib.ticker import MaxNLocator

    ax.xaxis.set_major_locator(MaxNLocator(integer=True))  # orders are whole numbers
    ax.set_title(f"Subspace singular values ({result.block_rows} block rows)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(loc="upper right")
    return fig


def plot_correlations(
    panels: Sequence[tuple[str, np.ndarray, np.ndarray, float]], *, title: str = ""
) -> Figure:
    """Correlation functions with their 95 % bands.

    Parameters
    ----------
    panels : sequence of (title, lags, values, bound)
        One panel each (as :meth:`flexid.ValidationReport.correlation_panels` gives them):
        ``lags`` (K,) in samples, ``values`` (K,) correlation coefficients and ``bound`` the
        half-width of the 95 % band (1.96/sqrt(N)).
    title : str, optional
        Figure title.

    Returns
    -------
    matplotlib.figure.Figure
        A new figure, one row of axes per panel.
    """
    plt = _plt()
    fig, axes = plt.subplots(len(panels), 1, figsize=(7.0, 2.3 * len(panels)), squeeze=False)
    for ax, (name, lags, values, bound) in zip(axes[:, 0], panels):
        lags = np.asarray(lags)
        ax.vlines(lags, 0, values, lw=1.5)
        ax.plot(lags, values, ".", ms=4)
        ax.axhline(bound, color="tab:red", ls=":", lw=1)
        ax.axhline(-bound, color="tab:red", ls=":", lw=1)
        ax.axhline(0, color="k", lw=0.5)
        ax.set_title(name, fontsize=10)
        ax.set_ylim(-1.05, 1.05)
        ax.set_ylabel("correlation [-]")
        ax.grid(True, alpha=0.3)
    axes[-1, 0].set_xlabel("lag [samples]")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig


def identification_figures(
    ident: Identification, outdir: str | Path, prefix: str = ""
) -> list[Path]:
    """Write the paper's figures of an identification as PNG files.

    Convergence (if an optimiser ran), measured vs model output with the error on the
    estimation and validation records (one-step and simulation), power spectra, pole-zero
    map with the unit circle, residual correlations with 95 % bands.

    Parameters
    ----------
    ident : Identification
        The identification (from :func:`flexid.identify`).
    outdir : str or pathlib.Path
        Directory to write to (created if needed; files there are overwritten).
    prefix : str, optional
        Prefix of every file name.

    Returns
    -------
    list of pathlib.Path
        The files written: ``convergence.png`` (when an optimiser ran), then
        ``{estimation,validation}_{simulation,one_step}.png``, ``spectra.png``,
        ``correlations.png`` and ``bode.png`` (validation record; no Bode figure for a model
        without a frequency response), and ``pole_zero.png`` (zeros of the first
        input, to the first output), each with ``prefix``; with several outputs each output's
        figures carry its name (``validation_simulation_<output>.png``).

    Raises
    ------
    flexid.errors.DataFileError
        When the folder cannot be made or a figure cannot be written (a full disk, no
        permission, a file of that name): one line naming the folder and the cause; none of
        the figures is written then, nor any part of one.
    """
    from ..data._files import write_files

    files: list[tuple[str, bytes]] = []  # every figure drawn before the first is written
    p = prefix
    output = ident.data_info.get("output", "output")
    unit = ident.data_info.get("output_unit", "")
    if ident.history is not None:
        arx = getattr(getattr(ident.model, "structure", None), "kind", "arx") == "arx"
        fig = plot_convergence(
            {ident.optimiser: ident.history},
            reference=ident.cost_ls,
            reference_label="least squares" if arx else "ARX least squares read as the model",
            cost=cost_label(ident.cost.metric, _cost_unit(ident.cost, unit)),
        )
        files.append(_drawn(fig, f"{p}convergence.png"))
    if ident.outputs:  # several outputs: each one's figures, its name in the file name
        per = [(v.output_name, v.output_unit, e, v, f"_{v.output_name}")
               for e, v in ident.outputs]  # fmt: skip
    else:
        per = [(output, unit, ident.estimation, ident.validation, "")]
    for name, unit, est_report, val_report, tail in per:
        for part, report in (("estimation", est_report), ("validation", val_report)):
            arrays = report.arrays()
            for kind, words, fit in (
                ("simulation", "simulation (free run)", report.fit_simulation),
                ("one_step", "one-step prediction", report.fit_one_step),
            ):
                fig = plot_time_response(
                    arrays["time"], arrays["y"], arrays[f"y_{kind}"],
                    title=f"{part}: {words}, fit {fit:.1f} %", output=name, unit=unit,
                )  # fmt: skip
                files.append(_drawn(fig, f"{p}{part}_{kind}{tail}.png"))
        arrays = val_report.arrays()
        fig = plot_spectra(
            arrays["psd_frequency"],
            {"measured": arrays["psd_measured"], "model (simulation)": arrays["psd_model"]},
            title=f"Power spectral density of {name} (validation)",
            unit=unit,
        )
        files.append(_drawn(fig, f"{p}spectra{tail}.png"))
        fig = plot_correlations(
            val_report.correlation_panels(),
            title=f"Residual correlation tests (validation){f', {name}' if tail else ''}",
        )
        files.append(_drawn(fig, f"{p}correlations{tail}.png"))
        fig = _identification_bode(ident, name, val_report)
        if fig is not None:
            files.append(_drawn(fig, f"{p}bode{tail}.png"))
    fig = plot_pole_zero(ident.model.poles(), ident.model.zeros())
    files.append(_drawn(fig, f"{p}pole_zero.png"))
    return write_files(Path(outdir), files, "figures")


# ============================================================================ comparison
def reference_name(result: ComparisonResult) -> str:
    """The reference a comparison's costs are relative to, in a few words (for legends).

    Parameters
    ----------
    result : ComparisonResult

    Returns
    -------
    str
        E.g. ``"least squares"``, ``"prediction-error reference"``, ``"output-error
        reference"`` or ``"best stable run"``.
    """
    note = result.reference_note or "reference"
    if note.startswith("best stable cost"):
        return "best stable run"
    if note.startswith("the ARX least-squares estimate"):
        return "ARX least squares"
    return note.split(" (")[0].split(",")[0]


def _max_fe(result: ComparisonResult) -> int:
    """The FE axis's end: the budget (a "schedule" budget has none: the longest run)."""
    budget = result.spec.budget if isinstance(result.spec.budget, int) else 0
    runs = [int(r["nfev"]) for rs in result.records.values() for r in rs if r["status"] == "ok"]
    return max([budget, 1, *runs])


def plot_comparison_convergence(result: ComparisonResult, *, ax: Axes | None = None) -> Figure:
    """Median (line) and quartiles (band) of the best cost against FE, per optimiser.

    Both axes are logarithmic: FE from the first evaluation to the budget, and the cost
    relative to the comparison's reference (:func:`reference_name`), so that the early
    progress and a spread of a few percent near the reference are both visible; the
    reference is the line at 1.  Without a finite reference the raw cost is drawn.

    Parameters
    ----------
    result : ComparisonResult
        The comparison; failed runs are left out.
    ax : matplotlib.axes.Axes, optional
        Axes to draw on (default: a new figure).

    Returns
    -------
    matplotlib.figure.Figure
        The figure drawn on.
    """
    fig, ax = _axes(ax, figsize=(8.6, 4.4))
    max_fe = _max_fe(result)
    ref = result.reference_cost
    relative = math.isfinite(ref) and ref > 0
    scale = ref if relative else 1.0
    name = reference_name(result)
    for i, (label, records) in enumerate(result.records.items()):
        hist = [r["history"] for r in records if r["status"] == "ok"]
        if not hist:
            continue
        band = convergence_band(hist, max_fe, log=True)
        style = _style(i)
        ax.plot(band["fe"], band["median"] / scale, lw=1.6, label=f"{label} ({len(hist)} runs)",
                **style)
        ax.fill_between(band["fe"], band["q25"] / scale, band["q75"] / scale,
                        color=style["color"], alpha=0.1, lw=0)
        for edge in ("q25", "q75"):  # thin edges: overlapping bands stay readable
            ax.plot(band["fe"], band[edge] / scale, color=style["color"], lw=0.5, alpha=0.6)
    if relative:
        ax.axhline(1.0, color="k", ls="--", lw=1, label=f"{name} ({ref:.4g})")
        ax.set_ylabel(f"best cost / {name} [-]")
    else:
        ax.set_ylabel(f"best {cost_label(result.spec.cost.metric)}")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlim(1, max_fe)
    ax.set_xlabel("function evaluations")
    ax.set_title(
        f"{result.spec.name}: best cost, median and quartiles over {result.spec.runs} runs",
        fontsize=10,
    )
    ax.grid(True, which="both", alpha=0.3)
    _readable_log_ticks(ax)
    _outside_legend(ax)
    return fig


def plot_fe_to_target(
    result: ComparisonResult, target: float, *, ax: Axes | None = None
) -> Figure:
    """Fraction of runs that reached ``reference * (1 + target)`` against FE (log axis).

    Each curve runs to the budget and ends at its success rate; when no run of any
    optimiser reaches the target the figure says so instead of drawing empty axes.

    Parameters
    ----------
    result : ComparisonResult
        The comparison.
    target : float
        A relative target of ``result.spec.targets``; optimisers without statistics for it
        are left out.
    ax : matplotlib.axes.Axes, optional
        Axes to draw on (default: a new figure).

    Returns
    -------
    matplotlib.figure.Figure
        The figure drawn on.
    """
    fig, ax = _axes(ax, figsize=(8.0, 4.0))
    max_fe = _max_fe(result)
    name = reference_name(result)
    reached = 0
    for i, (label, stats) in enumerate(result.stats.items()):
        reach = stats.get("reach", {}).get(str(target))
        if reach is None:
            continue
        fe = np.sort(np.asarray(reach["fe"], float))
        n = fe.size
        hit = fe[np.isfinite(fe)]
        reached += hit.size
        x = np.concatenate([[1.0], np.maximum(hit, 1.0), [max_fe]])
        y = np.concatenate([[0.0], np.arange(1, hit.size + 1) / n, [hit.size / n]])
        ax.step(x, y, where="post", lw=1.6, label=f"{label} ({hit.size}/{n})", **_style(i))
    if not reached:
        ax.text(0.5, 0.5, f"no run reached {name} x (1 + {target:g})\nwithin {max_fe:,} FE",
                transform=ax.transAxes, ha="center", va="center", fontsize=11)
    ax.set_xscale("log")
    ax.set_xlim(1, max_fe)
    ax.set_ylim(-0.02, 1.02)
    ax.set_xlabel("function evaluations")
    ax.set_ylabel("fraction of runs at target [-]")
    ax.set_title(f"FE to reach {name} x (1 + {target:g})", fontsize=10)
    _readable_log_ticks(ax)
    ax.grid(True, which="both", alpha=0.3)
    _outside_legend(ax)
    return fig


def plot_ecdf(ecdf: dict[str, Any], *, ax: Axes | None = None, title: str = "") -> Figure:
    """ECDF of (run, target) pairs reached against function evaluations (log axis).

    Parameters
    ----------
    ecdf : dict
        The output of :func:`flexid.report.comparison_ecdf`: ``targets`` (target costs),
        ``curves`` (``label -> {"fe", "fraction", "runs"}``, each curve a step function of
        FE).
    ax : matplotlib.axes.Axes, optional
        Axes to draw on (default: a new figure).
    title : str, optional
        Figure title (default: the number of targets).

    Returns
    -------
    matplotlib.figure.Figure
        The figure drawn on.
    """
    fig, ax = _axes(ax, figsize=(6.4, 4.0))
    n_targets = len(ecdf["targets"])
    for label, curve in ecdf["curves"].items():
        fe = np.asarray(curve["fe"], float)
        fraction = np.asarray(curve["fraction"], float)
        if fe.size:
            ax.step(fe, fraction, where="post", label=f"{label} ({curve['runs']} runs)")
    ax.set_xscale("log")
    ax.set_xlim(left=1)  # the first evaluation
    ax.set_ylim(-0.02, 1.02)
    ax.set_xlabel("function evaluations")
    ax.set_ylabel("fraction of (run, target) pairs reached [-]")
    ax.set_title(title or f"ECDF over {n_targets} targets reference x (1 + d)")
    _readable_log_ticks(ax)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(loc="lower right")
    return fig


def comparison_figures(
    result: ComparisonResult, outdir: str | Path, prefix: str = ""
) -> list[Path]:
    """Write the convergence band figure, one FE-to-target ECDF per target and the Bode figure.

    Parameters
    ----------
    result : ComparisonResult
        The comparison.
    outdir : str or pathlib.Path
        Directory to write to (created if needed; files there are overwritten).
    prefix : str, optional
        Prefix of every file name.

    Returns
    -------
    list of pathlib.Path
        ``convergence.png``, then ``fe_to_target_<t>.png`` for each target ``t`` of the
        spec, then ``bode.png`` (:func:`comparison_bode`, where there is one), each with
        ``prefix``.

    Raises
    ------
    flexid.errors.DataFileError
        When the folder cannot be made or a figure cannot be written: as
        :func:`identification_figures`, all the figures or none.
    """
    from ..data._files import write_files

    return write_files(Path(outdir), _comparison_images(result, prefix), "figures")


def _comparison_images(result: ComparisonResult, prefix: str) -> list[tuple[str, bytes]]:
    """The file names and PNG bytes of :func:`comparison_figures`, nothing written."""
    files = [_drawn(plot_comparison_convergence(result), f"{prefix}convergence.png")]
    for t in result.spec.targets:
        files.append(_drawn(plot_fe_to_target(result, t), f"{prefix}fe_to_target_{t:g}.png"))
    bode = comparison_bode(result)
    if bode is not None:
        files.append(_drawn(bode, f"{prefix}bode.png"))
    return files


def _identification_bode(ident: Identification, name: str, report: Any) -> Figure | None:
    """The Bode figure of one output of an identification against its held-out record's
    estimate (None without an estimate: a grey-box model, a record too short)."""
    if report.frequency_estimate is None:
        return None
    names = list(getattr(ident.model, "output_names", ()))
    k = names.index(name) if name in names else 0
    return plot_bode(
        report.frequency_estimate,
        {"model": lambda f, k=k: ident.model.frequency_response(f)[:, k : k + 1, :]},
        modes={"model": _model_modes(ident.model)},
        title=f"{name} (validation): {_agreement_words(report.frequency)}",
    )  # fmt: skip


def notebook_figures(kind: str, result: Any) -> list[bytes]:
    """The Bode figures of a result for its notebook display, as PNG images.

    Parameters
    ----------
    kind : {"identification", "comparison", "selection"}
        What ``result`` is.
    result : Identification, ComparisonResult or Selection

    Returns
    -------
    list of bytes
        An identification's held-out Bode figure per output, a comparison's
        (:func:`comparison_bode`) or a selection's (:func:`selection_bode`); empty where
        there is none, or without matplotlib (the display then shows its tables alone).
    """
    try:
        if kind == "identification":
            if result.outputs:
                shown = [(v.output_name, v) for _, v in result.outputs]
            else:
                shown = [(result.data_info.get("output", "output"), result.validation)]
            drawn = [_identification_bode(result, name, v) for name, v in shown]
        else:
            drawn = [{"comparison": comparison_bode, "selection": selection_bode}[kind](result)]
    except PlottingUnavailable:
        return []
    return [_image(fig, dpi=80) for fig in drawn if fig is not None]


def comparison_bode(result: ComparisonResult) -> Figure | None:
    """The Bode figure of a comparison: the held-out record's estimate, the reference and
    each optimiser's best run (:func:`flexid.jobs._compare.frequency_views`).

    Parameters
    ----------
    result : ComparisonResult
        The comparison.

    Returns
    -------
    matplotlib.figure.Figure or None
        None when its models have no frequency response (grey-box) or its record cannot be
        read again (a data file moved or changed since the runs).
    """
    from ..jobs._compare import frequency_views

    try:
        estimate, models = frequency_views(result)
    except FlexidError:
        return None
    if not models:
        return None
    return plot_bode(estimate, models,
                     title=f"{result.spec.name or 'comparison'}: held-out record")  # fmt: skip


# ============================================================================ selection
_STRUCTURE_STYLE = {
    "arx": ("tab:blue", "s"),
    "armax": ("tab:green", "^"),
    "oe": ("tab:orange", "o"),
    "bj": ("tab:purple", "D"),
    "polynomial": ("tab:gray", "v"),
    "greybox": ("tab:red", "*"),
}
# fits below this (%) are drawn on the lower edge of the fit panel, as a down-pointing marker
_FIT_FLOOR = -20.0


def selection_figure(
    selection: Selection, path: str | Path | None = None, *, criterion: bool = True
) -> Figure | Path:
    """Held-out simulation fit against the number of parameters, per structure.

    The left panel is what :func:`flexid.jobs.selection.select` recommends from: one line and
    marker style per structure, filled markers for candidates that pass every residual
    correlation test and hollow ones for those that fail, a cross over an unstable model,
    and the recommendation ringed and annotated.  Fits below -20 % (or a diverging
    simulation) sit on the lower edge as down-pointing markers.  The optional right panel is
    the normalized AIC (``log V + 2 d / K``) against ``d`` with the same styles, where the
    information criterion's own choice (its minimum) can be compared with the
    recommendation.

    Parameters
    ----------
    selection : Selection
        The result of :func:`flexid.jobs.selection.select`; candidates that failed to fit are not
        drawn.
    path : str or pathlib.Path, optional
        Write the figure there as a PNG (and close it).
    criterion : bool, optional
        Draw the AIC panel (default True).

    Returns
    -------
    matplotlib.figure.Figure or pathlib.Path
        The figure, or ``path`` when one is given.
    """
    plt = _plt()
    from matplotlib.ticker import MaxNLocator

    ncols = 2 if criterion else 1
    fig, axes = plt.subplots(
        1, ncols, figsize=(11.0 if criterion else 7.0, 4.6), squeeze=False,
        width_ratios=[3, 2] if criterion else None,
    )
    ax_fit = axes[0, 0]
    drawn = [c for c in selection.candidates if c.ok]
    fits = np.array([c.fit_simulation for c in drawn], float)
    finite = fits[np.isfinite(fits)]
    low = max(float(finite.min()) if finite.size else 0.0, _FIT_FLOOR)
    high = float(finite.max()) if finite.size else 100.0
    pad = 0.06 * max(high - low, 1.0)
    floor = low - pad
    kinds = list(dict.fromkeys(c.kind for c in drawn))

    _draw_candidates(ax_fit, drawn, kinds, _fit, low, floor)
    ax_fit.set_ylim(floor - pad * 0.5, min(high + pad, 100.0 + pad))
    ax_fit.set_xlabel("number of parameters d")
    ax_fit.set_ylabel("held-out simulation fit [%]")
    ax_fit.set_title("Held-out simulation fit (filled: passes every correlation test)")
    ax_fit.grid(True, alpha=0.3)
    _marker_legend(ax_fit, drawn, low)

    best = selection.best
    d_all = [c.n_params for c in drawn] or [0]
    x_mid = 0.5 * (min(d_all) + max(d_all))
    title = (
        f"Structure selection: {len(selection.candidates)} candidates, "
        f"{sum(c.passed for c in selection.candidates)} pass every correlation test"
    )
    if best is not None and best.ok:
        title += _mark_recommendation(ax_fit, best, low, floor, x_mid)
    if criterion:
        _criterion_panel(axes[0, 1], drawn, kinds, best, x_mid)
    ax_fit.xaxis.set_major_locator(MaxNLocator(integer=True))
    fig.suptitle(title)
    fig.tight_layout()
    if path is not None:
        return _save(fig, Path(path))
    return fig


def _held_out_estimate(selection: Selection) -> Any:
    """The held-out record's frequency-response estimate, every output of the recommendation
    (or of the first candidate validated)."""
    from ..data.records import IOData
    from ..validation.frequency import frf

    for c in [selection.best, *selection.candidates]:
        if c is None or c.report is None:
            continue
        if not c.reports:
            return c.report.frequency_estimate
        first = c.reports[0]
        record = IOData(first.u, np.column_stack([r.y for r in c.reports]), dt=first.dt,
                        input_names=list(first.input_names),
                        output_names=[r.output_name for r in c.reports])  # fmt: skip
        try:
            return frf(record)
        except FlexidError:
            return None
    return None


def selection_bode(selection: Selection, *, shown: int = 4) -> Figure | None:
    """Bode figure of a selection: the held-out record's estimate, the recommendation and the
    candidates with the next best held-out fits.

    Parameters
    ----------
    selection : Selection
        The result of :func:`flexid.select`.
    shown : int, optional
        How many models to draw, the recommendation first (default 4).

    Returns
    -------
    matplotlib.figure.Figure or None
        None without a linear candidate or an estimate of the held-out record.
    """
    estimate = _held_out_estimate(selection)
    linear = [c for c in selection.candidates
              if c.ok and hasattr(c.model, "frequency_response")]  # fmt: skip
    if estimate is None or not linear:
        return None
    best = selection.best if selection.best in linear else None
    others = sorted((c for c in linear if c is not best), key=lambda c: -_fit(c))
    chosen = ([best] if best is not None else []) + others
    models = {(f"{c.label} (recommended)" if c is best else c.label): c.model
              for c in chosen[:shown]}  # fmt: skip
    return plot_bode(estimate, models, title="Structure selection: held-out record")


# Two modes of neighbouring orders are the same physical mode when their frequencies differ
# by less than 1 % and their damping ratios by less than 5 % (the usual criteria of a
# stabilisation diagram in modal analysis, e.g. Peeters & De Roeck 2001)
_STABLE_FREQUENCY = 0.01
_STABLE_DAMPING = 0.05


def stabilisation_diagram(selection: Selection) -> Figure | None:
    """Stabilisation diagram of a selection: each candidate's modes against its order.

    For the recommendation's structure (or the first linear one), one row per order (the
    best ranked candidate with that many poles), one marker per oscillating mode at its
    natural frequency: filled where a mode of the next lower order lies within 1 % in
    frequency and 5 % in damping (stable), hollow where within 1 % in frequency only, a
    cross where new.  Physical modes line up in columns as the order grows; modes that
    wander are the fit's.  The held-out record's estimated magnitude is drawn behind, on its
    own axis.

    Parameters
    ----------
    selection : Selection
        The result of :func:`flexid.select`.

    Returns
    -------
    matplotlib.figure.Figure or None
        None with fewer than two orders of one linear structure.
    """
    linear = [c for c in selection.candidates
              if c.ok and hasattr(c.model, "frequency_response")]  # fmt: skip
    if not linear:
        return None
    kind = selection.best.kind if selection.best in linear else linear[0].kind
    rows = _stabilisation_rows(selection, linear, kind)
    if len({order for order, _, _ in rows}) < 2:
        return None
    fig, ax = _axes(None, figsize=(8.0, 4.8))
    estimate = _held_out_estimate(selection)
    if estimate is not None:
        _draw_held_out_magnitude(ax, estimate)
    _draw_stabilisation_modes(ax, rows)
    ax.set_xscale("log")
    ax.set_xlabel("natural frequency [Hz]")
    ax.set_ylabel("model order (poles) [-]")
    name = "grey-box" if kind == "greybox" else kind.upper()
    ax.set_title(f"Stabilisation diagram: {name} candidates (vs the next lower order: "
                 "1 % in frequency, 5 % in damping)", fontsize=10)  # fmt: skip
    ax.grid(True, which="both", alpha=0.3)
    _readable_log_ticks(ax)
    if estimate is not None:
        ax.set_xlim(estimate.frequency[0], estimate.frequency[-1])
    handles, labels = ax.get_legend_handles_labels()
    order = sorted(range(len(labels)), key=lambda i: ["stable", "stable in frequency",
                                                      "new"].index(labels[i]))  # fmt: skip
    ax.legend([handles[i] for i in order], [labels[i] for i in order], loc="upper left",
              bbox_to_anchor=(1.12, 1.0), frameon=False)  # fmt: skip
    return fig


def _stabilisation_rows(
    selection: Selection, linear: list, kind: str
) -> list[tuple[int, np.ndarray, np.ndarray]]:
    """``(order, natural frequencies, damping ratios)`` of the oscillating modes of one
    candidate of ``kind`` per order: the best ranked of those with that many poles."""
    from ..models.modes import model_modes

    def order(found: list) -> int:  # each mode once, however many inputs repeat it
        return sum(2 if m.kind == "pair" else 1 for m in found)

    per_order: dict[int, tuple] = {}
    for c in selection.ranked():
        if c in linear and c.kind == kind:
            found = model_modes(c.model)
            per_order.setdefault(order(found), (c, found))
    rows = []
    for n in sorted(per_order):
        pairs = [m for m in per_order[n][1] if m.kind == "pair" and 0 < m.damping < 1]
        rows.append((n, np.array([m.frequency for m in pairs]),
                     np.array([m.damping for m in pairs])))  # fmt: skip
    return rows


def _draw_held_out_magnitude(ax: Any, estimate: Any) -> None:
    """The held-out record's estimated magnitude behind ``ax``, on an axis of its own."""
    back = ax.twinx()
    power = np.sqrt(np.sum(np.abs(estimate.response) ** 2, axis=(1, 2)))
    back.plot(estimate.frequency, 20 * np.log10(np.maximum(power, 1e-300)), color="0.75",
              lw=1, zorder=0)  # fmt: skip
    back.set_ylabel("held-out record's magnitude [dB]", color="0.5")
    back.tick_params(axis="y", colors="0.5")
    ax.set_zorder(back.get_zorder() + 1)
    ax.patch.set_visible(False)


def _mode_marker(
    prev_f: np.ndarray, prev_z: np.ndarray, fi: float, zi: float
) -> tuple[dict[str, str], str]:
    """The marker style and legend label of a mode against the modes of the next lower
    order: stable, stable in frequency only, or new."""
    near = np.abs(prev_f - fi) <= _STABLE_FREQUENCY * fi
    if near.any() and np.any(np.abs(prev_z[near] - zi) <= _STABLE_DAMPING * zi):
        return {"marker": "o", "mfc": "k", "mec": "k"}, "stable"
    if near.any():
        return {"marker": "o", "mfc": "white", "mec": "k"}, "stable in frequency"
    return {"marker": "x", "color": "0.45"}, "new"


def _draw_stabilisation_modes(ax: Any, rows: list[tuple[int, np.ndarray, np.ndarray]]) -> None:
    """One marker per mode and order, each label in the legend once."""
    seen = set()
    for k, (order, f, zeta) in enumerate(rows):
        lower = [r for r in rows[:k] if r[0] < order]
        prev_f, prev_z = (lower[-1][1], lower[-1][2]) if lower else (np.zeros(0), np.zeros(0))
        for fi, zi in zip(f, zeta):
            style, label = _mode_marker(prev_f, prev_z, fi, zi)
            ax.plot(fi, order, ls="none", ms=6, label=None if label in seen else label, **style)
            seen.add(label)


def _draw_candidates(ax, drawn, kinds, value, low: float, floor: float) -> None:
    """One line (the best value at each ``d``) and one marker per candidate, per structure."""
    for kind in kinds:
        color, marker = _STRUCTURE_STYLE.get(kind, _STRUCTURE_STYLE["polynomial"])
        group = sorted((c for c in drawn if c.kind == kind), key=lambda c: c.n_params)
        d = np.array([c.n_params for c in group], float)
        v = np.array([value(c) for c in group], float)
        if value is _fit:  # clipped fits (and diverging runs) on the lower edge
            v = np.where(v >= low, v, floor)
        # the line joins the best value at each d (ARMAX and BJ have several per d)
        ds = np.unique(d)
        best = [np.nanmax(v[d == x]) if value is _fit else np.nanmin(v[d == x]) for x in ds]
        name = "grey-box" if kind == "greybox" else kind.upper()
        ax.plot(ds, best, "-", color=color, lw=1.2, alpha=0.7, label=name)
        for c, x, y in zip(group, d, v):
            clipped = value is _fit and not (c.fit_simulation >= low)
            ax.plot(
                x,
                y,
                "v" if clipped else marker,
                ms=7,
                mec=color,
                mew=1.5,
                mfc=color if c.passed else "white",
                zorder=3,
            )
            if not c.stable:
                ax.plot(x, y, "x", ms=9, mew=1.5, color="k", zorder=4)


def _marker_legend(ax, drawn, low: float) -> None:
    """The legend: the structures, then what the marker styles mean."""
    ax.plot([], [], "o", mec="0.3", mfc="0.3", label="passes tests")
    ax.plot([], [], "o", mec="0.3", mfc="white", label="fails tests")
    if any(not c.stable for c in drawn):
        ax.plot([], [], "x", color="k", mew=1.5, label="unstable")
    if any(not (c.fit_simulation >= low) for c in drawn):
        ax.plot([], [], "v", mec="0.3", mfc="white", label=f"fit < {low:.0f} %")
    ax.legend(loc="lower right", fontsize=8, ncol=2)


def _mark_recommendation(ax, best, low: float, floor: float, x_mid: float) -> str:
    """Ring and label the recommended candidate; the title's line about it."""
    # the label points at its marker from the side with more room
    side = 1 if best.n_params > x_mid else -1
    y = best.fit_simulation if best.fit_simulation >= low else floor
    word = "recommended" if best.passed and best.stable else "fallback (fails the tests)"
    ax.plot(best.n_params, y, "o", ms=17, mfc="none", mec="k", mew=2, zorder=5)
    ax.annotate(
        word,
        xy=(best.n_params, y),
        xytext=(-14 * side, -34),
        textcoords="offset points",
        ha="right" if side > 0 else "left",
        fontsize=9,
        fontweight="bold",
        bbox={"boxstyle": "round", "fc": "lightyellow", "ec": "0.5"},
        arrowprops={"arrowstyle": "->", "color": "k", "lw": 1.2},
        zorder=6,
    )
    return (
        f"\n{word}: {best.label}, held-out simulation fit "
        f"{best.fit_simulation:.2f} %, d = {best.n_params}"
    )


def _criterion_panel(ax, drawn, kinds, best, x_mid: float) -> None:
    """The AIC panel: the same styles, the recommendation ringed, the AIC's own minimum."""
    from matplotlib.ticker import MaxNLocator

    _draw_candidates(ax, drawn, kinds, _aic, -np.inf, -np.inf)
    if best is not None and best.ok:
        ax.plot(best.n_params, _aic(best), "o", ms=17, mfc="none", mec="k", mew=2)
    scored = [c for c in drawn if np.isfinite(_aic(c))]
    if scored:
        low_aic = min(scored, key=_aic)
        if low_aic is not best:
            left = 1 if low_aic.n_params > x_mid else -1
            ax.annotate(
                f"AIC minimum:\n{low_aic.label}",
                xy=(low_aic.n_params, _aic(low_aic)),
                xytext=(-14 * left, 30),
                textcoords="offset points",
                ha="right" if left > 0 else "left",
                fontsize=8,
                bbox={"boxstyle": "round", "fc": "white", "ec": "0.5"},
                arrowprops={"arrowstyle": "->", "color": "0.3"},
            )
    ax.set_xlabel("number of parameters d")
    ax.set_ylabel("normalized AIC, log V + 2d/K")
    ax.set_title("Information criterion (estimation data)")
    ax.grid(True, alpha=0.3)
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))


def _fit(c) -> float:
    return c.fit_simulation


def _aic(c) -> float:
    return c.aic_normalized


# ================================================================================ suite
def _suite_panel(
    ax, ecdf: Mapping[str, Mapping[str, Any]], styles: Mapping[str, dict], budget: float,
    title: str,
) -> None:
    """One runtime-distribution panel: a step curve per optimiser, in its own style."""
    for label, style in styles.items():
        curve = ecdf[label]
        x = np.concatenate([[1.0], np.maximum(curve["x"], 1.0), [budget]])
        last = curve["fraction"][-1] if curve["fraction"].size else 0.0
        f = np.concatenate([[0.0], curve["fraction"], [last]])
        ax.step(x, f, where="post", lw=1.5, **style)
    ax.set_xscale("log")
    ax.set_xlim(1.0, budget)
    ax.set_ylim(-0.02, 1.02)
    ax.set_title(title, fontsize=10)
    _readable_log_ticks(ax)
    ax.grid(True, which="both", alpha=0.3)


def suite_figure(
    result: Any, path: str | Path | None = None, *, by: str | None = "structure"
) -> Figure | Path:
    """Runtime distributions of a suite: every problem, and per group (COCO's ECDF).

    The left panel aggregates every (problem, target, run) triple of the suite; the others
    split the problems by ``by`` (one panel per value).  A curve rises when a run first gets
    within ``reference * (1 + d)`` of a problem's reference, for the 31 precisions ``d`` from
    100 to 1e-4 (:data:`flexid.jobs.suite.PRECISIONS`); the legend gives each optimiser's area
    under its curve (1: every target at the first evaluation), best first.

    Parameters
    ----------
    result : SuiteResult
        From :func:`flexid.jobs.suite.run_suite` or :func:`flexid.jobs.suite.load_suite`.
    path : str or pathlib.Path, optional
        Write the figure there as a PNG (and close it).
    by : {"structure", "plant", "cost"} or None
        The group of the other panels; None draws the aggregate alone.

    Returns
    -------
    matplotlib.figure.Figure or pathlib.Path
        The figure, or ``path`` when one is given.
    """
    plt = _plt()
    budget = float(result.suite.budget_per_dim)
    values: list[str] = []
    if by is not None:
        values = list(dict.fromkeys(
            p.groups[by] for p in result.suite.problems if p.name in result.results
        ))  # fmt: skip
    overall = result.ecdf()
    # one style per optimiser in every panel, best aggregate area first
    ranked = sorted(overall, key=lambda label: -overall[label]["area"])
    styles = {label: _style(i) for i, label in enumerate(ranked)}
    n = 1 + len(values)
    cols = min(n, 3)
    rows = -(-n // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4.3 * cols + 2.6, 3.6 * rows), squeeze=False,
                             sharex=True, sharey=True, layout="constrained")  # fmt: skip
    panels = list(axes.flat)
    _suite_panel(panels[0], overall, styles, budget, f"all {len(result.results)} problems")
    for ax, value in zip(panels[1:], values):
        count = sum(p.groups[by] == value for p in result.suite.problems
                    if p.name in result.results)  # fmt: skip
        _suite_panel(ax, result.ecdf({by: value}), styles, budget,
                     f"{by} {value} ({count} problem{'s' if count != 1 else ''})")  # fmt: skip
    for ax in panels[n:]:
        ax.set_visible(False)
    for ax in axes[:, 0]:
        ax.set_ylabel("fraction of triples reached [-]")
    for ax in panels[:n]:
        ax.set_xlabel("function evaluations / dimension")
        ax.tick_params(labelbottom=True)
    handles = [plt.Line2D([], [], lw=1.5, **styles[label]) for label in ranked]
    names = [f"{label}  {overall[label]['area']:.2f}" for label in ranked]
    fig.legend(handles, names, loc="outside right upper", fontsize=8, frameon=False,
               title="optimiser, area\n(all problems)", title_fontsize=8)  # fmt: skip
    fig.suptitle(
        f"{result.suite.label} {result.version}: (problem, target, run) triples reached; "
        f"{result.suite.runs} runs of {result.suite.budget_per_dim} FE per dimension, "
        "targets reference x (1 + d), d = 100 ... 1e-4",
        fontsize=10,
    )
    if path is not None:
        return _save(fig, Path(path))
    return fig
