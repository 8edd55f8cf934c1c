"""What a run records: the best-cost history and the per-iteration callback information."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["History", "IterationInfo"]


class History:
    """Best cost against function evaluations, one row per iteration.

    Attributes
    ----------
    fe : ndarray of int, shape (T,)
        FE used at the end of each iteration (cumulative).
    iteration : ndarray of int, shape (T,)
        Iteration index (0 = initial evaluation).
    phase : list of str, length T
        Phase name (``"init"``, ``"chemotaxis"``, ``"spiral"``...).
    best : ndarray of float, shape (T,)
        Best cost found so far (non-increasing).
    """

    def __init__(self) -> None:
        self._fe: list[int] = []
        self._it: list[int] = []
        self._phase: list[str] = []
        self._best: list[float] = []

    def append(self, fe: int, iteration: int, phase: str, best: float) -> None:
        """Add the row of one iteration.

        Parameters
        ----------
        fe : int
            Cumulative function evaluations at the end of the iteration.
        iteration : int
            Iteration index (0 = initial evaluation).
        phase : str
            Phase name of the algorithm.
        best : float
            Best cost found so far.
        """
        self._fe.append(fe)
        self._it.append(iteration)
        self._phase.append(phase)
        self._best.append(best)

    @property
    def fe(self) -> np.ndarray:
        """FE used at the end of each iteration (cumulative), int64, shape (T,)."""
        return np.asarray(self._fe, dtype=np.int64)

    @property
    def iteration(self) -> np.ndarray:
        """Iteration index of each row (0 = initial evaluation), int64, shape (T,)."""
        return np.asarray(self._it, dtype=np.int64)

    @property
    def phase(self) -> list[str]:
        """Phase name of each row, a list of T str (a copy)."""
        return list(self._phase)

    @property
    def best(self) -> np.ndarray:
        """Best cost found so far at each row, float, shape (T,)."""
        return np.asarray(self._best, dtype=float)

    def __len__(self) -> int:
        return len(self._fe)

    def best_at(self, fe: Any) -> np.ndarray:
        """Best cost after a number of function evaluations (a step function of the rows).

        Parameters
        ----------
        fe : int or array_like of int
            Function-evaluation counts.

        Returns
        -------
        float or ndarray
            Best cost of the last row with ``fe`` at most the given count, same shape as
            ``fe``; ``inf`` before the first row.
        """
        fe = np.asarray(fe)
        idx = np.searchsorted(self.fe, fe, side="right") - 1
        best = np.concatenate([[np.inf], self.best])
        return best[idx + 1]

    def fe_to_reach(self, target: float) -> int | None:
        """Fewest function evaluations after which the best cost is at most ``target``.

        Parameters
        ----------
        target : float
            Cost to reach.

        Returns
        -------
        int or None
            FE of the first row with ``best <= target`` (row resolution), or None when no
            row reaches it.
        """
        hits = np.flatnonzero(self.best <= target)
        return int(self.fe[hits[0]]) if hits.size else None

    def to_dict(self) -> dict[str, list]:
        """The rows as plain lists, for JSON; :meth:`from_dict` restores them.

        Returns
        -------
        dict of str to list
            ``fe`` (int), ``iteration`` (int), ``phase`` (str) and ``best`` (float), T
            values each.
        """
        return {
            "fe": list(self._fe),
            "iteration": list(self._it),
            "phase": list(self._phase),
            "best": [float(b) for b in self._best],
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, list]) -> History:
        """Rebuild a history from :meth:`to_dict` output.

        Parameters
        ----------
        data : mapping of str to list
            ``fe``, ``iteration``, ``phase`` and ``best``, one value per row (values beyond
            the shortest list are dropped).

        Returns
        -------
        History
            The history.
        """
        history = cls()
        for row in zip(data["fe"], data["iteration"], data["phase"], data["best"]):
            history.append(int(row[0]), int(row[1]), str(row[2]), float(row[3]))
        return history

    def __repr__(self) -> str:
        if not self._fe:
            return "History(empty)"
        return f"History({len(self)} rows, fe={self._fe[-1]}, best={self._best[-1]:.6g})"


@dataclass(frozen=True)
class IterationInfo:
    """What a callback receives after each iteration.

    A callback returning ``True`` stops the run (message ``"stopped by callback"``).

    Attributes
    ----------
    fe : int
        Function evaluations used so far.
    iteration : int
        Index of the iteration that just ended.
    phase : str
        Its phase name.
    best : float
        Best cost found so far.
    x_best : ndarray, shape (n,)
        The point of ``best``, in the problem's box (original units); a copy.
    elapsed : float
        Wall time since the start of the run, in seconds.
    max_fe : int or None
        The run's FE budget (None without one).
    """

    fe: int
    iteration: int
    phase: str
    best: float
    x_best: np.ndarray
    elapsed: float
    max_fe: int | None
