"""The result of a comparison: its runs, their statistics, its tables and its notes.

:class:`ComparisonResult` is built from a comparison's stored run records
(:meth:`ComparisonResult.from_records`), by :func:`flexid.compare` as the runs finish and by
:func:`flexid.load_result` from a store: the statistics and the tables never depend on
where or when the runs were made.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .._json import jsonable
from .._table import LINE_WIDTH, labelled, text_table, wrapped
from ..errors import StoreError
from ..fit.estimation import choose_reference
from ..models.vocabulary import GREYBOX, LEAST_SQUARES, VALIDATION_GUIDE
from ..validation.diagnostics import format_fit as _fit
from .specs import ComparisonSpec
from .statistics import headline, rank_sum_against_best, summarise

__all__ = ["ComparisonResult"]


# ================================================================================ result
#: The tables' row of the gradient reference (Levenberg-Marquardt with analytic gradients).
_REFERENCE_ROW = "reference (LM)"




@dataclass
class ComparisonResult:
    """The runs of a comparison and their statistics.

    Attributes
    ----------
    spec : ComparisonSpec
        What was compared.
    key : str
        Store key.
    reference : dict
        The least-squares record (cost, fits, stability...).
    records : dict
        ``label -> list of run records`` (run order).
    stats : dict
        ``label -> summary`` (see :func:`flexid.jobs.statistics.summarise`); each summary also
        holds its rank-sum ``"test"`` against the best optimiser
        (:func:`flexid.jobs.statistics.rank_sum_against_best`).
    reference_cost : float
        The cost targets are relative to: the lower stable cost of least squares and (for
        the simulation cost) the output-error reference, else the best stable cost found by
        any run, else NaN (``reference_note`` says which).
    reference_note : str
        Where ``reference_cost`` comes from, in words.
    store_path : str or None
        Path of the result store the runs are kept in (None when not stored).
    elapsed : float
        Wall time of the comparison in seconds (0.0 when loaded from a store).
    """

    spec: ComparisonSpec
    key: str
    reference: dict
    records: dict
    stats: dict = field(default_factory=dict)
    reference_cost: float = math.nan
    reference_note: str = ""
    store_path: str | None = None
    elapsed: float = 0.0

    @classmethod
    def from_records(
        cls, spec: ComparisonSpec, key: str, records: Iterable[Mapping[str, Any]], **extra: Any
    ) -> ComparisonResult:
        """Build a result from stored run records and compute its statistics.

        Parameters
        ----------
        spec : ComparisonSpec
            The comparison the records belong to.
        key : str
            Its store key.
        records : iterable of mapping
            Run records (as :meth:`flexid.jobs.store.ResultStore.runs` returns them): the
            least-squares row and the optimisers' runs.  Runs of optimisers not in ``spec``
            and runs numbered ``>= spec.runs`` are left out.
        **extra
            Further fields of the result (``store_path``, ``elapsed``, ...).

        Returns
        -------
        ComparisonResult
            With ``stats``, ``reference_cost`` and ``reference_note`` computed.

        Raises
        ------
        StoreError
            If the least-squares reference row is missing.
        """
        by_label: dict[str, list] = {}
        reference = None
        order = [o.display for o in spec.optimisers]
        for r in records:
            if r["label"] == LEAST_SQUARES:
                reference = dict(r)
                continue
            if r["label"] in order and r["run"] < spec.runs:
                by_label.setdefault(r["label"], []).append(dict(r))
        if reference is None:
            raise StoreError(f"comparison {key}: the least-squares reference row is missing")
        by_label = {k: sorted(by_label.get(k, []), key=lambda r: r["run"]) for k in order}
        result = cls(spec, key, reference, by_label, **extra)
        result._compute()
        return result

    def _compute(self) -> None:
        ref = self.reference
        oe = ref.get("output_error")
        choice = choose_reference(
            float(ref["cost"]),
            bool(ref.get("stable")),
            (float(oe["cost"]), bool(oe.get("stable"))) if oe else None,
        )
        if choice is None:
            stable = [
                r["cost"]
                for rs in self.records.values()
                for r in rs
                if r["status"] == "ok" and r.get("stable")
            ]
            self.reference_cost = float(min(stable)) if stable else math.nan
            self.reference_note = (
                "best stable cost of any run (least squares gives an UNSTABLE model here)"
            )
        elif choice[1] == "least squares":
            self.reference_cost = choice[0]
            self.reference_note = self._start_note(ref)
        else:
            self.reference_cost = choice[0]
            self.reference_note = self._reference_note(choice[1], ref, oe)
        self.stats = {
            label: summarise(rs, self.reference_cost, self.spec.targets)
            for label, rs in self.records.items()
        }
        costs = {
            label: [r["cost"] for r in rs if r["status"] == "ok"]
            for label, rs in self.records.items()
        }
        tests = rank_sum_against_best(costs)
        for label, t in tests.items():
            self.stats[label]["test"] = t

    def _start_note(self, ref: dict[str, Any]) -> str:
        """What the reference row is when the start (least squares) is the reference."""
        model = self.spec.model
        if model.structure == GREYBOX:
            return "the parameters' given values (below the reference)"
        if model.registered:
            return str(ref.get("start_name", "least squares"))
        if model.structure != "arx":
            return "the ARX least-squares estimate read as the structure"
        if self.spec.cost.predictor == "one-step":
            return "least squares (the exact optimum of the one-step cost)"
        return "least squares (the one-step optimum; not the optimum of this cost)"

    def _reference_note(self, name: str, ref: dict[str, Any], oe: dict[str, Any]) -> str:
        """What the reference row is when the gradient reference reached it."""
        model = self.spec.model
        if model.structure == GREYBOX:
            return (
                "grey-box reference (Levenberg-Marquardt on the simulation residuals), "
                f"from the given values and random starts; given values {_f(ref['cost'])}"
            )
        if model.registered and oe.get("name"):  # a family's own words
            return f"{oe['name']}; {self.start_label} {_f(ref['cost'])}"
        if model.structure != "arx":
            name = "prediction-error reference (Levenberg-Marquardt, analytic gradients)"
        return f"{name}, from least squares and stable starts; least squares {_f(ref['cost'])}"

    @property
    def reference_label(self) -> str:
        """The reference's row in the tables (its optimum of the posed cost)."""
        return _REFERENCE_ROW

    @property
    def start_label(self) -> str:
        """What the first row of the tables is: least squares, or a grey-box model's given
        parameter values."""
        if self.spec.model.structure == GREYBOX:
            return "nominal values"
        if self.spec.model.registered:  # a family's own start (state space: n4sid)
            return str(self.reference.get("start_name", "least squares"))
        return "least squares"

    # ------------------------------------------------------------------ tables
    def cost_table(self, width: int | None = None) -> str:
        """Final cost, FE to target and success rate per optimiser.

        Parameters
        ----------
        width : int, optional
            The longest line: a wider table is printed in blocks of columns, each repeating
            the row names (default: one block; :meth:`summary` keeps to the terminal's width).

        Returns
        -------
        str
            A plain-text table: least squares, then one row per optimiser with the number of
            runs, median, IQR and best cost, median FE to each target with the success rate,
            the Holm-corrected rank-sum p-value and the median wall time in seconds.
        """
        return text_table(self._cost_rows(), width=width)

    def _cost_rows(self) -> list[list[str]]:
        targets = self.spec.targets
        head = ["optimiser", "runs", "median", "IQR", "best"]
        head += [f"FE to {t:g} (ok)" for t in targets]
        head += ["p (Holm)", "time s"]
        rows = [head]
        for label, ref in self._reference_rows():
            rows.append(
                [label, "-", _f(ref["cost"]), "-", _f(ref["cost"])]
                + ["-"] * len(targets)
                + ["-", f"{ref.get('wall_time', 0):.3f}"]
            )
        for label, s in self.stats.items():
            runs = f"{s['ok']}" + (f" ({s['failed']} failed)" if s["failed"] else "")
            if not s["ok"]:
                rows.append([label, runs] + ["-"] * (len(head) - 2))
                continue
            row = [label, runs, _f(s["median"]), _f(s["iqr"]), _f(s["best"])]
            for t in targets:
                reach = s["reach"][str(t)]
                fe = "-" if math.isnan(reach["median_fe"]) else f"{reach['median_fe']:.0f}"
                row.append(f"{fe} ({reach['success'] * 100:.0f}%)")
            test = s.get("test", {})
            row.append("best" if test.get("best") else _p(test.get("p_holm")))
            row.append(f"{s['median_time']:.2f}")
            rows.append(row)
        return rows

    def validation_table(self, width: int | None = None) -> str:
        """Held-out fits, modelling-error range and correlation-test pass rate.

        Parameters
        ----------
        width : int, optional
            The longest line: a wider table is printed in blocks of columns, each repeating
            the row names (default: one block; :meth:`summary` keeps to the terminal's width).

        Returns
        -------
        str
            A plain-text table: least squares, then one row per optimiser with the median
            one-step and simulation fits (%), the one-step error range, the correlation-test
            pass rate and the share of stable models.
        """
        return text_table(self._validation_rows(), width=width)

    def _validation_rows(self) -> list[list[str]]:
        head = [
            "optimiser",
            "fit 1-step %",
            "fit sim %",
            "error range (1-step)",
            "corr. pass",
            "in freq. band",
            "stable",
        ]
        rows = [head]
        for label, ref in self._reference_rows():
            if "validation" not in ref:
                continue
            v = headline(ref["validation"])
            rows.append(
                [
                    label,
                    _fit(v["fit_one_step"]),
                    _sim_fit(v["fit_simulation"], bool(ref.get("stable"))),
                    _range(v["error_min"], v["error_max"]),
                    "yes" if v["correlation_passed"] else "no",
                    _share(v.get("frequency_share")),
                    "yes" if ref.get("stable") else "NO",
                ]
            )
        for label, s in self.stats.items():
            if not s["ok"]:
                rows.append([label] + ["-"] * (len(head) - 1))
                continue
            rows.append(
                [
                    label,
                    _fit(s["fit_one_step"]),
                    _sim_fit(s["fit_simulation"], s["stable_rate"] == 1.0),
                    _range(s["error_min"], s["error_max"]),
                    f"{s['correlation_pass_rate'] * 100:.0f}%",
                    _share(s.get("frequency_share")),
                    f"{s['stable_rate'] * 100:.0f}%",
                ]
            )
        return rows

    def _reference_rows(self) -> list[tuple[str, dict[str, Any]]]:
        """The rows above the optimisers': the start (least squares, n4sid or the nominal
        values), then the gradient reference when it was run."""
        rows = [(self.start_label, self.reference)]
        oe = self.reference.get("output_error")
        if oe:
            rows.append((_REFERENCE_ROW, oe))
        return rows

    def _any_unstable(self) -> bool:
        """Whether a row of the validation table holds an unstable model (marked ``!``)."""
        oe = self.reference.get("output_error")
        runs = any(s["ok"] and s["stable_rate"] < 1.0 for s in self.stats.values())
        reference = bool(oe and "validation" in oe and not oe.get("stable"))
        return not self.reference.get("stable") or reference or runs

    def _title(self) -> str:
        return f"Comparison {self.spec.name!r} [{self.key}]"

    def _items(self) -> list[tuple[str, str]]:
        """The labelled header lines of :meth:`summary` (shared with the notebook display)."""
        s = self.spec
        m = s.model
        return [
            ("data", s.data.describe()),
            (
                "model",
                f"{m.describe()}, cost {s.cost.metric} of the simulation from the model's "
                "initial state; validated by running on from the record's start"
                if m.structure == GREYBOX
                else f"{m.describe()}, cost {s.cost.metric}, {s.cost.predictor} predictor, "
                f"initial state {s.cost.initial}; validated with initial state "
                f"{s.validate_initial}",
            ),
            (
                "search",
                "the estimated physical parameters in their bounds (log10 where they span "
                "decades)" if m.structure == GREYBOX
                else _search_text(s.search) if not m.registered
                else self.reference.get("search_text", "the family's own"),
            ),
            ("budget", f"{s.budget_label()} per run, {s.runs} runs per optimiser, seed {s.seed}"),
            ("reference", f"{self.reference_note}: {_f(self.reference_cost)}"),
            ("targets", f"reference x (1 + t), t in {list(s.targets)}"),
        ]

    def summary(self) -> str:
        """Both tables with a header saying what was compared and how.

        Returns
        -------
        str
            The header (data, model, search, budget, reference, targets), :meth:`cost_table`,
            :meth:`validation_table`, failed runs and the rank-sum conclusion.
        """
        lines = [self._title()]
        lines += labelled(self._items(), label_width=10)
        lines += [
            "",
            self.cost_table(LINE_WIDTH),
            "",
            _VALIDATION_CAPTION,
            self.validation_table(LINE_WIDTH),
            *([_UNSTABLE_NOTE] if self._any_unstable() else []),
            f"corr. pass: no residual test rejected at {100 * self.spec.alpha:g} % (Holm); how "
            "to read a failure:",
            f"  {VALIDATION_GUIDE}",
        ]
        outputs = self._output_rows()
        if outputs:
            lines += ["", _OUTPUTS_CAPTION, text_table(outputs, width=LINE_WIDTH)]
        return "\n".join(lines + self._notes())

    def _output_rows(self) -> list[list[str]]:
        """With several outputs: each row's held-out simulation fit, correlation-test pass
        rate and share inside the frequency band per output (medians and shares over its
        runs); empty with one output."""
        names = list(self.reference["validation"].get("outputs", {}))
        if not names:
            return []
        columns = ("fit sim %", "error range", "pass", "in band")
        head = ["optimiser"] + [f"{h} {o}" for o in names for h in columns]
        rows = [head]

        def row(label: str, validations: list[dict]) -> list[str]:
            cells = [label]
            for o in names:
                each = [v["outputs"][o] for v in validations if o in v.get("outputs", {})]
                if not each:
                    cells += ["-", "-", "-", "-"]
                    continue
                cells.append(_fit(float(np.median([e["fit_simulation"] for e in each]))))
                cells.append(_range(float(np.median([e["error_min"] for e in each])),
                                    float(np.median([e["error_max"] for e in each]))))  # fmt: skip
                share = np.mean([e["correlation_passed"] for e in each])
                cells.append(f"{share * 100:.0f}%")
                bands = [e["frequency_share"] for e in each
                         if e.get("frequency_share") is not None]  # fmt: skip
                cells.append(_share(float(np.median(bands)) if bands else None))
            return cells

        rows.append(row(self.start_label, [self.reference["validation"]]))
        oe = self.reference.get("output_error")
        if oe and "validation" in oe:
            rows.append(row(_REFERENCE_ROW, [oe["validation"]]))
        for label, rs in self.records.items():
            rows.append(row(label, [r["validation"] for r in rs
                                    if r["status"] == "ok" and "validation" in r]))  # fmt: skip
        return rows

    def _notes(self) -> list[str]:
        """The lines after the tables: failed runs and the rank-sum conclusion."""
        lines: list[str] = []
        oe = self.reference.get("output_error") or {}
        if oe.get("local_minimum") is False and oe.get("cost") == self.reference_cost:
            where = "on the pole-radius cap" if oe.get("on_cap") else "short of it"
            lines.append(wrapped(
                f"The reference (LM) did not end at a verified local minimum ({where}): "
                "a run below it is news, not an error.", indent="  "))  # fmt: skip
        failed = {k: v.get("errors") for k, v in self.stats.items() if v.get("failed")}
        for label, errors in failed.items():
            lines.append(f"  {label}: failed runs: {'; '.join(errors or [])}")
        conclusion = self._conclusion()
        if conclusion:
            lines += ["", wrapped(conclusion, hang="")]
        return lines

    def _conclusion(self) -> str:
        """The rank-sum conclusion: the lowest median and who is not significantly worse."""
        tests = [(k, v["test"]) for k, v in self.stats.items() if "test" in v]
        best = [k for k, t in tests if t["best"]]
        if not best:
            return ""
        tested = [(k, t) for k, t in tests if not t["best"] and not math.isnan(t["p_holm"])]
        untested = [k for k, t in tests if not t["best"] and math.isnan(t["p_holm"])]
        same = [k for k, t in tested if not t["significant"]]
        text = f"Lowest median cost: {best[0]}"
        if untested:
            text += (
                " (of the optimisers with two or more finished runs; not tested: "
                f"{', '.join(untested)})"
            )
        text += ". "
        if same:
            text += f"Not significantly different (rank-sum, Holm, 5 %): {', '.join(same)}."
        elif tested:
            text += "Every other tested optimiser is significantly worse (rank-sum, Holm, 5 %)."
        return text.rstrip()

    def _repr_html_(self) -> str:
        """The notebook display: the header and both tables of :meth:`summary` in HTML, and
        the held-out record's Bode figure (the start, the reference, each optimiser's best)."""
        from .. import _html

        return _html.block(
            self._title(),
            _html.key_values(self._items()),
            _html.table(self._cost_rows()),
            _html.table(self._validation_rows(), caption=_VALIDATION_CAPTION),
            *(_html.paragraph(line.strip()) for line in self._notes() if line),
            _html.figures("comparison", self, "Bode figure of the held-out record"),
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe result: spec, reference, statistics (without per-run histories).

        Non-finite numbers are ``None`` (see :func:`flexid._json.jsonable`).

        Returns
        -------
        dict
            ``key``, ``spec`` (:meth:`ComparisonSpec.to_dict`), ``reference`` (without its
            history), ``reference_cost``, ``reference_note`` and ``stats``.
        """
        return jsonable(
            {
                "key": self.key,
                "spec": self.spec.to_dict(),
                "reference": {k: v for k, v in self.reference.items() if k != "history"},
                "reference_cost": self.reference_cost,
                "reference_note": self.reference_note,
                "stats": self.stats,
            }
        )


_VALIDATION_CAPTION = (
    "Validation on the held-out record (medians over runs; with several outputs the weakest's)"
)
_OUTPUTS_CAPTION = "Each output on the held-out record (medians and shares over runs)"


def _search_text(search) -> str:
    if search.parametrisation == "coefficients":
        text = (
            f"coefficient box, {search.penalty} stability penalty, {search.init} initial population"
        )
    else:
        text = f"{search.parametrisation} (stable by construction)"
    if search.numerator == "fit":
        text += "; b fitted by least squares for each denominator"
    return text


#: Under the validation table when a row is marked: why an unstable model's fit misleads.
_UNSTABLE_NOTE = ("!: an UNSTABLE model (or some runs'): its free run diverges; fit over the "
                  "held-out record only")


def _sim_fit(value: float, stable: bool) -> str:
    """A held-out simulation fit, marked ``!`` for an unstable model."""
    return _fit(value) + ("" if stable else " !")


def _f(value: float) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "-"
    return f"{value:.5g}"


def _p(value: float | None) -> str:
    if value is None or math.isnan(value):
        return "-"
    return f"{value:.2g}" + ("*" if value < 0.05 else "")


def _range(low: float, high: float) -> str:
    """An error range; ``"per output"`` where the outputs' units differ (no one range)."""
    if not (math.isfinite(low) and math.isfinite(high)):
        return "per output"
    return f"[{low:.4g}, {high:.4g}]"


def _share(value: Any) -> str:
    """A share inside the frequency band as a percentage; ``"-"`` without a verdict."""
    if value is None or not math.isfinite(value):
        return "-"
    return f"{100 * value:.0f}%"
