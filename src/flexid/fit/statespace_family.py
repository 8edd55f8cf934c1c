"""State-space models in the one model interface: the modal search space, n4sid and ssest.

:class:`StateSpaceFamily` builds :class:`~flexid.models.statespace.StateSpaceStructure` from
``structure="ss"`` with ``order`` (and ``modes``), poses it as a
:class:`StateSpaceEstimationProblem` (the modal search space of
:class:`~flexid.fit.statespace_fit.ModalBox` on the batched
:class:`~flexid.costs.modal.ModalCost`), fits it by subspace identification (``"n4sid"``)
or its prediction-error reference (``"pem"``, :func:`flexid.fit.statespace_fit.ssest`), and
validates a :class:`~flexid.models.statespace.StateSpaceModel` output by output.

Where a polynomial problem starts from least squares, a state-space problem starts from the
subspace estimate: :func:`flexid.n4sid`'s poles read in the modal structure, its gains and
initial state fitted.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from ..costs.modal import ModalCost
from ..data.records import IOData
from ..errors import ConfigError, DataError, ModelOrderError
from ..models.families import Family, ReferenceFit
from ..models.specs import CostSpec, SearchSpec
from ..models.statespace import StateSpaceModel, StateSpaceStructure, state_sequence
from ..optimisers import Problem
from ..validation.portmanteau import (
    GRADIENT_STEP,
    ParameterEffect,
    estimation_records,
    estimation_root,
)
from ..validation.verdict import ValidationReport, residual_report
from .parametrisation import SearchBox
from .reference import StartOrReference, _simulation_in_own_bounds
from .statespace_fit import SSEST_STARTS, ModalBox, StateSpaceResult, modal_start, refine
from .subspace import SubspaceResult, n4sid

__all__ = ["StateSpaceEstimationProblem", "StateSpaceFamily", "free_response_fit"]

#: What a state-space problem's start row is.
START_NAME = "subspace estimate (n4sid)"
#: Its reference, in words.
REFERENCE_NAME = (
    "state-space reference (Levenberg-Marquardt on the modal parameters, from the subspace "
    f"estimate and {SSEST_STARTS} random starts)"
)


@dataclass
class StateSpaceEstimationProblem(StartOrReference):
    """The search problem of a state-space identification, and how to read its results.

    Attributes
    ----------
    structure : StateSpaceStructure
    cost : ModalCost
        The simulation cost on the estimation record, of physical modal parameters.
    problem : Problem
        What the optimisers minimise: the cost over :attr:`modal_box`'s coordinates.
    search : SearchSpec
        Recorded only: the modal space has its own coordinates.
    box : SearchBox
        The coordinates' bounds and their rule.
    box_rule : str
    modal_box : ModalBox
    subspace : SubspaceResult
        The subspace estimate on the estimation record.
    start : ndarray, shape (2 m + r,)
        Its poles read in the structure (:func:`~flexid.fit.statespace_fit.modal_start`): the
        modal parameters every search and the reference start from.
    """

    structure: StateSpaceStructure
    cost: ModalCost
    problem: Problem
    search: SearchSpec
    box: Any
    box_rule: str
    modal_box: ModalBox
    subspace: SubspaceResult
    start: np.ndarray
    _ref: Any = field(default=None, repr=False)
    #: The start and the reference in words, as a comparison's header names them.
    start_name: ClassVar[str] = START_NAME
    reference_name: ClassVar[str] = REFERENCE_NAME

    @property
    def theta_ls(self) -> np.ndarray:
        """The start's whole parameter vector."""
        return self.cost.fit(self.start[None])[0][0]

    @property
    def cost_ls(self) -> float:
        """The cost at the start."""
        return float(self.cost(self.start[None])[0])

    def theta(self, z: Any) -> np.ndarray:
        """Whole parameter vectors of search vectors (gains and initial state fitted).

        Parameters
        ----------
        z : array_like, shape (P, 2 m + r) or (2 m + r,)

        Returns
        -------
        ndarray, shape (P, n_params) or (n_params,)
        """
        z = np.asarray(z, dtype=float)
        theta = self.cost.fit(self.modal_box.physical(np.atleast_2d(z)))[0]
        return theta[0] if z.ndim == 1 else theta

    def describe(self) -> str:
        """One line: the modal space and its bounds.

        Returns
        -------
        str
        """
        s = self.structure
        return (f"modal space of {s!r}: {s.n_modes} mode(s) (frequency, damping) and "
                f"{s.n_real} real pole(s); {self.box_rule}; gains"
                f"{' and initial state' if self.cost.initial == 'estimate' else ''} fitted by "
                "least squares for each candidate")  # fmt: skip

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe description of the search.

        Returns
        -------
        dict
        """
        return {"parametrisation": {"name": "modal", **self.structure.to_dict()},
                "box_rule": self.box_rule}  # fmt: skip

    def output_error_reference(
        self, *, starts: int = SSEST_STARTS, seed: int = 0
    ) -> StateSpaceResult:
        """The gradient reference (:func:`flexid.fit.statespace_fit.refine` from the subspace
        start and ``starts`` random ones); cached for the last ``(starts, seed)``.

        Parameters
        ----------
        starts : int, optional
            Random starts after the subspace one.
        seed : int, optional

        Returns
        -------
        StateSpaceResult
            With ``cost`` the problem's cost at ``x``.
        """
        if self._ref is None or self._ref[0] != (starts, seed):
            t0 = time.perf_counter()
            rng = np.random.default_rng(seed)
            box = self.modal_box
            points = [("subspace", self.start), *box.random(rng, starts)]
            ref = refine(self.cost, box, points, t_begin=t0, subspace=self.subspace)
            ref["cost"] = float(self.cost(ref.x[None])[0])
            self._ref = ((starts, seed), ref)
        return self._ref[1]


def _record(data: Any, dt: float | None, model: StateSpaceModel) -> IOData:
    if isinstance(data, IOData):
        return data
    if isinstance(data, (tuple, list)) and len(data) == 2:
        u, y = (np.asarray(v, dtype=float) for v in data)
        return IOData(u, y, dt=model.dt if dt is None else dt,
                      input_names=list(model.input_names),
                      output_names=list(model.output_names)[: (1 if y.ndim == 1 else y.shape[1])])
    raise DataError(f"validate takes an IOData or a (u, y) pair, got {type(data).__name__}")


def free_response_fit(model: StateSpaceModel, u: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The initial state that best explains what the input does not, over every output.

    Parameters
    ----------
    model : StateSpaceModel
    u : ndarray, shape (N, nu)
    y : ndarray, shape (N, ny)

    Returns
    -------
    ndarray, shape (n,)
        ``x0`` minimising ``sum_o sum_t ((y_o - y_u,o - (C A^t x0)_o) / s_o)^2`` by least
        squares, ``y_u`` the response from rest and ``s_o`` output ``o``'s standard
        deviation (with several outputs, as the modal cost weighs them: an output in small
        units is not left to the others).
    """
    n = model.order
    forced = model.simulate(u, x0=np.zeros(n))
    free = model.C @ state_sequence(model.A, np.zeros((u.shape[0], n, n)), np.eye(n))
    std = np.std(y, axis=0)
    scale = np.where(std > 0, std, 1.0) if y.shape[1] > 1 else np.ones(1)
    design = (free / scale[None, :, None]).reshape(-1, n)  # (N ny, n)
    return np.linalg.lstsq(design, ((y - forced) / scale).reshape(-1), rcond=None)[0]


def _output_gradient(model: StateSpaceModel, record: IOData, initial: str) -> np.ndarray:
    """``d e / d theta`` of every output's simulation residual on ``record``, ``(N, ny, p)``,
    over the realised structure's parameters but the initial state (which each tested
    record fits anew under ``initial="estimate"``, so the derivative runs through that fit).
    """
    s, theta, dt = model.structure, model.theta, model.dt
    n_dynamic = theta.size - s.n_states

    def simulated(th: np.ndarray) -> np.ndarray:
        m = s.model(th, dt)
        x0 = free_response_fit(m, record.u, record.y) if initial == "estimate" else None
        return m.simulate(record.u, x0=np.zeros(m.order) if x0 is None else x0)

    out = np.empty((record.n_samples, model.n_outputs, n_dynamic))
    for j in range(n_dynamic):
        h = GRADIENT_STEP * max(abs(theta[j]), 1e-3)
        up, down = theta.copy(), theta.copy()
        up[j] += h
        down[j] -= h
        out[:, :, j] = -(simulated(up) - simulated(down)) / (2.0 * h)
    return out


def _parameter_effect(
    model: StateSpaceModel, record: IOData, estimated_on: Any, k: int, initial: str
) -> ParameterEffect | None:
    """How the model's estimate enters output ``k``'s residual tests on ``record``
    (:mod:`flexid.validation.portmanteau`), or None: the parameters then taken as known.

    On a held-out record the estimation error of the structure's parameters (its initial
    state aside) is added to the null. Its covariance is that of the estimate weighing each
    output by its noise, ``(sum_o J_o' J_o / sigma_o^2)^-1`` from the estimation records'
    gradients ``J_o`` and residual deviations ``sigma_o``: exact where the fit's own weights
    (each output's standard deviation) are proportional to the noise, a lower bound of it
    otherwise. On the estimation record itself the estimate is partialled out of the tests
    with one output; with several the joint estimate is orthogonal to no single output's
    gradient, and the parameters are taken as known. None, too, for a model that is not a
    realisation of its structure (a subspace estimate's matrices).
    """
    records = estimation_records(estimated_on)
    if records is None or not getattr(model, "realised", False):
        return None
    if records == "same" and model.n_outputs > 1:
        return None
    here = _output_gradient(model, record, initial)[:, k, :]
    if records == "same":
        return ParameterEffect(here)
    rows = []
    for r in records:
        if r.n_outputs != model.n_outputs:
            r = r.select(outputs=list(model.output_names))
        x0 = free_response_fit(model, r.u, r.y) if initial == "estimate" else np.zeros(model.order)
        sigma = np.std(r.y - model.simulate(r.u, x0=x0), axis=0)
        weight = sigma[k] / np.where(sigma > 0, sigma, 1.0)  # sigma_k / sigma_o
        gradient = _output_gradient(model, r, initial) * weight[None, :, None]
        rows.append(gradient.reshape(-1, gradient.shape[2]))
    return ParameterEffect(here, estimation_root(rows))


class StateSpaceFamily(Family):
    """State-space models: modes, real poles and every sensor's gains."""

    name = "statespace"
    structures = (StateSpaceStructure,)
    models = (StateSpaceModel,)
    names = ("ss",)
    several_outputs = True
    predictors = ("simulation",)

    def structure(self, spec: Any, n_inputs: int, **orders: Any) -> StateSpaceStructure:
        n_outputs = orders.pop("n_outputs", 1)
        if isinstance(spec, StateSpaceStructure):
            self.refuse_orders(spec, orders)
            if (spec.n_inputs, spec.n_outputs) != (n_inputs, n_outputs):
                raise ModelOrderError(
                    f"the record has {n_inputs} input(s) and {n_outputs} output(s) but "
                    f"{spec!r} has {spec.n_inputs} and {spec.n_outputs}"
                )
            return spec
        order, modes = orders.pop("order", None), orders.pop("modes", None)
        bounds = {k: orders.pop(k) for k in ("frequency", "damping", "feedthrough")
                  if k in orders}  # fmt: skip
        other = sorted(k for k, v in orders.items() if v is not None and (k, v) != ("nk", 1))
        if other:
            raise ModelOrderError(
                f"structure 'ss' takes order, modes, frequency, damping and feedthrough, not "
                f"{', '.join(other)}"
            )
        if order is None:
            raise ModelOrderError("structure 'ss' needs its order (order=4, or --order 4)")
        return StateSpaceStructure(order, n_inputs, n_outputs, n_modes=modes, **bounds)

    structure.__doc__ = Family.structure.__doc__

    def start_name(self, structure: Any) -> str:
        return START_NAME

    start_name.__doc__ = None  # Family.start_name's

    def reference_hint(self, structure: Any, predictor: str) -> str:
        return "optimiser='pem' (ssest)"

    reference_hint.__doc__ = None  # Family.reference_hint's

    def pose(
        self, data: Any, structure: Any, cost: CostSpec, search: SearchSpec, *, bounds: Any
    ) -> StateSpaceEstimationProblem:
        if isinstance(data, (list, tuple)):
            raise ConfigError(f"{structure!r}: several estimation records are not supported; "
                              "estimate on one")  # fmt: skip
        _simulation_in_own_bounds(
            cost, bounds,
            f"{structure!r} is an output-error model (K = 0): its cost is the simulation error;",
            f"{structure!r} is searched in its frequency and damping bounds: set them on the "
            "structure (frequency=, damping=)",
        )  # fmt: skip
        initial = "estimate" if cost.initial == "auto" else cost.initial
        objective = ModalCost(data, structure, metric=cost.metric, weight=cost.weight,
                              initial=initial)  # fmt: skip
        box = ModalBox.on(structure, data.dt, data.n_samples)
        sub = n4sid(data, structure.order, feedthrough=structure.feedthrough)
        start = modal_start(sub.model.poles(), box, data.dt)

        def evaluate(Z: np.ndarray) -> np.ndarray:
            return objective(box.physical(Z))

        problem = Problem(evaluate, box.lower, box.upper, x0=box.coordinates(start),
                          name=repr(structure))  # fmt: skip
        return StateSpaceEstimationProblem(
            structure=structure, cost=objective, problem=problem, search=search,
            box=SearchBox(box.lower.copy(), box.upper.copy(), box.rule), box_rule=box.rule,
            modal_box=box, subspace=sub, start=start,
        )  # fmt: skip

    pose.__doc__ = None  # Family.pose's

    def fit(self, estimation: Any, structure: Any, method: str, *, data: Any,
            seed: int | None) -> ReferenceFit:
        if method == "n4sid":
            # the subspace poles read in the structure asked for, its gains and initial state
            # by least squares on this cost: the comparison's start row, and never worse
            # there than the subspace model's own gains (those are one point of that fit)
            model = structure.model(estimation.theta_ls, data.dt)
            return ReferenceFit(model, estimation.cost_ls, {
                "order": estimation.subspace.order, "block_rows": estimation.subspace.block_rows,
            })  # fmt: skip
        if method == "pem":
            starts = SSEST_STARTS
            ref = estimation.output_error_reference(starts=starts, seed=seed or 0)
            return ReferenceFit(ref.model, ref.cost, {"starts": starts}, seed or 0, ref)
        return super().fit(estimation, structure, method, data=data, seed=seed)

    fit.__doc__ = None  # Family.fit's

    def reference(self, data: Any, structure: Any, *, initial: str, starts: int | None,
                  seed: int) -> tuple[Any, float, bool]:
        estimation = self.pose(data, structure, CostSpec(metric="sse", predictor="simulation",
                                                         initial=initial), SearchSpec(),
                               bounds="auto")  # fmt: skip
        ref = estimation.output_error_reference(
            starts=SSEST_STARTS if starts is None else starts, seed=seed)
        return ref.model, float(ref.fun), bool(ref.local_minimum)

    reference.__doc__ = None  # Family.reference's

    def validate(
        self, model: Any, data: Any, *, max_lag: int, initial: str,
        split: float | int | None, dt: float | None, output: str | None,
        estimated_on: Any = None,
    ) -> ValidationReport:
        record = _record(data, dt, model)
        if split is not None:
            parts = record.split(split) if isinstance(split, float) else record.split(index=split)
            record = parts[1]
        if record.n_inputs != model.n_inputs:
            raise ModelOrderError(f"the model has {model.n_inputs} input(s), the record "
                                  f"{record.n_inputs}")  # fmt: skip
        names = list(record.output_names)
        if record.n_outputs != model.n_outputs:
            missing = [o for o in model.output_names if o not in names]
            if missing:
                raise DataError(f"the record has no output {missing[0]!r} of the model "
                                f"(its outputs: {names})")  # fmt: skip
            record = record.select(outputs=list(model.output_names))
            names = list(model.output_names)
        if output is None:
            if model.n_outputs != 1:
                raise DataError(f"the model has outputs {list(model.output_names)}: give the "
                                "one to validate (output=...)")  # fmt: skip
            k = 0
        elif output in model.output_names:
            k = list(model.output_names).index(output)
        else:
            raise DataError(f"the model has no output {output!r} (its outputs: "
                            f"{list(model.output_names)})")  # fmt: skip
        if initial not in ("estimate", "zero"):
            raise DataError(
                f"a state-space model's initial state is estimated or zero, not {initial!r}"
            )
        u, y = record.u, record.y
        effect = _parameter_effect(model, record, estimated_on, k, initial)
        x0 = free_response_fit(model, u, y) if initial == "estimate" else np.zeros(model.order)
        with np.errstate(all="ignore"):
            ysim = model.simulate(u, x0=x0)
            y1 = None if not np.any(model.K) else model.predict(u, y, x0=x0)
        zeros = [model.zeros(input=j, output=k) for j in range(model.n_inputs)]
        return residual_report(
            y[:, k], None if y1 is None else y1[:, k], ysim[:, k], u, start=0, dt=record.dt,
            max_lag=max_lag, names=list(record.input_names), output_name=names[k],
            initial=initial, initial_one_step=initial,
            poles=model.poles(), zeros=zeros,
            predictor_stable=model.predictor_stable if y1 is not None else None,
            output_unit=record.output_units[k] if record.output_units else "",
            response=lambda f: model.frequency_response(f)[:, k, :],
            input_units=record.input_units, effect=effect,
        )  # fmt: skip

    validate.__doc__ = None  # Family.validate's

    def held_out(
        self, model: Any, estimation: Any, validation: Any, *, max_lag: int, initial: str
    ) -> ValidationReport:
        return self.validate(model, validation, max_lag=max_lag, initial=initial, split=None,
                             dt=None, output=model.output_names[0],
                             estimated_on=estimation)  # fmt: skip

    held_out.__doc__ = None  # Family.held_out's

    def model_numbers(self, model: Any, estimation: Any, records: Any) -> dict[str, Any]:
        ranges = [
            self.validate(model, r, max_lag=1, initial="estimate", split=None, dt=None,
                          output=model.output_names[0]).error_range_simulation
            for r in records
        ]  # fmt: skip
        radius = float(np.max(np.abs(model.poles()), initial=0.0))
        return {
            "theta": [float(v) for v in model.theta],
            "stable": bool(model.is_stable),
            "max_pole_radius": radius,
            "estimation_error_min": float(min(lo for lo, _ in ranges)),
            "estimation_error_max": float(max(hi for _, hi in ranges)),
        }

    model_numbers.__doc__ = None  # Family.model_numbers's
