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

from .errors import UnknownNameError

__all__ = ["METRICS", "METRIC_TABLE", "Metric", "metric_from_sse", "metrics_rst"]


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
    """

    name: str
    formula: str
    description: str
    from_sse: Callable[[np.ndarray, int, float, float], np.ndarray]


#: The metrics, by name; the first is the default.
METRIC_TABLE: dict[str, Metric] = {
    m.name: m
    for m in (
        Metric(
            "paper", "w sqrt(SSE) / K",
            "Nasir & Tokhi's eq. 5-6 (w = 1000), plus a penalty for an unstable candidate",
            lambda sse, k, w, s: np.sqrt(sse) * (w / k),
        ),
        Metric(
            "rmse", "sqrt(SSE / K)", "root mean squared error, in the output's unit",
            lambda sse, k, w, s: np.sqrt(sse / k),
        ),
        Metric(
            "nrmse", "sqrt(SSE / K) / std(y)",
            "root mean squared error over the output's standard deviation (no unit)",
            lambda sse, k, w, s: np.sqrt(sse / k) / (s if s > 0 else 1.0),
        ),
        Metric(
            "sse", "SSE", "sum of squared errors, in the output's unit squared",
            lambda sse, k, w, s: sse,
        ),
        Metric(
            "mse", "SSE / K", "mean squared error, in the output's unit squared",
            lambda sse, k, w, s: sse / k,
        ),
    )
}

#: The metrics' names, the default first.
METRICS: tuple[str, ...] = tuple(METRIC_TABLE)


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
