"""The result of an identification: :class:`Identification`, its report and its summary.

:func:`flexid.identify` makes one; the grey-box identification's result
(:class:`~flexid.jobs._identify_greybox.GreyBoxIdentification`) extends it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from .._json import jsonable
from .._table import labelled, wrapped
from ..costs.arx import ARXCost
from ..data.records import IOData
from ..fit.parametrisation import SearchBox
from ..models.arx import ARX
from ..models.families import family_of
from ..models.specs import SearchSpec
from ..models.vocabulary import VALIDATION_GUIDE
from ..optimisers import History
from ..validation.diagnostics import format_fit
from ..validation.frequency import mode_table_text
from ..validation.verdict import ValidationReport, joint_tests, joint_verdict

__all__ = ["Identification", "data_info", "timings"]


# ================================================================================ result
@dataclass
class Identification:
    """The outcome of :func:`identify`.

    Attributes
    ----------
    model : ARX or PolynomialModel
        The identified model (:class:`~flexid.models.arx.ARX` for the ARX structure).
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
        The search space (:meth:`flexid.fit.estimation.EstimationProblem.to_dict` plus a
        ``description``).
    output_error : OEResult, PEMResult or None
        The Levenberg-Marquardt result when ``optimiser`` is ``"oe"`` or ``"pem"``, else
        None.
    cost_search : float or None
        The final model's cost as the search computed it (the fast direct form), where it
        disagreed with ``cost_value`` (the model run in a well-conditioned realisation) by
        more than :data:`flexid.jobs._identify.RESCORE_BOUND`; None where they agree.
    estimation_records : tuple of ValidationReport
        With several estimation records, the validation on each (``estimation`` is the
        first); empty with one.
    outputs : tuple of (ValidationReport, ValidationReport)
        With several outputs (a state-space model), each output's estimation and held-out
        reports, in the record's order (``estimation`` and ``validation`` are the first
        output's); empty with one.
    output_tests : tuple of CorrelationTest
        With several outputs, the held-out residuals' cross-correlation between every pair
        of outputs at nonzero lags (:func:`flexid.validation.diagnostics.output_cross_tests`).
    modes : tuple of ModeMatch
        A linear model's oscillating modes with the held-out record's confirmed resonance
        peaks and, on a record simulated by a flexid plant, the plant's own modes
        (:func:`flexid.validation.frequency.mode_table`); empty for a model without modes.
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
    cost_search: float | None = None
    estimation_records: tuple = ()
    outputs: tuple = ()
    output_tests: tuple = ()
    modes: tuple = ()

    @property
    def joint_tests(self) -> list:
        """With several outputs, every output's held-out tests and those between outputs
        judged together (:func:`flexid.validation.joint_tests`); empty with one output."""
        if not self.outputs:
            return []
        return joint_tests([v for _, v in self.outputs], self.output_tests)

    @property
    def passed(self) -> bool:
        """The held-out verdict: the validation report's, or with several outputs the joint
        one (a true model fails it in at most ``alpha`` of records)."""
        if self.outputs:
            return all(t.passed for t in self.joint_tests)
        return self.validation.passed

    @property
    def held_out(self) -> tuple[ValidationReport, ...]:
        """The held-out report of every output (one with one output)."""
        return tuple(v for _, v in self.outputs) or (self.validation,)

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

    def _name(self) -> str:
        """What was identified, for the summary's first line."""
        return family_of(self.model.structure).title(self.model.structure)

    def _start_name(self) -> str:
        """The start the final cost is compared with (least squares, n4sid, ...)."""
        return family_of(self.model.structure).start_name(self.model.structure)

    def _reference_text(self) -> str:
        """The gradient reference's search line: its runs, evaluations and where it ended."""
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
            if oe.on_cap and oe.get("cap_reason"):
                where += f": {oe.cap_reason}"
            text += f"; first-order optimality {oe.optimality:.2g}: {where}"
        return text

    def _box_items(self) -> list[tuple[str, str]]:
        """The search box's line (a family whose bounds are its parameters' has none)."""
        return [("search box", self.search.get("box_rule", self.box.rule))]

    def _title(self) -> str:
        return f"{self._name()} identified by {self.optimiser}" + (
            f" (seed {self.seed})" if self.seed is not None else ""
        )

    def _items(self) -> list[tuple[str, str]]:
        """The labelled header lines of :meth:`summary` (shared with the notebook display)."""
        items = [
            ("data", self.data_info.get("description", "")),
            *([("delay", self.data_info["delay"])] if "delay" in self.data_info else []),
            ("cost", self.cost.describe()),
            *self._box_items(),
        ]
        if self.search:
            items.append(("search space", self.search.get("description", "")))
        if self.output_error is not None:
            items.append(("search", self._reference_text()))
        if self.result is not None:
            items.append(
                (
                    "search",
                    f"{self.result.nfev} FE, {self.result.nit} iterations, {self.result.message}",
                )
            )
        ratio = self.cost_value / self.cost_ls if self.cost_ls > 0 else float("nan")
        items.append(
            (
                "final cost",
                f"{self.cost_value:.6g}  ({self._start_name()} {self.cost_ls:.6g}, "
                f"ratio {ratio:.4g})",
            )
        )
        if self.cost_search is not None:
            items.append(
                (
                    "rescored",
                    f"the search's cost of this model was {self.cost_search:.6g} (its direct "
                    "form is ill-conditioned); the final cost is the model's in second-order "
                    "sections",
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
        reference = family_of(structure).reference_hint(structure, self.cost.predictor)
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
        several = len(self.held_out) > 1
        for report in self.held_out:
            which = f" of output {report.output_name!r}" if several else ""
            if not report.linear_passed:
                problems.append(f"the held-out correlation tests{which} fail")
                tries.append("another structure or higher orders (flexid select)")
            if report.fit_simulation < 0:
                problems.append(f"the held-out simulation fit{which} is "
                                f"{format_fit(report.fit_simulation)} %")  # fmt: skip
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
        lines += labelled(self._items(), label_width=12)
        lines.append("")
        lines.append(self.model.summary())
        lines.append("")
        if self.modes:
            lines.append(self._modes_title())
            lines.append(_indent(mode_table_text(list(self.modes))))
            lines.append("")
        estimation = self.estimation_records or (self.estimation,)
        for i, report in enumerate(estimation):
            several = f" {i + 1} of {len(estimation)}" if len(estimation) > 1 else ""
            lines.append(f"Estimation record{several}")
            lines.append(_indent(report.summary()))
        if self.outputs:
            lines.append(f"{'output':<24} {'fit sim. est. %':>16} {'fit sim. held-out %':>20} "
                         f"{'correlation tests':>18} {'in frequency band':>18}")  # fmt: skip
            for est, val in self.outputs:
                lines.append(f"{val.output_name:<24} {format_fit(est.fit_simulation):>16} "
                             f"{format_fit(val.fit_simulation):>20} "
                             f"{'PASS' if val.passed else 'FAIL':>18} "
                             f"{val.frequency_verdict:>18}")  # fmt: skip
            if self.output_tests:
                lines.append("residuals between outputs (held out, every lag but 0)")
                width = max(len(t.name) for t in self.output_tests)
                lines += [f"  {t.name:{width}}  {t.verdict()}" for t in self.output_tests]
            lines.append(wrapped(f"joint verdict of the {len(self.outputs)} outputs (held out): "
                                 f"{joint_verdict(self.joint_tests)}"))  # fmt: skip
            if not self.passed:
                lines.append(f"  how to read a failure: {VALIDATION_GUIDE}")
            lines.append("")
        for report in self.held_out:
            which = f", output {report.output_name!r}" if self.outputs else ""
            lines.append(f"Validation record (held out){which}")
            lines.append(_indent(report.summary()))
        advice = self.advice()
        if advice:
            lines.append(wrapped(advice, hang="  "))
        return "\n".join(lines)

    def _modes_title(self) -> str:
        parts = ["the model's"]
        if any(math.isfinite(r.peak) for r in self.modes):
            parts.append("the held-out record's confirmed peaks")
        if any(math.isfinite(r.true_frequency) for r in self.modes):
            parts.append("the plant's own")
        return "Modes: " + ", ".join(parts)

    def _repr_html_(self) -> str:
        """The notebook display: the numbers of :meth:`summary`, the held-out record's Bode
        figure (each output's), the long parts collapsed."""
        from .. import _html

        modes = [_html.details(self._modes_title(), mode_table_text(list(self.modes)))]

        rows = [["", "estimation", "validation (held out)"]]
        columns = [_report_column(r) for r in (self.estimation, self.validation)]
        for label, est, val in zip(_REPORT_ROWS, *columns):
            rows.append([label, est, val])
        return _html.block(
            self._title(),
            _html.key_values(self._items()),
            _html.table(rows),
            _html.figures("identification", self, "Bode figure of the held-out record"),
            _html.details("model", self.model.summary()),
            *(modes if self.modes else []),
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
                "structure": family_of(m.structure).structure_dict(m.structure),
                "optimiser": self.optimiser,
                "params": self.params,
                "seed": self.seed,
                "cost": {
                    "description": self.cost.describe(),
                    "value": self.cost_value,
                    "search_value": self.cost_search,
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
                **({"estimation_records": [r.to_dict() for r in self.estimation_records]}
                   if self.estimation_records else {}),
                "validation": self.validation.to_dict(),
                **({"outputs": [{"output": v.output_name, "estimation": e.to_dict(),
                                 "validation": v.to_dict()} for e, v in self.outputs],
                    "output_tests": [t.to_dict() for t in self.output_tests],
                    "joint": {"passed": self.passed, "verdict": joint_verdict(self.joint_tests),
                              "tests": [t.to_dict() for t in self.joint_tests]}}
                   if self.outputs else {}),
                "modes": [r.to_dict() for r in self.modes],
                "timings": {k: round(v, 6) for k, v in self.timings.items()},
                "data": self.data_info,
            }
        )


_REPORT_ROWS = (
    "samples",
    "fit one-step %",
    "fit simulation %",
    "RMSE one-step",
    "RMSE simulation",
    "error range one-step",
    "correlation tests",
    "inside the frequency band",
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
        format_fit(report.fit_simulation) + (" (diverged)" if report.simulation_diverged else
                                             "" if st.stable else " (UNSTABLE model)"),
        f"{report.rmse_one_step:.4g}",
        f"{report.rmse_simulation:.4g}",
        f"[{lo:.4g}, {hi:.4g}]",
        f"{'PASS' if report.passed else 'FAIL'} at {100 * report.alpha:g} %",
        report.frequency_verdict,
        f"{st.max_pole_radius:.5f}" + ("" if st.stable else " (UNSTABLE)"),
        f"{report.peak_measured:.4g}",
        f"{report.peak_model:.4g}",
    ]


def _indent(text: str, prefix: str = "  ") -> str:
    return "\n".join(prefix + line if line else line for line in text.splitlines())


# ================================================================================ identify


def timings(t_start: float, t_opt: float, t_val: float, t_end: float) -> dict[str, float]:
    """Seconds spent setting up, optimising and validating, and in all (an identification's)."""
    return {
        "setup_s": t_opt - t_start,
        "optimise_s": t_val - t_opt,
        "validate_s": t_end - t_val,
        "total_s": t_end - t_start,
    }


def data_info(
    est: IOData | Sequence[IOData], n_validation: int, inputs: list[str], outputs: list[str],
    unit: str, metadata: Mapping[str, Any],
) -> dict[str, Any]:
    """What an identification says of its records (:attr:`Identification.data_info`)."""
    records = tuple(est) if isinstance(est, (list, tuple)) else (est,)
    assumed = bool(metadata.get("dt_assumed"))  # no time column, no dt given
    named = f"output {outputs[0]!r}" if len(outputs) == 1 else f"outputs {outputs}"
    n_est = sum(r.n_samples for r in records)
    counts = (f" ({' + '.join(str(r.n_samples) for r in records)} in {len(records)} records)"
              if len(records) > 1 else "")  # fmt: skip
    est = records[0]
    out = {
        "description": (
            f"{n_est} estimation{counts} + {n_validation} validation samples, dt {est.dt:g} s"
            f"{' (ASSUMED: the record has no time column; give --dt or dt=)' if assumed else ''}"
            f", inputs {inputs}, {named}"
        ),
        "n_estimation": n_est,
        "n_validation": n_validation,
        "dt": est.dt,
        "inputs": inputs,
        "output": outputs[0],
        "output_unit": unit,
        "source": metadata.get("source") or metadata.get("plant"),
    }
    if len(records) > 1:
        out["estimation_records"] = [
            {"n_samples": r.n_samples, "source": r.metadata.get("source")} for r in records
        ]
    return out
