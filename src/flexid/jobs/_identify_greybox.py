"""``identify`` for a grey-box model: the physical parameters, found by any optimiser.

The record is split as for the polynomial structures (default 2/3 for estimation); the
model is fitted on the first part and, as an output-error model has no state to re-estimate,
validated by running it on from the record's start through the estimation part into the
held-out part (or from its initial state at the start of a separate validation record).
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from typing import Any

from .._json import jsonable
from ..data.records import ESTIMATION_SHARE, IOData, detrend_kind, detrend_pair, load
from ..errors import ConfigError, DataError
from ..fit.estimation import build_problem
from ..fit.greybox_estimation import START_NAME
from ..models.greybox import GreyBoxModel
from ..models.specs import CostSpec, SearchSpec
from ..models.vocabulary import GREYBOX_REFERENCE_STARTS, VALIDATION_ALPHA
from ..optimisers import Budget, minimize
from ..validation.diagnostics import format_fit
from ..validation.verdict import ValidationReport, validate
from ._identification import Identification, _indent, data_info, timings
from .specs import specs_from_keywords

__all__ = ["GreyBoxIdentification", "identify_greybox"]


@dataclass
class GreyBoxIdentification(Identification):
    """The outcome of :func:`flexid.identify` for a grey-box model.

    As :class:`~flexid.Identification`, with ``model`` the fitted
    :class:`~flexid.models.greybox.GreyBoxModel`, ``cost_ls`` the cost at the parameters' given
    values (the start; a grey-box model has no least squares) and, for ``optimiser="pem"``,
    ``output_error`` the :class:`~flexid.fit.greybox_fit.GreyBoxResult` with standard
    errors and identifiability.

    Attributes
    ----------
    outputs : dict of str to (ValidationReport, ValidationReport)
        Every output's estimation and held-out reports (``estimation`` and ``validation``
        are the first output's).
    """

    outputs: dict = field(default_factory=dict)

    def _name(self) -> str:
        return f"grey-box model {self.model.name}"

    def _start_name(self) -> str:
        return START_NAME

    def _reference_text(self) -> str:
        ref = self.output_error
        where = "a local minimum" if ref.local_minimum else "NOT a verified local minimum"
        return (
            f"Levenberg-Marquardt, {len(ref.runs)} start(s), {ref.simulations} simulations; "
            f"first-order optimality {ref.optimality:.2g}: {where}"
        )

    def _box_items(self) -> list[tuple[str, str]]:
        return []  # the bounds are the parameters', listed in the parameter table

    def _parameter_table(self) -> str:
        ref = self.output_error
        if ref is not None:
            return ref.summary()
        return self.model.summary()

    def advice(self) -> str | None:
        """One plain line when the model should not be trusted, with what to try next.

        Checked: an optimiser's final cost more than 10 % above the reference's (when it was
        run), an estimated parameter on a bound, failing held-out correlation tests, a
        negative held-out simulation fit.

        Returns
        -------
        str or None
        """
        problems: list[str] = []
        tries: list[str] = []
        model = self.model
        on_bound = [
            p.name for p in model.parameters
            if not p.fixed and (p.value <= p.lower or p.value >= p.upper)
        ]
        if on_bound:
            problems.append(f"{', '.join(on_bound)} ended on a bound")
            tries.append("wider bounds (--set NAME=VALUE moves a start, not a bound)")
        if self.output_error is None and self.result is not None:
            tries.append("optimiser='pem' (the reference) or a larger budget")
        if not all(val.linear_passed for _, val in self.outputs.values()):
            problems.append("the held-out correlation tests fail")
            tries.append("another model (its physics miss something the record shows)")
        if any(val.fit_simulation < 0 for _, val in self.outputs.values()):
            problems.append(
                f"the held-out simulation fit is {format_fit(self.validation.fit_simulation)} %"
            )
        if not problems:
            return None
        return "warning: " + "; ".join(problems) + ": try " + ", or ".join(
            dict.fromkeys(tries)
        )

    def summary(self) -> str:
        """The header, the parameters, and each output's estimation and held-out reports.

        Returns
        -------
        str
        """
        lines = [self._title()]
        lines += [f"  {label:<12}: {value}" for label, value in self._items()]
        lines += ["", self._parameter_table(), ""]
        several = len(self.outputs) > 1
        for name, (est, val) in self.outputs.items():
            suffix = f", output {name}" if several else ""
            lines.append(f"Estimation record{suffix}")
            lines.append(_indent(est.summary()))
            lines.append(f"Validation record (held out; run on from the start){suffix}")
            lines.append(_indent(val.summary()))
        advice = self.advice()
        if advice:
            lines.append(advice)
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        """Machine-readable result (JSON-safe): parameters, cost, fits, timings.

        Returns
        -------
        dict
        """
        ref = self.output_error
        reference = None
        if ref is not None:
            fit = ref
            reference = {
                "std_errors": fit.std_errors,
                "local_minimum": fit.local_minimum,
                "optimality": fit.optimality,
                "on_bound": list(fit.on_bound),
                "unidentifiable": list(fit.unidentifiable),
            }
        return jsonable({
            "structure": {"structure": "greybox", "name": self.model.name},
            "optimiser": self.optimiser,
            "params": self.params,
            "seed": self.seed,
            "cost": {
                "description": self.cost.describe(),
                "value": self.cost_value,
                "start": self.cost_ls,
            },
            "search": {
                "space": self.search,
                "nfev": self.nfev,
                "nit": 0 if self.result is None else int(self.result.nit),
                "message": "Levenberg-Marquardt reference" if self.result is None
                else self.result.message,
            },
            "model": self.model.to_dict(),
            "reference": reference,
            "estimation": self.estimation.to_dict(),
            "validation": self.validation.to_dict(),
            "outputs": {
                name: {"estimation": est.to_dict(), "validation": val.to_dict()}
                for name, (est, val) in self.outputs.items()
            },
            "timings": {k: round(v, 6) for k, v in self.timings.items()},
            "data": self.data_info,
        })


def _record(
    data: IOData | str | os.PathLike, model: GreyBoxModel, load_options: Mapping[str, Any] | None
) -> IOData:
    """The record, read by the model's channels when it is a file."""
    if isinstance(data, IOData):
        return data
    options = dict(load_options or {})
    options.setdefault("inputs", [model.column(name)[0] for name in model.inputs])
    options.setdefault("outputs", [model.column(name)[0] for name in model.outputs])
    try:
        return load(data, **options)
    except DataError as exc:
        if "no column" not in str(exc):
            raise
        raise type(exc)(
            f"{exc}; map the channels {list(model.inputs + model.outputs)} of grey-box model "
            f"{model.name!r} to the record's columns with --channels CHANNEL=COLUMN[*FACTOR] "
            "(GreyBoxModel.reading)"
        ) from None


def _initial_state_on(fitted: GreyBoxModel, record: IOData) -> GreyBoxModel:
    """``fitted`` with its estimated initial states refitted on another record (its
    physical parameters held): a separate validation record starts from its own state, as
    MATLAB ``compare`` estimates it."""
    from ..fit.greybox_fit import greyest

    initial = {f"{state}_0" for state in fitted.estimated_initial_states}
    held = fitted.fixing(*(name for name in fitted.free if name not in initial))
    start = _estimated_initial_state(held, record)
    return greyest(record, start, starts=0).model


def _estimated_initial_state(model: GreyBoxModel, est: IOData) -> GreyBoxModel:
    """``model`` with the initial value of each state that is an output estimated: from the
    record's first sample, within its range widened by the range's span on each side."""
    from ..costs.greybox import record_for

    _, y, _ = record_for(model, est)
    states = {}
    for k, name in enumerate(model.outputs):
        if name not in model.states:
            continue
        lo, hi = float(y[:, k].min()), float(y[:, k].max())
        span = max(hi - lo, 1e-9 * max(abs(lo), abs(hi), 1.0))
        states[name] = (float(y[0, k]), lo - span, hi + span)
    if not states:
        raise ConfigError(
            f"grey-box model {model.name!r}: none of its outputs {list(model.outputs)} is a "
            f"state {list(model.states)}, so initial='estimate' has nothing to estimate; give "
            "the initial states with GreyBoxModel.with_initial_states"
        )
    return model.with_initial_states(**states)


def identify_greybox(
    data: IOData | str | os.PathLike,
    model: GreyBoxModel,
    *,
    optimiser: str,
    params: Mapping[str, Any] | None,
    cost: str | CostSpec | None,
    predictor: str | None,
    weight: float | None,
    budget: Budget,
    seed: int | None,
    split: float | int | None,
    validation: IOData | str | os.PathLike | None,
    max_lag: int,
    callback: Callable | None,
    load_options: Mapping[str, Any] | None,
    alpha: float = VALIDATION_ALPHA,
    reference_starts: int = GREYBOX_REFERENCE_STARTS,
    initial: str | None = None,
    detrend: bool | str | None = None,
) -> GreyBoxIdentification:
    """:func:`flexid.identify` for a grey-box model (called by it; see its parameters)."""
    from ..models.vocabulary import LEAST_SQUARES, OUTPUT_ERROR, PREDICTION_ERROR

    t_start = time.perf_counter()
    if optimiser == LEAST_SQUARES:
        raise ConfigError(
            f"grey-box model {model.name!r} has no least-squares estimate: use "
            "optimiser='pem' (Levenberg-Marquardt) or a registered optimiser"
        )
    record = _record(data, model, load_options)
    if split is None:
        split = ESTIMATION_SHARE
    if validation is not None:
        est, val_record, val_split = record, _record(validation, model, load_options), None
    else:
        est = record.split(split)[0] if isinstance(split, float) else record.split(
            index=int(split))[0]
        val_record, val_split = record, split
    kind = detrend_kind(detrend)
    if kind is not None:
        # a held-out part is validated by running on from the record's start (shift 0)
        est, val_record = detrend_pair(est, val_record, kind, 0 if val_split is not None else None)
    if initial not in (None, "auto", "model", "estimate"):
        raise ConfigError(
            f"grey-box model {model.name!r}: initial must be 'estimate' (the initial values "
            f"of the states that are outputs) or 'model' (its own x0), got {initial!r}"
        )
    if initial == "estimate":
        model = _estimated_initial_state(model, est)
    model.check_samples(est.n_samples)
    cost_spec, _ = specs_from_keywords(cost, predictor=predictor, weight=weight)
    if predictor is None:  # a grey-box model's prediction is its simulation
        cost_spec = replace(cost_spec, predictor="simulation")
    estimation = build_problem(est, model, cost_spec, SearchSpec())
    objective = estimation.cost
    cost_ls = estimation.cost_ls

    t_opt = time.perf_counter()
    ref = None
    if optimiser in (PREDICTION_ERROR, OUTPUT_ERROR):
        ref = estimation.output_error_reference(
            starts=reference_starts, seed=0 if seed is None else seed
        )
        fitted = model.model(ref.theta)
        result, used_params, cost_value = None, {"starts": len(ref.runs)}, ref.cost
    else:
        result = minimize(
            optimiser, estimation.problem, budget, seed, params=params, callback=callback
        )
        fitted = model.model(estimation.theta(result.x))
        used_params, cost_value = dict(result.params), float(result.fun)
    t_val = time.perf_counter()
    on_val = fitted
    if val_split is None and fitted.estimated_initial_states:
        on_val = _initial_state_on(fitted, val_record)
    reports: dict[str, tuple[ValidationReport, ValidationReport]] = {}
    for name in model.outputs:
        reports[name] = (
            validate(fitted, est, max_lag=max_lag, output=name, alpha=alpha,
                     estimated_on="same"),
            validate(on_val, val_record, max_lag=max_lag, split=val_split, output=name,
                     alpha=alpha, estimated_on=est),
        )
    t_end = time.perf_counter()
    first = reports[model.outputs[0]]
    n_val = val_record.n_samples - (0 if val_split is None else est.n_samples)
    units = dict(zip(record.output_names, record.output_units))
    column, factor = model.column(model.outputs[0])
    info = data_info(
        est, n_val, list(model.inputs), list(model.outputs),
        units.get(column, "") if factor == 1.0 else "", record.metadata,
    )
    return GreyBoxIdentification(
        model=fitted,
        optimiser=optimiser,
        params=used_params,
        cost=objective,
        cost_value=float(cost_value),
        cost_ls=cost_ls,
        box=estimation.box,
        result=result,
        estimation=first[0],
        validation=first[1],
        seed=seed,
        search={**estimation.to_dict(), "description": estimation.describe()},
        output_error=ref,
        timings=timings(t_start, t_opt, t_val, t_end),
        data_info=info,
        outputs=reports,
    )
