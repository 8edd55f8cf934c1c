"""One path from a record to the search problem an optimiser solves.

:func:`build_problem` is used by :func:`flexid.identify` and :func:`flexid.compare` alike:
model structure (with the same default ``nb`` for every input), the batched cost, the
search box, the parametrisation of the search space, the stability penalty, the initial
population and the references (least squares; for the simulation cost, the output-error
reference too).  Optimisers search the parametrisation's box; results are always reported
as ARX coefficients, converted by :meth:`EstimationProblem.theta`.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy import linalg

from .._validate import checked_keywords, is_integer, positive_real
from ..costs.arx import ARXCost
from ..data.records import IOData
from ..errors import (
    ConfigError,
    DataError,
    IdentificationWarning,
    ModelOrderError,
    UnknownNameError,
)
from ..models.arx import ARXStructure
from ..models.families import family_named, family_of
from ..models.polynomial import PolynomialStructure
from ..models.specs import CostSpec, SearchSpec
from ..models.stability import is_stable
from ..models.vocabulary import REFERENCE_STARTS, auto_initial
from ..optimisers import Problem
from .parametrisation import PARAMETRISATIONS, Parametrisation, SearchBox

if TYPE_CHECKING:  # pragma: no cover - the references load on first use
    from .output_error import OEResult
    from .prediction_error import PEMResult

__all__ = [
    "ILL_CONDITIONED",
    "INIT_RULES",
    "NUMERATOR_RULES",
    "EstimationProblem",
    "PolynomialEstimationProblem",
    "build_problem",
    "check_excitation",
    "check_search",
    "choose_reference",
    "model_structure",
    "resolve_initial",
    "search_box",
    "structure_of",
]

# ================================================================================ search box
def _round_up(value: float) -> float:
    """Round up to one significant digit (0.061 -> 0.07, 3.2 -> 4)."""
    if value <= 0 or not math.isfinite(value):
        return 1.0
    exponent = math.floor(math.log10(value))
    return math.ceil(value / 10**exponent) * 10**exponent


@checked_keywords
def search_box(
    structure: ARXStructure,
    bounds: Any = "auto",
    theta_ls: np.ndarray | None = None,
) -> SearchBox:
    """The search box for an ARX structure.

    Parameters
    ----------
    structure : ARXStructure
        Model orders.
    bounds : "auto", float, (low, high), mapping or (2, n_params) array, optional
        * ``"auto"`` (default): ``|a_k| <= C(na, k)``, the binomial coefficients of
          ``(z + 1)^na``, a box that contains *every* stable denominator (the coefficients
          of a polynomial with all roots in the unit disc are bounded by those of
          ``(z + 1)^na``); and ``|b| <= 2 max|b_LS|`` rounded up to one significant digit, a
          data-informed scale from the least-squares estimate.
        * a number ``s``: every parameter in ``[-s, s]``;
        * ``(low, high)``: every parameter in ``[low, high]``;
        * ``{"a": s or (low, high), "b": s or (low, high)}``;
        * ``{"lower": [...], "upper": [...]}`` or an array of shape ``(2, n_params)``.
    theta_ls : ndarray, optional
        Least-squares estimate, needed by ``"auto"``.

    Returns
    -------
    SearchBox
        The bounds, shapes (n_params,), and the rule that made them.

    Raises
    ------
    ConfigError
        For bounds of the wrong form or length, or ``lower >= upper``.
    """
    n, na = structure.n_params, structure.na

    def pair(value: Any, what: str) -> tuple[float, float]:
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            name = " ".join(filter(None, ["bounds", what, "half-width"]))
            half = positive_real(value, name, error=ConfigError)
            return -half, half
        if isinstance(value, Sequence) and len(value) == 2 and not isinstance(value, str):
            return float(value[0]), float(value[1])
        raise ConfigError(f"bounds {what}: expected a half-width or (low, high), got {value!r}")

    if isinstance(bounds, str):
        if bounds != "auto":
            raise ConfigError(
                f"bounds must be 'auto', a number, (low, high) or a mapping, not {bounds!r}"
            )
        if theta_ls is None:
            raise ConfigError("automatic bounds need the least-squares estimate")
        a_half = np.array([math.comb(na, k) for k in range(1, na + 1)], dtype=float)
        b_ls = np.asarray(theta_ls[na:], dtype=float)
        b_half = _round_up(2.0 * float(np.max(np.abs(b_ls)))) if b_ls.size else 1.0
        upper = np.concatenate([a_half, np.full(n - na, b_half)])
        rule = (
            f"auto: |a_k| <= C({na}, k) (contains every stable A), "
            f"|b| <= {b_half:g} (2 max|b_LS|, rounded up)"
        )
        return SearchBox(-upper, upper, rule)
    if isinstance(bounds, Mapping):
        if set(bounds) <= {"lower", "upper"} and bounds:
            try:
                lower = np.asarray(bounds["lower"], dtype=float).reshape(-1)
                upper = np.asarray(bounds["upper"], dtype=float).reshape(-1)
            except KeyError as exc:
                raise ConfigError(f"bounds mapping lacks {exc}") from None
            rule = "explicit lower/upper"
        else:
            unknown = set(bounds) - {"a", "b"}
            if unknown:
                raise ConfigError(f"unknown bounds key(s) {sorted(unknown)}; use 'a' and 'b'")
            a_lo, a_hi = pair(bounds.get("a", 2.0), "a")
            b_lo, b_hi = pair(bounds.get("b", 1.0), "b")
            lower = np.concatenate([np.full(na, a_lo), np.full(n - na, b_lo)])
            upper = np.concatenate([np.full(na, a_hi), np.full(n - na, b_hi)])
            rule = f"a in [{a_lo:g}, {a_hi:g}], b in [{b_lo:g}, {b_hi:g}]"
    elif isinstance(bounds, np.ndarray) and bounds.ndim == 2:
        if bounds.shape != (2, n):
            raise ConfigError(f"bounds array must have shape (2, {n}), got {bounds.shape}")
        lower, upper = bounds[0].astype(float), bounds[1].astype(float)
        rule = "explicit lower/upper"
    else:
        lo, hi = pair(bounds, "")
        lower, upper = np.full(n, lo), np.full(n, hi)
        rule = f"every parameter in [{lo:g}, {hi:g}]"
    if lower.shape != (n,) or upper.shape != (n,):
        raise ConfigError(f"bounds need {n} values each ({structure.n_params} parameters)")
    if not (np.all(np.isfinite(lower)) and np.all(np.isfinite(upper))):
        raise ConfigError("bounds must be finite")
    bad = np.flatnonzero(lower >= upper)
    if bad.size:
        name = structure.param_names[int(bad[0])]
        raise ConfigError(f"bounds: lower >= upper for parameter {name}")
    return SearchBox(lower, upper, rule)



# ================================================================================ structure
def structure_of(structure: Any, n_inputs: int, n_outputs: int = 1, **orders: Any) -> Any:
    """The model structure of an identification, from a name or object and the orders.

    The family that builds the name (:func:`~flexid.models.families.family_named`) or owns
    the object (:func:`~flexid.models.families.family_of`) makes it
    (:meth:`~flexid.models.families.Family.structure`).

    Parameters
    ----------
    structure : str, structure object or None
        ``None`` (ARX from ``na``, ``nb``, ``nk``), a structure name of a registered family
        (:data:`flexid.models.polynomial.STRUCTURES` with its orders, for the polynomial
        family), or a structure (no orders).
    n_inputs : int
        Inputs of the record (a scalar ``nb``, ``nf`` or ``nk`` applies to each).
    n_outputs : int, optional
        Outputs of the record, for a family whose models take every output
        (:attr:`~flexid.models.families.Family.several_outputs`); the others model one.
    **orders : int, sequence of int or None
        ``na``, ``nb``, ``nc``, ``nd``, ``nf``, ``nk`` (None: not given).

    Returns
    -------
    object
        An :class:`~flexid.models.arx.ARXStructure` for ARX (the paper's path, unchanged),
        otherwise the family's structure.

    Raises
    ------
    ModelOrderError
        Orders the structure does not have, missing orders, or orders that do not match the
        record's inputs.
    UnknownNameError
        An unknown structure name.
    ConfigError
        An object of no registered family.
    """
    if structure is None or isinstance(structure, str):
        name = "arx" if structure is None else str(structure).lower()
        try:
            family = family_named(name)
        except UnknownNameError as exc:  # the name as given, not lowered
            raise UnknownNameError(exc.kind, str(structure), exc.known) from None
    else:
        family, name = family_of(structure), structure
    if family.several_outputs:
        orders["n_outputs"] = n_outputs
    return family.structure(name, n_inputs, **orders)


# ================================================================================ rules
INIT_RULES = ("uniform", "stable")
NUMERATOR_RULES = ("search", "fit")


_NUMERATOR_WORDS = {"search": "searched", "fit": "fitted by least squares for each denominator"}


def resolve_initial(initial: str, structure: Any) -> str:
    """The initial-condition rule a cost uses: ``"auto"`` resolved for the structure
    (:func:`flexid.config.auto_initial`).

    Parameters
    ----------
    initial : {"auto", "estimate", "zero", "measured"}
    structure : ARXStructure or PolynomialStructure

    Returns
    -------
    str
    """
    if initial != "auto":
        return initial
    return auto_initial(structure.kind)


def model_structure(
    na: int, nb: int | Sequence[int] | None, nk: int | Sequence[int], n_inputs: int
) -> ARXStructure:
    """The ARX structure for a record with ``n_inputs`` inputs.

    ``nb = None`` gives ``na`` for every input; a scalar ``nb`` or ``nk`` applies to every
    input.

    Parameters
    ----------
    na : int
        Order of ``A``.
    nb : int, sequence of int or None
        Number of ``B`` coefficients, per input or for all.
    nk : int or sequence of int
        Input delay in samples, per input or for all.
    n_inputs : int
        Number of inputs of the record.

    Returns
    -------
    ARXStructure
        The orders, one ``nb`` and ``nk`` per input.

    Raises
    ------
    ModelOrderError
        If per-input orders do not match the record's inputs.
    """
    if nb is None:
        nb = na
    if n_inputs > 1:
        if is_integer(nb):
            nb = [int(nb)] * n_inputs
        if is_integer(nk):
            nk = [int(nk)] * n_inputs
    structure = ARXStructure(na, nb, nk)
    if structure.n_inputs != n_inputs:
        raise ModelOrderError(
            f"the record has {n_inputs} input(s) but the orders give {structure.n_inputs} "
            "(one nb and nk per input)"
        )
    return structure


# ================================================================================ excitation
#: Condition number of the lagged-input matrix (columns scaled to unit norm) above which
#: :func:`check_excitation` warns.  To first order the relative change of least-squares
#: coefficients is at most the condition number times the relative change of the data: at
#: 1e8, a change of 1e-8 in the recorded input -- below the resolution of a 24-bit converter
#: and of float32 storage (both about 6e-8) -- can change the ``b`` coefficients by their own
#: size, so the estimate says more about rounding and noise than about the plant.
ILL_CONDITIONED = 1e8

#: Rows of the lagged-input matrix formed at a time (its R factor is accumulated block by
#: block), so the check of a long record needs a few MB, not the whole matrix.
_EXCITATION_BLOCK = 65_536


def _lagged_singular_values(
    u: np.ndarray, columns: list[tuple[int, int]], first: int
) -> tuple[np.ndarray, int]:
    """Singular values of the lagged-input matrix, its columns scaled to unit norm.

    Column ``i`` is ``u[t - lag_i, j_i]`` for ``(j_i, lag_i) = columns[i]`` and rows
    ``t = first .. N - 1``.  The matrix is reduced to its R factor block by block (Householder
    QR of the previous R stacked on the next block), which has the same singular values.

    Returns
    -------
    sv : ndarray
        Singular values, largest first (fewer than ``len(columns)`` when there are fewer
        rows: the missing ones are zero).
    rows : int
        Number of rows ``K = N - first``.
    """
    n = u.shape[0]
    scale = np.array([np.linalg.norm(u[first - lag : n - lag, j]) for j, lag in columns])
    scale[scale == 0] = 1.0  # a zero column stays zero: its singular value is 0
    r = np.zeros((0, len(columns)))
    for lo in range(first, n, _EXCITATION_BLOCK):
        hi = min(lo + _EXCITATION_BLOCK, n)
        block = np.column_stack([u[lo - lag : hi - lag, j] for j, lag in columns]) / scale
        r = linalg.qr(np.vstack([r, block]), mode="r", check_finite=False)[0]
    return linalg.svdvals(r, check_finite=False), n - first


def _rank(sv: np.ndarray, rows: int, n: int) -> int:
    """Numerical rank: the singular values above ``max(rows, n) * eps * sv[0]``.

    That is the rounding error of computing the singular values of a ``rows x n`` matrix
    (the backward error of Householder QR and of the SVD is a modest multiple of
    ``max(rows, n) * eps * ||U||``; ``numpy.linalg.matrix_rank``'s default and MATLAB's
    ``rank``).  The matrix holds the recorded samples exactly, so nothing else perturbs it:
    a direction with a smaller singular value is indistinguishable from one the data do not
    excite at all.
    """
    if not sv.size or sv[0] == 0:
        return 0
    return int(np.sum(sv > max(rows, n) * np.finfo(float).eps * sv[0]))


def check_excitation(data: IOData, structure: ARXStructure | PolynomialStructure) -> None:
    """Check that the inputs are persistently exciting enough for the model's orders.

    An input ``u_j`` modelled by ``B_j / F_j`` (``nb_j`` coefficients, ``F_j`` of order
    ``nf_j``, 0 in ARX and ARMAX) determines the model uniquely only if it is persistently
    exciting of order ``n_j = nb_j + nf_j`` (Ljung, *System Identification*, 2nd ed., 1999,
    section 13.2, theorem 13.1): the ``n_j`` lagged copies
    ``[u_j(t - nk_j), ..., u_j(t - nk_j - n_j + 1)]`` over the estimation samples must be
    linearly independent.  (In ARX and ARMAX the
    noise excites ``A`` through the output, so ``nb_j`` is what the input must cover;
    ``F_j`` is seen through the input alone.)  The order found is the numerical rank of that
    matrix, with its columns scaled to unit norm and singular values below
    ``max(K, n_j) * eps`` times the largest counted as zero (the rounding error of computing
    them, see ``numpy.linalg.matrix_rank``).  An input that is zero has order 0, a constant
    one order 1, a sinusoid order 2.  With several inputs their lagged copies together must
    be independent too.

    Parameters
    ----------
    data : IOData
        The estimation record; for input ``j`` its samples from
        ``t = max(structure.start, nk_j + n_j - 1)`` on are used (in ARX, the rows of the
        least-squares regression).
    structure : ARXStructure or PolynomialStructure
        The model's orders.

    Raises
    ------
    DataError
        When an input's order is below what the model needs (the message names the input,
        the order found and the order needed), or when the inputs together are dependent:
        the identification problem has no unique answer.

    Warns
    -----
    IdentificationWarning
        When the lagged-input matrix is ill-conditioned: condition number above
        :data:`ILL_CONDITIONED`.
    """
    u = data.u
    nf = getattr(structure, "nf", (0,) * structure.n_inputs)
    names = data.input_names
    used: list[tuple[int, int, int]] = []  # (input, order needed, first row)
    warned = False
    for j in range(structure.n_inputs):
        nb, nk = structure.nb[j], structure.nk[j]
        if nb == 0:
            continue  # the model does not use this input
        need = nb + nf[j]
        first = max(structure.start, nk + need - 1)
        if first >= u.shape[0]:
            continue  # too short: check_samples says so
        sv, rows = _lagged_singular_values(u, [(j, nk + i) for i in range(need)], first)
        order = _rank(sv, rows, need)
        what = f"{nb} b coefficient(s)" + (f" and F of order {nf[j]}" if nf[j] else "")
        if order < need:
            orders = "nb + nf" if nf[j] else "nb"
            found, hint = (
                ("is zero (persistently exciting of order 0)", "a record where it moves")
                if order == 0
                else (
                    f"is persistently exciting of order {order}",
                    f"{orders} <= {order} or a richer input (a constant input has order 1, "
                    "a sinusoid 2)",
                )
            )
            raise DataError(
                f"input {names[j]!r} {found} over the {rows} estimation samples t >= "
                f"{first}, but {structure!r} needs order {need} for its {what}: the model "
                f"is not unique; use {hint}"
            )
        cond = sv[0] / sv[-1]
        if cond > ILL_CONDITIONED:
            warned = True
            warnings.warn(
                f"input {names[j]!r} is barely persistently exciting of order {need} for "
                f"{structure!r}: its {need} lagged copies over the estimation samples have "
                f"condition number {cond:.2g} (> {ILL_CONDITIONED:g}), so the coefficients "
                f"of its {'B and F' if nf[j] else 'B'} are ill-determined; use lower orders "
                "or a richer input",
                IdentificationWarning,
                stacklevel=2,
            )
        used.append((j, need, first))
    if len(used) < 2:
        return
    first = max(f for _, _, f in used)
    columns = [(j, structure.nk[j] + i) for j, need, _ in used for i in range(need)]
    sv, rows = _lagged_singular_values(u, columns, first)
    order = _rank(sv, rows, len(columns))
    listed = ", ".join(repr(names[j]) for j, _, _ in used)
    if order < len(columns):
        raise DataError(
            f"inputs {listed} are not jointly persistently exciting for {structure!r}: their "
            f"{len(columns)} lagged copies over the {rows} estimation samples t >= {first} "
            f"span only {order} dimensions (an input is a combination of the others, or "
            "they share too few frequencies): the model is not unique"
        )
    cond = sv[0] / sv[-1]
    if cond > ILL_CONDITIONED and not warned:
        warnings.warn(
            f"inputs {listed} are barely jointly persistently exciting for {structure!r}: "
            f"their {len(columns)} lagged copies have condition number {cond:.2g} "
            f"(> {ILL_CONDITIONED:g}), so the coefficients of their B are ill-determined",
            IdentificationWarning,
            stacklevel=2,
        )


@dataclass
class EstimationProblem:
    """The search problem of one identification, and how to read its results.

    Attributes
    ----------
    structure : ARXStructure
        Model orders.
    cost : ARXCost
        The cost on the estimation record, in ARX coefficients.
    parametrisation : Parametrisation
        The map from the search box to ARX coefficients.
    problem : Problem
        What the optimisers minimise: ``cost(parametrisation.to_coefficients(z))`` over the
        parametrisation's box, with the shared initial population.  With
        ``search.numerator == "fit"`` the box is the parametrisation's ``A`` part only and
        each candidate's ``b`` is fitted (:meth:`ARXCost.fit_numerator`).
    search : SearchSpec
        The settings it was built from.
    box : SearchBox
        The coefficient box the bounds gave (in the stable spaces only its ``b`` part is
        searched).
    box_rule : str
        How the box of the ``b`` coefficients (and of ``a`` in the coefficient space) was
        chosen.
    """

    structure: ARXStructure
    cost: ARXCost
    parametrisation: Parametrisation
    problem: Problem
    search: SearchSpec
    box: Any
    box_rule: str
    _oe: Any = field(default=None, repr=False)

    @property
    def theta_ls(self) -> np.ndarray:
        """Least-squares estimate, shape (n_params,) (the cost's :attr:`ARXCost.theta_ls`)."""
        return self.cost.theta_ls

    @property
    def cost_ls(self) -> float:
        """The cost at :attr:`theta_ls` (the cost's :attr:`ARXCost.cost_ls`)."""
        return self.cost.cost_ls

    def theta(self, z: Any) -> np.ndarray:
        """ARX coefficients of search vectors.

        In the stable spaces a point outside the box (optimisers that do not clip can leave
        it) is read as its nearest point of the box, so every candidate stays stable.

        Parameters
        ----------
        z : array_like, shape (P, n) or (n,)
            Points of the search space (``n = problem.n``).

        Returns
        -------
        ndarray, shape (P, n_params) or (n_params,)
            ``[a_1 .. a_na, b ...]`` of each point (the fitted ``b`` when
            ``search.numerator == "fit"``).
        """
        return _coefficients_of(z, self.parametrisation, self.cost, self.search.numerator)

    def describe(self) -> str:
        """One line: the parametrisation, its box rule, penalty, initial population, numerator.

        Returns
        -------
        str
            The parts that apply to this search space, joined by ``"; "``.
        """
        param, search = self.parametrisation, self.search
        if search.numerator == "fit":
            text = f"{param.name} parametrisation of {self.structure!r}: {param._describe_a()}"
        else:
            text = param.describe().rstrip(".")
        parts = [text]
        if param.name == "coefficients":
            parts += [self.box_rule, f"{search.penalty} penalty"]
            parts.append(f"{search.init} initial population")
        elif search.numerator != "fit":
            parts.append(self.box_rule)
        parts.append(f"numerator {_NUMERATOR_WORDS[search.numerator]}")
        return "; ".join(parts)

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe description of the search (for results and the store).

        Returns
        -------
        dict
            ``parametrisation`` (:meth:`Parametrisation.to_dict`), ``penalty``, ``init``,
            ``numerator`` and ``box_rule``.
        """
        return {
            "parametrisation": self.parametrisation.to_dict(),
            "penalty": self.search.penalty,
            "init": self.search.init,
            "numerator": self.search.numerator,
            "box_rule": self.box_rule,
        }

    def output_error_reference(
        self, *, starts: int = REFERENCE_STARTS, seed: int = 0
    ) -> OEResult | None:
        """The output-error reference of a simulation cost; ``None`` for one-step.

        Levenberg-Marquardt from least squares and stable starts
        (:func:`flexid.fit.output_error.output_error`), with every pole radius at most
        ``search.r_max``: the same set the ``"poles"`` space searches.  Cached for the last
        ``(starts, seed)``.

        Parameters
        ----------
        starts : int, optional
            Number of Levenberg-Marquardt starts, >= 1 (default 4).
        seed : int, optional
            Seed of the random stable starts (default 0).

        Returns
        -------
        OEResult or None
            The best stable fit, or None when the cost's predictor is ``"one-step"``.
        """
        if self.cost.predictor != "simulation":
            return None
        if self._oe is None or self._oe[0] != (starts, seed):
            from .output_error import output_error

            oe = output_error(self.cost, starts=starts, seed=seed, r_max=self.search.r_max)
            if oe.on_cap:  # the direct form's simulation is far off for a pole on the cap
                oe.cost = self.cost.realised_cost(oe.theta)
            self._oe = ((starts, seed), oe)
        return self._oe[1]

    def reference_cost(self) -> tuple[float, str]:
        """The best known stable cost and what it is (see :func:`choose_reference`).

        Returns
        -------
        cost : float
            The lower stable cost of least squares and the output-error reference (seed 0),
            or NaN when neither is stable.
        name : str
            Which one it is (``"no stable reference"`` for NaN).
        """
        oe = self.output_error_reference()
        ls_stable = bool(is_stable(self.theta_ls[None, : self.structure.na])[0])
        choice = choose_reference(
            self.cost_ls, ls_stable, None if oe is None else (float(oe.cost), bool(oe.stable))
        )
        return choice if choice is not None else (math.nan, "no stable reference")


def _coefficients_of(z: Any, param: Parametrisation, cost: ARXCost, numerator: str) -> np.ndarray:
    """The one map from search vectors to ARX coefficients (what the optimisers' costs see)."""
    fit = numerator == "fit"
    if fit:
        return cost.fit_numerator(_denominators_of(z, param))
    if param.name != "coefficients":
        # outside the box the maps lose their guarantee (|k| > 1, r > r_max): read a point
        # there as its projection on the box, which is stable
        z = np.clip(z, param.lower[: param.n_search], param.upper[: param.n_search])
    return param.to_coefficients(z)


def _denominators_of(z: Any, param: Parametrisation) -> np.ndarray:
    """The denominators of search vectors of the denominator only (``numerator="fit"``)."""
    if param.name != "coefficients":
        z = np.clip(z, param.lower[: param.na], param.upper[: param.na])  # as above
    return param.denominator(z)


def choose_reference(
    ls_cost: float, ls_stable: bool, oe: tuple[float, bool] | None
) -> tuple[float, str] | None:
    """The reference of targets: the lower stable cost of least squares and output error.

    Parameters
    ----------
    ls_cost, ls_stable : float, bool
        Least squares' cost and whether its model is stable.
    oe : (cost, stable) or None
        The output-error reference (simulation cost only).

    Returns
    -------
    (cost, name) or None
        ``None`` when neither is stable.
    """
    if oe is not None and oe[1] and (not ls_stable or oe[0] < ls_cost):
        return oe[0], "output-error reference (Levenberg-Marquardt on the simulation residuals)"
    if ls_stable:
        return ls_cost, "least squares"
    return None


def build_problem(
    est: IOData,
    structure: ARXStructure,
    cost: CostSpec,
    search: SearchSpec,
    *,
    bounds: Any = "auto",
) -> EstimationProblem:
    """Build the search problem of an identification.

    Parameters
    ----------
    est : IOData or sequence of IOData
        Estimation record (one output), or several records of one system: one cost over
        them all, each record with its own initial state
        (:class:`~flexid.costs.experiments.MultiExperimentCost`; an ARX structure is then
        read as a polynomial one).
    structure : ARXStructure, PolynomialStructure or GreyBoxModel
        Model orders (see :func:`model_structure`), or a grey-box model (then see
        :func:`flexid.fit.greybox_estimation.build_greybox_problem`).
    cost : CostSpec
        The cost (metric, predictor, weight, flat penalty value, initial conditions).
    search : SearchSpec
        Parametrisation, stability penalty kind, initial population rule, pole radius cap.
    bounds : see :func:`flexid.search_box`
        The box of the coefficients; with ``"poles"`` or ``"reflection"`` only its ``b``
        part is used.

    Returns
    -------
    EstimationProblem

    Raises
    ------
    UnknownNameError, ConfigError
        For an unknown parametrisation, penalty or initialisation, or bad bounds.
    DataError
        When the inputs are not persistently exciting enough for the orders
        (:func:`check_excitation`), or the regressors are otherwise singular.

    Warns
    -----
    IdentificationWarning
        When they barely are (:func:`check_excitation`).
    """
    check_search(search)
    return family_of(structure).pose(est, structure, cost, search, bounds=bounds)


def check_search(search: SearchSpec) -> None:
    """Validate search settings without data (for specs checked before anything runs).

    Parameters
    ----------
    search : SearchSpec
        The search settings.
    """
    if search.parametrisation not in PARAMETRISATIONS:
        raise UnknownNameError("parametrisation", search.parametrisation, PARAMETRISATIONS)
    if search.init not in INIT_RULES:
        raise UnknownNameError("initial population rule", search.init, INIT_RULES)
    if search.numerator not in NUMERATOR_RULES:
        raise UnknownNameError("numerator rule", search.numerator, NUMERATOR_RULES)
    from ..costs.arx import PENALTY_KINDS

    if search.penalty not in PENALTY_KINDS:
        raise UnknownNameError("stability penalty", search.penalty, PENALTY_KINDS)
    for name in ("r_max", "k_max"):
        v = getattr(search, name)
        if not (isinstance(v, (int, float)) and 0 < v < 1):
            raise ConfigError(f"[search] {name} must be in (0, 1), got {v!r}")


# ================================================================================ polynomial
@dataclass
class PolynomialEstimationProblem(EstimationProblem):
    """The search problem of a polynomial structure (ARMAX, OE, BJ, general).

    As :class:`EstimationProblem`, with ``cost`` a
    :class:`~flexid.costs.polynomial.PolynomialCost` and ``parametrisation`` a
    :class:`~flexid.fit.polynomial_space.PolynomialSpace`; the reference is the prediction-error
    method (:func:`flexid.fit.prediction_error.pem`), Levenberg-Marquardt from several starts.

    Attributes
    ----------
    structure : PolynomialStructure
        Model orders.
    cost : PolynomialCost
        The cost on the estimation record, in the structure's parameters ``theta``.
    parametrisation : PolynomialSpace
        The map from the search box to ``theta``.
    problem : Problem
        What the optimisers minimise, with the shared initial population.
    search : SearchSpec
        The settings it was built from.
    box : SearchBox
        Unbounded except for the rule (the polynomials are searched in their own spaces).
    box_rule : str
        How the box of the ``b`` coefficients was chosen (``numerator="search"``).
    """

    def theta(self, z: Any) -> np.ndarray:
        """Parameters ``theta`` of search vectors (``B`` fitted when it is not searched).

        Parameters
        ----------
        z : array_like, shape (P, n) or (n,)

        Returns
        -------
        ndarray, shape (P, n_params) or (n_params,)
        """
        theta = self.parametrisation.to_theta(z)
        if self.search.numerator == "fit":
            return self.cost.fit_numerator(theta)
        return theta

    def describe(self) -> str:
        """One line: the search space and how ``B`` is found.

        Returns
        -------
        str
        """
        text = self.parametrisation.describe()
        if self.parametrisation.name == "coefficients":
            text += f"; {self.search.penalty} penalty"
        if self.search.numerator == "search":
            text += f"; {self.box_rule}"
        return text

    def output_error_reference(
        self, *, starts: int = REFERENCE_STARTS, seed: int = 0
    ) -> PEMResult:
        """The prediction-error reference (:func:`flexid.fit.prediction_error.pem`) of this cost.

        Levenberg-Marquardt on the structure's prediction errors (with this cost's predictor
        and initial-condition rule) from least squares, Steiglitz-McBride and
        Hannan-Rissanen starts.  Cached for the last ``(starts, seed)``.

        Parameters
        ----------
        starts : int, optional
        seed : int, optional

        Returns
        -------
        PEMResult
        """
        if self._oe is None or self._oe[0] != (starts, seed):
            from .prediction_error import pem

            cost = self.cost
            data = list(cost.records) if len(cost.records) > 1 else cost.records[0]
            ref = pem(data, self.structure, initial=cost.initial, starts=starts, seed=seed)
            ref.cost = float(cost(ref.theta)[0])
            if ref.on_cap:
                # the direct form is far off for a pole on the cap: on the DaISy robot arm's
                # OE(8,8,1), 22.7 against 0.1618 in second-order sections
                ref.cost = cost.realised_cost(ref.theta)
            self._oe = ((starts, seed), ref)
        return self._oe[1]

    def reference_cost(self) -> tuple[float, str]:
        """The lower admissible cost of the least-squares start and the reference.

        Returns
        -------
        cost : float
        name : str
        """
        ref = self.output_error_reference()
        ls_ok = bool(np.isfinite(self.cost_ls)) and bool(
            self.cost._admissible(self.theta_ls[None, :])[0]
        )
        choice = choose_reference(self.cost_ls, ls_ok, (float(ref.cost), bool(ref.stable)))
        if choice is None:
            return math.nan, "no stable reference"
        cost, name = choice
        if name.startswith("output-error"):
            name = "prediction-error reference (Levenberg-Marquardt, analytic gradients)"
        return cost, name


def _build_polynomial(
    est: IOData,
    structure: PolynomialStructure,
    cost: CostSpec,
    search: SearchSpec,
    *,
    bounds: Any = "auto",
) -> PolynomialEstimationProblem:
    """:func:`build_problem` for a structure other than ARX."""
    from ..costs.experiments import polynomial_cost
    from .polynomial_space import PolynomialSpace

    objective = polynomial_cost(structure, est, **asdict(cost), penalty_kind=search.penalty)
    b_ls = np.nan_to_num(objective.theta_ls[structure.b_columns])
    if isinstance(bounds, str) and bounds == "auto":
        half = _round_up(2.0 * float(np.max(np.abs(b_ls)))) if b_ls.size else 1.0
        rule = f"b box: |b| <= {half:g} (2 max|b_LS|, rounded up)"
    elif isinstance(bounds, (int, float)) and not isinstance(bounds, bool) and bounds > 0:
        half = float(bounds)
        rule = f"b box: |b| <= {half:g}"
    else:
        raise ConfigError(
            f"bounds for {structure!r} must be 'auto' or a positive half-width of the b "
            f"box, got {bounds!r} (its other polynomials are searched in their own spaces)"
        )
    space = PolynomialSpace(
        structure,
        search.parametrisation,
        search.numerator,
        b_lower=-half,
        b_upper=half,
        r_max=search.r_max,
        real_pairs=search.real_pairs,
        k_max=search.k_max,
    )
    box = SearchBox(
        np.full(structure.n_params, -np.inf), np.full(structure.n_params, np.inf), rule
    )
    sampler = None
    if search.parametrisation == "coefficients" and search.init == "stable":
        poles = PolynomialSpace(
            structure, "poles", search.numerator, b_lower=-half, b_upper=half,
            r_max=search.r_max,
        )

        def sampler(size: int, rng: np.random.Generator) -> np.ndarray:
            Z = poles.lower + (poles.upper - poles.lower) * rng.random((size, poles.n_search))
            return np.clip(space.from_theta(poles.to_theta(Z)), space.lower, space.upper)

    if search.numerator == "fit":

        def evaluate(Z: np.ndarray) -> np.ndarray:
            return objective.fitted_costs(space.to_theta(Z))[0]

    else:

        def evaluate(Z: np.ndarray) -> np.ndarray:
            return objective(space.to_theta(Z))

    problem = Problem(evaluate, space.lower, space.upper, name=structure.kind, sampler=sampler)
    return PolynomialEstimationProblem(
        structure=structure,
        cost=objective,
        parametrisation=space,
        problem=problem,
        search=search,
        box=box,
        box_rule=rule if search.numerator == "search" else "b fitted (unbounded)",
    )
