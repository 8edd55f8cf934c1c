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
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ._json import jsonable
from ._validate import checked_keywords, integer
from .arx import ARX
from .config import (
    IDENTIFY_BUDGET,
    LEAST_SQUARES,
    OUTPUT_ERROR,
    PREDICTION_ERROR,
    REFERENCES,
    CostSpec,
    SearchSpec,
)
from .data import IOData, prepare_data
from .diagnostics import format_fit
from .errors import BudgetError, ConfigError
from .estimation import SearchBox, build_problem, greybox_of, structure_of
from .greybox import GreyBoxModel
from .objective import ARXCost
from .optimisers import Budget, History, minimize
from .polynomial import PolynomialStructure, _check_initial
from .validation import ValidationReport, validate

__all__ = ["Identification", "identify"]



# ================================================================================ result
@dataclass
class Identification:
    """The outcome of :func:`identify`.

    Attributes
    ----------
    model : ARX or PolynomialModel
        The identified model (:class:`~flexid.arx.ARX` for the ARX structure).
    optimiser : str
        Optimiser name (``"ls"`` for least squares, ``"oe"`` for the output-error
        reference).
    params : dict
        The optimiser's hyper-parameters.
    cost : ARXCost or PolynomialCost
        The cost that was minimised (on the estimation record).
    cost_value : float
        Cost of ``model`` under it.
    cost_ls : float
        Cost of the least-squares estimate under it (the reference).
    box : SearchBox
        The search box (for ``"ls"``: the box an optimiser would have searched).
    result : OptimizeResult or None
        The optimiser's result (``None`` for least squares and the output-error reference).
    estimation, validation : ValidationReport
        Validation on the estimation and on the held-out record.
    seed : int or None
        Seed of the optimiser run.
    timings : dict
        Seconds spent: ``setup_s``, ``optimise_s``, ``validate_s`` and ``total_s``.
    data_info : dict
        The records used: ``description``, ``n_estimation``, ``n_validation``, ``dt`` (s),
        ``inputs``, ``output``, ``output_unit`` and ``source``.
    search : dict
        The search space (:meth:`flexid.estimation.EstimationProblem.to_dict` plus a
        ``description``).
    output_error : OEResult, PEMResult or None
        The Levenberg-Marquardt result when ``optimiser`` is ``"oe"`` or ``"pem"``, else
        None.
    """

    model: ARX
    optimiser: str
    params: dict
    cost: ARXCost
    cost_value: float
    cost_ls: float
    box: SearchBox
    result: Any
    estimation: ValidationReport
    validation: ValidationReport
    seed: int | None
    timings: dict = field(default_factory=dict)
    data_info: dict = field(default_factory=dict)
    search: dict = field(default_factory=dict)
    output_error: Any = None

    @property
    def history(self) -> History | None:
        """Best cost against function evaluations (``None`` for least squares)."""
        return None if self.result is None else self.result.history

    @property
    def nfev(self) -> int:
        """Function evaluations used (0 for least squares; simulations for ``"oe"``)."""
        if self.output_error is not None:
            return int(self.output_error.nfev_equivalent)
        return 0 if self.result is None else int(self.result.nfev)

    def _title(self) -> str:
        s = self.model.structure
        name = (
            repr(s)
            if isinstance(s, PolynomialStructure)
            else f"ARX(na={s.na}, nb={list(s.nb)}, nk={list(s.nk)})"
        )
        return f"{name} identified by {self.optimiser}" + (
            f" (seed {self.seed})" if self.seed is not None else ""
        )

    def _items(self) -> list[tuple[str, str]]:
        """The labelled header lines of :meth:`summary` (shared with the notebook display)."""
        items = [
            ("data", self.data_info.get("description", "")),
            ("cost", self.cost.describe()),
            ("search box", self.search.get("box_rule", self.box.rule)),
        ]
        if self.search:
            items.append(("search space", self.search.get("description", "")))
        if self.output_error is not None:
            oe = self.output_error
            text = (
                f"Levenberg-Marquardt, {len(oe.runs)} runs (starts and continuations), "
                f"{oe.nfev} residual + {oe.njev} Jacobian evaluations"
            )
            if hasattr(oe, "optimality"):
                where = (
                    "a local minimum"
                    if oe.local_minimum
                    else ("on the pole-radius cap" if oe.on_cap else "not a local minimum")
                )
                text += f"; first-order optimality {oe.optimality:.2g}: {where}"
            items.append(("search", text))
        if self.result is not None:
            items.append(
                (
                    "search",
                    f"{self.result.nfev} FE, {self.result.nit} iterations, {self.result.message}",
                )
            )
        ratio = self.cost_value / self.cost_ls if self.cost_ls > 0 else float("nan")
        ls_name = (
            "ARX least squares read as the structure"
            if isinstance(self.model.structure, PolynomialStructure)
            else "least squares"
        )
        items.append(
            (
                "final cost",
                f"{self.cost_value:.6g}  ({ls_name} {self.cost_ls:.6g}, ratio {ratio:.4g})",
            )
        )
        items.append(
            (
                "time",
                f"optimise {self.timings.get('optimise_s', 0):.3f} s, "
                f"validate {self.timings.get('validate_s', 0):.3f} s",
            )
        )
        return items

    def advice(self) -> str | None:
        """One plain line when the model should not be trusted, with what to try next.

        Checked: an optimiser's final cost more than 10 % above the least-squares cost (the
        exact optimum of the one-step ARX cost, and where the other searches start), a pole
        on the search space's radius cap (the search ran into its boundary), the held-out
        whiteness or cross-correlation test failing (the structure does not describe the
        data), a negative held-out simulation fit.

        Returns
        -------
        str or None
            ``"warning: ...: try ..."``, or None when none of these holds.
        """
        problems: list[str] = []
        tries: list[str] = []
        structure = self.model.structure
        arx = not isinstance(structure, PolynomialStructure) or structure.kind == "arx"
        reference = "optimiser='ls'" if arx and self.cost.predictor == "one-step" else (
            "optimiser='oe'" if arx else "optimiser='pem'"
        )
        if self.result is not None:
            if self.cost_ls > 0 and self.cost_value > 1.1 * self.cost_ls:
                problems.append(
                    f"the final cost is {self.cost_value / self.cost_ls:.3g} times the "
                    "least-squares cost"
                )
                tries.append(f"{reference} (the reference) or a larger budget")
            r_max = float(self.search.get("r_max", SearchSpec().r_max))
            radius = self.validation.stability.max_pole_radius
            if math.isfinite(radius) and radius >= r_max * (1.0 - 1e-9):
                problems.append(f"a pole sits on the radius cap {r_max:g}")
                tries.append(f"{reference} (the reference) or a larger budget")
        if not self.validation.linear_passed:
            problems.append("the held-out correlation tests fail")
            tries.append("another structure or higher orders (flexid select)")
        if self.validation.fit_simulation < 0:
            problems.append(
                f"the held-out simulation fit is {format_fit(self.validation.fit_simulation)} %"
            )
        if not problems:
            return None
        unique = list(dict.fromkeys(tries))
        return "warning: " + "; ".join(problems) + (
            ": try " + ", or ".join(unique) if unique else ""
        )

    def summary(self) -> str:
        """A readable multi-line account: data, search, cost, model, validation, advice.

        Returns
        -------
        str
            The header lines (data, cost, search, final cost, time), the model's
            :meth:`~flexid.ARX.summary`, the validation summaries of both records and, when
            the model should not be trusted, one last line that says why (:meth:`advice`).
        """
        lines = [self._title()]
        lines += [f"  {label:<12}: {value}" for label, value in self._items()]
        lines.append("")
        lines.append(self.model.summary())
        lines.append("")
        lines.append("Estimation record")
        lines.append(_indent(self.estimation.summary()))
        lines.append("Validation record (held out)")
        lines.append(_indent(self.validation.summary()))
        advice = self.advice()
        if advice:
            lines.append(advice)
        return "\n".join(lines)

    def _repr_html_(self) -> str:
        """The notebook display: the numbers of :meth:`summary`, the long parts collapsed."""
        from . import _html

        rows = [["", "estimation", "validation (held out)"]]
        columns = [_report_column(r) for r in (self.estimation, self.validation)]
        for label, est, val in zip(_REPORT_ROWS, *columns):
            rows.append([label, est, val])
        return _html.block(
            self._title(),
            _html.key_values(self._items()),
            _html.table(rows),
            _html.details("model", self.model.summary()),
            _html.details("estimation record", self.estimation.summary()),
            _html.details("validation record (held out)", self.validation.summary()),
        )

    def to_dict(self) -> dict[str, Any]:
        """Machine-readable result (JSON-safe): coefficients, cost, fits, stability, timings.

        Non-finite numbers are ``None`` (see :func:`flexid._json.jsonable`).

        Returns
        -------
        dict
            ``structure``, ``optimiser``, ``params``, ``seed``, ``cost`` (description,
            value, least squares), ``search``, ``model`` (:meth:`~flexid.ARX.to_dict`),
            ``estimation`` and ``validation`` (:meth:`ValidationReport.to_dict`),
            ``timings`` (s) and ``data``.
        """
        m = self.model
        return jsonable(
            {
                "structure": _structure_dict(m.structure),
                "optimiser": self.optimiser,
                "params": self.params,
                "seed": self.seed,
                "cost": {
                    "description": self.cost.describe(),
                    "value": self.cost_value,
                    "least_squares": self.cost_ls,
                },
                "search": {
                    "space": self.search,
                    "box": self.box.to_dict(),
                    "nfev": self.nfev,
                    "nit": 0 if self.result is None else int(self.result.nit),
                    "message": "least squares (closed form)"
                    if self.result is None
                    else self.result.message,
                },
                "model": m.to_dict(),
                "estimation": self.estimation.to_dict(),
                "validation": self.validation.to_dict(),
                "timings": {k: round(v, 6) for k, v in self.timings.items()},
                "data": self.data_info,
            }
        )


def _structure_dict(structure: Any) -> dict[str, Any]:
    """The structure's name and orders (an ARX structure's as before, with its name)."""
    if isinstance(structure, PolynomialStructure):
        return structure.to_dict()
    return {
        "structure": "arx",
        "na": structure.na,
        "nb": list(structure.nb),
        "nk": list(structure.nk),
    }


_REPORT_ROWS = (
    "samples",
    "fit one-step %",
    "fit simulation %",
    "RMSE one-step",
    "RMSE simulation",
    "error range one-step",
    "correlation tests",
    "largest pole radius",
    "spectral peak measured, Hz",
    "spectral peak model, Hz",
)


def _report_column(report: ValidationReport) -> list[str]:
    """One report's entries of the notebook table, formatted as its ``summary()`` does."""
    lo, hi = report.error_range_one_step
    st = report.stability
    return [
        f"{report.n_samples}",
        format_fit(report.fit_one_step),
        format_fit(report.fit_simulation) + (" (diverged)" if report.simulation_diverged else ""),
        f"{report.rmse_one_step:.4g}",
        f"{report.rmse_simulation:.4g}",
        f"[{lo:.4g}, {hi:.4g}]",
        "PASS" if report.passed else "FAIL",
        f"{st.max_pole_radius:.5f}" + ("" if st.stable else " (UNSTABLE)"),
        f"{report.peak_measured:.4g}",
        f"{report.peak_model:.4g}",
    ]


def _indent(text: str, prefix: str = "  ") -> str:
    return "\n".join(prefix + line if line else line for line in text.splitlines())


# ================================================================================ identify
@checked_keywords
def identify(
    data: IOData | str | os.PathLike,
    na: int | None = None,
    nb: int | Sequence[int] | None = None,
    nk: int | Sequence[int] | None = None,
    *,
    structure: str | PolynomialStructure | GreyBoxModel | None = None,
    greybox: str | GreyBoxModel | None = None,
    nc: int | None = None,
    nd: int | None = None,
    nf: int | Sequence[int] | None = None,
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
    detrend: bool = False,
    max_lag: int = 25,
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
    data : IOData or path
        The record (CSV, NPZ, ``.dat`` or MATLAB ``.mat`` when a path; see
        :func:`flexid.data.load`).
    na, nb, nk : int
        Orders and delay in MATLAB's convention.  Without ``structure`` they are the ARX
        model ``A(q) y(t) = B(q) u(t - nk) + e(t)`` (``nb`` defaults to ``na``, ``nk`` to 1;
        one ``nb``/``nk`` per input for several inputs).
    structure : {"arx", "armax", "oe", "bj", "greybox"}, PolynomialStructure or GreyBoxModel
        The model structure (:mod:`flexid.polynomial`): a name, whose orders are given as
        ``na``, ``nb``, ``nc``, ``nd``, ``nf``, ``nk`` (only those the structure has, e.g.
        ``structure="oe", nb=16, nf=16``), or a whole structure (then no orders); or a
        grey-box model (:class:`~flexid.greybox.GreyBoxModel`, or ``"greybox"`` with
        ``greybox``): its estimated parameters are fitted on the simulation cost, by
        ``optimiser`` or the reference :func:`flexid.greybox_fit.greyest` (``"pem"``), and it
        is validated by running it on from the record's start into the held-out part.
    greybox : str or GreyBoxModel, optional
        The grey-box model of ``structure="greybox"``: a name of
        :func:`flexid.greybox_models.greybox_model` (``"twin-rotor-pitch"``, a registered or
        installed model, or ``"path/to/file.py:NAME"``).
    nc, nd, nf : int, optional
        Orders of ``C``, ``D`` and ``F`` (``nf`` one per input) for ``structure``.
    optimiser : str
        A registered optimiser name (``flexid list optimisers``), ``"ls"`` for least
        squares (the exact optimum of the one-step ARX cost; for other structures the ARX
        least-squares estimate read as the structure, the start of the reference), or
        ``"pem"`` for the gradient reference of the cost: Levenberg-Marquardt with analytic
        gradients from several starts (:func:`flexid.prediction_error.pem`; for ARX with the
        simulation predictor :func:`flexid.output_error.output_error`, also named ``"oe"``;
        for the one-step ARX cost, least squares, its exact optimum).  Default ``"pem"``:
        measured on the built-in plants, a metaheuristic at a default budget ends far from
        it (the twin rotor's ARX(5,5,1) by HBCSD: a pole on the radius cap, held-out
        simulation fit 2.9 % against least squares' 83.4 %), so a metaheuristic is run
        when asked for by name (the paper's: ``"hbcsd"``).
    params : mapping, optional
        The optimiser's hyper-parameters.
    cost : str or CostSpec, optional
        ``"paper"`` (eq. 5-6: ``1e3 sqrt(sum e^2) / K``, plus 1e9 for an unstable model),
        ``"rmse"``, ``"nrmse"``, ``"sse"`` or ``"mse"``.
    predictor : str, optional
        ``"one-step"`` (equation error, as in the paper) or ``"simulation"`` (output error).
    bounds : see :func:`~flexid.estimation.search_box`
        The search box; recorded in the result.
    budget : int, Budget or mapping
        Function evaluations (an int) or a :class:`~flexid.optimisers.Budget`.
    seed : int, optional
        Seed of the optimiser run (initial population and random draws).
    split : float or int, optional
        Estimation share (default 2/3) or split index.
    validation : IOData or path, optional
        A separate validation record.
    output : str or int, optional
        Output channel of a multi-output record.
    detrend : bool
        Remove the estimation record's means first.
    max_lag : int
        Lags of the correlation tests.
    weight, penalty : float, optional
        Gain ``w`` and stability penalty of the paper cost.
    initial : str, optional
        Initial-condition rule of the cost: ``"estimate"``, ``"zero"``, ``"measured"`` or
        ``"auto"`` (the default: ``"measured"`` for ARX, ``"estimate"`` otherwise; see
        :func:`flexid.estimation.resolve_initial`).

        ``predictor``, ``weight``, ``penalty`` and ``initial`` override the fields of ``cost``
        (a metric name or a whole :class:`~flexid.config.CostSpec`); what is not given is
        :class:`~flexid.config.CostSpec`'s default, the one definition of a cost's settings.
    parametrisation : {"poles", "reflection", "coefficients"}, optional
        The search space (default ``"poles"``; ``"coefficients"`` is the paper's box).
    penalty_kind : {"graded", "flat"}, optional
        Stability penalty in the coefficient space (default ``"graded"``; ``"flat"`` is the
        paper's constant ``penalty``).
    init : {"stable", "uniform"}, optional
        Initial population in the coefficient space (default ``"stable"``).
    numerator : {"search", "fit"}, optional
        ``"fit"``: the optimiser searches the denominator only and each candidate's ``b`` is
        the least-squares optimum of the cost for it (see :class:`~flexid.config.SearchSpec`).
    search : SearchSpec, optional
        All search settings at once (the four above override its fields).
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
    if optimiser not in REFERENCES:
        budget = _budget(budget)
    model_gb = greybox_of(structure, greybox)
    if model_gb is not None:
        given = {
            "na": na, "nb": nb, "nk": nk, "nc": nc, "nd": nd, "nf": nf, "output": output,
            "bounds": None if bounds == "auto" else bounds, "penalty": penalty,
            "initial": initial, "parametrisation": parametrisation,
            "penalty_kind": penalty_kind, "init": init, "numerator": numerator,
            "search": search, "detrend": detrend or None,
        }
        extra = sorted(k for k, v in given.items() if v is not None)
        if extra:
            raise ConfigError(
                f"grey-box model {model_gb.name!r} does not take {', '.join(extra)} (its "
                "parameters, bounds and channels are set on the model)"
            )
        from ._identify_greybox import identify_greybox

        return identify_greybox(
            data, model_gb, optimiser=optimiser, params=params, cost=cost,
            predictor=predictor, weight=weight, budget=budget, seed=seed, split=split,
            validation=validation, max_lag=max_lag, callback=callback,
            load_options=load_options,
        )
    est, val = prepare_data(
        data,
        output=output,
        split=split,
        validation=validation,
        detrend=detrend,
        load_options=load_options,
    )
    structure = structure_of(structure, est.n_inputs, na=na, nb=nb, nc=nc, nd=nd, nf=nf, nk=nk)
    polynomial = isinstance(structure, PolynomialStructure)
    structure.check_samples(est.n_samples)
    structure.check_samples(val.n_samples)
    given = {
        "parametrisation": parametrisation,
        "penalty": penalty_kind,
        "init": init,
        "numerator": numerator,
    }
    overrides = {k: v for k, v in given.items() if v is not None}
    search = replace(search or SearchSpec(), **overrides)
    if optimiser in REFERENCES and not polynomial and structure.na == 0:
        # an FIR model (na = 0) has no denominator to search, so the default numerator="fit"
        # space does not exist; a reference searches nothing: the space is only recorded
        search = replace(search, numerator="search")
    cost_given = {
        "metric": None if isinstance(cost, CostSpec) else cost,
        "predictor": predictor,
        "weight": weight,
        "penalty": penalty,
        "initial": initial,
    }
    base = cost if isinstance(cost, CostSpec) else CostSpec()
    cost_spec = replace(base, **{k: v for k, v in cost_given.items() if v is not None})
    predictor = cost_spec.predictor  # build_problem resolves the "auto" initial rule
    estimation = build_problem(est, structure, cost_spec, search, bounds=bounds)
    objective = estimation.cost
    box = estimation.box
    cost_ls = estimation.cost_ls

    t_opt = time.perf_counter()
    model, result, used_params, used_seed, cost_value, oe = _search(
        estimation, structure, est, optimiser, predictor, budget, seed, params, callback
    )
    t_val = time.perf_counter()
    report_est = validate(model, est, max_lag=max_lag, initial=validate_initial)
    report_val = validate(model, val, max_lag=max_lag, initial=validate_initial)
    t_end = time.perf_counter()
    info = data_info(
        est, val.n_samples, list(est.input_names), [est.output_names[0]],
        est.output_units[0], est.metadata,
    )
    return Identification(
        model=model,
        optimiser=optimiser,
        params=used_params,
        cost=objective,
        cost_value=cost_value,
        cost_ls=cost_ls,
        box=box,
        result=result,
        estimation=report_est,
        validation=report_val,
        seed=used_seed,
        search={**estimation.to_dict(), "description": estimation.describe()},
        output_error=oe,
        timings=timings(t_start, t_opt, t_val, t_end),
        data_info=info,
    )


def _search(
    estimation: Any, structure: Any, est: IOData, optimiser: str, predictor: str, budget: Any,
    seed: int | None, params: Mapping[str, Any] | None, callback: Callable | None,
) -> tuple[Any, Any, dict, int | None, float, Any]:
    """Fit a polynomial structure by least squares, its gradient reference or an optimiser.

    Returns ``(model, optimiser result or None, hyper-parameters used, seed used, cost,
    reference result or None)``.
    """
    polynomial = isinstance(structure, PolynomialStructure)
    objective, cost_ls = estimation.cost, estimation.cost_ls
    # the gradient reference of the one-step ARX cost is its exact optimum, least squares
    arx_ls = optimiser == PREDICTION_ERROR and not polynomial and predictor != "simulation"
    if (optimiser == LEAST_SQUARES or arx_ls) and not polynomial:
        return structure.least_squares(est.u, est.y[:, 0], dt=est.dt), None, {}, None, \
            cost_ls, None
    if optimiser == LEAST_SQUARES:
        if not np.isfinite(objective.theta_ls).all():
            raise ConfigError(
                f"{structure!r} has no least-squares start (its F polynomials differ in "
                "order); use optimiser='pem'"
            )
        return structure.model(objective.theta_ls, dt=est.dt), None, {}, None, cost_ls, None
    if optimiser in (OUTPUT_ERROR, PREDICTION_ERROR):
        if not polynomial and predictor != "simulation":
            raise ConfigError(
                "the output-error reference ('oe') minimises the simulation cost: use "
                "predictor='simulation' (--predictor simulation); least squares ('ls') is "
                "the optimum of the one-step cost"
            )
        oe = estimation.output_error_reference(seed=0 if seed is None else seed)
        if polynomial:
            model = type(oe.model)(
                structure, oe.theta, dt=est.dt, param_std=oe.model.param_std,
                noise_variance=oe.model.noise_variance,
            )
        else:
            model = structure.model(oe.theta, dt=est.dt)
        return model, None, {"starts": len(oe.runs)}, seed, float(oe.cost), oe
    result = minimize(optimiser, estimation.problem, budget, seed, params=params,
                      callback=callback)
    model = structure.model(estimation.theta(result.x), dt=est.dt)
    return model, result, dict(result.params), result.seed, float(result.fun), None


def timings(t_start: float, t_opt: float, t_val: float, t_end: float) -> dict[str, float]:
    """Seconds spent setting up, optimising and validating, and in all (an identification's)."""
    return {
        "setup_s": t_opt - t_start,
        "optimise_s": t_val - t_opt,
        "validate_s": t_end - t_val,
        "total_s": t_end - t_start,
    }


def data_info(
    est: IOData, n_validation: int, inputs: list[str], outputs: list[str], unit: str,
    metadata: Mapping[str, Any],
) -> dict[str, Any]:
    """What an identification says of its records (:attr:`Identification.data_info`)."""
    assumed = bool(metadata.get("dt_assumed"))  # no time column, no dt given
    named = f"output {outputs[0]!r}" if len(outputs) == 1 else f"outputs {outputs}"
    return {
        "description": (
            f"{est.n_samples} estimation + {n_validation} validation samples, dt {est.dt:g} s"
            f"{' (ASSUMED: the record has no time column; give --dt or dt=)' if assumed else ''}"
            f", inputs {inputs}, {named}"
        ),
        "n_estimation": est.n_samples,
        "n_validation": n_validation,
        "dt": est.dt,
        "inputs": inputs,
        "output": outputs[0],
        "output_unit": unit,
        "source": metadata.get("source") or metadata.get("plant"),
    }


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
