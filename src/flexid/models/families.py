"""One interface for every model family: posing its problem and validating its models.

A model family (the polynomial models ARX, ARMAX, OE and BJ; grey-box models; one of your
own) registers one :class:`Family` object.  :func:`flexid.fit.estimation.build_problem` and
:func:`flexid.validate`, and through them :func:`flexid.identify`, :func:`flexid.select`,
:func:`flexid.compare` and the suite, find it with :func:`family_of` from the structure or
model they hold and ask it, so none of them asks which family it holds.

The object is what identification needs of a family that the structure and model cannot
say themselves (they live a layer below the costs and the searches):

- :meth:`Family.structure`: the structure a name and its orders give (``"oe", nb=2, nf=2``);
- :meth:`Family.pose`: a record, a structure, a cost and a search as an
  :class:`~flexid.fit.estimation.EstimationProblem` (its search space and batched cost);
- :meth:`Family.fit`: the family's own estimate (least squares, its gradient reference)
  where it has one, for ``identify(optimiser="ls")`` or ``"pem"``;
- :meth:`Family.reference`: that reference straight from a record, for :func:`flexid.select`;
- :meth:`Family.validate`: a model's validation report on a record.

What the jobs read of a structure itself: ``kind`` (its name), ``orders`` (a dict),
``n_params``, ``n_inputs``, ``start`` (the first sample a cost scores), ``check_samples(n)``,
``model(theta, dt=...)`` and ``to_dict()``; of a model: ``structure``, ``theta``,
``named(inputs, output)``, ``is_stable``, ``summary()`` and ``to_dict()``.
``examples/recipe_family.py`` writes a family in one file.

Examples
--------
>>> import flexid
>>> from flexid.models.families import family_of
>>> family_of(flexid.structure("oe", nb=2, nf=2)).name
'polynomial'
"""

from __future__ import annotations

import abc
import importlib
from dataclasses import dataclass, field
from typing import Any, ClassVar

from ..errors import ConfigError, ModelOrderError, UnknownNameError
from .specs import CostSpec, SearchSpec
from .vocabulary import add_structure_names

__all__ = [
    "Family",
    "ReferenceFit",
    "families",
    "family_named",
    "family_of",
    "register_family",
    "structure_names",
]


@dataclass
class ReferenceFit:
    """A family's own estimate of a structure: its least squares or gradient reference.

    Attributes
    ----------
    model : object
        The fitted model.
    cost : float
        Its value of the posed cost.
    params : dict
        What the method used (``{"starts": 4}``), as a result records an optimiser's
        hyper-parameters.
    seed : int or None
        The seed of its random starts (None: it has none).
    result : object, optional
        The reference's own result (standard errors, optimality), or None.
    """

    model: Any
    cost: float
    params: dict = field(default_factory=dict)
    seed: int | None = None
    result: Any = None


class Family(abc.ABC):
    """What identification needs of one model family; subclass it and register an instance.

    Attributes
    ----------
    name : str
        The family's name (``"polynomial"``, ``"greybox"``).
    structures : tuple of type
        The structure classes it poses (an instance of one belongs to the family).
    models : tuple of type
        The model classes it validates.
    names : tuple of str
        The structure names :meth:`structure` builds from orders (``"arx"``, ``"oe"``); a
        job's ``structure="oe"`` finds the family by them.
    reads_channels : bool
        Whether its models read a record's channels by their own names (a grey-box model),
        rather than take the record's inputs in order.
    runs_on : bool
        Whether its models' states run on from a record's start, so that a held-out part
        cut from the estimation record is validated by running on through the estimation
        part (a grey-box model), and whether a model's stability is read from that run
        (:meth:`held_out_stable`) rather than from its poles.
    start_stop : str
        How a comparison's start row (the posed problem's ``theta_ls``) was reached, as its
        ``stop`` field says: ``"closed form"`` for least squares.
    several_outputs : bool
        Whether its models take every output of a record at once (a state-space model);
        the others are fitted to one output.
    predictors : tuple of str
        The predictors its costs have (``("simulation",)`` for an output-error family: a
        job that names none uses it).
    """

    name: ClassVar[str]
    structures: ClassVar[tuple[type, ...]] = ()
    models: ClassVar[tuple[type, ...]] = ()
    names: ClassVar[tuple[str, ...]] = ()
    reads_channels: ClassVar[bool] = False
    runs_on: ClassVar[bool] = False
    start_stop: ClassVar[str] = "closed form"
    several_outputs: ClassVar[bool] = False
    predictors: ClassVar[tuple[str, ...]] = ("one-step", "simulation")

    def owns(self, obj: Any) -> bool:
        """Whether ``obj`` is a structure or model of this family.

        Parameters
        ----------
        obj : object

        Returns
        -------
        bool
        """
        return isinstance(obj, (*self.structures, *self.models))

    def title(self, structure: Any) -> str:
        """The structure as a summary names it (default: its ``repr``).

        Parameters
        ----------
        structure : object
            A structure of this family.

        Returns
        -------
        str
        """
        return repr(structure)

    def structure_dict(self, structure: Any) -> dict[str, Any]:
        """The structure's name and orders as a result's JSON stores them.

        Parameters
        ----------
        structure : object
            A structure of this family.

        Returns
        -------
        dict
            ``structure.to_dict()`` by default.
        """
        return structure.to_dict()

    def structure(self, spec: Any, n_inputs: int, **orders: Any) -> Any:
        """The structure a name and its orders, or a whole structure, give for a record.

        Parameters
        ----------
        spec : str or object
            One of :attr:`names`, or a structure of this family (then no orders).
        n_inputs : int
            Inputs of the record.
        **orders : int, sequence of int or None
            The orders by name (None: not given).

        Returns
        -------
        object
            The structure, checked against the record's inputs.

        Raises
        ------
        ModelOrderError
            Orders the structure does not have, or that do not match the inputs.
        """
        if isinstance(spec, str):
            raise ConfigError(f"the {self.name} family builds no structure from a name")
        self.refuse_orders(spec, orders)
        if not self.reads_channels and getattr(spec, "n_inputs", n_inputs) != n_inputs:
            raise ModelOrderError(
                f"the record has {n_inputs} input(s) but {spec!r} has {spec.n_inputs}"
            )
        return spec

    @staticmethod
    def refuse_orders(spec: Any, orders: dict[str, Any]) -> None:
        """Refuse orders given with a whole structure (``nk=1``, the default, is no order).

        Parameters
        ----------
        spec : object
            The structure given.
        orders : dict
            The orders by name (None: not given).

        Raises
        ------
        ModelOrderError
            If any order is given.
        """
        given = sorted(k for k, v in orders.items() if v is not None and (k, v) != ("nk", 1))
        if given:
            raise ModelOrderError(
                f"give either a structure object or orders, not both (got {', '.join(given)} "
                f"with {spec!r})"
            )

    def canonical(self, structure: Any) -> Any:
        """The structure in the form that compares equal across its spellings (default:
        itself); :func:`flexid.select` removes duplicate candidates by it.

        Parameters
        ----------
        structure : object

        Returns
        -------
        object
        """
        return structure

    def fit(self, estimation: Any, structure: Any, method: str, *, data: Any,
            seed: int | None) -> ReferenceFit:
        """The family's own estimate: ``method`` ``"ls"`` (least squares) or ``"pem"`` (its
        gradient reference) of the posed problem (``"oe"``, the old spelling of ``"pem"``).

        Parameters
        ----------
        estimation : EstimationProblem
            The problem :meth:`pose` gave.
        structure : object
            The structure asked for.
        method : {"ls", "pem", "oe"}
        data : IOData
            The (first) estimation record.
        seed : int or None
            Seed of the reference's random starts.

        Returns
        -------
        ReferenceFit

        Raises
        ------
        ConfigError
            When the family has no such estimate (the default: name an optimiser).
        """
        raise ConfigError(
            f"the {self.name} model family has no estimate {method!r}: name a registered "
            "optimiser (flexid list optimisers)"
        )

    def reference(self, data: Any, structure: Any, *, initial: str, starts: int | None,
                  seed: int) -> tuple[Any, float, bool]:
        """The gradient reference of ``structure`` on a record, as :func:`flexid.select`
        fits a candidate.

        Parameters
        ----------
        data : IOData
            The estimation record.
        structure : object
        initial : str
            The initial-condition rule of its prediction errors.
        starts : int or None
            Starts of the reference (None: the family's default).
        seed : int
            Seed of its random starts.

        Returns
        -------
        model : object
        sse : float
            Sum of squared one-step prediction errors of the fit (output units squared).
        local_minimum : bool
            Whether it verified a local minimum.

        Raises
        ------
        ConfigError
            When the family has none (the default).
        """
        raise ConfigError(f"the {self.name} model family has no reference to select with")

    def reference_hint(self, structure: Any, predictor: str) -> str:
        """The estimate a user should compare a search with, as advice names it.

        Parameters
        ----------
        structure : object
        predictor : str
            The cost's predictor.

        Returns
        -------
        str
        """
        return "optimiser='pem'"

    def start_name(self, structure: Any) -> str:
        """What the start of the search is, as a summary names the cost it compares with.

        Parameters
        ----------
        structure : object

        Returns
        -------
        str
        """
        return "least squares"

    @abc.abstractmethod
    def pose(
        self, data: Any, structure: Any, cost: CostSpec, search: SearchSpec, *, bounds: Any
    ) -> Any:  # an EstimationProblem (whose module imports this one)
        """The search problem of fitting ``structure`` to ``data``.

        Parameters
        ----------
        data : IOData or sequence of IOData
            The estimation record, or several records of one system.
        structure : object
            A structure of this family.
        cost : CostSpec
            Metric, predictor, weight, penalty value and initial-condition rule.
        search : SearchSpec
            Parametrisation, penalty kind, initial population rule and pole-radius cap
            (checked by the caller).
        bounds : object
            The box rule (see :func:`flexid.search_box`).

        Returns
        -------
        EstimationProblem
        """

    @abc.abstractmethod
    def validate(
        self, model: Any, data: Any, *, max_lag: int, initial: str,
        split: float | int | None, dt: float | None, output: str | None,
        estimated_on: Any = None,
    ) -> Any:  # a ValidationReport (whose module imports this one)
        """The validation report of ``model`` on ``data`` (see :func:`flexid.validate`).

        Parameters
        ----------
        model : object
            A model of this family.
        data : IOData or (u, y) pair
            The record.
        max_lag : int
            Lags of the correlation tests.
        initial : str
            The initial-condition rule, checked by the caller.
        split : float, int or None
            Validate on the part of the record after this split only.
        dt : float or None
            Sample time of an array pair.
        output : str or None
            The output to validate, for a model with several.
        estimated_on : IOData, sequence of IOData, "same" or None
            The record(s) the model was estimated on (see :func:`flexid.validate`), for the
            residual tests' null distribution; a family that cannot use it takes the
            parameters as known.

        Returns
        -------
        ValidationReport
        """


    def held_out(
        self, model: Any, estimation: Any, validation: Any, *, max_lag: int, initial: str
    ) -> Any:  # a ValidationReport
        """The held-out report a comparison records of each run's model.

        Parameters
        ----------
        model : object
            A model of this family.
        estimation : IOData
            The estimation record (or the first of several).
        validation : IOData
            The validation record.
        max_lag : int
            Lags of the correlation tests.
        initial : str
            The comparison's initial-condition rule of validation, checked.

        Returns
        -------
        ValidationReport
            By default :meth:`validate` on ``validation``, the model estimated on
            ``estimation``.
        """
        return self.validate(model, validation, max_lag=max_lag, initial=initial, split=None,
                             dt=None, output=None, estimated_on=estimation)  # fmt: skip

    def held_out_stable(self, model: Any, report: Any) -> bool:
        """Whether a model counts as stable in a selection, given its held-out report.

        Parameters
        ----------
        model : object
            A model of this family.
        report : ValidationReport
            Its report on the held-out part.

        Returns
        -------
        bool
            By default the model's own ``is_stable`` (its poles).
        """
        return bool(model.is_stable)

    def model_numbers(self, model: Any, estimation: Any, records: Any) -> dict[str, Any]:
        """What a comparison stores of each run's model, beside its held-out report.

        Parameters
        ----------
        model : object
            A model of this family.
        estimation : EstimationProblem
            The posed problem the model was searched in.
        records : tuple of IOData
            The estimation records.

        Returns
        -------
        dict
            ``theta`` (list of float), ``stable`` (bool), ``max_pole_radius`` (float) and
            the range of the one-step errors on the estimation records,
            ``estimation_error_min`` and ``estimation_error_max``.  By default the errors are
            those of :meth:`validate` under ``initial="zero"``, the poles ``model.poles()``.
        """
        import numpy as np

        reports = [
            self.validate(model, r, max_lag=1, initial="zero", split=None, dt=None, output=None)
            for r in records
        ]
        ranges = [report.error_range_one_step for report in reports]
        poles = np.asarray(model.poles()) if hasattr(model, "poles") else np.zeros(0)
        return {
            "theta": [float(v) for v in model.theta],
            "stable": bool(getattr(model, "is_stable", np.all(np.abs(poles) < 1.0))),
            "max_pole_radius": float(np.max(np.abs(poles), initial=0.0)),
            "estimation_error_min": float(min(lo for lo, _ in ranges)),
            "estimation_error_max": float(max(hi for _, hi in ranges)),
        }


_FAMILIES: list[Family] = []

#: The built-in families: module and class, registered on the first lookup (a name kept as
#: text so that this module imports none of them: they import it).
_BUILTINS = (
    ("flexid.fit.polynomial_family", "PolynomialFamily"),
    ("flexid.fit.greybox_family", "GreyBoxFamily"),
    ("flexid.fit.statespace_family", "StateSpaceFamily"),
)
_loaded = False


def _load_builtins() -> None:
    global _loaded
    if _loaded:
        return
    _loaded = True
    for module, name in _BUILTINS:
        _FAMILIES.append(getattr(importlib.import_module(module), name)())


def register_family(family: Family) -> Family:
    """Register a model family; a later registration of the same name replaces it.

    Parameters
    ----------
    family : Family

    Returns
    -------
    Family
        ``family``, so that a module can keep it under a name.

    Raises
    ------
    ConfigError
        If ``family`` is not a :class:`Family`.
    """
    if not isinstance(family, Family):
        raise ConfigError(f"register_family takes a Family, got {type(family).__name__}")
    _load_builtins()
    _FAMILIES[:] = [f for f in _FAMILIES if f.name != family.name]
    _FAMILIES.append(family)
    add_structure_names(family.names)  # a comparison's [model] may name them now
    return family


def families() -> tuple[Family, ...]:
    """The registered families, in registration order.

    Returns
    -------
    tuple of Family
    """
    _load_builtins()
    return tuple(_FAMILIES)


def family_named(name: str) -> Family:
    """The family that builds the structure ``name`` (``"oe"``: the polynomial family).

    Parameters
    ----------
    name : str
        A structure name, any case.

    Returns
    -------
    Family

    Raises
    ------
    UnknownNameError
        If no registered family builds it; the message lists every name that is known.
    """
    _load_builtins()
    key = str(name).lower()
    for family in reversed(_FAMILIES):
        if key in family.names:
            return family
    raise UnknownNameError("model structure", str(name), structure_names())


def structure_names() -> tuple[str, ...]:
    """Every structure name the registered families build, in registration order.

    Returns
    -------
    tuple of str
    """
    _load_builtins()
    return tuple(dict.fromkeys(n for f in _FAMILIES for n in f.names))


def family_of(obj: Any, default: str | None = None) -> Family:
    """The family of a structure or model.

    Parameters
    ----------
    obj : object
        A structure or model.
    default : str, optional
        The family to read an object of no registered family as (a model that only looks
        like one: validation reads duck-typed ARX models as polynomial ones).

    Returns
    -------
    Family

    Raises
    ------
    ConfigError
        If no registered family owns ``obj`` and there is no ``default``.
    """
    _load_builtins()
    for family in reversed(_FAMILIES):  # the latest registration wins
        if family.owns(obj):
            return family
    for family in _FAMILIES:
        if family.name == default:
            return family
    known = ", ".join(f.name for f in _FAMILIES) or "none registered"
    raise ConfigError(
        f"{type(obj).__name__} is not a structure or model of a registered model family "
        f"({known}); give a structure such as flexid.structure('oe', nb=2, nf=2)"
    )
