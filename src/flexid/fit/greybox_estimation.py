"""The search problem of a grey-box identification, in the interface the polynomial ones share.

:func:`flexid.fit.estimation.build_problem` returns a :class:`GreyBoxEstimationProblem` for a
:class:`~flexid.models.greybox.GreyBoxModel`, so ``identify`` and ``compare`` run a grey-box model
exactly as they run a polynomial structure: every optimiser searches the same
:class:`~flexid.optimisers.Problem` (the estimated parameters in their bounds, ``log10`` of
those that span decades) with the same shared initial population and exact budget, and the
gradient reference is :func:`flexid.fit.greybox_fit.greyest` (Levenberg-Marquardt on the
simulation residuals from several starts).  The cost is the simulation (output-error) cost:
a grey-box model has no one-step predictor.

Where a polynomial problem has least squares (the start of its searches and a row of every
comparison), a grey-box problem has the model's parameter values as given: the user's
nominal values, the start of the reference.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from ..costs.greybox import GreyBoxCost
from ..errors import ConfigError
from ..models.greybox import GreyBoxModel
from ..models.specs import CostSpec, SearchSpec
from ..models.vocabulary import GREYBOX_REFERENCE_STARTS
from ..optimisers import Problem
from .parametrisation import SearchBox
from .reference import StartOrReference, _simulation_in_own_bounds

if TYPE_CHECKING:
    from .greybox_fit import GreyBoxResult

__all__ = ["GreyBoxEstimationProblem", "build_greybox_problem"]

#: What a grey-box problem's "least squares" row is: the parameters' given values.
START_NAME = "nominal values"
#: The reference of a grey-box problem, in words.
REFERENCE_NAME = (
    "grey-box reference (Levenberg-Marquardt on the simulation residuals, several starts)"
)


@dataclass
class GreyBoxEstimationProblem(StartOrReference):
    """The search problem of a grey-box identification, and how to read its results.

    Attributes
    ----------
    structure : GreyBoxModel
        The model as given: its parameters' values are the start, its bounds the box.
    cost : GreyBoxCost
        The simulation cost on the estimation record, in the estimated parameters' values.
    problem : Problem
        What the optimisers minimise, over the search coordinates.
    search : SearchSpec
        Recorded only: a grey-box model is searched in its parameters' own bounds.
    box : SearchBox
        The search coordinates' bounds and the rule that made them.
    box_rule : str
        The same rule, for reports.
    """

    structure: GreyBoxModel
    cost: GreyBoxCost
    problem: Problem
    search: SearchSpec
    box: Any
    box_rule: str
    _ref: Any = field(default=None, repr=False)
    start_name: ClassVar[str] = START_NAME
    reference_name: ClassVar[str] = REFERENCE_NAME

    @property
    def theta_ls(self) -> np.ndarray:
        """The start: the estimated parameters' given values, shape (n_free,)."""
        return self.structure.theta

    @cached_property
    def cost_ls(self) -> float:
        """The cost at :attr:`theta_ls` (one simulation, made once)."""
        return float(self.cost(self.theta_ls[None, :])[0])

    def theta(self, z: Any) -> np.ndarray:
        """The estimated parameters' values of search vectors (clipped to their bounds).

        Parameters
        ----------
        z : array_like, shape (P, n_free) or (n_free,)

        Returns
        -------
        ndarray, same shape
        """
        return self.cost.values(z)  # the map the optimisers' objective uses

    def describe(self) -> str:
        """One line: what is searched and on which scale.

        Returns
        -------
        str
        """
        model = self.structure
        scales = [
            f"{p.name} ({'log' if p.log else 'linear'})"
            for p in model.parameters
            if not p.fixed
        ]
        fixed = [p.name for p in model.parameters if p.fixed]
        text = f"{model.n_free} physical parameters in their bounds: {', '.join(scales)}"
        if fixed:
            text += f"; fixed: {', '.join(fixed)}"
        return text

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe description of the search.

        Returns
        -------
        dict
        """
        return {
            "parametrisation": {"name": "greybox", "parameters": list(self.structure.free)},
            "box_rule": self.box_rule,
        }

    def output_error_reference(
        self, *, starts: int = GREYBOX_REFERENCE_STARTS, seed: int = 0
    ) -> GreyBoxResult:
        """The gradient reference, :func:`flexid.fit.greybox_fit.greyest`, from the given values.

        Cached for the last ``(starts, seed)``.

        Parameters
        ----------
        starts : int, optional
            Random starts after the first (the given values); default 3.
        seed : int, optional
            Seed of the random starts.

        Returns
        -------
        GreyBoxResult
            With ``cost`` the problem's cost at ``x`` (its metric, not greyest's RMSE) and
            ``wall_time`` including the cost's setting up.
        """
        if self._ref is None or self._ref[0] != (starts, seed):
            from .greybox_fit import greyest

            t0 = time.perf_counter()
            ref = greyest((self.cost.u, self.cost.y), self.structure, starts=starts,
                          seed=seed, dt=self.cost.dt)  # fmt: skip
            ref["cost"] = float(self.cost(ref.x[None, :])[0])
            ref["wall_time"] = time.perf_counter() - t0
            self._ref = ((starts, seed), ref)
        return self._ref[1]


def build_greybox_problem(
    est: Any, model: GreyBoxModel, cost: CostSpec, search: SearchSpec, *, bounds: Any = "auto"
) -> GreyBoxEstimationProblem:
    """:func:`flexid.fit.estimation.build_problem` for a grey-box model.

    Parameters
    ----------
    est : IOData
        Estimation record, read by the model's channel names.
    model : GreyBoxModel
    cost : CostSpec
        Its ``metric`` and ``weight``; the predictor must be ``"simulation"``.
    search : SearchSpec
        Recorded only.
    bounds : "auto"
        A grey-box model is searched in its parameters' bounds; change them on the model
        (:meth:`GreyBoxModel.with_parameters <flexid.models.greybox.GreyBoxModel.with_parameters>`).

    Returns
    -------
    GreyBoxEstimationProblem

    Raises
    ------
    ConfigError
        The one-step predictor, other bounds, or a model with nothing to estimate.
    DataError
        A record without the model's channels.
    """
    _simulation_in_own_bounds(
        cost, bounds,
        f"grey-box model {model.name!r} is fitted on the simulation cost (it has no one-step "
        "predictor):",
        f"grey-box model {model.name!r} is searched in its parameters' own bounds: set them on "
        "the model (--set NAME=VALUE, with_parameters)",
    )  # fmt: skip
    if model.n_free == 0:
        raise ConfigError(f"grey-box model {model.name!r} has no estimated parameter")
    objective = GreyBoxCost(model, est, metric=cost.metric, weight=cost.weight)
    lower, upper = model.search_bounds()
    rule = "each parameter's own bounds (log10 where they span two decades or more)"
    return GreyBoxEstimationProblem(
        structure=model,
        cost=objective,
        problem=objective.problem(),
        search=search,
        box=SearchBox(lower, upper, rule),
        box_rule=rule,
    )
