"""One interface for every model family: posing its problem and validating its models.

A model family (the polynomial models ARX, ARMAX, OE and BJ; grey-box models; one of your
own) registers one :class:`Family` object.  :func:`flexid.estimation.build_problem` and
:func:`flexid.validate`, and through them :func:`flexid.identify`, :func:`flexid.select`,
:func:`flexid.compare` and the suite, find it with :func:`family_of` from the structure or
model they hold and ask it, so none of them asks which family it holds.

The object is what identification needs of a family that the structure and model cannot
say themselves (they live a layer below the costs and the searches):

- :meth:`Family.pose`: a record, a structure, a cost and a search as an
  :class:`~flexid.estimation.EstimationProblem` (its search space and batched cost);
- :meth:`Family.validate`: a model's validation report on a record.

Examples
--------
>>> import flexid
>>> from flexid.families import family_of
>>> family_of(flexid.structure("oe", nb=2, nf=2)).name
'polynomial'
"""

from __future__ import annotations

import abc
import importlib
from typing import Any, ClassVar

from .config import CostSpec, SearchSpec
from .errors import ConfigError

__all__ = ["Family", "families", "family_of", "register_family"]


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
    """

    name: ClassVar[str]
    structures: ClassVar[tuple[type, ...]] = ()
    models: ClassVar[tuple[type, ...]] = ()

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

        Returns
        -------
        ValidationReport
        """


_FAMILIES: list[Family] = []

#: The built-in families: module and class, registered on the first lookup (a name kept as
#: text so that this module imports none of them: they import it).
_BUILTINS = (
    ("flexid.polynomial_family", "PolynomialFamily"),
    ("flexid.greybox_family", "GreyBoxFamily"),
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
    return family


def families() -> tuple[Family, ...]:
    """The registered families, in registration order.

    Returns
    -------
    tuple of Family
    """
    _load_builtins()
    return tuple(_FAMILIES)


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
