"""Order and structure selection (MATLAB ``arxstruc``/``selstruc``, ``aic``, ``fpe``).

:func:`select` fits every candidate of a grid of polynomial structures (ARX, ARMAX, OE, BJ;
:mod:`flexid.models.polynomial`) on the estimation part of a record, validates each on the
held-out part (:func:`flexid.validation.validate`), scores each by the information criteria, and
recommends one.  The result is a :class:`Selection`.

Notes
-----
**Fitting.**  ARX candidates are fitted by least squares; the regressor matrix of the largest
orders in the grid is built once and every candidate is a QR solve of its own columns over
its own rows ``t >= start``, which is exactly what
:meth:`flexid.models.arx.ARXStructure.least_squares` computes for that order alone (the
``arxstruc`` trick of sharing one regressor matrix; unlike ``arxstruc``, each order keeps all
the samples it can use).  The other structures are fitted by
:func:`flexid.fit.prediction_error.pem` (Levenberg-Marquardt from ``2 + starts`` starts).

**Criteria** (Ljung, *System Identification*, 2nd ed., sec. 16.4), with ``V = SSE / K`` the
mean squared one-step prediction error on the estimation part, ``K = N - start`` the number of
error samples of the candidate (``N`` in the formulas is ``K``) and ``d`` the number of
estimated parameters (initial states, estimated under ``initial="estimate"``, are not
counted, as in MATLAB):

* ``AIC = K log V + 2 d``; MATLAB's *normalized* AIC (``aic(sys, "nAIC")``, the value
  ``arxstruc``/``selstruc`` plot) is ``log V + 2 d / K`` (``aic_normalized``);
* ``FPE = V (1 + d/K) / (1 - d/K)`` (Akaike's final prediction error);
* ``MDL = BIC = K log V + d log K`` (Rissanen; Schwarz), normalized ``log V + d log(K) / K``.

The ranking by AIC and MDL uses the normalized values.  With one ``K`` for all candidates the
two forms rank alike; here ``K`` varies a little with the orders (``start`` does), and then
the raw form ``K log V`` depends on the output's units (a change of unit adds ``K log c``,
different for each candidate) while the normalized one does not.

**Recommendation.**  An information criterion only weighs the one-step loss against the
number of parameters: on coloured noise (any output-error situation: white noise *added to
the output*) an ARX model keeps lowering its one-step loss by modelling the noise colour, so
AIC, FPE and MDL pick over-fitted ARX orders whose simulation is poor.  The recommendation
(:attr:`Selection.best`) is therefore the candidate with the best held-out *simulation* fit
among those that pass every residual correlation test (:attr:`ValidationReport.passed
<flexid.validation.ValidationReport.passed>`: whiteness, input cross-correlation and the
Billings-Voon tests) and are stable, where a candidate whose held-out simulation error
``||y - y_sim||`` is within ``parsimony`` (relative, default 1 %) of the best one's counts as
equally good and the fewest parameters win.  When no candidate passes, the recommendation
falls back to the best candidate by ``criterion`` (a stable one if any) and
:attr:`Selection.note` says so.

**Default grids** (:data:`DEFAULT_GRIDS`, ``nk`` from :func:`select`'s ``nk``):

* ARX: ``na = nb`` in 1..20 (20 least-squares fits and validations, well under 1 s);
* OE: ``nb = nf`` in 1, 2, 3, 4, 6, 8, 16 (every order to 4, then sparser: ``nf = 2 m``
  holds ``m`` lightly damped modes);
* ARMAX: ``na = nb`` in 1..8 with ``nc`` in 1..2;
* BJ: ``nb = nf`` in 1..8 with ``nc = nd`` in 1..2.

The grids are a first, coarse scan: refine around the recommendation with an explicit grid,
e.g. ``orders={"oe": [{"nb": n, "nf": n} for n in range(12, 17)]}``.  On the simulated
flexible manipulator (``flexid.generate("manipulator", preset="paper-manipulator")``, 2,300
samples, 1,533 for estimation) the default ``structures=("arx", "oe")`` took 16, 33 and 24 s
for seeds 0, 1 and 2 (one process, one BLAS thread); nearly all of it is Levenberg-Marquardt
on OE(6, 6), OE(8, 8) and OE(16, 16), which ran 0.5-5 s, 0.6-7 s and 2.5-30 s.  OE(16, 16, 1)
is recommended on seeds 0 and 2 (held-out simulation fit 99.02 % and 99.14 %, every test
passed); on seed 1 it fails one Billings-Voon test and is the fallback (99.09 %): a chance
failure of the record (every candidate fails it at the same lag, and the test passes on a
30,000-sample continuation; ``benchmarks/long_record_validation.py``).
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from itertools import product
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy import linalg

from .._json import jsonable
from .._table import LINE_WIDTH, labelled, text_table, wrapped
from .._validate import checked_keywords, integer, real
from ..errors import (
    ConfigError,
    DataError,
    FlexidError,
    ModelOrderError,
    UnknownNameError,
)
from ..fit.estimation import structure_of
from ..models.families import family_of
from ..models.polynomial import (
    STRUCTURES,
    PolynomialModel,
    PolynomialStructure,
    _check_initial,
    structure,
)
from ..models.vocabulary import CORRELATION_LAGS, STATE_SPACE, VALIDATION_ALPHA, VALIDATION_GUIDE
from ..validation.diagnostics import check_level, format_fit

if TYPE_CHECKING:  # pragma: no cover
    from ..data.records import IOData
    from ..validation.verdict import ValidationReport

__all__ = [
    "CRITERIA",
    "DEFAULT_GRIDS",
    "Candidate",
    "Selection",
    "arx_grid",
    "default_grid",
    "select",
]

#: The ranking criteria of :func:`select` and what each ranks by.
CRITERIA: dict[str, str] = {
    "aic": "normalized AIC, log V + 2 d / K, smallest first",
    "fpe": "FPE, V (1 + d/K) / (1 - d/K), smallest first",
    "mdl": "normalized MDL (BIC), log V + d log(K) / K, smallest first",
    "bic": "normalized MDL (BIC), log V + d log(K) / K, smallest first",
    "simulation": "held-out simulation fit, largest first",
}

_OE_ORDERS = (1, 2, 3, 4, 6, 8, 16)

#: The default order grid of each structure (without ``nk``, which :func:`select` adds).
DEFAULT_GRIDS: dict[str, tuple[dict[str, int], ...]] = {
    "arx": tuple({"na": n, "nb": n} for n in range(1, 21)),
    "armax": tuple({"na": n, "nb": n, "nc": c} for n in range(1, 9) for c in (1, 2)),
    "oe": tuple({"nb": n, "nf": n} for n in _OE_ORDERS),
    "bj": tuple({"nb": n, "nc": c, "nd": c, "nf": n} for n in range(1, 9) for c in (1, 2)),
    STATE_SPACE: tuple({"order": n} for n in (2, 4, 6, 8, 10, 12, 16)),
}

#: The structures a grid may name: the polynomial ones and the state-space model of every
#: output (:mod:`flexid.models.statespace`).
NAMES = (*STRUCTURES, STATE_SPACE)
_ORDER_KEYS = frozenset(k for orders in STRUCTURES.values() for k in orders) | {"order", "modes"}
_PER_INPUT = ("nb", "nf", "nk")


# ================================================================================ results
@dataclass
class Candidate:
    """One fitted and validated candidate of :func:`select`.

    Attributes
    ----------
    structure : PolynomialStructure
        The orders.
    n_params : int
        ``d``, the number of estimated parameters.
    K : int
        Error samples of the estimation loss, ``N_est - structure.start`` (times the outputs
        of a state-space model: its loss sums every output's, each over its standard
        deviation, so AIC and MDL rank the joint cost).
    sse : float
        Sum of squared one-step prediction errors on the estimation part (output units
        squared); NaN when the fit failed.
    fit_simulation, fit_one_step : float
        Held-out NRMSE fits in % (validation part, ``initial`` rule); ``-inf`` for a
        diverging simulation, NaN when the fit failed.
    passed : bool
        Every residual correlation test passes (linear and Billings-Voon).
    linear_passed : bool
        The whiteness and input cross-correlation tests pass.
    stable : bool
        Every pole of the plant part inside the unit circle.
    local_minimum : bool
        The estimate is a first-order local minimum (always true for least squares).
    fit_time : float
        Seconds spent fitting (for ARX: its QR solve and an equal share of building the
        shared regressor matrix).
    validation_time : float
        Seconds spent validating.
    model : PolynomialModel or None
        The fitted model (None when the fit failed).
    report : ValidationReport or None
        The held-out validation (None when the fit or the validation failed); of the first
        output of a model of several.
    error : str or None
        Why the candidate could not be fitted or validated (a rank-deficient regression,
        say); such a candidate is ranked last and never recommended.
    reports : tuple of ValidationReport
        A model of several outputs: each output's held-out report (then the fits are the
        lowest output's, and the tests pass when every output's do); empty otherwise.
    """

    structure: PolynomialStructure
    n_params: int
    K: int
    sse: float = math.nan
    fit_simulation: float = math.nan
    fit_one_step: float = math.nan
    passed: bool = False
    linear_passed: bool = False
    stable: bool = False
    local_minimum: bool = False
    fit_time: float = 0.0
    validation_time: float = 0.0
    model: PolynomialModel | None = field(default=None, repr=False)
    report: ValidationReport | None = field(default=None, repr=False)
    error: str | None = None
    reports: tuple = field(default=(), repr=False)

    @property
    def kind(self) -> str:
        """The structure's name: ``"arx"``, ``"armax"``, ``"oe"``, ``"bj"`` or ``"polynomial"``."""
        return self.structure.kind

    @property
    def orders(self) -> dict[str, Any]:
        """The orders, MATLAB's order (``{"nb": 2, "nf": 2, "nk": 1}``)."""
        return self.structure.orders

    @property
    def label(self) -> str:
        """``"OE(nb=2, nf=2, nk=1)"``, or ``"grey-box twin-rotor-pitch"``."""
        return str(self.structure) if self.kind == "greybox" else repr(self.structure)

    @property
    def loss(self) -> float:
        """``V = SSE / K``, the mean squared one-step prediction error (output units squared)."""
        return self.sse / self.K

    @property
    def aic(self) -> float:
        """``K log V + 2 d``."""
        return self.K * _log(self.loss) + 2.0 * self.n_params

    @property
    def aic_normalized(self) -> float:
        """MATLAB's normalized AIC, ``log V + 2 d / K``."""
        return _log(self.loss) + 2.0 * self.n_params / self.K

    @property
    def fpe(self) -> float:
        """Akaike's final prediction error ``V (1 + d/K) / (1 - d/K)`` (output units squared)."""
        r = self.n_params / self.K
        return self.loss * (1.0 + r) / (1.0 - r)

    @property
    def mdl(self) -> float:
        """Rissanen's MDL (Schwarz's BIC), ``K log V + d log K``."""
        return self.K * _log(self.loss) + self.n_params * math.log(self.K)

    @property
    def mdl_normalized(self) -> float:
        """``log V + d log(K) / K``."""
        return _log(self.loss) + self.n_params * math.log(self.K) / self.K

    @property
    def ok(self) -> bool:
        """The candidate was fitted and validated (no :attr:`error`)."""
        return self.error is None

    def score(self, criterion: str) -> float:
        """The value ranked by ``criterion``, smaller is better.

        Parameters
        ----------
        criterion : {"aic", "fpe", "mdl", "bic", "simulation"}
            See :data:`CRITERIA`.

        Returns
        -------
        float
            The normalized AIC or MDL, the FPE, or minus the held-out simulation fit; ``inf``
            for a failed candidate (and a diverging simulation under ``"simulation"``).

        Raises
        ------
        UnknownNameError
            For an unknown criterion.
        """
        criterion = _check_criterion(criterion)
        if not self.ok:
            return math.inf
        value = {
            "aic": self.aic_normalized,
            "fpe": self.fpe,
            "mdl": self.mdl_normalized,
            "bic": self.mdl_normalized,
            "simulation": -self.fit_simulation,
        }[criterion]
        return value if not math.isnan(value) else math.inf

    def to_dict(self) -> dict[str, Any]:
        """The candidate's numbers as a JSON-safe dictionary.

        Returns
        -------
        dict
            ``structure`` (name), ``orders``, ``label``, ``n_params``, ``K``, ``sse``,
            ``loss``, ``aic``, ``aic_normalized``, ``fpe``, ``mdl``, ``mdl_normalized``,
            ``fit_simulation``, ``fit_one_step``, ``passed``, ``linear_passed``, ``stable``,
            ``local_minimum``, ``fit_time``, ``validation_time`` (s), ``error`` and
            ``theta`` (None when the fit failed).  Non-finite numbers are None.
        """
        return jsonable(
            {
                "structure": self.kind,
                "orders": self.orders,
                "label": self.label,
                "n_params": self.n_params,
                "K": self.K,
                "sse": self.sse,
                "loss": self.loss,
                "aic": self.aic,
                "aic_normalized": self.aic_normalized,
                "fpe": self.fpe,
                "mdl": self.mdl,
                "mdl_normalized": self.mdl_normalized,
                "fit_simulation": self.fit_simulation,
                "fit_one_step": self.fit_one_step,
                "passed": self.passed,
                "linear_passed": self.linear_passed,
                "stable": self.stable,
                "local_minimum": self.local_minimum,
                "fit_time": self.fit_time,
                "validation_time": self.validation_time,
                "error": self.error,
                "theta": None if self.model is None else self.model.theta,
            }
        )


def _log(v: float) -> float:
    if math.isnan(v):
        return math.nan
    return math.log(v) if v > 0 else -math.inf


@dataclass
class Selection:
    """The outcome of :func:`select`.

    Attributes
    ----------
    candidates : list of Candidate
        Every candidate, in grid order.
    best : Candidate or None
        The recommendation (see the module notes); None only when no candidate could be
        fitted.
    criterion : str
        The ranking criterion (:data:`CRITERIA`).
    note : str
        How the recommendation was reached (and when it is only a fallback, why).
    initial : str
        The initial-condition rule of the fits and validations.
    max_lag : int
        Largest lag of the correlation tests.
    alpha : float
        Family-wise level of the validation verdicts.
    n_estimation, n_validation : int
        Samples of the estimation and validation parts.
    dt : float
        Sample time in seconds.
    parsimony : float
        Relative tolerance on the held-out simulation error within which fewer parameters
        win.
    wall_time : float
        Seconds, start to finish.
    delay : str
        How the delays were chosen, when :func:`select` estimated them (``nk="auto"``);
        empty when they were given.
    """

    candidates: list[Candidate]
    best: Candidate | None
    criterion: str
    note: str
    initial: str = "estimate"
    max_lag: int = CORRELATION_LAGS
    alpha: float = VALIDATION_ALPHA
    n_estimation: int = 0
    n_validation: int = 0
    dt: float = 1.0
    parsimony: float = 0.01
    wall_time: float = 0.0
    delay: str = ""

    @property
    def best_model(self) -> PolynomialModel | None:
        """The recommended model (None when no candidate could be fitted)."""
        return None if self.best is None else self.best.model

    def ranked(self, criterion: str | None = None) -> list[Candidate]:
        """The candidates sorted by a criterion, best first (failed candidates last).

        Parameters
        ----------
        criterion : {"aic", "fpe", "mdl", "bic", "simulation"}, optional
            Default: :attr:`criterion`.

        Returns
        -------
        list of Candidate
            Ties keep the grid order.

        Raises
        ------
        UnknownNameError
            For an unknown criterion.
        """
        criterion = _check_criterion(self.criterion if criterion is None else criterion)
        return sorted(self.candidates, key=lambda c: c.score(criterion))

    def _unstable_above_stable(self) -> list[Candidate]:
        """The unstable candidates the ranking puts above a stable one (said under the table:
        a criterion ranks the fit, and an unstable model's fit holds over one record only)."""
        ranked = [c for c in self.ranked() if c.ok]
        last_stable = max((i for i, c in enumerate(ranked) if c.stable), default=-1)
        return [c for c in ranked[:last_stable] if not c.stable]

    def _title(self) -> str:
        n_passed = sum(c.passed for c in self.candidates)
        return (
            f"Structure selection: {len(self.candidates)} candidates, {n_passed} pass every "
            f"correlation test"
        )

    def _items(self) -> list[tuple[str, str]]:
        kinds = sorted({c.kind for c in self.candidates})
        return [
            (
                "data",
                f"{self.n_estimation} samples for estimation, {self.n_validation} held out "
                f"for validation, dt = {self.dt:g} s",
            ),
            ("structures", ", ".join("grey-box" if k == "greybox" else k.upper() for k in kinds)),
            ("ranked by", f"{self.criterion}: {CRITERIA[self.criterion]}"),
            *([("delay", self.delay)] if self.delay else []),
            (
                "validation",
                f"initial state {self.initial}, residual tests up to lag {self.max_lag} "
                f"judged at {100 * self.alpha:g} %",
            ),
            (
                "recommended",
                "none" if self.best is None else
                f"{self.best.label}, held-out simulation fit "
                f"{format_fit(self.best.fit_simulation)} %",
            ),
            ("time", f"{self.wall_time:.2f} s"),
        ]

    def _rows(self) -> list[list[str]]:
        head = [
            "rank",
            "candidate",
            "d",
            "V",
            "AIC/K",
            "FPE",
            "MDL/K",
            "fit sim %",
            "fit 1-step %",
            "tests",
            "in band",
            "stable",
            "time s",
            "note",
        ]
        rows = [head]
        for i, c in enumerate(self.ranked(), start=1):
            mark = "<- recommended" if c is self.best else ""
            if not c.ok:
                rows.append(
                    [str(i), c.label, str(c.n_params)] + ["-"] * 10 + [f"failed: {c.error}"]
                )
                continue
            tests = "pass" if c.passed else ("fail BV" if c.linear_passed else "fail")
            rows.append(
                [
                    str(i),
                    c.label,
                    str(c.n_params),
                    _g(c.loss),
                    f"{c.aic_normalized:.4f}",
                    _g(c.fpe),
                    f"{c.mdl_normalized:.4f}",
                    format_fit(c.fit_simulation) + ("" if c.stable else " !"),
                    format_fit(c.fit_one_step),
                    tests,
                    _band(c),
                    "yes" if c.stable else "NO",
                    f"{c.fit_time + c.validation_time:.2f}",
                    mark,
                ]
            )
        return rows

    def table(self, width: int | None = None) -> str:
        """The candidates as a plain-text table, sorted by :attr:`criterion`.

        Parameters
        ----------
        width : int, optional
            The longest line: a wider table is printed in blocks of columns, each repeating
            the row names (default: one block; :meth:`summary` keeps to the terminal's width).

        Returns
        -------
        str
            One row per candidate: rank, structure and orders, ``d``, ``V``, the normalized
            AIC and MDL (``AIC/K``, ``MDL/K``), FPE, held-out simulation and one-step fits,
            the correlation tests (``pass``; ``fail BV``: only the Billings-Voon tests fail;
            ``fail``), the share of trusted frequencies inside the held-out record's band
            (the weakest output's), stability, fit + validation time, and the
            recommendation marked.
        """
        return text_table(self._rows(), left=(1, -1), width=width, keys=2)

    def summary(self) -> str:
        """A readable account: what was compared, the table, and the recommendation's note.

        Returns
        -------
        str
            The header lines, :meth:`table` and :attr:`note`.
        """
        lines = [self._title()]
        lines += labelled(self._items(), label_width=11)
        lines += ["", self.table(LINE_WIDTH)]
        above = self._unstable_above_stable()
        if above:
            lines.append(wrapped(f"!: UNSTABLE, its free run diverges; ranked by {self.criterion} "
                                 f"above stable candidates: {', '.join(c.label for c in above)}"))
        if any(c.ok and not c.passed for c in self.candidates):
            lines += [wrapped(f"fail: a residual test rejected at {100 * self.alpha:g} % (Holm; "
                              "fail BV: only a Billings-Voon test); how to read a failure:"),
                      f"  {VALIDATION_GUIDE}"]  # fmt: skip
        lines += ["", wrapped(self.note, hang="")]
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()

    def __repr__(self) -> str:
        best = None if self.best is None else self.best.label
        return (
            f"Selection({len(self.candidates)} candidates, best={best}, "
            f"criterion={self.criterion!r})"
        )

    def _repr_html_(self) -> str:
        """The notebook display: the header, the table and the note of :meth:`summary`, and
        the held-out record's Bode figure of the best candidates."""
        from .. import _html

        return _html.block(
            self._title(),
            _html.key_values(self._items()),
            _html.table(self._rows(), left=2),
            _html.paragraph(self.note),
            _html.figures("selection", self, "Bode figure of the held-out record"),
        )

    def to_dict(self) -> dict[str, Any]:
        """The selection as a JSON-safe dictionary.

        Returns
        -------
        dict
            ``criterion``, ``note``, ``initial``, ``max_lag``, ``n_estimation``,
            ``n_validation``, ``dt`` (s), ``parsimony``, ``wall_time`` (s), ``best`` (the
            index of the recommendation in ``candidates``, or None), ``best_model``
            (:meth:`PolynomialModel.to_dict <flexid.models.polynomial.PolynomialModel.to_dict>` or
            None), ``ranking`` (candidate indices sorted by the criterion) and
            ``candidates`` (:meth:`Candidate.to_dict` each, grid order).  Non-finite numbers
            are None.
        """
        index = {id(c): i for i, c in enumerate(self.candidates)}
        return jsonable(
            {
                "criterion": self.criterion,
                "note": self.note,
                "initial": self.initial,
                "max_lag": self.max_lag,
                "alpha": self.alpha,
                "n_estimation": self.n_estimation,
                "n_validation": self.n_validation,
                "dt": self.dt,
                "parsimony": self.parsimony,
                "wall_time": self.wall_time,
                "delay": self.delay,
                "best": None if self.best is None else index[id(self.best)],
                "best_model": None if self.best_model is None else self.best_model.to_dict(),
                "ranking": [index[id(c)] for c in self.ranked()],
                "candidates": [c.to_dict() for c in self.candidates],
            }
        )


def _g(value: float) -> str:
    return "-" if value is None or math.isnan(value) else f"{value:.4g}"


# ================================================================================ grids
def default_grid(name: str, nk: int | Sequence[int] = 1) -> list[dict[str, Any]]:
    """The default order grid of a structure (:data:`DEFAULT_GRIDS`) with the delay ``nk``.

    Parameters
    ----------
    name : {"arx", "armax", "oe", "bj"}
        The structure.
    nk : int or sequence of int, optional
        Input delay in samples (one per input), added to every entry.

    Returns
    -------
    list of dict
        One dictionary of orders per candidate, e.g. ``{"nb": 2, "nf": 2, "nk": 1}``.

    Raises
    ------
    UnknownNameError
        For an unknown structure name.
    """
    key = _check_name(name)
    return [{**entry, "nk": nk} for entry in DEFAULT_GRIDS[key]]


def _check_name(name: Any) -> str:
    key = str(name).lower() if isinstance(name, str) else None
    if key not in NAMES:
        raise UnknownNameError("model structure in structures", str(name), NAMES)
    return key


def _check_criterion(criterion: Any) -> str:
    if not isinstance(criterion, str) or criterion.lower() not in CRITERIA:
        raise UnknownNameError("selection criterion", str(criterion), tuple(CRITERIA))
    return criterion.lower()


def _product_grid(spec: Mapping[str, Any], where: str) -> list[dict[str, Any]]:
    """``{"nb": range(1, 4), "nf": [2, 3], "nk": 1}`` -> the product of the values."""
    unknown = [k for k in spec if k not in _ORDER_KEYS]
    if unknown:
        raise ModelOrderError(
            f"{where} has unknown order name(s) {', '.join(map(repr, unknown))}; order names "
            f"are {', '.join(sorted(_ORDER_KEYS))}"
        )
    names = list(spec)
    values = []
    for k in names:
        v = spec[k]
        items = [v] if np.isscalar(v) else list(v)
        if not items:
            raise ModelOrderError(f"{where}: the values of {k} are empty")
        values.append(items)
    return [dict(zip(names, combo)) for combo in product(*values)]


def _entries(grid: Any, where: str) -> list[dict[str, Any]]:
    """A grid given as a list of dicts or a product mapping, as a list of dicts."""
    if isinstance(grid, Mapping):
        return _product_grid(grid, where)
    if isinstance(grid, (str, bytes)) or not isinstance(grid, Iterable):
        raise ModelOrderError(
            f"{where} must be a list of dicts of orders or a mapping order name -> values, "
            f"got {type(grid).__name__}"
        )
    out = []
    for i, entry in enumerate(grid):
        if not isinstance(entry, Mapping):
            raise ModelOrderError(
                f"{where}[{i}] must be a dict of orders such as {{'nb': 2, 'nf': 2}}, got "
                f"{entry!r}"
            )
        out.append(dict(entry))
    if not out:
        raise ModelOrderError(f"{where} is empty")
    return out


def _grids(names: list[str], orders: Any) -> dict[str, list[dict[str, Any]]]:
    """The grid of each named structure (``nk`` not filled in yet)."""
    if orders is None:
        return {name: [dict(e) for e in DEFAULT_GRIDS[name]] for name in names}
    if isinstance(orders, Mapping) and orders:
        keys = [str(k).lower() if isinstance(k, str) else k for k in orders]
        if all(k in NAMES for k in keys):
            return _grids_by_structure(names, dict(zip(keys, orders.values())))
        if any(k in NAMES for k in keys):
            raise ModelOrderError(
                "orders mixes structure names and order names; give either a mapping "
                "structure -> grid or a mapping order name -> values"
            )
    if isinstance(orders, Mapping) and len(names) > 1:
        return {name: _own_grid(name, orders) for name in names}
    entries = _entries(orders, "orders")
    return {name: [dict(e) for e in entries] for name in names}


def _grids_by_structure(
    names: list[str], per: dict[str, Any]
) -> dict[str, list[dict[str, Any]]]:
    """:func:`_grids` of ``orders`` given as a mapping structure name -> grid; a structure
    it leaves out takes its default grid."""
    extra = [k for k in per if k not in names]
    if extra:
        raise ModelOrderError(
            f"orders has a grid for {', '.join(map(repr, extra))}, which is not in "
            f"structures {tuple(names)}"
        )
    return {
        name: _entries(per[name], f"orders[{name!r}]")
        if name in per
        else [dict(e) for e in DEFAULT_GRIDS[name]]
        for name in names
    }


#: An order a structure needs that a grid over several structures leaves out is tied to
#: another, as the default grids tie them: ARX's and ARMAX's na = nb, OE's and BJ's nf = nb
_TIES = {"na": "nb", "nf": "nb"}


def _own_grid(name: str, orders: Mapping[str, Any]) -> list[dict[str, Any]]:
    """The product of the orders of a flat grid that structure ``name`` takes (its default
    grid when it takes none of them), the orders it needs tied (:data:`_TIES`)."""
    own = STRUCTURES.get(name, ("order", "modes"))
    taken = {k: v for k, v in orders.items() if k in own}
    if not taken:
        return [dict(e) for e in DEFAULT_GRIDS[name]]
    return [_tied(name, e) for e in _entries(taken, "orders")]


def _tied(name: str, entry: dict[str, Any]) -> dict[str, Any]:
    own = STRUCTURES.get(name, ())
    return {**{k: entry[v] for k, v in _TIES.items() if k in own and k not in entry
               and v in entry}, **entry}  # fmt: skip


#: A grey-box candidate of :func:`select` by name: ``"greybox:twin-rotor-pitch"``.
GREYBOX_PREFIX = "greybox:"


def _candidate_structures(
    structures: Any, orders: Any, nk: Any, n_inputs: int, n_outputs: int = 1
) -> list[Any]:
    """Every candidate's structure, checked (orders, inputs), duplicates removed."""
    if isinstance(structures, str) or not isinstance(structures, Iterable):
        structures = (structures,)
    structures = list(structures)
    if not structures:
        raise ConfigError(f"structures is empty; give names from {tuple(STRUCTURES)}")
    names, fixed, by_name = _requested(structures)
    made = _from_grids(names, orders, nk, n_inputs, n_outputs)
    out: list[Any] = []
    for s in [*made, *fixed]:
        if s.n_inputs != n_inputs:
            raise ModelOrderError(
                f"{s!r} has {s.n_inputs} input(s) but the record has {n_inputs}; give nb, nf "
                "and nk one value per input (or one value for all)"
            )
        if s not in out:
            out.append(s)
    return out + by_name  # a grey-box model reads its channels by name


def _requested(structures: list[Any]) -> tuple[list[str], list[Any], list[Any]]:
    """The names to take from the order grids, the structures given whole that take the
    record's inputs in order, and those that read its channels by name (grey-box models),
    of the entries of ``structures``."""
    names: list[str] = []
    fixed: list[Any] = []
    by_name: list[Any] = []
    for s in structures:
        if isinstance(s, str) and s.lower().startswith(GREYBOX_PREFIX):
            from ..models.greybox_library import greybox_model

            by_name.append(greybox_model(s[len(GREYBOX_PREFIX):]))
        elif isinstance(s, str):
            key = _check_name(s)
            if key not in names:
                names.append(key)
        else:
            family = family_of(s)
            (by_name if family.reads_channels else fixed).append(family.canonical(s))
    return names, fixed, by_name


def _from_grids(names: list[str], orders: Any, nk: Any, n_inputs: int,
                n_outputs: int = 1) -> list:  # fmt: skip
    """The structures of the order grids of ``names``; an entry's error names the entry."""
    made: list[PolynomialStructure] = []
    for name, entries in _grids(names, orders).items():
        for i, entry in enumerate(entries):
            if name == STATE_SPACE:  # its family builds it, for every output of the record
                try:
                    made.append(structure_of(name, n_inputs, n_outputs, **entry))
                except ModelOrderError as exc:
                    raise ModelOrderError(
                        f"orders entry {i} of {name} ({_entry_text(entry)}): {exc}"
                    ) from None
                continue
            entry = {"nk": nk, **entry}
            if n_inputs > 1:  # one value of a per-input order is every input's
                entry = {
                    k: [v] * n_inputs if k in _PER_INPUT and np.isscalar(v) else v
                    for k, v in entry.items()
                }
            try:
                made.append(structure(name, **entry))
            except ModelOrderError as exc:
                raise ModelOrderError(
                    f"orders entry {i} of {name} ({_entry_text(entry)}): {exc}"
                ) from None
    return made


def _state_space_requested(structures: Any) -> bool:
    """Whether ``structures`` asks for state-space models (which keep every output)."""
    if isinstance(structures, str) or not isinstance(structures, Iterable):
        structures = (structures,)
    return any(
        (isinstance(s, str) and s.lower() == STATE_SPACE)
        or (not isinstance(s, str) and family_of(s).several_outputs)
        for s in structures
    )


def _entry_text(entry: Mapping[str, Any]) -> str:
    return ", ".join(f"{k}={v}" for k, v in entry.items())


# ================================================================================ ARX grid
def arx_grid(
    u: Any, y: Any, structures: Sequence[PolynomialStructure], dt: float = 1.0
) -> list[PolynomialModel | FlexidError]:
    """Least-squares ARX fits of many orders from one shared regressor matrix.

    The regressor matrix of the largest orders (``-y(t-1) .. -y(t-na_max)`` and each input's
    lags ``0 .. max(nk + nb - 1)``, zero before ``t = 0``) is built once; each order is the
    QR solve of its own columns over its own rows ``t >= start``, the same numbers as
    :meth:`flexid.models.arx.ARXStructure.least_squares` for that order alone.

    Parameters
    ----------
    u : array_like, shape (N,) or (N, n_u)
        Inputs.
    y : array_like, shape (N,)
        Output.
    structures : sequence of PolynomialStructure
        ARX structures (``structure.kind == "arx"``), each with ``n_u`` inputs and fewer
        parameters than its ``N - start`` equations.
    dt : float, optional
        Sample time in seconds, given to the models.

    Returns
    -------
    list
        Per structure, a :class:`~flexid.models.polynomial.PolynomialModel` with ``param_std`` and
        ``noise_variance = SSE / (K - d)`` as :meth:`~flexid.models.arx.ARXStructure.least_squares`
        gives them, or the :class:`~flexid.errors.DataError` raised for a rank-deficient
        regression (an input that does not excite that order).

    Raises
    ------
    ModelOrderError
        For a structure that is not ARX, has the wrong number of inputs, or does not fit in
        the record.
    DataError
        For bad signals.
    """
    return [fit[0] for fit in _arx_fits(u, y, structures, dt)]


def _arx_fits(
    u: Any, y: Any, structures: Sequence[PolynomialStructure], dt: float
) -> list[tuple[PolynomialModel | FlexidError, float, float]]:
    """:func:`arx_grid` with each fit's SSE and seconds (its solve plus a share of the
    regressor matrix)."""
    from ..models.arx import _io_arrays

    t_build = time.perf_counter()
    u, y = _io_arrays(u, y)
    n, m = u.shape[0], u.shape[1]
    for s in structures:
        if s.kind != "arx" or s.nc or s.nd or any(s.nf):
            raise ModelOrderError(f"arx_grid takes ARX structures only, got {s!r}")
        if s.n_inputs != m:
            raise ModelOrderError(f"{s!r} has {s.n_inputs} input(s) but u has {m} column(s)")
        s.check_samples(n)
    if not structures:
        return []
    na_max = max(s.na for s in structures)
    last = [
        max((s.nk[j] + s.nb[j] - 1 for s in structures if s.nb[j]), default=-1)
        for j in range(m)
    ]
    pad = max([na_max, *last, 0])
    yp = np.concatenate([np.zeros(pad), y])
    up = np.vstack([np.zeros((pad, m)), u])
    cols = [-yp[pad - i : pad - i + n] for i in range(1, na_max + 1)]
    offsets = []
    for j in range(m):
        offsets.append(len(cols))
        cols += [up[pad - k : pad - k + n, j] for k in range(last[j] + 1)]
    phi_all = np.column_stack(cols)
    share = (time.perf_counter() - t_build) / len(structures)
    out: list[tuple[PolynomialModel | FlexidError, float, float]] = []
    for s in structures:
        t0 = time.perf_counter()
        index = list(range(s.na))
        for j in range(m):
            index += [offsets[j] + k for k in range(s.nk[j], s.nk[j] + s.nb[j])]
        try:
            model, sse = _least_squares(s, phi_all[s.start :, index], y[s.start :], dt)
        except DataError as exc:
            model, sse = exc, math.nan
        out.append((model, sse, share + time.perf_counter() - t0))
    return out


def _least_squares(
    s: PolynomialStructure, phi: np.ndarray, target: np.ndarray, dt: float
) -> tuple[PolynomialModel, float]:
    """:meth:`ARXStructure.least_squares`'s computation on given regressors, and the SSE."""
    q, r = linalg.qr(phi, mode="economic")
    diag = np.abs(np.diag(r))
    if diag.size and diag.min() <= diag.max() * 1e-13:
        raise DataError(
            f"the regressors are rank deficient (the input is not persistently exciting for "
            f"{s!r})"
        )
    theta = linalg.solve_triangular(r, q.T @ target)
    resid = target - phi @ theta
    k = target.shape[0]
    sse = float(resid @ resid)
    sigma2 = sse / (k - s.n_params)
    rinv = linalg.solve_triangular(r, np.eye(s.n_params))
    std = np.sqrt(sigma2 * np.sum(rinv * rinv, axis=1))
    return PolynomialModel(s, theta, dt=dt, param_std=std, noise_variance=sigma2), sse


# ================================================================================ select
def _as_record(data: Any, what: str) -> Any:
    from ..data.records import IOData

    if isinstance(data, tuple) and len(data) == 2:
        return IOData(*data)
    if isinstance(data, (IOData, str, os.PathLike)):
        return data
    raise DataError(
        f"{what} must be an IOData, a (u, y) tuple or a path, got {type(data).__name__}"
    )


def _progress(progress: Any, total: int) -> Callable[[Candidate | None], None]:
    if callable(progress) and not isinstance(progress, bool):
        return lambda c: None if c is None else progress(c)
    if not progress or total == 0:
        return lambda c: None
    from .progress import ProgressBar

    bar = ProgressBar(total, "select")

    def update(c: Candidate | None) -> None:
        if c is None:
            bar.close()
        else:
            bar.update(1, f"{c.label} fit {format_fit(c.fit_simulation)} %")

    return update


@checked_keywords
def select(
    data: IOData | tuple | str | os.PathLike,
    structures: Any = ("arx", "oe"),
    orders: Any = None,
    *,
    nk: int | Sequence[int] | str = "auto",
    split: float | int | None = None,
    validation: IOData | tuple | str | os.PathLike | None = None,
    initial: str = "estimate",
    criterion: str = "simulation",
    max_lag: int = CORRELATION_LAGS,
    alpha: float = VALIDATION_ALPHA,
    starts: int | None = None,
    seed: int = 0,
    parsimony: float = 0.01,
    progress: bool | Callable[[Candidate], Any] = False,
    detrend: bool | str = False,
) -> Selection:
    """Fit, validate and rank a grid of polynomial structures, and recommend one.

    Every candidate is fitted on the estimation part (ARX by least squares from one shared
    regressor matrix, the others by :func:`flexid.fit.prediction_error.pem`), validated on the
    held-out part (:func:`flexid.validation.validate`: simulation and one-step fits, residual
    correlation tests, stability) and scored by AIC, FPE and MDL (see the module notes).  The
    recommendation is the best held-out simulation fit among the candidates that pass every
    correlation test and are stable (fewest parameters among those within ``parsimony`` of
    it); an information criterion alone is not used for it, since on coloured noise it picks
    over-fitted ARX orders.

    Parameters
    ----------
    data : IOData, (u, y) tuple or path
        Single-output record (``u`` shape (N,) or (N, n_u), ``y`` shape (N,)); a path is read
        with :func:`flexid.data.load`.  Several outputs for state-space candidates only.
    structures : str, PolynomialStructure, GreyBoxModel or sequence of them, optional
        Structure names from :data:`flexid.models.polynomial.STRUCTURES` (``"arx"``, ``"armax"``,
        ``"oe"``, ``"bj"``; each gets its grid from ``orders``), and/or
        :class:`~flexid.models.polynomial.PolynomialStructure` objects (each one candidate as it
        is), and/or grey-box models (:class:`~flexid.models.greybox.GreyBoxModel` objects or
        ``"greybox:NAME"`` with a name of :func:`flexid.models.greybox_library.greybox_model`): each
        one candidate, fitted by :func:`flexid.fit.greybox_fit.greyest` (``starts`` random
        starts), its loss the simulation error (its only predictor) and its ``d`` the
        estimated parameters, validated by running on from the record's start; and/or
        ``"ss"`` (:class:`~flexid.models.statespace.StateSpaceStructure`, its grid of
        ``order`` and ``modes``): a state-space model of every output, fitted by
        :func:`flexid.ssest`, its loss the joint simulation cost (each output over its
        standard deviation, ``K`` the samples of every output), validated output by output
        (its fits the lowest output's, its tests passed when every output's are).  Default
        ``("arx", "oe")``.
    orders : list of dict or mapping, optional
        The grid.  None: :data:`DEFAULT_GRIDS`.  A list of dicts of orders
        (``[{"nb": 16, "nf": 16}, ...]``) applies to every named structure; a mapping
        order name -> values (``{"nb": range(1, 5), "nf": range(1, 5)}``; a scalar is one
        value) is the product of the values, for each structure over the orders it takes
        (``{"nb": [8, 16], "nf": [8, 16]}`` with ``("arx", "oe")``: ARX(nb, nb) and
        OE(nb, nf); an order a structure needs and the grid leaves out is tied as the
        default grids tie it, ``na = nb``, ``nf = nb``; a structure that takes none of them
        keeps its default grid); a mapping structure name -> either of those gives each
        structure its grid (structures it leaves out keep their default grid).
    nk : int, sequence of int or "auto", optional
        Input delay in samples (one per input) of every grid entry without its own ``nk``;
        ``"auto"`` (default): every grid entry at ``nk = 1`` and at the delays estimated
        on the estimation record by both methods of :func:`flexid.fit.delay.estimate_delay`
        (MATLAB ``delayest`` and the prewhitened cross-correlation; on the DaISy dryer
        both find 3, where ``nk = 1`` fits 70 % and ``nk = 3`` 85 %).  ``nk = 1`` stays
        because the estimators find where the response becomes significant, which can be
        later than where it starts (on the simulated manipulator 10-11 samples, where
        ``nk = 1`` fits best); :attr:`Selection.delay` says what they found.
        With several inputs, a single value of ``nb``, ``nf`` or ``nk`` (in the grid or
        here) is every input's.
    split : float or int, optional
        Estimation share in (0, 1) (default 2/3, the first part) or the sample index where
        the validation part starts.
    validation : IOData, (u, y) tuple or path, optional
        A separate validation record; then all of ``data`` is for estimation.
    initial : {"estimate", "zero", "measured"}, optional
        Initial-condition rule (:data:`flexid.models.polynomial.INITIAL_RULES`) of the prediction
        errors minimised by PEM and of the validation's predictors (default ``"estimate"``,
        MATLAB's).
    criterion : {"simulation", "aic", "fpe", "mdl", "bic"}, optional
        What :meth:`Selection.table` sorts by and the fallback recommendation uses when no
        candidate passes (default the held-out simulation fit; ``"bic"`` is ``"mdl"``).
    max_lag : int, optional
        Largest lag of the correlation tests (>= 1); the validation part must hold
        ``start + 2 max_lag + 2`` samples for every candidate.
    alpha : float, optional
        Family-wise level of the validation verdicts (default 5 %): a true model fails its
        residual tests in at most ``alpha`` of records (:func:`flexid.validate`).
    starts : int, optional
        Extra random/perturbed starts of each PEM fit (>= 0; see
        :func:`flexid.fit.prediction_error.pem`).  Default: the references' own
        (:data:`flexid.config.REFERENCE_STARTS`, and
        :data:`~flexid.config.GREYBOX_REFERENCE_STARTS` for a grey-box model), so a
        candidate's model is the one :func:`flexid.identify` finds for that structure.
    seed : int, optional
        Seed of those starts (>= 0); every PEM fit uses it, so a candidate's result does not
        depend on the rest of the grid.
    parsimony : float, optional
        Relative tolerance (>= 0) on the held-out simulation error ``||y - y_sim||``: among
        the passing, stable candidates, those within ``(1 + parsimony)`` times the best
        one's error count as equally good and the fewest parameters win (0: the best fit,
        whatever its size).  Default 0.01.
    progress : bool or callable, optional
        Show a progress bar on stderr (True), or call ``progress(candidate)`` after each
        candidate.
    detrend : {False, True, "constant", "linear"}, optional
        Remove the estimation record's means or least-squares line first, as
        :func:`flexid.identify` does (:func:`flexid.data.prepare_data`).

    Returns
    -------
    Selection
        Every candidate's numbers, the recommendation and a note on how it was reached.

    Raises
    ------
    UnknownNameError
        An unknown structure name, ``criterion`` or ``initial`` rule (the message lists the
        valid ones).
    ModelOrderError
        Before any fit: a grid entry with an order its structure does not have (``nc`` for
        OE), a missing or invalid order, the wrong number of per-input orders, or orders
        the estimation or validation part is too short for.
    ConfigError
        A bad ``max_lag``, ``starts``, ``seed`` or ``parsimony``, empty ``structures``, or
        both ``split`` and ``validation``.
    DataError, DataFileError
        Unusable data (several outputs, NaN, an unreadable file).
    """
    t_begin = time.perf_counter()
    from ..data.records import prepare_data

    criterion = _check_criterion(criterion)
    initial = _check_initial(initial)
    max_lag = integer(max_lag, "max_lag", error=ConfigError, minimum=1)
    alpha = check_level(alpha, ConfigError)
    if starts is not None:  # None: each family's default
        starts = integer(starts, "starts", error=ConfigError, minimum=0)
    seed = integer(seed, "seed", error=ConfigError, minimum=0)
    parsimony = real(parsimony, "parsimony", error=ConfigError, minimum=0)
    record = _as_record(data, "data")
    several = _state_space_requested(structures)
    est, val = prepare_data(
        record,
        split=split,
        detrend=detrend,
        validation=None if validation is None else _as_record(validation, "validation"),
        several=several,
    )
    if val.n_inputs != est.n_inputs:
        raise DataError(
            f"the validation record has {val.n_inputs} input(s), the estimation record "
            f"{est.n_inputs}"
        )

    # every grid entry is checked before any fit
    if isinstance(nk, str) and several:  # a state-space model's delays are in its states
        nk = 1
    candidates_s, delay_text = _grid_with_delays(structures, orders, nk, est)
    _check_candidates(candidates_s, est, val, max_lag)

    bar = _progress(progress, len(candidates_s))
    arx = [i for i, s in enumerate(candidates_s) if s.kind == "arx"]
    grid = [candidates_s[i] for i in arx]
    fitted = dict(zip(arx, _arx_fits(est.u, est.y[:, 0], grid, float(est.dt)))) if arx else {}
    held_out = _HeldOut(est, val, record if validation is None else None, initial, max_lag,
                        alpha, several)  # fmt: skip
    candidates: list[Candidate] = []
    try:
        for i, s in enumerate(candidates_s):
            c = _fitted_candidate(s, est, fitted.get(i), initial=initial, starts=starts,
                                  seed=seed)  # fmt: skip
            if c.model is not None:
                held_out.judge(c)
            candidates.append(c)
            bar(c)
    finally:
        bar(None)

    best, note = _recommend(candidates, criterion, parsimony)
    return Selection(
        candidates=candidates,
        best=best,
        criterion=criterion,
        note=note,
        initial=initial,
        max_lag=max_lag,
        alpha=alpha,
        n_estimation=est.n_samples,
        n_validation=val.n_samples,
        dt=float(est.dt),
        parsimony=parsimony,
        wall_time=time.perf_counter() - t_begin,
        delay=delay_text,
    )


def _grid_with_delays(
    structures: Any, orders: Any, nk: Any, est: IOData
) -> tuple[list[Any], str]:
    """The grid's structures at the given delays, or at each estimated delay and at
    ``nk = 1`` (``nk="auto"``), and the line that says which delays were used."""
    from ..fit.delay import DELAY_METHODS, estimate_delay

    if not isinstance(nk, str):
        return _candidate_structures(structures, orders, nk, est.n_inputs, est.n_outputs), ""
    if nk != "auto":
        raise ConfigError(f"nk must be a delay in samples (per input) or 'auto', got {nk!r}")
    conventional = tuple([1] * est.n_inputs)
    try:
        found = [estimate_delay(est, method=m) for m in DELAY_METHODS]
    except DataError as exc:  # e.g. a constant input: the candidates' own checks fail
        delays = [conventional]
        delay_text = f"nk = 1: the delay could not be estimated ({exc})"
    else:
        # the estimators find where the response becomes significant, which can be later
        # than where it starts (the manipulator's: 10-11 samples, where OE(16,16,1) fits
        # best): the conventional nk = 1 stays a candidate, the held-out fit decides
        delays = list(dict.fromkeys([conventional, *(d.nk for d in found)]))
        estimated = list(dict.fromkeys(d.nk for d in found))
        lo, hi = found[0].nk_range
        if len(estimated) == 1:
            text = (f"nk = {', '.join(map(str, estimated[0]))} (MATLAB delayest and the "
                    f"prewhitened cross-correlation agree, over nk = {lo} .. {hi})")
        else:
            text = "; ".join(d.describe() for d in found)
        delay_text = f"{text}; the grid at each estimate and at nk = 1"
    candidates_s: list[Any] = []
    for k, d in enumerate(delays):
        for s in _candidate_structures(structures, orders, list(d), est.n_inputs,
                                       est.n_outputs):  # fmt: skip
            if k and not hasattr(s, "nk"):  # its delays are its own equations': once
                continue
            if s not in candidates_s:
                candidates_s.append(s)
    return candidates_s, delay_text


def _check_candidates(candidates_s: list[Any], est: IOData, val: IOData, max_lag: int) -> None:
    """Every candidate fits the record: its outputs, the estimation part's length, and room
    in the validation part for the correlation tests."""
    if est.n_outputs > 1:
        single = [s for s in candidates_s if not family_of(s).several_outputs]
        if single:
            raise DataError(
                f"the record has {est.n_outputs} outputs {list(est.output_names)}; {single[0]!r} "
                "models one: select among state-space models ('ss') or give one output"
            )
    for s in candidates_s:
        try:
            s.check_samples(est.n_samples)
        except ModelOrderError as exc:
            raise ModelOrderError(f"the estimation part is too short: {exc}") from None
        room = val.n_samples - s.start
        if room < 2 * max_lag + 2:
            raise ModelOrderError(
                f"the validation part ({val.n_samples} samples) is too short for {s!r} with "
                f"max_lag={max_lag}: it needs start + 2*max_lag + 2 = "
                f"{s.start + 2 * max_lag + 2} samples; lower the orders or max_lag"
            )


def _fitted_candidate(
    s: Any, est: IOData, least_squares: tuple | None, *, initial: str, starts: int | None,
    seed: int,
) -> Candidate:
    """One candidate fitted on the estimation part: by its least-squares fit when it has one
    (ARX: the global minimum), else by its family's reference; a candidate the input cannot
    determine keeps its error, and the search goes on."""
    if least_squares is not None:
        model, sse, fit_time = least_squares
        local = True
    else:
        t0 = time.perf_counter()
        try:
            model, sse, local = family_of(s).reference(
                est, s, initial=initial, starts=starts, seed=seed
            )
        except FlexidError as exc:
            model, sse, local = exc, math.nan, False
        fit_time = time.perf_counter() - t0
    c = Candidate(
        structure=s,
        n_params=s.n_params,
        K=(est.n_samples - s.start) * est.n_outputs,
        fit_time=fit_time,
        local_minimum=bool(local),
    )
    if isinstance(model, FlexidError):
        c.error = str(model)
        return c
    named = getattr(model, "named", None)  # a grey-box model has its channels
    outputs = list(est.output_names)
    several = family_of(s).several_outputs
    c.model = named(est.input_names, outputs if several else outputs[0]) if named else model
    c.sse = float(sse)
    return c


@dataclass
class _HeldOut:
    """How a selection judges each fitted candidate on the validation part.

    ``whole`` is the record the estimation part was cut from when no validation record was
    given: a family whose models run on from the record's start validates there.
    """

    est: IOData
    val: IOData
    whole: IOData | None
    initial: str
    max_lag: int
    alpha: float
    several: bool

    def judge(self, c: Candidate) -> None:
        """Validate ``c.model``: its report(s), fits, verdict and stability, in place."""
        from ..validation.verdict import between_outputs, joint_tests

        family = family_of(c.structure)
        t0 = time.perf_counter()
        try:
            if not family.runs_on:  # a model whose poles tell, even if validation fails
                c.stable = bool(c.model.is_stable)
            each = self._reports(c.model, family)
            if family.runs_on:
                c.stable = family.held_out_stable(c.model, each[0])
        except FlexidError as exc:
            c.error = f"validation failed: {exc}"
        else:
            c.report = each[0]
            if self.several:  # every output's held-out report; the first is the summary's
                c.reports = each
            c.fit_simulation = float(min(r.fit_simulation for r in each))  # the weakest
            c.fit_one_step = float(min(r.fit_one_step for r in each))
            if self.several:  # one verdict at alpha over every output's tests and the
                # tests between their residuals, as identify and compare judge
                between = between_outputs(each) if len(each) > 1 else ()
                c.passed = all(t.passed for t in joint_tests(each, between))
            else:
                c.passed = each[0].passed
            c.linear_passed = all(r.linear_passed for r in each)
        c.validation_time = time.perf_counter() - t0

    def _reports(self, model: Any, family: Any) -> tuple[ValidationReport, ...]:
        from ..validation.verdict import validate

        check = {"max_lag": self.max_lag, "alpha": self.alpha}
        if self.several:
            return tuple(validate(model, self.val, initial=self.initial, output=o,
                                  estimated_on=self.est, **check)
                         for o in self.est.output_names)  # fmt: skip
        if family.runs_on and self.whole is not None:  # run on from the record's start
            return (validate(model, self.whole, split=self.est.n_samples, **check),)
        return (validate(model, self.val, initial=self.initial, estimated_on=self.est,
                         **check),)  # fmt: skip


def _recommend(
    candidates: list[Candidate], criterion: str, parsimony: float
) -> tuple[Candidate | None, str]:
    """The recommendation and the note explaining it (module notes, "Recommendation")."""
    ok = [c for c in candidates if c.ok]
    if not ok:
        return None, "No candidate could be fitted and validated; see the errors in the table."
    eligible = [
        c for c in ok if c.passed and c.stable and math.isfinite(c.fit_simulation)
    ]
    if eligible:
        return _recommend_passing(eligible, ok, len(candidates), criterion, parsimony)
    return _fallback(ok, criterion)


def _recommend_passing(
    eligible: list[Candidate], ok: list[Candidate], n_candidates: int, criterion: str,
    parsimony: float,
) -> tuple[Candidate, str]:
    """The fewest parameters within ``parsimony`` of the best fit among the candidates that
    pass every test while stable, and the note saying so (and what a criterion alone picks)."""
    top = max(eligible, key=lambda c: c.fit_simulation)
    limit = (1.0 + parsimony) * (100.0 - top.fit_simulation)
    close = [c for c in eligible if 100.0 - c.fit_simulation <= limit]
    best = min(close, key=lambda c: (c.n_params, -c.fit_simulation))
    note = (
        f"Recommended {best.label}: held-out simulation fit "
        f"{format_fit(best.fit_simulation)} % with {best.n_params} parameters; "
        f"{len(eligible)} of {n_candidates} candidates pass every correlation test "
        "and are stable"
    )
    if best is top:
        note += ", and it fits best of them."
    else:
        note += (
            f".  The best of them, {top.label} ({format_fit(top.fit_simulation)} %, "
            f"{top.n_params} parameters), is within {parsimony:.3g} (relative) of its "
            "simulation error, so the one with fewer parameters is recommended."
        )
    ic = criterion if criterion != "simulation" else "aic"
    by_ic = min(ok, key=lambda c: c.score(ic))
    if by_ic is not best:
        note += (
            f"  {ic.upper()} alone would pick {by_ic.label} (held-out simulation fit "
            f"{format_fit(by_ic.fit_simulation)} %, correlation tests "
            f"{'pass' if by_ic.passed else 'fail'})."
        )
    return best, note


def _fallback(ok: list[Candidate], criterion: str) -> tuple[Candidate, str]:
    """When no candidate passes every test while stable: the best stable one by
    ``criterion``, and a note on why it fails and what to try."""
    stable = [c for c in ok if c.stable]
    best = min(stable or ok, key=lambda c: c.score(criterion))
    note = (
        f"NO CANDIDATE PASSES every correlation test while stable: this is only the best "
        f"{'stable ' if stable else ''}candidate by {criterion} ({CRITERIA[criterion]}): "
        f"{best.label}, held-out simulation fit {format_fit(best.fit_simulation)} %"
        f"{'' if best.stable else ' (UNSTABLE)'}.  "
    )
    within, across = _failed_tests(best)
    failed = within + across
    if across and not within:
        note += (
            "Each output's residuals pass alone, but they predict each other "
            f"({', '.join(across)}): a disturbance or a mode the model misses reaches several "
            "sensors (try a higher order), or the sensors' noise is correlated at nonzero "
            "lags; check it on another record."
        )
    elif best.linear_passed:
        note += (
            "Its residuals are white and independent of the input, but fail the "
            f"Billings-Voon test(s) {', '.join(failed) or '-'}: a nonlinear effect the "
            "linear model cannot hold, or chance (a valid model fails the battery in "
            f"{100 * best.report.alpha:g} % of records, the verdicts' level); check it on "
            "another record."
        )
    else:
        note += (
            f"Its residuals fail {', '.join(failed)}: the model misses dynamics (input "
            "cross-correlation) or the noise is not what the structure assumes (whiteness); "
            "try higher orders, another structure or another delay nk."
        )
    linear = [c for c in ok if c.linear_passed and c.stable and c is not best]
    if linear:
        lin = max(linear, key=lambda c: c.fit_simulation)
        note += (
            f"  {len(linear)} other candidate(s) pass the linear tests and fail only "
            f"Billings-Voon; the best of them is {lin.label} "
            f"({format_fit(lin.fit_simulation)} %)."
        )
    return best, note


def _failed_tests(c: Candidate) -> tuple[list[str], list[str]]:
    """The names of the failing tests of ``c``'s verdict: those of its outputs, and those
    between its outputs' residuals (none with one output)."""
    from ..validation.verdict import between_outputs, joint_tests

    if len(c.reports) < 2:
        return ([t.name for t in c.report.all_tests if not t.passed] if c.report else []), []
    between = between_outputs(c.reports)
    names = {t.name for t in between}
    failed = [t.name for t in joint_tests(c.reports, between) if not t.passed]
    return [n for n in failed if n not in names], [n for n in failed if n in names]


def _band(c: Candidate) -> str:
    """The candidate's frequency verdict: its (weakest output's) share inside the band."""
    reports = [r for r in (c.reports or (c.report,)) if r is not None]
    judged = [r for r in reports if r.frequency_verdict != "-"]
    if not judged:
        return "-"
    return min(judged, key=lambda r: float(r.frequency.share[0])).frequency_verdict
