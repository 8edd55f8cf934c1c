"""The cost metrics: one table of name, formula and description, and the one conversion.

Every cost of flexid (:class:`~flexid.costs.arx.ARXCost`,
:class:`~flexid.costs.polynomial.PolynomialCost`, :class:`~flexid.costs.greybox.GreyBoxCost`)
turns the sums of squared errors of a population into its metric by :func:`metric_from_sse`,
and the names it accepts, the command line's help and the documentation's table of metrics
are read from :data:`METRIC_TABLE`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import UnknownNameError

__all__ = [
    "METRICS",
    "METRIC_TABLE",
    "Metric",
    "cost_label",
    "describe_cost",
    "metric_from_sse",
    "metrics_rst",
]


@dataclass(frozen=True)
class Metric:
    """One cost metric.

    Attributes
    ----------
    name : str
        Its name in specs, the command line and results.
    formula : str
        In terms of ``SSE`` (sum of squared errors over the ``K`` error samples), ``w`` (the
        paper cost's weight) and ``std(y)`` (the output's standard deviation over them).
    description : str
        One sentence.
    from_sse : callable
        ``from_sse(sse, K, w, std_y) -> metric``, elementwise over a population's ``sse``.
    words : str
        The metric in plain words, with ``{errors}`` for what is squared and ``{w}`` for the
        weight (:func:`describe_cost`).
    label : str
        A few words for an axis (:func:`cost_label`).
    power : int
        The power of the output's unit the metric carries (0: none).
    """

    name: str
    formula: str
    description: str
    from_sse: Callable[[np.ndarray, int, float, float], np.ndarray]
    words: str = ""
    label: str = ""
    power: int = 1


#: The metrics, by name; the first is the default.
METRIC_TABLE: dict[str, Metric] = {
    m.name: m
    for m in (
        Metric(
            "paper", "w sqrt(SSE) / K",
            "Nasir & Tokhi's eq. 5-6 (w = 1000), plus a penalty for an unstable candidate",
            lambda sse, k, w, s: np.sqrt(sse) * (w / k),
            "{w} x the root of the sum of squared {errors}, divided by their number (the "
            "paper's cost, eq. 5-6)",
            "paper cost, w sqrt(SSE) / K",
        ),
        Metric(
            "rmse", "sqrt(SSE / K)", "root mean squared error, in the output's unit",
            lambda sse, k, w, s: np.sqrt(sse / k),
            "root-mean-square {errors}",
            "RMS error",
        ),
        Metric(
            "nrmse", "sqrt(SSE / K) / std(y)",
            "root mean squared error over the output's standard deviation (no unit)",
            lambda sse, k, w, s: np.sqrt(sse / k) / (s if s > 0 else 1.0),
            "root-mean-square {errors} over the output's standard deviation",
            "RMS error / std(y)",
            0,
        ),
        Metric(
            "sse", "SSE", "sum of squared errors, in the output's unit squared",
            lambda sse, k, w, s: sse,
            "sum of squared {errors}",
            "sum of squared errors",
            2,
        ),
        Metric(
            "mse", "SSE / K", "mean squared error, in the output's unit squared",
            lambda sse, k, w, s: sse / k,
            "mean squared {errors}",
            "mean squared error",
            2,
        ),
    )
}

#: The metrics' names, the default first.
METRICS: tuple[str, ...] = tuple(METRIC_TABLE)


def describe_cost(
    metric: str, errors: str, k: int, weight: float = 1000.0,
    penalty: float | None = None, graded: bool = False,
) -> str:
    """A cost in plain words: what is squared, over how many samples, and the penalty.

    Parameters
    ----------
    metric : str
        A name of :data:`METRIC_TABLE`.
    errors : str
        What the errors are, e.g. ``"one-step prediction errors of OE(nb=2, nf=2, nk=1)"``.
    k : int
        Number of error samples.
    weight : float, optional
        ``w`` of the paper's cost.
    penalty : float, optional
        The stability penalty (None: no penalty is said).
    graded : bool, optional
        The penalty grows with the largest pole radius (``penalty * radius``).

    Returns
    -------
    str
        For example ``"1000 x the root of the sum of squared one-step prediction errors of
        OE(nb=2, nf=2, nk=1), divided by their number (the paper's cost, eq. 5-6), over
        K = 997 samples; an unstable candidate costs the zero prediction's cost plus 1e+09 x
        its largest pole radius"``.
    """
    text = METRIC_TABLE[metric].words.format(errors=errors, w=f"{weight:g}")
    text += f", over K = {k} samples"
    if penalty is not None:
        scale = " x its largest pole radius" if graded else ""
        text += (f"; an unstable candidate costs the zero prediction's cost plus "
                 f"{penalty:g}{scale}")  # fmt: skip
    return text


def cost_label(metric: str, unit: str = "") -> str:
    """An axis label of a cost: the metric in a few words and its unit.

    Parameters
    ----------
    metric : str
        A name of :data:`METRIC_TABLE`.
    unit : str, optional
        The output's unit (``""``: unknown, said as "output unit").

    Returns
    -------
    str
        For example ``"RMS error [deg]"``, ``"mean squared error [(deg)^2]"``,
        ``"RMS error / std(y) [-]"``.
    """
    m = METRIC_TABLE[metric]
    base = unit or "output unit"
    if m.power == 0:
        return f"{m.label} [-]"
    if m.power == 1:
        return f"{m.label} [{base}]"
    return f"{m.label} [({base})^{m.power}]"


def metric_from_sse(
    metric: str, sse: np.ndarray, k: int, weight: float, std_y: float
) -> np.ndarray:
    """A cost metric from sums of squared errors over ``k`` samples (the one conversion).

    Parameters
    ----------
    metric : str
        A name of :data:`METRIC_TABLE`.
    sse : ndarray
        Sums of squared errors (output units squared).
    k : int
        Number of error samples.
    weight : float
        ``w`` of the paper's cost.
    std_y : float
        Standard deviation of the output over the error samples (``nrmse``).

    Returns
    -------
    ndarray
        Like ``sse``.

    Raises
    ------
    UnknownNameError
        An unknown metric (the message lists them).
    """
    try:
        entry = METRIC_TABLE[metric]
    except (KeyError, TypeError):
        raise UnknownNameError("cost metric", metric, METRICS) from None
    return entry.from_sse(sse, k, weight, std_y)


def metrics_rst() -> str:
    """The table of metrics as reStructuredText (for the documentation).

    Returns
    -------
    str
        A ``list-table`` of name, formula and description.
    """
    lines = [".. list-table::", "   :header-rows: 1", "", "   * - metric", "     - formula",
             "     - what it is"]
    for m in METRIC_TABLE.values():
        lines += [f"   * - ``{m.name}``", f"     - ``{m.formula}``", f"     - {m.description}"]
    return "\n".join(lines) + "\n"


__doc__ = f"{__doc__}\nThe metrics:\n\n{metrics_rst()}"
