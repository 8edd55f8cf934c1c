"""Hyper-parameters (:class:`Param`) and the base class of every optimiser (:class:`Optimiser`)."""

from __future__ import annotations

import math
from collections.abc import Generator, Mapping
from typing import Any, ClassVar

import numpy as np

from ..errors import HyperParameterError
from ._problem import SearchSpace

__all__ = ["Optimiser", "Param", "SearchGenerator"]

SearchGenerator = Generator[np.ndarray, np.ndarray, Any]


class Param:
    """A validated hyper-parameter, declared as a class attribute of an optimiser.

    Parameters
    ----------
    kind : type
        ``int``, ``float``, ``bool`` or ``str``.  An ``int`` parameter refuses floats and
        booleans; a ``float`` parameter accepts ints and refuses booleans, NaN and inf.
    default : object
        The default value (validated like any other).
    doc : str
        One-line description, with units where there are any.
    low, high : float, optional
        Bounds of the allowed range.
    low_open, high_open : bool, optional
        Whether ``low``/``high`` themselves are excluded (default: included).
    choices : sequence, optional
        The allowed values (for ``str`` parameters).
    none_ok : bool, optional
        Whether ``None`` is allowed (e.g. "no limit").
    aliases : sequence of str, optional
        Other names accepted for this hyper-parameter at construction (old names kept for
        configurations and scripts written before a rename).  Only the canonical name is
        an attribute, a key of :attr:`Optimiser.params` and listed by ``describe``.

    Examples
    --------
    >>> class Toy(Optimiser):
    ...     name = "toy"
    ...     population = Param(int, 20, "population size", low=2, aliases=("points",))
    >>> Toy(points=30).population
    30
    """

    def __init__(
        self,
        kind: type,
        default: Any,
        doc: str = "",
        *,
        low: float | None = None,
        high: float | None = None,
        low_open: bool = False,
        high_open: bool = False,
        choices: tuple | list | None = None,
        none_ok: bool = False,
        aliases: tuple[str, ...] | list[str] = (),
    ) -> None:
        if kind not in (int, float, bool, str):
            raise TypeError(f"Param kind must be int, float, bool or str, not {kind!r}")
        if isinstance(aliases, str) or not all(isinstance(a, str) and a for a in aliases):
            raise TypeError(f"Param aliases must be a sequence of names, not {aliases!r}")
        self.kind = kind
        self.doc = doc
        self.low = low
        self.high = high
        self.low_open = low_open
        self.high_open = high_open
        self.choices = tuple(choices) if choices is not None else None
        self.none_ok = none_ok
        self.aliases = tuple(aliases)
        self.name = "?"
        self.owner = "?"
        self.default = default

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name
        self.owner = getattr(owner, "name", owner.__name__)
        self.default = self.validate(self.default)

    def __get__(self, instance: Any, owner: type | None = None) -> Any:
        if instance is None:
            return self
        return instance._params[self.name]

    def __set__(self, instance: Any, value: Any) -> None:
        raise AttributeError(
            f"hyper-parameter {self.name!r} is fixed at construction; create a new optimiser"
        )

    def range_text(self) -> str:
        """The allowed values in words or interval notation.

        Returns
        -------
        str
            ``"one of 'a', 'b'"`` for choices, ``"any"`` without bounds, else an interval
            such as ``"(0, 1]"`` or ``"[1, inf)"``.
        """
        if self.choices is not None:
            return "one of " + ", ".join(repr(c) for c in self.choices)
        if self.low is None and self.high is None:
            return "any"
        left = ("(" if self.low_open else "[") + (
            f"{self.low:g}" if self.low is not None else "-inf"
        )
        right = (f"{self.high:g}" if self.high is not None else "inf") + (
            ")" if self.high_open or self.high is None else "]"
        )
        if self.low is None:
            left = "(-inf"
        return f"{left}, {right}"

    def validate(self, value: Any, owner: str | None = None, given_as: str | None = None) -> Any:
        """Check a value of this hyper-parameter and convert it to the parameter's type.

        Parameters
        ----------
        value : object
            The value given.  With ``none_ok``, None and the strings ``"none"``/``"null"``
            (any case) mean None.
        owner : str, optional
            Optimiser name used in the message (default: the declaring class's).
        given_as : str, optional
            The alias the value was passed under, if any (named in the message).

        Returns
        -------
        int, float, bool, str or None
            The value as ``kind`` (an int given for a float parameter becomes a float).

        Raises
        ------
        HyperParameterError
            For a value of the wrong type, NaN or inf, outside the range or choices, or None
            when ``none_ok`` is False.
        """
        where = f"{owner or self.owner}: hyper-parameter {self.name!r}"
        if given_as is not None and given_as != self.name:
            where += f" (given as {given_as!r})"
        if self.none_ok and isinstance(value, str) and value.strip().lower() in ("none", "null"):
            value = None  # TOML has no null: "none" stands for None in configuration files
        if value is None:
            if self.none_ok:
                return None
            raise HyperParameterError(f"{where} must not be None")
        value = self._typed(value, where)
        if self.choices is not None and value not in self.choices:
            raise HyperParameterError(f"{where} must be {self.range_text()}, got {value!r}")
        if self.kind in (int, float) and not self._in_range(value):
            raise HyperParameterError(f"{where} must lie in {self.range_text()}, got {value!r}")
        return value

    def _typed(self, value: Any, where: str) -> Any:
        """``value`` (not None) as :attr:`kind`: a bool only for a bool parameter, an integer
        for an int, a finite number for a float, a string for a str."""
        kind = self.kind
        if kind is bool:
            if isinstance(value, (bool, np.bool_)):
                return bool(value)
            raise HyperParameterError(f"{where} must be true or false, got {value!r}")
        if isinstance(value, (bool, np.bool_)):
            raise HyperParameterError(f"{where} must be {kind.__name__}, got the boolean {value!r}")
        if kind is int:
            if isinstance(value, (int, np.integer)):
                return int(value)
            raise HyperParameterError(
                f"{where} must be an integer, got {type(value).__name__} {value!r}"
            )
        if kind is float:
            if not isinstance(value, (int, float, np.integer, np.floating)):
                raise HyperParameterError(
                    f"{where} must be a number, got {type(value).__name__} {value!r}"
                )
            value = float(value)
            if not math.isfinite(value):
                raise HyperParameterError(f"{where} must be finite, got {value!r}")
            return value
        if kind is str and not isinstance(value, str):
            raise HyperParameterError(f"{where} must be a string, got {value!r}")
        return value

    def _in_range(self, value: float) -> bool:
        """Whether a number lies within ``low``/``high`` (each open or closed)."""
        too_low = self.low is not None and (
            value < self.low or (self.low_open and value == self.low)
        )
        too_high = self.high is not None and (
            value > self.high or (self.high_open and value == self.high)
        )
        return not (too_low or too_high)

    def describe(self) -> dict[str, Any]:
        """A plain description of the hyper-parameter.

        Returns
        -------
        dict
            ``type`` (e.g. ``"float or None"``), ``default``, ``range``
            (:meth:`range_text`), ``doc`` and, when it has any, ``aliases`` (list of str).
        """
        out = {
            "type": self.kind.__name__ + (" or None" if self.none_ok else ""),
            "default": self.default,
            "range": self.range_text(),
            "doc": self.doc,
        }
        if self.aliases:
            out["aliases"] = list(self.aliases)
        return out


class Optimiser:
    """Base class of every optimiser.

    Subclasses set ``name``, declare hyper-parameters as :class:`Param` class attributes
    and implement :meth:`search` as a generator.  Construction validates the
    hyper-parameters: an unknown name, a wrong type or an out-of-range value raises
    :class:`~flexid.errors.HyperParameterError`; :meth:`check` may add cross-parameter
    rules.

    Attributes
    ----------
    name : str
        Registry name.
    auto_iterations : bool
        If True (default), every yielded batch after the first is one iteration.  If False,
        the search calls ``space.end_iteration(phase)`` itself (needed when an iteration
        evaluates several batches, as the swims of bacterial foraging do); the first batch
        is always iteration 0, phase ``"init"``.
    reference : str
        Where the algorithm comes from.
    bounds : str
        What it does at the bounds, in a few words (``"clip"``, ``"midpoint repair"``,
        ``"periodic transform"``, ``"leaves the box (paper)"``...); ``""``: not stated.
    bounds_note : str
        The same in one sentence.
    stays_in_box : bool or None
        Whether every point it evaluates lies in the box (with its default
        hyper-parameters); None: not stated.  The conformance suite checks the claim.
    """

    name: ClassVar[str] = ""
    auto_iterations: ClassVar[bool] = True
    reference: ClassVar[str] = ""
    bounds: ClassVar[str] = ""
    bounds_note: ClassVar[str] = ""
    stays_in_box: ClassVar[bool | None] = None

    def __init__(self, **params: Any) -> None:
        spec = self.hyperparameters()
        given = self._given_names(params, self.name or type(self).__name__)
        values = {}
        for key, param in spec.items():
            values[key] = (
                param.validate(params[given[key]], owner=self.name or None, given_as=given[key])
                if key in given
                else param.default
            )
        self._params = values
        self.check()

    @classmethod
    def hyperparameters(cls) -> dict[str, Param]:
        """The declared hyper-parameters, in declaration order (base classes first).

        Keys are the canonical names; the aliases a parameter also accepts are in
        :meth:`aliases`.

        Returns
        -------
        dict of str to Param
            ``{canonical name: Param}``; a subclass's declaration overrides its base's.
        """
        spec: dict[str, Param] = {}
        for klass in reversed(cls.__mro__):
            for key, value in vars(klass).items():
                if isinstance(value, Param):
                    spec[key] = value
        return spec

    @classmethod
    def aliases(cls) -> dict[str, str]:
        """The other names hyper-parameters accept.

        Returns
        -------
        dict of str to str
            ``{alias: canonical name}`` (empty when no parameter has aliases).

        Raises
        ------
        TypeError
            If an alias is the name of a hyper-parameter or the alias of two of them (a
            mistake in the optimiser's declaration).
        """
        spec = cls.hyperparameters()
        table: dict[str, str] = {}
        for key, param in spec.items():
            for alias in param.aliases:
                if alias in spec or table.get(alias, key) != key:
                    raise TypeError(
                        f"{cls.name or cls.__name__}: alias {alias!r} of hyper-parameter "
                        f"{key!r} clashes with another hyper-parameter or alias"
                    )
                table[alias] = key
        return table

    @classmethod
    def canonical_params(cls, params: Mapping[str, Any], owner: str | None = None) -> dict:
        """``params`` keyed by canonical hyper-parameter names (aliases replaced).

        Parameters
        ----------
        params : mapping of str to object
            Hyper-parameter values under their names or aliases.
        owner : str, optional
            Optimiser name used in error messages (default: this class's ``name``).

        Returns
        -------
        dict
            ``{canonical name: value}`` in the order of ``params``; the values are not
            validated.

        Raises
        ------
        HyperParameterError
            For a name that is neither a hyper-parameter nor an alias, or a hyper-parameter
            given twice (under its name and an alias, or under two aliases).
        """
        given = cls._given_names(params, owner or cls.name or cls.__name__)
        return {key: params[name] for key, name in given.items()}

    @classmethod
    def _given_names(cls, params: Mapping[str, Any], owner: str) -> dict[str, str]:
        """``{canonical name: the name it was given under in params}``."""
        spec = cls.hyperparameters()
        table = cls.aliases()
        unknown = sorted(k for k in params if k not in spec and k not in table)
        if unknown:
            raise HyperParameterError(
                f"{owner}: unknown hyper-parameter(s) "
                f"{', '.join(map(repr, unknown))}; valid: {', '.join(spec) or 'none'}"
            )
        given: dict[str, str] = {}
        for name in params:
            key = table.get(name, name)
            if key in given:
                raise HyperParameterError(
                    f"{owner}: hyper-parameter {key!r} given twice, as {given[key]!r} and "
                    f"{name!r}"
                )
            given[key] = name
        return given

    @property
    def params(self) -> dict[str, Any]:
        """The hyper-parameter values of this instance (a copy)."""
        return dict(self._params)

    def check(self) -> None:
        """Cross-parameter validation; raise HyperParameterError.  Default: nothing."""

    def search(self, space: SearchSpace, rng: np.random.Generator) -> SearchGenerator:
        """The algorithm: ``F = yield X`` for every population to evaluate.

        Parameters
        ----------
        space : SearchSpace
            Box, shared initial population, clipping, iteration marks.
        rng : numpy.random.Generator
            The run's only source of randomness.
        """
        raise NotImplementedError

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self._params.items())
        return f"{type(self).__name__}({args})"
