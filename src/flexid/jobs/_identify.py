"""Identify an ARX model from a record in one call, with an optimiser or least squares.

:func:`identify` splits the record (the paper uses the first 2/3 for estimation), builds the
batched cost, searches an explicit box with the chosen optimiser (``"ls"`` gives least
squares, the exact optimum of the one-step cost), and validates the model on the held-out
part: fit % (one-step and simulation), modelling-error range, residual correlation tests,
stability and spectra.
"""

from __future__ import annotations

import math
import os
import textwrap
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from .._validate import checked_keywords, integer
from ..data.plants import PLANTS, get_plant
from ..data.records import IOData, is_records, joined, prepare_data
from ..errors import BudgetError, ConfigError, DataError, FlexidError, UnknownNameError
from ..fit.delay import estimate_delay
from ..fit.estimation import build_problem, structure_of
from ..fit.greybox_family import greybox_of
from ..models.families import family_named, family_of
from ..models.greybox import GreyBoxModel
from ..models.polynomial import PolynomialStructure, _check_initial
from ..models.specs import CostSpec, SearchSpec
from ..models.statespace import StateSpaceStructure
from ..models.vocabulary import (
    CORRELATION_LAGS,
    IDENTIFY_BUDGET,
    PREDICTION_ERROR,
    REFERENCES,
    VALIDATION_ALPHA,
    current_reference,
)
from ..optimisers import Budget, minimize
from ..validation.diagnostics import check_level
from ..validation.frequency import frf, mode_table
from ..validation.verdict import between_outputs, validate
from ._identification import Identification, data_info, timings
from ._identify_greybox import identify_greybox
from .specs import KEYWORDS, specs_from_keywords

__all__ = ["Identification", "identify"]



@checked_keywords
def identify(
    data: IOData | str | os.PathLike,
    na: int | None = None,
    nb: int | Sequence[int] | None = None,
    nk: int | Sequence[int] | str | None = None,
    *,
    structure: str | PolynomialStructure | GreyBoxModel | StateSpaceStructure | None = None,
    greybox: str | GreyBoxModel | None = None,
    nc: int | None = None,
    nd: int | None = None,
    nf: int | Sequence[int] | None = None,
    order: int | None = None,
    modes: int | None = None,
    frequency: tuple[float, float] | None = None,
    damping: tuple[float, float] | None = None,
    feedthrough: bool | None = None,
    optimiser: str = PREDICTION_ERROR,
    params: Mapping[str, Any] | None = None,
    cost: str | CostSpec | None = None,
    predictor: str | None = None,
    bounds: Any = "auto",
    budget: Budget | int | Mapping[str, Any] = IDENTIFY_BUDGET,
    seed: int | None = 0,
    split: float | int | None = None,
    validation: IOData | str | os.PathLike | None = None,
    output: str | int | None = None,
    detrend: bool | str = False,
    max_lag: int = CORRELATION_LAGS,
    alpha: float = VALIDATION_ALPHA,
    weight: float | None = None,
    penalty: float | None = None,
    initial: str | None = None,
    parametrisation: str | None = None,
    penalty_kind: str | None = None,
    init: str | None = None,
    numerator: str | None = None,
    search: SearchSpec | None = None,
    callback: Callable | None = None,
    load_options: Mapping[str, Any] | None = None,
    validate_initial: str = "estimate",
) -> Identification:
    """Identify a polynomial model (ARX by default) from a record and validate it.

    Parameters
    ----------
    data : IOData or path, or a list of them
        The record (CSV, NPZ, ``.dat`` or MATLAB ``.mat`` when a path; see
        :func:`flexid.data.load`).  A list: several estimation records of one system (MATLAB
        ``merge``), fitted together, each with its own initial state; then ``validation``
        is required, ``split`` is not taken, and an ARX structure is read as a polynomial
        one (:func:`flexid.data.prepare_data`).
    na, nb, nk : int
        Orders and delay in MATLAB's convention.  Without ``structure`` they are the ARX
        model ``A(q) y(t) = B(q) u(t - nk) + e(t)`` (``nb`` defaults to ``na``, ``nk`` to 1;
        one ``nb``/``nk`` per input for several inputs).  ``nk="auto"``: the delays
        estimated from the estimation record as MATLAB ``delayest`` does
        (:func:`flexid.fit.delay.estimate_delay`), said in the summary.
    structure : {"arx", "armax", "oe", "bj", "greybox", "ss"} or a structure object
        The model structure (:mod:`flexid.models.polynomial`): a name, whose orders are given as
        ``na``, ``nb``, ``nc``, ``nd``, ``nf``, ``nk`` (only those the structure has, e.g.
        ``structure="oe", nb=16, nf=16``), or a whole structure (then no orders); or a
        grey-box model (:class:`~flexid.models.greybox.GreyBoxModel`, or ``"greybox"`` with
        ``greybox``): its estimated parameters are fitted on the simulation cost, by
        ``optimiser`` or the reference :func:`flexid.fit.greybox_fit.greyest` (``"pem"``), and it
        is validated by running it on from the record's start into the held-out part.  For
        a grey-box model ``initial="estimate"`` estimates the initial value of every state
        that is an output, searched over the estimation record's range of that output
        widened by its span on each side
        (:meth:`~flexid.models.greybox.GreyBoxModel.with_initial_states`); the default is the
        model's own initial state.
    greybox : str or GreyBoxModel, optional
        The grey-box model of ``structure="greybox"``: a name of
        :func:`flexid.models.greybox_library.greybox_model` (``"twin-rotor-pitch"``, a registered or
        installed model, or ``"path/to/file.py:NAME"``).
    nc, nd, nf : int, optional
        Orders of ``C``, ``D`` and ``F`` (``nf`` one per input) for ``structure``.
    order, modes : int, optional
        For ``structure="ss"``: the state-space model's number of poles and how many of them
        are lightly damped modes (default ``order // 2``;
        :class:`~flexid.models.statespace.StateSpaceStructure`).  It models every output of the
        record (or those ``output`` names) at once, and the summary gives each one's fits.
        Its optimisers search the modal space (frequency and damping of each mode);
        ``"n4sid"`` is subspace identification (:func:`flexid.n4sid`) and ``"pem"`` its
        prediction-error refinement (:func:`flexid.fit.statespace_fit.ssest`).
    frequency, damping : (float, float), optional
        For ``structure="ss"``: the bounds of the modes' natural frequencies (Hz, within
        Nyquist) and damping ratios (within (0, 1]) that the search keeps to.
    feedthrough : bool, optional
        For ``structure="ss"``: estimate ``D`` (default no, MATLAB ``ssest``'s default).
    optimiser : str
        A registered optimiser name (``flexid list optimisers``), ``"ls"`` for least
        squares (the exact optimum of the one-step ARX cost; for other structures the ARX
        least-squares estimate read as the structure, the start of the reference), or
        ``"pem"`` for the gradient reference of the cost: Levenberg-Marquardt with analytic
        gradients from several starts (:func:`flexid.fit.prediction_error.pem`; for ARX with the
        simulation predictor :func:`flexid.fit.output_error.output_error`; for the one-step ARX
        cost, least squares, its exact optimum).  ``"oe"``, its old spelling, warns and runs
        ``"pem"``: an output-error model is ``structure="oe"``.  Default ``"pem"``:
        measured on the built-in plants, a metaheuristic at a default budget ends far from
        it (the twin rotor's ARX(5,5,1) by HBCSD: a pole on the radius cap, held-out
        simulation fit 2.9 % against least squares' 83.4 %), so a metaheuristic is run
        when asked for by name (the paper's: ``"hbcsd"``).
    params : mapping, optional
        The optimiser's hyper-parameters.
    cost : str or CostSpec, optional
        ``"paper"`` (eq. 5-6: ``1e3 sqrt(sum e^2) / K``, plus 1e9 for an unstable model),
        ``"rmse"``, ``"nrmse"``, ``"sse"`` or ``"mse"``; or a whole
        :class:`~flexid.config.CostSpec`, as a program builds it (then none of the cost
        keywords below).
    bounds : see :func:`~flexid.fit.estimation.search_box`
        The search box; recorded in the result.
    budget : int, Budget or mapping
        Function evaluations (an int) or a :class:`~flexid.optimisers.Budget`.
    seed : int, optional
        Seed of the optimiser run (initial population and random draws).
    split : float or int, optional
        Estimation share (default 2/3) or split index.
    validation : IOData or path, optional
        A separate validation record.
    output : str, int or sequence, optional
        Output channel of a multi-output record; for ``structure="ss"`` the outputs (a
        sequence or names joined by commas; default every output).
    detrend : {False, True, "constant", "linear"}
        Remove the estimation record's means (``"constant"`` or True) or its least-squares
        line (``"linear"``) first (:func:`flexid.data.prepare_data`); for a grey-box model,
        from the whole record it runs on (the model then describes the deviations from the
        estimation record's operating point).
    max_lag : int
        Lags of the correlation tests.
    alpha : float
        Family-wise level of the validation verdicts (default 5 %): a true model fails its
        residual tests in at most ``alpha`` of records (:func:`flexid.validate`).
{keywords}
    search : SearchSpec, optional
        All search settings at once, as a program builds them (then none of the search
        keywords above).
    callback : callable, optional
        Called after each optimiser iteration (progress bars).
    load_options : mapping, optional
        Options for reading a file (``inputs``, ``outputs``, ``dt``).
    validate_initial : {"estimate", "zero", "measured"}, optional
        Initial-condition rule of the validation's predictions and simulations (default
        ``"estimate"``, the initial state fitted by least squares, as MATLAB ``compare``):
        every reported fit states it.

    Returns
    -------
    Identification

    Raises
    ------
    DataError, DataFileError, ModelOrderError, UnknownNameError, HyperParameterError,
    BudgetError, ConfigError
        For bad data, files, orders, names, hyper-parameters, budgets or bounds.
    """
    t_start = time.perf_counter()
    _check_initial(validate_initial, "validation initial-condition rule")
    alpha = check_level(alpha, ConfigError)
    optimiser = current_reference(optimiser, stacklevel=4)  # past the keyword checker
    if optimiser not in REFERENCES:
        budget = _budget(budget)
    model_gb = greybox_of(structure, greybox)
    if model_gb is not None:
        _check_greybox_call(model_gb, data, {
            "na": na, "nb": nb, "nk": nk, "nc": nc, "nd": nd, "nf": nf, "output": output,
            "bounds": None if bounds == "auto" else bounds, "penalty": penalty,
            "parametrisation": parametrisation,
            "penalty_kind": penalty_kind, "init": init, "numerator": numerator,
            "search": search,
        })  # fmt: skip
        return identify_greybox(
            data, model_gb, optimiser=optimiser, params=params, cost=cost,
            predictor=predictor, weight=weight, budget=budget, seed=seed, split=split,
            validation=validation, max_lag=max_lag, alpha=alpha, callback=callback,
            load_options=load_options, initial=initial, detrend=detrend,
        )
    family = _family(structure)
    est, val = prepare_data(
        data,
        output=output,
        split=split,
        validation=validation,
        detrend=detrend,
        load_options=load_options,
        several=family.several_outputs,
    )
    records = est if isinstance(est, tuple) else (est,)
    first = records[0]
    nk, delay_text = _delay(nk, records)
    extra = {k: v for k, v in (("order", order), ("modes", modes), ("frequency", frequency),
                               ("damping", damping), ("feedthrough", feedthrough))
             if v is not None}  # fmt: skip
    structure = structure_of(structure, first.n_inputs, first.n_outputs, na=na, nb=nb, nc=nc,
                             nd=nd, nf=nf, nk=nk, **extra)  # fmt: skip
    for record in (*records, val):
        structure.check_samples(record.n_samples)
    cost_spec, search = specs_from_keywords(
        cost, search, predictor=predictor, weight=weight, penalty=penalty, initial=initial,
        parametrisation=parametrisation, penalty_kind=penalty_kind, init=init,
        numerator=numerator,
    )
    if predictor is None and not isinstance(cost, CostSpec) and "one-step" not in family.predictors:
        cost_spec = replace(cost_spec, predictor=family.predictors[0])
    if optimiser in REFERENCES and structure.kind == "arx" and structure.na == 0:
        # an FIR model (na = 0) has no denominator to search, so the default numerator="fit"
        # space does not exist; a reference searches nothing: the space is only recorded
        search = replace(search, numerator="search")
    estimation = build_problem(est, structure, cost_spec, search, bounds=bounds)
    if len(records) > 1:
        structure = estimation.structure  # ARX is fitted as the polynomial family's there
    objective = estimation.cost
    box = estimation.box
    cost_ls = estimation.cost_ls

    t_opt = time.perf_counter()
    model, result, used_params, used_seed, cost_value, oe = _search(
        estimation, structure, first, optimiser, budget, seed, params, callback
    )
    outputs = list(first.output_names) if family.several_outputs else [first.output_names[0]]
    model = model.named(first.input_names, outputs if len(outputs) > 1 else outputs[0])
    cost_value, cost_search = rescored(objective, model, cost_value)
    t_val = time.perf_counter()
    check = {"max_lag": max_lag, "initial": validate_initial, "alpha": alpha}
    reports, report_val, by_output, between = _reports(model, records, val, outputs, check)
    t_end = time.perf_counter()
    info = data_info(
        records, val.n_samples, list(first.input_names), outputs,
        first.output_units[0], first.metadata,
    )
    if delay_text is not None:
        info["delay"] = delay_text
    return Identification(
        model=model,
        optimiser=optimiser,
        params=used_params,
        cost=objective,
        cost_value=cost_value,
        cost_search=cost_search,
        cost_ls=cost_ls,
        box=box,
        result=result,
        estimation=reports[0],
        validation=report_val,
        estimation_records=reports if len(reports) > 1 else (),
        seed=used_seed,
        search={**estimation.to_dict(), "description": estimation.describe()},
        output_error=oe,
        timings=timings(t_start, t_opt, t_val, t_end),
        data_info=info,
        outputs=by_output,
        output_tests=between,
        modes=_modes(model, val, first.metadata),
    )


def _check_greybox_call(model: Any, data: Any, given: Mapping[str, Any]) -> None:
    """A grey-box model is identified on one record, and takes none of the orders and
    search settings of the other families (its parameters, bounds and channels are its own)."""
    if is_records(data):
        raise ConfigError(
            f"grey-box model {model.name!r}: several estimation records are not "
            "supported (its states run on from one record's start); estimate on one"
        )
    extra = sorted(k for k, v in given.items() if v is not None)
    if extra:
        raise ConfigError(
            f"grey-box model {model.name!r} does not take {', '.join(extra)} (its "
            "parameters, bounds and channels are set on the model)"
        )


def _delay(nk: Any, records: tuple[IOData, ...]) -> tuple[Any, str | None]:
    """``nk`` as given, or estimated from the records for ``"auto"``, with the line that
    says how (None when given)."""
    if not isinstance(nk, str):
        return nk, None
    if nk != "auto":
        raise ConfigError(f"nk must be a delay in samples (per input) or 'auto', got {nk!r}")
    first = records[0]
    found = estimate_delay(first if len(records) == 1 else joined(records))
    return (list(found.nk) if first.n_inputs > 1 else found.nk[0]), found.describe()


def _reports(
    model: Any, records: tuple[IOData, ...], val: IOData, outputs: list[str],
    check: Mapping[str, Any],
) -> tuple[tuple, Any, tuple, tuple]:
    """The estimation reports (one per record), the held-out report, and with several
    outputs every output's pair of reports (one record) and the tests between outputs."""
    if len(outputs) == 1:
        reports = tuple(validate(model, r, estimated_on="same", **check) for r in records)
        return reports, validate(model, val, estimated_on=records, **check), (), ()
    by_output = tuple(
        (validate(model, records[0], output=o, estimated_on="same", **check),
         validate(model, val, output=o, estimated_on=records, **check))
        for o in outputs
    )  # fmt: skip
    between = tuple(between_outputs([v for _, v in by_output]))
    return (by_output[0][0],), by_output[0][1], by_output, between  # the first's


def _modes(model: Any, val: IOData, metadata: Mapping[str, Any]) -> tuple:
    """The model's mode table against the held-out record's peaks and, on a record a flexid
    plant simulated, the plant's own modes at the record's mean input; empty for a model
    without a frequency response."""
    if not hasattr(model, "frequency_response"):
        return ()
    try:
        estimate = frf(val)
    except DataError:  # too short or a constant input: the table without the record's peaks
        estimate = None
    truth = None
    if metadata.get("plant") in PLANTS:
        # the operating point: the record's mean input, a removed mean put back
        removed = (metadata.get("detrend") or {}).get("u_mean")
        mean = val.u.mean(axis=0) + (np.asarray(removed) if removed is not None else 0.0)
        try:
            truth = get_plant(metadata["plant"]).true_modes(
                metadata.get("parameters"), inputs=dict(zip(val.input_names, mean)))
        except FlexidError:  # a plant without its modes, or parameters it does not know
            truth = None
    return tuple(mode_table(model, estimate=estimate, truth=truth))


def _family(structure: Any) -> Any:
    """The family a structure name or object belongs to (the polynomial one for ``None``)."""
    if structure is None:
        return family_named("arx")
    if isinstance(structure, str):
        try:
            return family_named(structure)
        except UnknownNameError:
            return family_named("arx")  # structure_of names the unknown name as given
    return family_of(structure)


#: Relative disagreement between a final model's cost as the search computed it (the fast
#: direct form) and in a well-conditioned realisation beyond which the model is rescored.
#: Where the direct form is well conditioned the two agree to about 1e-12.
RESCORE_BOUND = 1e-6


def rescored(objective: Any, model: Any, cost_value: float) -> tuple[float, float | None]:
    """A final model's cost in a well-conditioned realisation, where the search's is off.

    Parameters
    ----------
    objective : cost
        The search's cost; rescoring needs its ``realised_cost(theta)`` (the polynomial
        family's costs have it).
    model : model
        The final model (its ``theta``).
    cost_value : float
        The cost the search reported for it.

    Returns
    -------
    cost : float
        The realised cost where the two disagree by more than :data:`RESCORE_BOUND`
        (relative, and above the cost's ``rounding_floor()``), else ``cost_value``.
    search_cost : float or None
        ``cost_value`` when the model was rescored, else None.
    """
    realised = getattr(objective, "realised_cost", None)
    theta = getattr(model, "theta", None)
    if realised is None or theta is None or not math.isfinite(cost_value):
        return cost_value, None
    value = float(realised(theta))
    floor = getattr(objective, "rounding_floor", lambda: 0.0)()
    if not math.isfinite(value) or abs(value - cost_value) <= RESCORE_BOUND * max(
        abs(value), floor
    ):
        return cost_value, None
    return value, cost_value


def _search(
    estimation: Any, structure: Any, est: IOData, optimiser: str, budget: Any,
    seed: int | None, params: Mapping[str, Any] | None, callback: Callable | None,
) -> tuple[Any, Any, dict, int | None, float, Any]:
    """Fit a structure by its family's own estimate (``"ls"``, ``"pem"``, ``"oe"``) or an
    optimiser.

    Returns ``(model, optimiser result or None, hyper-parameters used, seed used, cost,
    reference result or None)``.
    """
    if optimiser in REFERENCES:
        fit = family_of(structure).fit(estimation, structure, optimiser, data=est, seed=seed)
        return fit.model, None, fit.params, fit.seed, fit.cost, fit.result
    result = minimize(optimiser, estimation.problem, budget, seed, params=params,
                      callback=callback)
    model = structure.model(estimation.theta(result.x), dt=est.dt)
    return model, result, dict(result.params), result.seed, float(result.fun), None


def _budget(budget: Budget | int | Mapping[str, Any]) -> Budget:
    """The budget, checked before any work; errors name the ``budget`` argument."""
    if isinstance(budget, (Budget, type(None))):
        return Budget.coerce(budget)  # a Budget is checked already; None is refused there
    if isinstance(budget, Mapping):
        try:
            return Budget.coerce(budget)
        except BudgetError as exc:
            raise BudgetError(f"budget: {exc}") from None
    max_fe = integer(budget, "budget (function evaluations)", error=BudgetError, minimum=1)
    return Budget.coerce(max_fe)


def _keyword_entries() -> str:
    """The docstring entries of the cost and search keywords, from the one table."""
    specs = {"cost": "CostSpec", "search": "SearchSpec"}
    lines = []
    for k in KEYWORDS:
        kind = "float" if k.field in ("weight", "penalty") and k.spec == "cost" else "str"
        lines.append(f"    {k.name} : {kind}, optional")
        text = (f"{k.help[0].upper()}{k.help[1:]}; the field ``{k.field}`` of "
                f":class:`~flexid.config.{specs[k.spec]}`.")  # fmt: skip
        lines += textwrap.wrap(text, 88, initial_indent=" " * 8, subsequent_indent=" " * 8)
    return "\n".join(lines)


# the checked wrapper and the function it wraps say the same
identify.__doc__ = identify.__wrapped__.__doc__ = (identify.__doc__ or "").replace(
    "{keywords}", _keyword_entries()
)
