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
        self._fe.append(fe)
        self._it.append(iteration)
        self._phase.append(phase)
        self._best.append(best)

    @property
    def fe(self) -> np.ndarray:
        return np.asarray(self._fe, dtype=np.int64)

    @property
    def iteration(self) -> np.ndarray:
        return np.asarray(self._it, dtype=np.int64)

    @property
    def phase(self) -> list[str]:
        return list(self._phase)

    @property
    def best(self) -> np.ndarray:
        return np.asarray(self._best, dtype=float)

    def __len__(self) -> int:
        return len(self._fe)

    def best_at(self, fe: Any) -> np.ndarray:
        """Best cost after ``fe`` evaluations (step function; ``inf`` before the first row)."""
        fe = np.asarray(fe)
        idx = np.searchsorted(self.fe, fe, side="right") - 1
        best = np.concatenate([[np.inf], self.best])
        return best[idx + 1]

    def fe_to_reach(self, target: float) -> int | None:
        """Fewest FE after which the best cost is ``<= target`` (row resolution), or None."""
        hits = np.flatnonzero(self.best <= target)
        return int(self.fe[hits[0]]) if hits.size else None

    def to_dict(self) -> dict[str, list]:
        """Plain lists, for JSON."""
        return {
            "fe": list(self._fe),
            "iteration": list(self._it),
            "phase": list(self._phase),
            "best": [float(b) for b in self._best],
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, list]) -> History:
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
    """

    fe: int
    iteration: int
    phase: str
    best: float
    x_best: np.ndarray
    elapsed: float
    max_fe: int | None
