"""The stop rules of a run: function-evaluation budget, iterations, target cost, wall time."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import BudgetError

__all__ = ["Budget"]


@dataclass(frozen=True)
class Budget:
    """When a run stops: whichever limit is reached first.

    Parameters
    ----------
    max_fe : int, optional
        Function evaluations (rows passed to the objective), the primary budget.  The
        last batch is truncated so exactly ``max_fe`` rows are evaluated.
    max_iter : int, optional
        Iterations (as the optimiser defines them; the initial evaluation is iteration 0).
    target : float, optional
        Stop as soon as the best cost is ``<= target``.
    max_time : float, optional
        Wall-clock seconds, checked after each batch.

    Raises
    ------
    BudgetError
        If no limit that guarantees termination (``max_fe``, ``max_iter`` or ``max_time``)
        is given, or a limit is not positive.
    """

    max_fe: int | None = None
    max_iter: int | None = None
    target: float | None = None
    max_time: float | None = None

    def __post_init__(self) -> None:
        for name in ("max_fe", "max_iter"):
            value = getattr(self, name)
            if value is not None:
                if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
                    raise BudgetError(f"{name} must be a positive integer, got {value!r}")
                if value < 1:
                    raise BudgetError(f"{name} must be a positive integer, got {value!r}")
                object.__setattr__(self, name, int(value))
        if self.max_time is not None and not (
            isinstance(self.max_time, (int, float)) and self.max_time > 0
        ):
            raise BudgetError(
                f"max_time must be a positive number of seconds, got {self.max_time!r}"
            )
        if self.target is not None and not (
            isinstance(self.target, (int, float)) and not math.isnan(self.target)
        ):
            raise BudgetError(f"target must be a number, got {self.target!r}")
        if self.max_fe is None and self.max_iter is None and self.max_time is None:
            raise BudgetError("a budget needs max_fe, max_iter or max_time")

    @classmethod
    def coerce(cls, budget: Budget | int | Mapping[str, Any] | None) -> Budget:
        """Accept a :class:`Budget`, an FE count, or a mapping of its fields."""
        if isinstance(budget, Budget):
            return budget
        if budget is None:
            raise BudgetError(
                "a budget is required (for example budget=10_000 function evaluations)"
            )
        if isinstance(budget, Mapping):
            try:
                return cls(**budget)
            except TypeError as exc:
                raise BudgetError(f"invalid budget fields: {exc}") from None
        return cls(max_fe=budget)
