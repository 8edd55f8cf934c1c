"""The stop rules of a run: function-evaluation budget, iterations, target cost, wall time."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from .._validate import positive_int, real
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
                object.__setattr__(self, name, positive_int(value, name, error=BudgetError))
        # an infinite max_time or target is no limit: allowed, but NaN is never a limit
        max_time = real(
            self.max_time, "max_time", error=BudgetError, minimum=0, low_open=True,
            allow_inf=True, none_ok=True, unit="s",
        )
        object.__setattr__(self, "max_time", max_time)
        target = real(self.target, "target", error=BudgetError, allow_inf=True, none_ok=True)
        object.__setattr__(self, "target", target)
        if self.max_fe is None and self.max_iter is None and self.max_time is None:
            raise BudgetError("a budget needs max_fe, max_iter or max_time")

    @classmethod
    def coerce(cls, budget: Budget | int | Mapping[str, Any] | None) -> Budget:
        """Make a :class:`Budget` from any of the accepted spellings.

        Parameters
        ----------
        budget : Budget, int or mapping
            A Budget (returned as is), a maximum number of function evaluations, or a
            mapping of Budget fields (``max_fe``, ``max_iter``, ``target``, ``max_time`` in s).

        Returns
        -------
        Budget
            The budget.

        Raises
        ------
        BudgetError
            If ``budget`` is None, a mapping has unknown fields, or the values are invalid.
        """
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
