"""One cost over several experiments of one system (MATLAB's multi-experiment data).

A model is fitted to several records at once, each with its own initial state: the sum of
squared errors is the sum over the records, each record's errors computed as
:class:`~flexid.costs.polynomial.PolynomialCost` computes them on that record alone (its own
``start``, its own initial-condition rule), and the metric is taken of that pooled sum over
the pooled error samples.  The least-squares start stacks the records' ARX regressors; the
numerator ``B`` fitted by variable projection stacks their regressors, with one block of
free responses per record under ``"estimate"`` (zero over the other records' samples).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ..models.polynomial import INITIAL_RULES, PolynomialStructure
from .polynomial import PolynomialCost

__all__ = ["MultiExperimentCost", "polynomial_cost"]


class MultiExperimentCost(PolynomialCost):
    """:class:`~flexid.costs.polynomial.PolynomialCost` over several records at once.

    Parameters
    ----------
    structure : PolynomialStructure
    records : sequence of IOData or (u, y)
        At least two single-output records with the structure's inputs.
    **settings
        ``metric``, ``predictor``, ``weight``, ``penalty``, ``initial``, ``penalty_kind``
        of :class:`~flexid.costs.polynomial.PolynomialCost`.

    Attributes
    ----------
    parts : list of PolynomialCost
        The cost of each record alone.
    K : int
        Error samples, summed over the records.
    records : tuple of (u, y)
        The records' arrays.
    theta_ls, cost_ls
        The least-squares start (ARX regressors of every record stacked) and its cost.

    Notes
    -----
    Errors, sums of squares and realised errors are those of
    :class:`~flexid.costs.polynomial.PolynomialCost`, over every record: the records'
    counted samples one after another.
    """

    def __init__(
        self, structure: PolynomialStructure, records: Sequence[Any], **settings: Any
    ) -> None:
        self.parts = [PolynomialCost(structure, r, **settings) for r in records]
        first = self.parts[0]
        for name in ("structure", "metric", "predictor", "initial", "weight", "penalty",
                     "penalty_kind", "n_params", "start", "_slices"):  # fmt: skip
            setattr(self, name, getattr(first, name))
        self.records = tuple(pair for c in self.parts for pair in c.records)
        self.K = sum(c.K for c in self.parts)
        self._target = np.concatenate([c._target for c in self.parts])
        self._std_y = float(np.std(self._target))
        self._sse_zero = float(self._target @ self._target)
        self.theta_ls = self._least_squares_start()
        finite = bool(np.isfinite(self.theta_ls).all())
        self.cost_ls = float(self(self.theta_ls)[0]) if finite else float("nan")

    def sse(self, X: np.ndarray) -> np.ndarray:
        return np.sum([c.sse(X) for c in self.parts], axis=0)

    def prediction_errors(self, X: np.ndarray) -> np.ndarray:
        return np.concatenate([c.prediction_errors(X) for c in self.parts], axis=1)

    def _fitted_b(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        # the compiled lag-sum fits solve one record; stacked records take the recursions
        return self._fitted_b_recursions(X)

    def b_regressors(
        self, X: np.ndarray
    ) -> tuple[list[np.ndarray], np.ndarray, list[np.ndarray]]:
        """The records' ``B`` regressors stacked in time, one free-response block per record.

        The bases depend on the candidate only, so every record has the same.

        Parameters
        ----------
        X : ndarray, shape (P, n_params)
            Admissible candidates (their ``B`` entries are ignored).

        Returns
        -------
        blocks : list of ndarray, shapes (P, n_i, K)
            One per input, then each record's free responses (zero outside its samples).
        z : ndarray, shape (P, K)
        bases : list of ndarray, shapes (P, nb_j, nb_j)
            As :meth:`PolynomialCost.b_regressors`.
        """
        parts = [c.b_regressors(X) for c in self.parts]
        n_u = self.structure.n_inputs
        blocks = [np.concatenate([p[0][j] for p in parts], axis=2) for j in range(n_u)]
        edges = np.cumsum([0, *(c.K for c in self.parts)])
        for (own, _, _), lo, hi in zip(parts, edges[:-1], edges[1:]):
            for free in own[n_u:]:  # this record's initial state acts on its samples only
                block = np.zeros((*free.shape[:2], self.K))
                block[:, :, lo:hi] = free
                blocks.append(block)
        return blocks, np.concatenate([p[1] for p in parts], axis=1), parts[0][2]

    def realised_errors(self, theta: np.ndarray) -> np.ndarray | None:
        found = [c.realised_errors(theta) for c in self.parts]
        return None if any(e is None for e in found) else np.concatenate(found)

    def _scope(self) -> str:
        return f" on {len(self.parts)} records ({INITIAL_RULES[self.initial]}, each its own)"

    def __repr__(self) -> str:
        return f"MultiExperimentCost({self.describe()})"


def polynomial_cost(structure: PolynomialStructure, data: Any, **settings: Any) -> PolynomialCost:
    """The cost of ``structure`` on one record, or on several (a list or tuple of records).

    Parameters
    ----------
    structure : PolynomialStructure
    data : IOData, (u, y), or a list or tuple of IOData
    **settings
        As :class:`~flexid.costs.polynomial.PolynomialCost`.

    Returns
    -------
    PolynomialCost or MultiExperimentCost
    """
    from ..data.records import is_records

    if is_records(data):
        if len(data) == 1:
            return PolynomialCost(structure, data[0], **settings)
        return MultiExperimentCost(structure, data, **settings)
    return PolynomialCost(structure, data, **settings)
