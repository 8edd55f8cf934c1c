"""The polynomial family (ARX, ARMAX, OE, BJ) in the one model interface.

:class:`PolynomialFamily` poses a polynomial structure with
:func:`flexid.fit.estimation.pose_polynomial` (ARX on its one-step least-squares cost where that
serves, every other case on the polynomial cost) and validates a polynomial model, an ARX
model or a model duck-typed to one, in a well-conditioned realisation.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import asdict, replace
from typing import Any

import numpy as np

from .._validate import is_integer
from ..costs.arx import ARXCost
from ..data.records import IOData, joined
from ..errors import (
    ConfigError,
    DataError,
    FlexidError,
    ModelOrderError,
    UnknownNameError,
    check_finite,
)
from ..models.arx import ARX, ARXStructure
from ..models.families import Family, ReferenceFit
from ..models.polynomial import STRUCTURES, PolynomialModel, PolynomialStructure
from ..models.polynomial import structure as _named_structure
from ..models.specs import CostSpec, SearchSpec
from ..models.vocabulary import (
    DEPRECATED_REFERENCES,
    LEAST_SQUARES,
    PREDICTION_ERROR,
    REFERENCE_STARTS,
)
from ..optimisers import Problem
from ..validation.diagnostics import _check_max_lag
from ..validation.portmanteau import ParameterEffect, estimation_records, estimation_root
from ..validation.verdict import ValidationReport, residual_report
from .estimation import (
    EstimationProblem,
    _build_polynomial,
    _coefficients_of,
    _denominators_of,
    check_excitation,
    model_structure,
    resolve_initial,
    search_box,
)
from .parametrisation import make_parametrisation
from .prediction_error import pem, prediction_jacobian

__all__ = ["PolynomialFamily", "pose_polynomial"]


class PolynomialFamily(Family):
    """The polynomial models ``A y = B/F u + C/D e``, ARX among them."""

    name = "polynomial"
    structures = (PolynomialStructure, ARXStructure)
    models = (PolynomialModel, ARX)
    names = tuple(STRUCTURES)

    def structure(self, spec: Any, n_inputs: int, **orders: Any) -> Any:
        given = {k: v for k, v in orders.items() if v is not None}
        spec = _polynomial_structure(spec)
        if isinstance(spec, PolynomialStructure):
            self.refuse_orders(spec, orders)
            made = spec
        else:
            name = str(spec).lower()
            if name not in STRUCTURES:
                raise UnknownNameError("model structure", str(spec), tuple(STRUCTURES))
            if name == "arx":
                extra = sorted(k for k in given if k not in STRUCTURES["arx"])
                if extra:
                    raise ModelOrderError(
                        f"the arx structure has no order {', '.join(extra)}; it takes na, nb, "
                        "nk (pass structure='armax', 'oe' or 'bj')"
                    )
                if "na" not in given:
                    raise ModelOrderError("the arx structure needs the order na (and nb, nk)")
                return model_structure(given["na"], given.get("nb"), given.get("nk", 1),
                                       n_inputs)  # fmt: skip
            per = {k: _per_input(v, n_inputs) for k, v in given.items()}
            made = _named_structure(name, **per)
        if made.n_inputs != n_inputs:
            raise ModelOrderError(
                f"the record has {n_inputs} input(s) but {made!r} has {made.n_inputs} "
                "(one nb, nf and nk per input)"
            )
        if made.kind == "arx":
            return made.arx_structure()  # the paper's path: ARX's one-step least squares
        return made

    structure.__doc__ = None  # Family.structure's

    def canonical(self, structure: Any) -> Any:
        return _polynomial_structure(structure)

    canonical.__doc__ = None  # Family.canonical's

    def fit(self, estimation: Any, structure: Any, method: str, *, data: Any,
            seed: int | None) -> ReferenceFit:
        method = DEPRECATED_REFERENCES.get(method, method)  # identify has warned
        polynomial = isinstance(structure, PolynomialStructure)
        objective, cost_ls = estimation.cost, estimation.cost_ls
        one_step = objective.predictor != "simulation"
        # the gradient reference of the one-step ARX cost is its exact optimum, least squares
        if not polynomial and (method == LEAST_SQUARES or (method == PREDICTION_ERROR
                                                           and one_step)):
            return ReferenceFit(structure.least_squares(data.u, data.y[:, 0], dt=data.dt),
                                cost_ls)  # fmt: skip
        if method == LEAST_SQUARES:
            if not np.isfinite(objective.theta_ls).all():
                raise ConfigError(
                    f"{structure!r} has no least-squares start (its F polynomials differ in "
                    "order); use optimiser='pem'"
                )
            return ReferenceFit(structure.model(objective.theta_ls, dt=data.dt), cost_ls)
        if method != PREDICTION_ERROR:
            return super().fit(estimation, structure, method, data=data, seed=seed)
        ref = estimation.output_error_reference(seed=0 if seed is None else seed)
        if polynomial:
            model = type(ref.model)(
                structure, ref.theta, dt=data.dt, param_std=ref.model.param_std,
                noise_variance=ref.model.noise_variance,
            )
        else:
            model = structure.model(ref.theta, dt=data.dt)
        return ReferenceFit(model, float(ref.cost), {"starts": len(ref.runs)}, seed, ref)

    fit.__doc__ = None  # Family.fit's

    def reference(self, data: Any, structure: Any, *, initial: str, starts: int | None,
                  seed: int) -> tuple[Any, float, bool]:
        check_excitation(data, structure)  # a structure the input cannot determine fails
        res = pem(data, structure, initial=initial,
                  starts=REFERENCE_STARTS if starts is None else starts, seed=seed)
        return res.model, res.sse, res.local_minimum

    reference.__doc__ = None  # Family.reference's

    def reference_hint(self, structure: Any, predictor: str) -> str:
        if structure.kind != "arx":
            return "optimiser='pem'"
        return "optimiser='ls'" if predictor == "one-step" else "optimiser='pem'"

    reference_hint.__doc__ = None  # Family.reference_hint's

    def start_name(self, structure: Any) -> str:
        if isinstance(structure, PolynomialStructure):
            return "ARX least squares read as the structure"
        return "least squares"

    start_name.__doc__ = None  # Family.start_name's

    def title(self, structure: Any) -> str:
        if isinstance(structure, ARXStructure):
            return f"ARX(na={structure.na}, nb={_orders(structure.nb)}, nk={_orders(structure.nk)})"
        return repr(structure)

    title.__doc__ = None  # Family.title's

    def structure_dict(self, structure: Any) -> dict[str, Any]:
        if isinstance(structure, ARXStructure):  # as results stored it before: with its name
            return {"structure": "arx", **structure.to_dict()}
        return structure.to_dict()

    structure_dict.__doc__ = None  # Family.structure_dict's

    def pose(
        self, data: Any, structure: Any, cost: CostSpec, search: SearchSpec, *, bounds: Any
    ) -> EstimationProblem:
        return pose_polynomial(data, structure, cost, search, bounds=bounds)

    pose.__doc__ = None  # Family.pose's

    def model_numbers(self, model: Any, estimation: Any, records: Any) -> dict[str, Any]:
        start = estimation.structure.start
        est_err = np.concatenate([model.residuals(r.u, r.y[:, 0])[start:] for r in records])
        return {
            "theta": [float(v) for v in model.theta],
            "stable": bool(model.is_stable),
            "max_pole_radius": float(model.max_pole_radius),
            "estimation_error_min": float(est_err.min()),
            "estimation_error_max": float(est_err.max()),
        }

    model_numbers.__doc__ = None  # Family.model_numbers's

    def validate(
        self, model: Any, data: Any, *, max_lag: int, initial: str,
        split: float | int | None, dt: float | None, output: str | None,
        estimated_on: Any = None,
    ) -> ValidationReport:
        if output is not None:
            raise DataError("output= selects a grey-box model's output; this model has one")
        record = _validation_record(data, dt if dt is not None else _model_dt(model), split)
        if record.n_outputs != 1:
            raise DataError(
                f"validate() takes a single-output record, got {record.n_outputs} outputs "
                f"{list(record.output_names)}; use data.select(outputs=...) first"
            )
        check_finite(record.u, "input u")
        check_finite(record.y, "output y")
        sample_time = float(record.dt)
        u_full = record.u
        y_full = record.y[:, 0]
        n = y_full.size
        structure = getattr(model, "structure", None)
        start = int(getattr(structure, "start", 0))
        nb = getattr(structure, "nb", None)
        if nb is not None and len(tuple(np.atleast_1d(nb))) != u_full.shape[1]:
            raise ModelOrderError(
                f"the model has {len(tuple(np.atleast_1d(nb)))} input(s), the record "
                f"{u_full.shape[1]}"
            )
        if n <= start:
            raise ModelOrderError(
                f"a record of {n} samples does not reach past the model's first full regressor "
                f"(start = {start})"
            )
        n_eval = n - start
        max_lag = _check_max_lag(max_lag, n_eval, f"the evaluated part (t >= {start})")

        u_model = u_full[:, 0] if u_full.shape[1] == 1 else u_full
        predictor_stable = None
        first = start if initial == "measured" else 0  # MATLAB counts every sample
        if isinstance(model, PolynomialModel):
            predictor_stable = model.predictor_stable
            y1, ysim, initial_one_step = _polynomial_outputs(
                model, u_model, y_full, initial, predictor_stable
            )
        else:
            y1, ysim, initial_one_step, first = _other_outputs(
                model, u_model, y_full, initial, start, first
            )
        for arr, what in ((y1, "one-step prediction"), (ysim, "simulated output")):
            if arr.size != n:
                raise DataError(f"the model's {what} has {arr.size} samples, the record {n}")
        check_finite(y1, "the model's one-step prediction")

        n_u = u_full.shape[1]
        return residual_report(
            y_full, y1, ysim, u_full, start=first, dt=sample_time, max_lag=max_lag,
            names=list(record.input_names), output_name=str(record.output_names[0]),
            output_unit=str(record.output_units[0]),
            initial=initial, initial_one_step=initial_one_step, poles=model.poles(),
            zeros=[np.asarray(model.zeros(input=i)) for i in range(n_u)],
            predictor_stable=predictor_stable, test_start=start,
            response=_response_of(model), input_units=record.input_units,
            effect=_parameter_effect(model, record, estimated_on, initial),
        )

    validate.__doc__ = None  # Family.validate's


def _validation_record(data: Any, dt: float | None, split: float | int | None) -> IOData:
    """The record :meth:`PolynomialFamily.validate` tests on: ``data``, or the part after
    ``split`` (a fraction or a sample index)."""
    record = _as_record(data, dt)
    if split is not None:
        if isinstance(split, float):
            record = record.split(split)[1]
        else:
            record = record.split(index=split)[1]
    return record


def _polynomial_outputs(
    model: PolynomialModel, u_model: np.ndarray, y_full: np.ndarray, initial: str,
    predictor_stable: bool,
) -> tuple[np.ndarray, np.ndarray, str | None]:
    """A polynomial model's one-step prediction, simulated output and the initial-condition
    rule of its one-step prediction (None when its predictor has no state)."""
    n = y_full.size
    y1 = _free_run(
        lambda: model.predict(u_model, y_full, initial=initial), n, not predictor_stable
    )
    ysim = _free_run(
        lambda: model.simulate(u_model, y_full, initial=initial), n, not model.is_stable
    )
    return y1, ysim, initial if model.structure.n_state else None


def _other_outputs(
    model: Any, u_model: np.ndarray, y_full: np.ndarray, initial: str, start: int, first: int
) -> tuple[np.ndarray, np.ndarray, str | None, int]:
    """An ARX-like model's one-step prediction, simulated output, the initial-condition rule
    of its one-step prediction and the first sample the residual tests count."""
    n = y_full.size
    poly = None  # its polynomial form, in a well-conditioned realisation, where it has one
    if initial != "measured":
        try:
            poly = _as_polynomial(model)
        except DataError:
            if initial == "estimate":
                raise
    if poly is None:  # ARX-like by its own routes: its one-step predictor has no state
        y1 = np.asarray(model.predict(u_model, y_full), dtype=float).reshape(-1)
        own = model.simulate(u_model, y_init=y_full[:start]) if initial == "measured" else (
            model.simulate(u_model)
        )
        ysim = np.asarray(own, dtype=float).reshape(-1)
        return y1, ysim, None, start
    y1 = _free_run(lambda: poly.predict(u_model, y_full, initial=initial), n, False)
    ysim = _free_run(
        lambda: poly.simulate(u_model, y_full, initial=initial), n, not poly.is_stable
    )
    return y1, ysim, initial, first


def _parameter_effect(
    model: Any, record: IOData, estimated_on: Any, initial: str
) -> ParameterEffect | None:
    """How the model's estimate enters the residual tests on ``record``
    (:mod:`flexid.validation.portmanteau`): the gradient of its one-step residual there (rows
    ``t >= start``, those the tests use) and, for held-out records, the triangular factor of
    the estimation records' gradients.  None when the model was not estimated from data, or its
    gradient cannot be had (a duck-typed model, an unstable predictor): the report then
    takes the parameters as known and says so."""
    records = estimation_records(estimated_on)
    if records is None:
        return None
    try:
        poly = model if isinstance(model, PolynomialModel) else _as_polynomial(model)

        def gradient(r: IOData) -> np.ndarray:
            u = r.u[:, 0] if r.n_inputs == 1 else r.u
            return prediction_jacobian(poly.structure, poly.theta, u, r.y[:, 0], initial)[1]

        here = gradient(record)
        if records == "same":
            return ParameterEffect(here)
        root = estimation_root([gradient(r) for r in records])
    except (DataError, ModelOrderError):
        return None
    return ParameterEffect(here, root)


def _response_of(model: Any) -> Any:
    """The model's frequency response as ``f -> (F, n_u)``, None for a duck-typed model
    without one."""
    response = getattr(model, "frequency_response", None)
    return None if response is None else (lambda f: response(f)[:, 0, :])


def _polynomial_structure(structure: Any) -> Any:
    """An :class:`ARXStructure` as the polynomial family's ARX structure; others as given."""
    if isinstance(structure, ARXStructure):
        return PolynomialStructure.arx(structure.na, structure.nb, structure.nk)
    return structure


def _per_input(value: Any, n_inputs: int) -> Any:
    """A scalar order repeated for every input (``nb``, ``nf``, ``nk``)."""
    if value is None or n_inputs == 1 or not is_integer(value):
        return value
    return [int(value)] * n_inputs


def pose_polynomial(
    est: IOData | Sequence[IOData],
    structure: ARXStructure | PolynomialStructure,
    cost: CostSpec,
    search: SearchSpec,
    *,
    bounds: Any = "auto",
) -> EstimationProblem:
    """The polynomial family's :meth:`~flexid.models.families.Family.pose`.

    See :func:`flexid.fit.estimation.build_problem`.

    ARX is posed on its one-step least-squares cost (:class:`~flexid.costs.arx.ARXCost`,
    the paper's route) where that cost serves; every other case on the polynomial cost.

    Parameters
    ----------
    est : IOData or sequence of IOData
    structure : ARXStructure or PolynomialStructure
    cost : CostSpec
    search : SearchSpec
    bounds : see :func:`flexid.search_box`

    Returns
    -------
    EstimationProblem
    """
    several = isinstance(est, (list, tuple))
    # before any fit: a problem without a unique answer gets an error, not a huge model
    # (several records: on them joined, whose junctions add a few rows to a rank test)
    check_excitation(joined(est) if several else est, structure)
    cost = replace(cost, initial=resolve_initial(cost.initial, structure))
    if cost.initial == "estimate" or several:
        # ARXCost has neither an estimated initial state nor several records; the polynomial
        # cost covers ARX as well
        structure = _polynomial_structure(structure)
    if isinstance(structure, PolynomialStructure):
        if structure.kind != "arx" or cost.initial == "estimate" or several:
            return _build_polynomial(est, structure, cost, search, bounds=bounds)
        structure = structure.arx_structure()
    objective = _arx_cost(structure, est, cost, search)
    box = search_box(structure, bounds, objective.theta_ls)
    na = structure.na
    b_lo, b_hi = box.lower[na:], box.upper[na:]
    param = make_parametrisation(
        search.parametrisation,
        structure,
        b_lower=b_lo,
        b_upper=b_hi,
        a_lower=box.lower[:na],
        a_upper=box.upper[:na],
        r_max=search.r_max,
        real_pairs=search.real_pairs,
        k_max=search.k_max,
    )
    fit = search.numerator == "fit"
    if fit and na == 0:
        raise ConfigError(
            "numerator = 'fit' searches the denominator, and na = 0 has none: least squares "
            "is the optimum"
        )
    keep = slice(0, na) if fit else slice(None)
    sampler = _stable_sampler(structure, search, b_lo, b_hi, param, keep)
    evaluate = _arx_evaluate(objective, param, search, fit)
    problem = Problem(evaluate, param.lower[keep], param.upper[keep], name="arx", sampler=sampler)
    rule = _arx_box_rule(box.rule, search.parametrisation, fit)
    return EstimationProblem(
        structure=structure,
        cost=objective,
        parametrisation=param,
        problem=problem,
        search=search,
        box=box,
        box_rule=rule,
    )


def _arx_cost(
    structure: ARXStructure, est: Any, cost: CostSpec, search: SearchSpec
) -> ARXCost:
    """The one-step least-squares cost of an ARX problem, singular regressors refused."""
    try:
        return ARXCost(structure, est, **asdict(cost), penalty_kind=search.penalty)
    except np.linalg.LinAlgError as exc:  # exactly singular regressors with exciting inputs
        raise DataError(
            f"the regressors of {structure!r} are singular on the estimation record ({exc}): "
            "an output that is zero or constant, or orders the data cannot determine; use "
            "lower orders or other data"
        ) from None


def _stable_sampler(
    structure: ARXStructure, search: SearchSpec, b_lo: np.ndarray, b_hi: np.ndarray,
    param: Any, keep: slice,
) -> Callable[[int, np.random.Generator], np.ndarray] | None:
    """The initial-population sampler of ``init = "stable"`` over coefficients, None for the
    problem's own uniform draws."""
    if search.init != "stable" or search.parametrisation != "coefficients" or not structure.na:
        return None
    # stable denominators drawn uniformly in the pole-pair space, b uniform in its box
    poles = make_parametrisation(
        "poles", structure, b_lower=b_lo, b_upper=b_hi, r_max=search.r_max
    )

    def sampler(size: int, rng: np.random.Generator) -> np.ndarray:
        Z = poles.lower + (poles.upper - poles.lower) * rng.random((size, poles.n_search))
        X = np.clip(poles.to_coefficients(Z), param.lower, param.upper)
        return X[:, keep]

    return sampler


def _arx_evaluate(
    objective: ARXCost, param: Any, search: SearchSpec, fit: bool
) -> Callable[[np.ndarray], np.ndarray]:
    """The cost of a batch of search vectors of an ARX problem."""
    if search.parametrisation == "coefficients" and not fit:
        return objective  # the search vector is theta
    if fit:

        def evaluate(Z: np.ndarray) -> np.ndarray:
            # the fit and the cost at it in one pass (ARXCost.fitted): the costs of
            # objective(_coefficients_of(...)) without simulating each candidate twice
            return objective.fitted(_denominators_of(Z, param))[1]

    else:

        def evaluate(Z: np.ndarray) -> np.ndarray:
            return objective(_coefficients_of(Z, param, objective, search.numerator))

    return evaluate


def _arx_box_rule(box_rule: str, parametrisation: str, fit: bool) -> str:
    """How an ARX problem's search box was chosen, for the reports."""
    if fit:
        rule = "b fitted (unbounded)"
        if parametrisation == "coefficients":
            rule = f"a box: {box_rule}; {rule}"
        return rule
    if parametrisation == "coefficients":
        return box_rule
    # the b part of the automatic rule (its a part, "C(na, k) (...)", has commas too)
    rule = box_rule.split("stable A), ", 1)[-1] if box_rule.startswith("auto") else box_rule
    return f"b box: {rule}"


def _as_polynomial(model: Any) -> PolynomialModel:
    """The polynomial form of an ARX-like model, for the ``"estimate"`` rule."""
    if isinstance(model, ARX):
        return PolynomialModel.from_arx(model)
    to_polynomial = getattr(model, "to_polynomial", None)
    if callable(to_polynomial):
        return to_polynomial()
    try:  # a duck-typed ARX: A = [1, a_1 ..], one B per input, structure.nk
        s = model.structure
        theta = np.concatenate(
            [np.asarray(model.a, dtype=float)[1:], *[np.asarray(b, dtype=float) for b in model.b]]
        )
        return PolynomialStructure.arx(s.na, s.nb, s.nk).model(theta, dt=_model_dt(model) or 1.0)
    except AttributeError:
        raise DataError(
            f"initial='estimate' needs the model as a polynomial model: {type(model).__name__} "
            "has no to_polynomial() (nor a, b and structure.na/nb/nk); pass initial='measured' "
            "or 'zero'"
        ) from None


def _orders(values: Any) -> Any:
    """Per-input orders as printed: one value for one input, else the list."""
    values = list(values)
    return values[0] if len(values) == 1 else values


def _as_record(data: Any, dt: float | None) -> IOData:
    if isinstance(data, IOData):
        return data
    if isinstance(data, (tuple, list)) and len(data) == 2:
        u, y = data
        return IOData(u, y, dt=1.0 if dt is None else dt)
    raise DataError(
        f"data must be an IOData or a (u, y) pair of arrays, got {type(data).__name__}"
    )


def _model_dt(model: Any) -> float | None:
    dt = getattr(model, "dt", None)
    try:
        dt = float(dt)
    except (TypeError, ValueError):
        return None
    return dt if math.isfinite(dt) and dt > 0 else None


def _free_run(run: Any, n: int, unstable: bool) -> np.ndarray:
    """``run()`` as a float vector; for an ``unstable`` filter an overflow gives inf.

    The least-squares fit of an initial state raises ValueError when the free responses of
    an unstable filter overflow; that is a diverged run to report, not an error.
    """
    try:
        with np.errstate(over="ignore", invalid="ignore"):
            out = run()
    except ValueError as exc:
        if isinstance(exc, FlexidError) or not unstable:
            raise
        return np.full(n, np.inf)
    return np.asarray(out, dtype=float).reshape(-1)
