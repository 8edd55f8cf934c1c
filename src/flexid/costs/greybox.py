"""The simulation (output-error) cost of a grey-box model, for a population of parameter sets.

``X`` of shape ``(P, n_free)`` (the estimated parameters' physical values, in the order of
:attr:`GreyBoxModel.free <flexid.models.greybox.GreyBoxModel.free>`) in, ``(P,)`` costs out.  Each
row is simulated from the model's initial state over the whole record (one batched run,
:meth:`GreyBoxModel.simulate <flexid.models.greybox.GreyBoxModel.simulate>`) and scored on the
error ``y - y_sim`` by the metrics of :data:`flexid.costs.arx.METRICS`.  With several outputs
each output's error is divided by that output's standard deviation first, so that outputs in
different units weigh alike (the costs are then dimensionless).

A row whose simulation overflows (a parameter set that makes the model blow up) costs
``+inf`` and is counted in :attr:`GreyBoxCost.n_diverged`; the evaluation of the others goes
on.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .._validate import real
from ..errors import DataError, UnknownNameError
from ..models.greybox import GreyBoxModel
from ..models.specs import CostSpec
from ..optimisers import Problem
from .arx import METRICS, metric_from_sse, population
from .metrics import describe_cost

__all__ = ["GreyBoxCost", "record_for"]

_DEFAULT = CostSpec()


def record_for(model: GreyBoxModel, data: Any, dt: float | None = None) -> tuple:
    """The inputs, outputs and sample time a grey-box model reads from a record.

    Parameters
    ----------
    model : GreyBoxModel
    data : IOData or (u, y)
        An :class:`~flexid.data.IOData` is read by column name (the model's ``inputs`` and
        ``outputs``, or the columns and unit factors of
        :meth:`GreyBoxModel.reading <flexid.models.greybox.GreyBoxModel.reading>`); a
        ``(u, y)`` pair by position, in the model's units.
    dt : float, optional
        Sample time [s] of a ``(u, y)`` pair (an IOData has its own).

    Returns
    -------
    u : ndarray, shape (N, n_u)
    y : ndarray, shape (N, n_y)
    dt : float

    Raises
    ------
    DataError
        A channel the model reads that the record does not have (named), a pair with the
        wrong number of columns, non-finite samples, a missing sample time.
    """
    from ..data.records import IOData

    if isinstance(data, IOData):
        picked = []
        for kind, wanted, have, values in (
            ("input", model.inputs, data.input_names, data.u),
            ("output", model.outputs, data.output_names, data.y),
        ):
            columns = [model.column(name) for name in wanted]
            missing = [column for column, _ in columns if column not in have]
            if missing:
                raise DataError(
                    f"grey-box model {model.name!r} reads {kind} column(s) {missing}, which "
                    f"the record does not have (its {kind}s: {list(have)}); map the model's "
                    f"channels {list(wanted)} to the record's columns with "
                    "GreyBoxModel.reading (--channels)"
                )
            index = [list(have).index(column) for column, _ in columns]
            picked.append(values[:, index] * np.array([f for _, f in columns]))
        u, y, dt = picked[0], picked[1], float(data.dt)
    else:
        try:
            u, y = data
        except (TypeError, ValueError):
            raise DataError("data must be an IOData or a (u, y) pair") from None
        u = np.asarray(u, dtype=float)
        y = np.asarray(y, dtype=float)
        u = u[:, None] if u.ndim == 1 else u
        y = y[:, None] if y.ndim == 1 else y
        for what, arr, count in (("u", u, len(model.inputs)), ("y", y, len(model.outputs))):
            if arr.ndim != 2 or arr.shape[1] != count:
                raise DataError(
                    f"grey-box model {model.name!r}: {what} must have {count} column(s), got "
                    f"shape {arr.shape}"
                )
        if u.shape[0] != y.shape[0]:
            raise DataError(f"u has {u.shape[0]} samples, y {y.shape[0]}")
        if dt is None:
            raise DataError("a (u, y) pair needs the sample time dt")
        dt = real(dt, "dt", error=DataError, minimum=0, low_open=True)
    for what, arr in (("input", u), ("output", y)):
        if not np.isfinite(arr).all():
            raise DataError(f"the record's {what} holds NaN or inf")
    if y.shape[0] < 2:
        raise DataError(f"a record of {y.shape[0]} sample(s) is too short to fit a model")
    return np.ascontiguousarray(u), np.ascontiguousarray(y), float(dt)


class GreyBoxCost:
    """The cost an optimiser minimises to fit a grey-box model: the simulation error.

    Parameters
    ----------
    model : GreyBoxModel
    data : IOData or (u, y)
        Estimation record (see :func:`record_for`).
    metric : str
        One of :data:`flexid.costs.arx.METRICS` (default the package's default cost).
    weight : float
        ``w`` of the paper's cost.
    dt : float, optional
        Sample time of a ``(u, y)`` pair.

    Attributes
    ----------
    n_params : int
        Estimated parameters ``n_free``.
    K : int
        Error samples per output (the record's length).
    lower, upper : ndarray, shape (n_params,)
        The estimated parameters' bounds (physical units).
    n_diverged : int
        Rows evaluated so far whose simulation overflowed (each cost ``+inf``).
    """

    def __init__(
        self,
        model: GreyBoxModel,
        data: Any,
        *,
        metric: str = _DEFAULT.metric,
        weight: float = _DEFAULT.weight,
        dt: float | None = None,
    ) -> None:
        if not isinstance(model, GreyBoxModel):
            raise DataError(f"model must be a GreyBoxModel, got {type(model).__name__}")
        if metric not in METRICS:
            raise UnknownNameError("cost metric", metric, METRICS)
        self.model = model
        self.metric = metric
        self.weight = real(weight, "weight", error=DataError, minimum=0)
        self.u, self.y, self.dt = record_for(model, data, dt)
        self.K = self.y.shape[0]
        self.n_params = model.n_free
        free = [model.parameter(n) for n in model.free]
        self.lower = np.array([p.lower for p in free])
        self.upper = np.array([p.upper for p in free])
        std = self.y.std(axis=0)
        # one output: errors in its own units; several: each in its standard deviations
        self._scale = np.ones(1) if self.y.shape[1] == 1 else np.where(std > 0, std, 1.0)
        self._target = self.y / self._scale
        self._std = float(std[0]) if self.y.shape[1] == 1 else 1.0
        self.n_diverged = 0

    def residuals(self, X: Any) -> np.ndarray:
        """Scaled simulation errors of a population, every output's errors end to end.

        Parameters
        ----------
        X : array_like, shape (P, n_params) or (n_params,)

        Returns
        -------
        ndarray, shape (P, K * n_y)
            Non-finite where a row's simulation overflowed.
        """
        X = population(X, self.n_params)
        y = self.model.simulate(self.model.full(X), self.u, self.dt)
        with np.errstate(invalid="ignore", over="ignore"):
            e = self._target[None, :, :] - y / self._scale
        return e.transpose(0, 2, 1).reshape(X.shape[0], -1)

    def sse(self, X: Any) -> np.ndarray:
        """Sums of squared (scaled) errors, ``+inf`` for rows that overflowed.

        Parameters
        ----------
        X : array_like, shape (P, n_params) or (n_params,)

        Returns
        -------
        ndarray, shape (P,)
        """
        e = self.residuals(X)
        with np.errstate(invalid="ignore", over="ignore"):
            sse = np.einsum("pk,pk->p", e, e)
        bad = ~np.isfinite(sse)
        sse[bad] = np.inf
        self.n_diverged += int(bad.sum())
        return sse

    def __call__(self, X: Any) -> np.ndarray:
        """Costs of a population.

        Parameters
        ----------
        X : array_like, shape (P, n_params) or (n_params,)
            The estimated parameters' physical values.

        Returns
        -------
        ndarray, shape (P,)
            ``+inf`` for rows whose simulation overflowed.
        """
        sse = self.sse(X)
        with np.errstate(invalid="ignore", over="ignore"):
            return metric_from_sse(self.metric, sse, self.K * self.y.shape[1], self.weight,
                                   self._std)

    def values(self, Z: Any) -> np.ndarray:
        """The estimated parameters' values of search coordinates, within their bounds.

        Parameters
        ----------
        Z : array_like, shape (P, n_params) or (n_params,)
            Search coordinates (``log10`` of a log-scaled parameter); a point outside the
            search box is read as its nearest point of the box.

        Returns
        -------
        ndarray, same shape
            Physical values; ``10 ** log10(bound)`` can round past a bound, so they are
            clipped to the bounds.
        """
        return np.clip(self.model.from_search(Z), self.lower, self.upper)

    def problem(self, name: str = "") -> Problem:
        """The problem an optimiser solves: this cost over the model's search box.

        The optimiser searches the estimated parameters in their search coordinates
        (:meth:`GreyBoxModel.search_bounds <flexid.models.greybox.GreyBoxModel.search_bounds>`:
        ``log10`` of a log-scaled parameter); a point ``z`` costs ``self(from_search(z))``.

        Parameters
        ----------
        name : str
            Label recorded in results (default the model's name).

        Returns
        -------
        flexid.optimisers.Problem
        """
        model = self.model
        lower, upper = model.search_bounds()

        def objective(Z: np.ndarray) -> np.ndarray:
            return self(self.values(Z))

        return Problem(objective, lower, upper, name=name or model.name)

    def describe(self) -> str:
        """One line in plain words: the metric, what is squared, the record's length.

        Returns
        -------
        str
            For example ``"root-mean-square simulation errors of grey-box model
            twin-rotor-pitch (6 estimated parameters), over K = 982 samples"``.
        """
        scaled = " (each output's over its standard deviation)" if self.y.shape[1] > 1 else ""
        errors = (
            f"simulation errors{scaled} of grey-box model {self.model.name} "
            f"({self.n_params} estimated parameters)"
        )
        return describe_cost(self.metric, errors, self.K, self.weight)

    def __repr__(self) -> str:
        return f"GreyBoxCost({self.describe()})"
