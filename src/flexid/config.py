"""Comparison specifications and their TOML configuration files.

A comparison is fully described by a :class:`ComparisonSpec`: where the data come from
(a simulated plant and its excitation, or a recorded file), the ARX orders, the cost, the
search box, the optimisers with their hyper-parameters, the number of runs, the seed and
the budget.  ``flexid compare CONFIG.toml`` reads one; ``flexid compare --plant ...``
builds one from the defaults and the command-line options.

Example (``experiments/paper-manipulator.toml`` is a complete one)::

    name = "small-manipulator"

    [data]
    plant = "manipulator"          # or: file = "record.csv", inputs = ["u"], outputs = ["y"]
    preset = "paper-manipulator"
    seed = 0

    [model]
    na = 8
    nb = 8
    nk = 1

    [cost]
    metric = "paper"               # paper | rmse | nrmse | sse | mse
    predictor = "one-step"         # one-step | simulation

    [run]
    runs = 10
    seed = 1
    budget = 10000                 # FE; a list runs several budgets; "schedule" = the
                                   # optimisers' own loop counts (capped by schedule_cap)

    [[optimisers]]
    name = "hbcsd"
    [[optimisers]]
    name = "bfa"
    params = { step_size = 0.01 }

    [compare]
    run_timeout = 600              # seconds; a longer run is ended and recorded as failed
"""

from __future__ import annotations

import codecs
import datetime
import difflib
import hashlib
import json
import math
import numbers
import os
import sys
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

from ._validate import _interval, _within, integer, is_integer, level, real
from .errors import ConfigError, FlexidDeprecationWarning

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on Python 3.10 only
    import tomli as tomllib

__all__ = [
    "COMPARE_BUDGET",
    "COMPARE_RUNS",
    "CONFIG_SCHEMA",
    "CORRELATION_LAGS",
    "DEFAULT_OPTIMISERS",
    "DEPRECATED_REFERENCES",
    "GREYBOX",
    "IDENTIFY_BUDGET",
    "KEYWORDS",
    "LEAST_SQUARES",
    "OUTPUT_ERROR",
    "PAPER_SEARCH",
    "POLE_RADIUS_CAP",
    "PREDICTION_ERROR",
    "REFERENCES",
    "REFLECTION_CAP",
    "SCHEDULE",
    "STATE_SPACE",
    "STRUCTURE_NAMES",
    "SUBSPACE",
    "VALIDATION_ALPHA",
    "VALIDATION_GUIDE",
    "ComparisonSpec",
    "ConfigKey",
    "CostSpec",
    "DataSpec",
    "Keyword",
    "ModelSpec",
    "OptimiserSpec",
    "SearchSpec",
    "add_structure_names",
    "auto_initial",
    "check_config",
    "command_specs",
    "current_reference",
    "default_spec",
    "keyword",
    "load_config",
    "spec_from_mapping",
    "specs_from_keywords",
    "with_optimiser_params",
]

DEFAULT_OPTIMISERS = ("hbcsd", "bfa", "sda", "pso", "de")
#: Function evaluations of one identification by an optimiser (``identify``, ``greybox``).
IDENTIFY_BUDGET = 20_000
#: Function evaluations of each run of a comparison, and its runs per optimiser.
COMPARE_BUDGET = 10_000
COMPARE_RUNS = 5
SCHEDULE = "schedule"
#: The least-squares reference: an ``optimiser`` name of ``identify`` and the label of the
#: reference row every comparison includes.
LEAST_SQUARES = "ls"
#: A deprecated spelling of :data:`PREDICTION_ERROR` (it read as "an output-error model",
#: which is ``structure="oe"``); ``identify`` warns and runs ``"pem"``.
OUTPUT_ERROR = "oe"
#: The gradient reference of any structure's cost (Levenberg-Marquardt with analytic
#: gradients, :func:`flexid.fit.prediction_error.pem`): an ``optimiser`` name of ``identify``.
PREDICTION_ERROR = "pem"
#: Subspace identification of a state-space model (:func:`flexid.n4sid`): an ``optimiser``
#: name of ``identify`` for ``structure="ss"``.
SUBSPACE = "n4sid"
#: The ``optimiser`` names of the references, which take no FE budget (the deprecated
#: spellings among them, so they are recognised before they are replaced).
REFERENCES = (LEAST_SQUARES, OUTPUT_ERROR, PREDICTION_ERROR, SUBSPACE)
#: Old reference names and the one each now is.
DEPRECATED_REFERENCES = {OUTPUT_ERROR: PREDICTION_ERROR}
#: Levenberg-Marquardt starts of the polynomial references beside the deterministic ones
#: (least squares, Steiglitz-McBride, Hannan-Rissanen), in identify, compare and select alike,
#: so one structure gives one model whichever job fits it.
REFERENCE_STARTS = 4
#: Starts of the grey-box reference (:func:`flexid.fit.greybox_fit.greyest`).
GREYBOX_REFERENCE_STARTS = 3
#: The named model structures (their orders: :data:`flexid.models.polynomial.STRUCTURES`).
STRUCTURE_NAMES = ("arx", "armax", "oe", "bj")
#: The structure name of a grey-box model (:mod:`flexid.models.greybox`), beside the
#: polynomial ones.
GREYBOX = "greybox"
#: The structure name of a state-space model of every output (:mod:`flexid.models.statespace`;
#: its orders, ``order`` and ``modes``, in a :class:`ModelSpec`'s ``options``).
STATE_SPACE = "ss"
# Structure names of the model families registered beyond the built-in ones
# (flexid.models.families.register_family adds theirs): a ModelSpec may name them.
_REGISTERED_NAMES: set[str] = set()


def add_structure_names(names: Sequence[str]) -> None:
    """Let a :class:`ModelSpec` name these structures (a registered family builds them).

    Parameters
    ----------
    names : sequence of str
        Lower-case structure names.
    """
    _REGISTERED_NAMES.update(str(n).lower() for n in names)
#: Lags of the residual correlation tests (auto- and cross-correlation, Billings-Voon), as
#: MATLAB's ``resid`` and Ljung (System Identification, 2nd ed., sec. 16.6) use.
CORRELATION_LAGS = 25
#: Family-wise level of a validation verdict: the rate at which the residual tests together
#: reject a true model (Holm's correction over the tests; see :mod:`flexid.validation.diagnostics`).
VALIDATION_ALPHA = 0.05
#: The guide's page on reading a validation verdict, named beside every FAIL.
VALIDATION_GUIDE = "https://github.com/flexid/flexid/blob/main/docs/guide/validation.rst"
#: Largest pole radius of the ``"poles"`` search space, and of every reference fitted to
#: compare with it: a pole closer to the circle than 1e-4 is not a model a user wants.
POLE_RADIUS_CAP = 0.9999
#: Bound of every reflection coefficient ``|k|`` of the ``"reflection"`` search space.
REFLECTION_CAP = 0.9999


def current_reference(optimiser: str, *, stacklevel: int = 3) -> str:
    """The optimiser name to run: a deprecated reference spelling warns and gives its new one.

    Parameters
    ----------
    optimiser : str
        An ``optimiser`` name as a user wrote it.
    stacklevel : int
        Passed to :func:`warnings.warn`, so the warning points at the user's call.

    Returns
    -------
    str
        ``optimiser`` itself, or the name a deprecated spelling stands for (``"oe"`` ->
        ``"pem"``).

    Warns
    -----
    FlexidDeprecationWarning
        For a deprecated spelling, saying what to write.
    """
    new = DEPRECATED_REFERENCES.get(optimiser) if isinstance(optimiser, str) else None
    if new is None:
        return optimiser
    warnings.warn(
        f"optimiser {optimiser!r} is deprecated: write {new!r}; an output-error model is "
        "structure 'oe'",
        FlexidDeprecationWarning,
        stacklevel=stacklevel,
    )
    return new


def auto_initial(structure: str) -> str:
    """The initial-condition rule ``"auto"`` stands for with a structure of this name.

    ``"measured"`` for ARX (the setting of the paper's experiments, kept as it was) and
    ``"estimate"`` for every other structure: their predictors are recursive, and starting a
    lightly damped high-order recursion from measured outputs excites a transient that is not
    the model's (see :mod:`flexid.models.polynomial`).

    Parameters
    ----------
    structure : str
        A structure's name (:data:`STRUCTURE_NAMES`, or ``"polynomial"``).

    Returns
    -------
    str
    """
    return "measured" if structure == "arx" else "estimate"


@dataclass(frozen=True)
class DataSpec:
    """Where the record comes from, and how it is split.

    Either ``plant`` (simulate; ``preset``, ``signal``, ``n_samples``, ``seed``,
    ``noise_std``, ``signal_options``, ``plant_params``, ``sensors`` as in
    :func:`flexid.data.datasets.generate`) or ``file`` (a CSV/NPZ/DAT record; ``inputs``,
    ``outputs``, ``dt`` as in :func:`flexid.data.load`).  ``output`` picks the modelled
    output channel; ``split`` is the estimation share (or a sample index); ``detrend``
    removes the estimation means.

    Attributes
    ----------
    plant : str or None
        A registered plant to simulate (``"manipulator"`` or ``"twin-rotor"``).
    preset : str or None
        A dataset preset (``"paper-manipulator"``, ``"paper-twin-rotor"``); the other
        fields override it.
    signal : str or None
        Excitation signal name (default: the preset's, else ``"uniform"``).
    n_samples : int or None
        Record length in samples (default: the preset's or the plant's).
    seed : int
        Seed of the simulated record (signal and noise), default 0.
    noise_std : float, list of float, str or None
        Measurement noise: one standard deviation for all outputs, one per output (output
        units), or ``"p%"`` of each noise-free output's standard deviation.
    signal_options : dict
        Options of the signal (``{"low": -0.3, "high": 0.3}``, ...).
    plant_params : dict
        Physical parameter overrides of the plant.
    sensors : {"lab", "ideal"}
        The plant read through its measurement chain (``"lab"``, default) or exactly.
    file : str, list of str, or None
        A recorded CSV/NPZ/DAT file to read instead of simulating; a list: several
        estimation records of one system, fitted together, each with its own initial state
        (they need ``validation``).
    validation : str or None
        A recorded file to validate on (read with the same ``inputs``, ``outputs`` and
        ``dt``); ``file`` is then all estimation (or the range ``split``).
    inputs : list of str or None
        Input columns of ``file``.
    outputs : list of str or None
        Output columns of ``file``, or the outputs a simulated plant records.
    dt : float or None
        Sample time of ``file`` in seconds, when the file does not give it.
    output : str, int or None
        The output channel modelled when the record has several.
    split : float, int, str, list or None
        Estimation share in (0, 1) (default 2/3), above 1 the first validation sample, or
        the two parts as sample ranges, ``[[0, 1000], [1000, 1473]]`` or
        ``"0:1000,1000:"`` (:func:`flexid.data.split_parts`).
    detrend : bool or str
        ``"constant"`` (or true): remove the estimation record's means from both records;
        ``"linear"``: its least-squares line (see :func:`flexid.data.prepare_data`); default
        False.
    digest : str or None
        SHA-256 of the record read from ``file`` (its samples, sample time and channel
        names), set by :func:`flexid.compare` when it reads the file, not in configuration
        files.  It is part of the store key, so a comparison on an edited file is a new
        comparison.  None for a simulated record (its settings determine it).

    Raises
    ------
    ConfigError
        Unless exactly one of ``plant`` and ``file`` is given.
    """

    plant: str | None = None
    preset: str | None = None
    signal: str | None = None
    n_samples: int | None = None
    seed: int = 0
    noise_std: Any = None
    signal_options: dict = field(default_factory=dict)
    plant_params: dict = field(default_factory=dict)
    sensors: str = "lab"
    file: str | list | None = None
    validation: str | None = None
    inputs: Any = None
    outputs: Any = None
    dt: float | None = None
    output: str | int | None = None
    split: float | int | str | list | None = None
    detrend: bool | str = False
    digest: str | None = None

    def __post_init__(self) -> None:
        if (self.plant is None) == (self.file is None):
            raise ConfigError("[data] needs exactly one of 'plant' (simulate) or 'file' (a record)")
        files = self.file if isinstance(self.file, list) else [self.file]
        if self.file is not None and not (files and all(isinstance(f, str) for f in files)):
            raise ConfigError(f"[data] file must be a path or a list of paths, got {self.file!r}")
        if self.validation is not None and (
            self.file is None or not isinstance(self.validation, str)
        ):
            raise ConfigError("[data] validation is the path of a recorded file beside 'file'")
        if len(files) > 1 and self.validation is None:
            raise ConfigError(
                f"[data] file lists {len(files)} estimation records: give the validation "
                "record ('validation = \"PATH\"'); none is split off"
            )
        numeric = isinstance(self.detrend, (int, float)) and not isinstance(self.detrend, bool)
        if numeric or self.detrend not in (False, True, "constant", "linear"):
            raise ConfigError(
                f"[data] detrend must be false, true, 'constant' or 'linear', got "
                f"{self.detrend!r}"
            )

    def describe(self) -> str:
        """One line saying where the record comes from.

        Returns
        -------
        str
            ``"file PATH"``, or ``"PLANT / PRESET-OR-SIGNAL[ / SENSORS sensors] (seed S)"``.
        """
        if self.file is not None:
            files = self.file if isinstance(self.file, list) else [self.file]
            text = f"file{'s' if len(files) > 1 else ''} {', '.join(files)}"
            return text + (f" (validation {self.validation})" if self.validation else "")
        parts = [self.plant, self.preset or self.signal or "default signal"]
        if self.sensors != "lab":
            parts.append(f"{self.sensors} sensors")
        return " / ".join(p for p in parts if p) + f" (seed {self.seed})"


@dataclass(frozen=True)
class ModelSpec:
    """The model structure and its orders, in MATLAB's convention.

    Attributes
    ----------
    na : int or None
        Number of ``A`` coefficients (poles); ARX's default is 8, the other structures have
        none unless they take it (``armax``).
    nb : int, list of int or None
        Number of ``B`` coefficients, for every input or one per input; for ARX None
        (default) means ``na``.
    nk : int or list of int
        Input delay in samples, for every input or one per input (default 1).
    structure : {"arx", "armax", "oe", "bj"}
        The structure (default ``"arx"``, the paper's); its orders are those of
        :data:`flexid.models.polynomial.STRUCTURES`.
    nc, nd : int or None
        Orders of ``C`` and ``D`` (``armax``, ``bj``).
    nf : int, list of int or None
        Order of ``F``, for every input or one per input (``oe``, ``bj``).
    greybox : str or None
        With ``structure = "greybox"``: the grey-box model's name
        (:func:`flexid.models.greybox_library.greybox_model`: a built-in, registered or installed
        model, or ``"path/to/file.py:NAME"``, relative to the configuration file).
    parameters : dict
        With ``structure = "greybox"``: parameter changes, ``name -> value`` (a new value)
        or ``name -> {"value": ..., "fixed": ..., "lower": ..., "upper": ...}``.
    options : dict
        With the structure of a registered family (:func:`flexid.models.families.register_family`):
        its orders by name, as its ``structure`` method takes them (``{"n": 6, "pole":
        0.8}``); ``nk`` is passed on when it is not 1.
    """

    na: int | None = None
    nb: Any = None
    nk: Any = 1
    structure: str = "arx"
    nc: int | None = None
    nd: int | None = None
    nf: Any = None
    greybox: str | None = None
    parameters: dict = field(default_factory=dict)
    options: dict = field(default_factory=dict)

    @property
    def registered(self) -> bool:
        """Whether the structure is a registered family's, not a built-in one (polynomial or
        grey-box): its orders are in :attr:`options`."""
        return self.structure not in (*STRUCTURE_NAMES, GREYBOX)

    def __post_init__(self) -> None:
        known = (*STRUCTURE_NAMES, GREYBOX, STATE_SPACE,
                 *sorted(_REGISTERED_NAMES - {*STRUCTURE_NAMES, STATE_SPACE}))  # fmt: skip
        if self.structure not in known:
            from .errors import UnknownNameError

            raise UnknownNameError("[model] structure", str(self.structure), known)
        if not isinstance(self.options, Mapping):
            raise ConfigError("[model] options must be a table: name = value")
        object.__setattr__(self, "options", dict(self.options))
        if self.registered:
            given = [k for k in ("na", "nb", "nc", "nd", "nf", "greybox") if getattr(self, k)]
            if given or self.parameters:
                raise ConfigError(
                    f"[model] structure {self.structure!r} takes its orders in options = "
                    f"{{...}}, not {', '.join(given or ['parameters'])}"
                )
            return
        if self.options:
            raise ConfigError(
                f"[model] options belong to a registered family's structure, not "
                f"{self.structure!r}: give its orders as na, nb, nc, nd, nf, nk"
            )
        if self.structure == GREYBOX:
            if not isinstance(self.greybox, str) or not self.greybox:
                raise ConfigError(
                    "[model] structure 'greybox' needs greybox = the model's name (e.g. "
                    "'twin-rotor-pitch', or 'path/to/file.py:NAME')"
                )
            orders = [k for k in ("na", "nb", "nc", "nd", "nf") if getattr(self, k) is not None]
            if orders or self.nk != 1:
                raise ConfigError(
                    f"[model] a grey-box model has no orders; remove {', '.join(orders or ['nk'])}"
                )
            if not isinstance(self.parameters, Mapping):
                raise ConfigError("[model] parameters must be a table: name = value or {...}")
            object.__setattr__(self, "parameters", dict(self.parameters))
            return
        if self.greybox is not None or self.parameters:
            raise ConfigError(
                "[model] greybox and parameters belong to structure = 'greybox', not "
                f"{self.structure!r}"
            )
        if self.structure == "arx" and self.na is None:
            object.__setattr__(self, "na", 8)  # the paper's order

    def greybox_model(self) -> Any:
        """The grey-box model this spec names, with its parameter changes.

        Returns
        -------
        GreyBoxModel

        Raises
        ------
        ConfigError, UnknownNameError
            Not a grey-box spec, an unknown model, a bad parameter change.
        """
        if self.structure != GREYBOX:
            raise ConfigError(f"[model] structure {self.structure!r} is not a grey-box model")
        from .models.greybox_library import greybox_model

        model = greybox_model(self.greybox)
        return model.with_parameters(**self.parameters) if self.parameters else model

    def orders(self) -> dict[str, Any]:
        """The orders given, by name (None left out).

        Returns
        -------
        dict
        """
        if self.registered:
            return {**self.options, **({"nk": self.nk} if self.nk != 1 else {})}
        names = ("na", "nb", "nc", "nd", "nf", "nk")
        return {k: getattr(self, k) for k in names if getattr(self, k) is not None}

    def key_material(self) -> dict[str, Any]:
        """The fields that determine a comparison's numbers; an ARX spec's as before the
        structures existed (so its store key is unchanged).

        Returns
        -------
        dict
        """
        d = asdict(self)
        if self.structure == "arx":
            return {k: d[k] for k in ("na", "nb", "nk")}
        if self.structure == GREYBOX:
            from .models.greybox_library import definition_digest

            model = self.greybox_model()
            return {
                "structure": GREYBOX,
                "greybox": self.greybox,
                "definition": definition_digest(self.greybox),
                "model": model.to_dict(),
            }
        if self.registered:
            return {"structure": self.structure, **self.orders()}
        for k in ("greybox", "parameters", "options"):  # keys of polynomial specs as before
            del d[k]
        return d

    def describe(self) -> str:
        """The structure and orders in MATLAB's words, e.g. ``"OE(nb=16, nf=16, nk=1)"``.

        Returns
        -------
        str
        """
        if self.structure == "arx":
            nb = self.nb if self.nb is not None else self.na
            return f"ARX(na={self.na}, nb={nb}, nk={self.nk})"
        if self.structure == GREYBOX:
            changed = f", {len(self.parameters)} parameter(s) changed" if self.parameters else ""
            return f"grey-box model {self.greybox}{changed}"
        text = ", ".join(f"{k}={v}" for k, v in self.orders().items())
        if self.registered:  # its name as written
            return f"{self.structure}({text})"
        return f"{self.structure.upper()}({text})"


@dataclass(frozen=True)
class CostSpec:
    """The cost the optimisers minimise (see :class:`flexid.costs.arx.ARXCost`).

    Attributes
    ----------
    metric : str
        Error measure, a name of :data:`flexid.costs.metrics.METRIC_TABLE`; ``"paper"`` (default)
        is ``weight * sqrt(SSE) / K``.
    predictor : {"one-step", "simulation"}
        Equation error (default) or output error.
    weight : float
        ``w`` of the paper's cost (default 1e3).
    penalty : float
        Cost added to an unstable candidate (default 1e9); its kind (flat or graded) is
        :attr:`SearchSpec.penalty`.
    initial : {"auto", "estimate", "zero", "measured"}
        Initial-condition rule of the predictor (default ``"auto"``: ``"measured"`` for ARX,
        the paper's setting, and ``"estimate"`` for the other structures; see
        :func:`flexid.fit.estimation.resolve_initial`).
    """

    metric: str = "paper"
    predictor: str = "one-step"
    weight: float = 1e3
    penalty: float = 1e9
    initial: str = "auto"


@dataclass(frozen=True)
class SearchSpec:
    """How the search space is posed (see :func:`flexid.fit.estimation.build_problem`).

    Attributes
    ----------
    parametrisation : {"poles", "reflection", "coefficients"}
        ``"coefficients"`` is the paper's ``a, b`` box; ``"poles"`` (default) searches pole
        pairs (radius, angle) and ``"reflection"`` lattice coefficients, both stable by
        construction.
    penalty : {"graded", "flat"}
        Stability penalty of an unstable candidate (only the coefficient space has any):
        ``"flat"`` is the paper's constant, ``"graded"`` grows with the largest pole radius.
    init : {"stable", "uniform"}
        Initial population of the coefficient space: stable denominators (drawn in the pole
        space) or uniform in the box (the paper's).  The other spaces are uniform in their
        own box, all stable.
    r_max : float
        Largest pole radius of the ``"poles"`` space and of stable initial populations.
    real_pairs : int
        Pole pairs searched as two real poles instead of a complex pair.
    k_max : float
        Bound of the reflection coefficients.
    numerator : {"fit", "search"}
        ``"search"``: the optimiser searches the ``b`` coefficients too (the paper's).
        ``"fit"`` (default): it searches the denominator only, and each candidate's ``b``
        is the exact least-squares optimum of the cost for its ``A`` (variable projection;
        both predictors are linear in ``b``).
    """

    parametrisation: str = "poles"
    penalty: str = "graded"
    init: str = "stable"
    r_max: float = POLE_RADIUS_CAP
    real_pairs: int = 0
    k_max: float = REFLECTION_CAP
    numerator: str = "fit"


PAPER_SEARCH = SearchSpec(
    parametrisation="coefficients", penalty="flat", init="uniform", numerator="search"
)


@dataclass(frozen=True)
class Keyword:
    """One setting of a cost or a search as a user types it.

    Attributes
    ----------
    name : str
        The keyword of :func:`flexid.identify`.
    spec : {"cost", "search"}
        The spec it sets a field of: :class:`CostSpec` or :class:`SearchSpec`.
    field : str
        That field.
    option : str or None
        The command line's option for it (``flexid identify`` and ``flexid compare``), if it
        has one.
    help : str
        What it means, with its values and default: the text of the option's help and of
        the keyword's entry in :func:`flexid.identify`'s docstring.
    """

    name: str
    spec: str
    field: str
    option: str | None
    help: str


#: The keywords of :func:`flexid.identify` that set a field of its cost or search spec, and
#: the command line's options for them: the one table keywords, specs, help and errors
#: derive from.  A program that builds a :class:`CostSpec` or :class:`SearchSpec` passes it
#: whole (``cost=``, ``search=``) and none of its keywords.
KEYWORDS = (
    Keyword("predictor", "cost", "predictor", "--predictor",
            "one-step (default; equation error, as in the paper) | simulation (output error)"),
    Keyword("weight", "cost", "weight", None,
            "gain w of the paper cost w sqrt(SSE) / K (default 1e3)"),
    Keyword("penalty", "cost", "penalty", None,
            "cost added to an unstable candidate (default 1e9)"),
    Keyword("initial", "cost", "initial", "--initial",
            "initial state of the cost's predictor: auto (default; measured for ARX, estimate "
            "otherwise) | estimate | zero | measured"),
    Keyword("parametrisation", "search", "parametrisation", "--parametrisation",
            "search space: poles (default) | reflection | coefficients (the paper's box)"),
    Keyword("penalty_kind", "search", "penalty", "--penalty",
            "stability penalty in the coefficient space: graded (default) | flat (the "
            "paper's constant penalty)"),
    Keyword("init", "search", "init", "--init",
            "initial population in the coefficient space: stable (default) | uniform"),
    Keyword("numerator", "search", "numerator", "--numerator",
            "fit (default: b fitted by least squares for each candidate denominator) | "
            "search (the optimiser searches b too)"),
)  # fmt: skip


def keyword(name: str) -> Keyword:
    """The entry of :data:`KEYWORDS` of an identify keyword or a command-line option.

    Parameters
    ----------
    name : str
        ``"predictor"`` or ``"--predictor"``.

    Returns
    -------
    Keyword

    Raises
    ------
    UnknownNameError
        For a name that is neither.
    """
    for k in KEYWORDS:
        if name in (k.name, k.option):
            return k
    from .errors import UnknownNameError

    raise UnknownNameError("keyword", name, [k.name for k in KEYWORDS])


def specs_from_keywords(
    cost: str | CostSpec | None = None, search: SearchSpec | None = None, **given: Any
) -> tuple[CostSpec, SearchSpec]:
    """The cost and search specs of keywords a user typed, or of the specs a program built.

    Parameters
    ----------
    cost : str or CostSpec, optional
        A metric name (then the cost keywords set the other fields) or a whole spec.
    search : SearchSpec, optional
        A whole spec (then no search keyword).
    **given
        Keywords of :data:`KEYWORDS`; None is not given.

    Returns
    -------
    cost : CostSpec
    search : SearchSpec
        The defaults of :class:`CostSpec` and :class:`SearchSpec` where nothing was given.

    Raises
    ------
    ConfigError
        A keyword given with the whole spec that holds its field (one way for each fact),
        or a name that is not a keyword.
    """
    by_name = {k.name: k for k in KEYWORDS}
    unknown = sorted(set(given) - set(by_name))
    if unknown:
        raise ConfigError(f"not a cost or search keyword: {', '.join(unknown)}")
    fields: dict[str, dict[str, Any]] = {"cost": {}, "search": {}}
    for name, value in given.items():
        if value is not None:
            fields[by_name[name].spec][by_name[name].field] = value
    whole = {"cost": cost if isinstance(cost, CostSpec) else None, "search": search}
    for spec, spec_fields in fields.items():
        if whole[spec] is not None and spec_fields:
            names = [k.name for k in KEYWORDS if k.spec == spec and given.get(k.name) is not None]
            raise ConfigError(
                f"{', '.join(names)} given both as keyword(s) and in {spec}="
                f"{type(whole[spec]).__name__}(...): give each setting one way"
            )
    if cost is not None and not isinstance(cost, CostSpec):
        fields["cost"]["metric"] = cost
    return (
        whole["cost"] if whole["cost"] is not None else CostSpec(**fields["cost"]),
        search if search is not None else SearchSpec(**fields["search"]),
    )


@dataclass(frozen=True)
class OptimiserSpec:
    """A registered optimiser, its hyper-parameters and the label it has in tables.

    Attributes
    ----------
    name : str
        Registry name (see :func:`flexid.optimisers.available`).
    params : dict
        Hyper-parameters, ``name -> value`` (default: the optimiser's defaults).
    label : str or None
        Label in tables and in the store (default: ``name``).
    """

    name: str
    params: dict = field(default_factory=dict)
    label: str | None = None

    @property
    def display(self) -> str:
        """The label in tables and in the store: ``label``, else ``name``."""
        return self.label or self.name

    def fingerprint(self) -> str:
        """A short hash of the name and hyper-parameters (not the label).

        Returns
        -------
        str
            The first 12 hexadecimal digits of the SHA-256 of ``{"name", "params"}`` as
            sorted-key JSON.
        """
        text = json.dumps({"name": self.name, "params": self.params}, sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:12]


@dataclass(frozen=True)
class ComparisonSpec:
    """Everything that determines a comparison's numbers.

    The comparison's store key is a hash of the data (for a file, the digest of the numbers
    it held too), model, cost, box, budget, seed and validation settings; it leaves out the
    name, the number of runs and the list of optimisers, so adding runs or optimisers to a
    finished comparison reuses its runs.

    Attributes
    ----------
    name : str
        Name in reports and in the store (default ``"comparison"``).
    data : DataSpec
        Where the record comes from (default: the paper's manipulator preset).
    model : ModelSpec
        The model structure and its orders.
    cost : CostSpec
        The cost the optimisers minimise.
    search : SearchSpec
        How the search space is posed.
    bounds : "auto", float, tuple or mapping
        The coefficient box, as in :func:`flexid.search_box` (default ``"auto"``).
    optimisers : tuple of OptimiserSpec
        The optimisers compared (default: hbcsd, bfa, sda, pso, de); labels must be unique.
    runs : int
        Runs per optimiser (default 10).
    seed : int
        Seed of the runs (default 0).
    budget : int or "schedule"
        Function evaluations per run (default 10,000), or ``"schedule"``: each optimiser's
        own loop counts, capped at ``schedule_cap``.
    schedule_cap : int
        FE cap of a run in schedule mode (default 2,000,000).
    targets : tuple of float
        Relative tolerances ``t > 0``: a run reaches a target when its cost is
        ``<= reference_cost * (1 + t)`` (default ``(0.1, 0.01, 0.001)``).
    max_lag : int
        Largest lag, in samples, of the validation correlation tests (default 25).
    alpha : float
        Family-wise level of the validation verdicts (``alpha`` in the ``[validation]``
        table; default :data:`VALIDATION_ALPHA`, 5 %).
    validate_initial : {"estimate", "zero", "measured"}
        Initial-condition rule of the validation's simulations and predictions (``initial``
        in the ``[validation]`` table; default ``"estimate"``, MATLAB ``compare``'s).
    run_timeout : float or None
        Wall-time limit of one optimiser run in seconds (``run_timeout`` in the
        ``[compare]`` table); a run that exceeds it is ended and recorded as failed.  None
        (the default) sets no limit.  It says how runs are executed, not what they compute,
        so it is not part of :attr:`key`.

    Raises
    ------
    ConfigError
        For a count that is not an integer or is out of its range in
        :data:`CONFIG_SCHEMA`, no optimiser, repeated labels, an optimiser labelled
        ``"ls"``, a target that is not positive or a time limit that is not a positive
        number of seconds.
    """

    name: str = "comparison"
    data: DataSpec = field(
        default_factory=lambda: DataSpec(plant="manipulator", preset="paper-manipulator")
    )
    model: ModelSpec = field(default_factory=ModelSpec)
    cost: CostSpec = field(default_factory=CostSpec)
    search: SearchSpec = field(default_factory=SearchSpec)
    bounds: Any = "auto"
    optimisers: tuple[OptimiserSpec, ...] = tuple(OptimiserSpec(n) for n in DEFAULT_OPTIMISERS)
    runs: int = 10
    seed: int = 0
    budget: int | str = COMPARE_BUDGET
    schedule_cap: int = 2_000_000
    targets: tuple[float, ...] = (0.1, 0.01, 0.001)
    max_lag: int = CORRELATION_LAGS
    validate_initial: str = "estimate"
    run_timeout: float | None = None
    alpha: float = VALIDATION_ALPHA

    def __post_init__(self) -> None:
        _check_int(self, "runs", "run")
        timeout = _check_run_timeout(self.run_timeout, "[compare] run_timeout")
        object.__setattr__(self, "run_timeout", timeout)
        _check_int(self, "seed", "run")
        _check_int(self, "max_lag", "validation")
        alpha = level(self.alpha, "[validation] alpha", error=ConfigError)
        object.__setattr__(self, "alpha", alpha)
        if self.validate_initial not in ("estimate", "zero", "measured"):
            from .errors import UnknownNameError

            raise UnknownNameError(
                "[validation] initial", str(self.validate_initial), ("estimate", "zero", "measured")
            )
        _check_int(self, "schedule_cap", "run")
        if self.budget != SCHEDULE:
            _check_int(self, "budget", "run")
        if not self.optimisers:
            raise ConfigError("a comparison needs at least one optimiser")
        labels = [o.display for o in self.optimisers]
        dup = sorted({x for x in labels if labels.count(x) > 1})
        if dup:
            raise ConfigError(f"optimiser labels must be unique; repeated: {dup} (set 'label')")
        if LEAST_SQUARES in labels:
            raise ConfigError(
                f"{LEAST_SQUARES!r} is the least-squares reference row, always included; remove it"
            )
        for t in self.targets:
            if not (isinstance(t, (int, float)) and t > 0):
                raise ConfigError(f"[run] targets must be positive relative tolerances, got {t!r}")
        if self.model.structure == GREYBOX and (
            self.cost.predictor != "simulation" or self.cost.initial != "auto"
        ):
            # a grey-box model has only its simulation, from its own initial state
            object.__setattr__(
                self, "cost", replace(self.cost, predictor="simulation", initial="auto")
            )
        if self.cost.initial == "auto":
            # resolved here so the store key of a spec does not depend on how the rule was
            # spelled ("auto" is "measured" for ARX, as before, and "estimate" otherwise)
            rule = auto_initial(self.model.structure)
            object.__setattr__(self, "cost", replace(self.cost, initial=rule))

    @property
    def max_fe(self) -> int:
        """The FE budget of every run (the cap in schedule mode)."""
        return self.schedule_cap if self.budget == SCHEDULE else int(self.budget)

    def key_material(self) -> dict[str, Any]:
        """What :attr:`key` hashes: the settings that determine the runs' numbers.

        Returns
        -------
        dict
            ``data``, ``model``, ``cost``, ``search`` (as dicts), ``bounds``, ``seed``,
            ``budget``, ``schedule_cap`` (None unless the budget is ``"schedule"``),
            ``max_lag``, ``alpha`` and ``validate_initial``.  ``data`` has ``digest`` only when
            it is set (a file's record once :func:`flexid.compare` has read it).
        """
        return {
            "data": _data_dict(self.data),
            "model": self.model.key_material(),
            "cost": asdict(self.cost),
            "search": asdict(self.search),
            "bounds": self.bounds,
            "seed": self.seed,
            "budget": self.budget,
            "schedule_cap": self.schedule_cap if self.budget == SCHEDULE else None,
            "max_lag": self.max_lag,
            "alpha": self.alpha,
            "validate_initial": self.validate_initial,
        }

    @property
    def key(self) -> str:
        """Store key: a hash of what determines the runs' numbers."""
        text = json.dumps(self.key_material(), sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def to_dict(self) -> dict[str, Any]:
        """The spec as plain dictionaries and lists; :meth:`from_dict` restores it.

        Returns
        -------
        dict
            Every field, the nested specs as dicts (``data`` without an unset ``digest``,
            ``model`` without empty ``options``: the dicts, and the versions and keys hashed
            from them, are those of specs written before the field existed), ``optimisers``
            as a list of dicts and ``targets`` as a list.
        """
        out = asdict(self)
        out["data"] = _data_dict(self.data)
        if not self.model.options:
            del out["model"]["options"]
        out["optimisers"] = [asdict(o) for o in self.optimisers]
        out["targets"] = list(self.targets)
        return out

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> ComparisonSpec:
        """Rebuild a spec from :meth:`to_dict` output.

        Parameters
        ----------
        d : mapping
            Needs ``data``, ``model``, ``cost``, ``optimisers`` and ``targets``; ``search``
            may be missing (default :class:`SearchSpec`), the other fields default as in
            the constructor.

        Returns
        -------
        ComparisonSpec
            The spec.
        """
        d = dict(d)
        d["data"] = DataSpec(**d["data"])
        d["model"] = ModelSpec(**d["model"])
        d["cost"] = CostSpec(**d["cost"])
        d["search"] = SearchSpec(**d.get("search", {}))
        d["optimisers"] = tuple(OptimiserSpec(**o) for o in d["optimisers"])
        d["targets"] = tuple(d["targets"])
        return cls(**d)

    def budget_label(self) -> str:
        """The budget in words.

        Returns
        -------
        str
            ``"N FE"``, or ``"paper loop counts"`` in schedule mode.
        """
        return "paper loop counts" if self.budget == SCHEDULE else f"{self.budget} FE"


def _data_dict(data: DataSpec) -> dict[str, Any]:
    """``asdict(data)`` without an unset digest or validation file: the keys of comparisons
    without them stay as they were."""
    out = asdict(data)
    for name in ("digest", "validation"):
        if out[name] is None:
            del out[name]
    return out


def _check_run_timeout(value: Any, what: str) -> float | None:
    """A per-run time limit: a positive, finite number of seconds, or None (no limit).

    Parameters
    ----------
    value : object
        The limit as given.
    what : str
        How the message names it (``"--run-timeout"``, ``"[compare] run_timeout"``).

    Returns
    -------
    float or None
        ``float(value)``, or None.

    Raises
    ------
    ConfigError
        For a ``bool``, a string, NaN, an infinity or a value <= 0.
    """
    key = CONFIG_SCHEMA["compare"]["run_timeout"]
    return real(value, what, error=ConfigError, minimum=key.minimum, low_open=key.low_open,
                none_ok=True, unit="s")  # fmt: skip


def _check_int(spec: ComparisonSpec, name: str, table: str) -> None:
    """Check an integer field against its key of :data:`CONFIG_SCHEMA` (a spec built in
    Python has the bounds of a file's) and store it as ``int`` (a NumPy integer would change
    the store key)."""
    key = CONFIG_SCHEMA[table][name]
    value = integer(getattr(spec, name), f"[{table}] {name}", error=ConfigError,
                    minimum=key.minimum, maximum=key.maximum)  # fmt: skip
    object.__setattr__(spec, name, value)


@dataclass(frozen=True)
class ConfigKey:
    """What one key of a configuration file takes: its TOML types and the range of its values.

    Attributes
    ----------
    types : tuple of str
        The TOML types it takes: ``"string"``, ``"integer"``, ``"number"`` (an integer or a
        float), ``"boolean"``, ``"table"``, ``"array"`` (never empty).
    minimum, maximum : int, float or None
        Bounds of a number; None for none.
    low_open, high_open : bool
        Exclude the bound itself (``minimum=0, low_open=True`` is "> 0").
    choices : tuple of str
        The only strings it takes; empty for any string.  A name that a registry or another
        module knows (a plant, an optimiser, a metric, a predictor...) is checked, and the
        known ones listed, by the code that looks it up.
    items : ConfigKey or None
        What each item of an array takes; None: the key's other types and range.
    table : str or None
        The entry of :data:`CONFIG_SCHEMA` a table (or each table of an array) is checked
        against; None for a table of free names (hyper-parameters, plant parameters, signal
        options...), which the code that takes them checks.
    """

    types: tuple[str, ...]
    minimum: float | None = None
    maximum: float | None = None
    low_open: bool = False
    high_open: bool = False
    choices: tuple[str, ...] = ()
    items: ConfigKey | None = None
    table: str | None = None

    def item(self) -> ConfigKey:
        """What each item of an array of this key takes.

        Returns
        -------
        ConfigKey
        """
        if self.items is not None:
            return self.items
        return replace(self, types=tuple(t for t in self.types if t != "array"))

    def wanted(self, ranged: bool = False, finite: bool = False) -> str:
        """What the key takes, in words.

        Parameters
        ----------
        ranged : bool, optional
            Say the range of its numbers (for a message about a number out of it), not its
            types.
        finite : bool, optional
            Say too that a number must be finite (for a message about an infinity or NaN).

        Returns
        -------
        str
            Its types, ``"an integer, 'schedule' or an array of them"``, or the range of its
            numbers, ``"an integer in [1, 10000]"``.
        """
        if ranged:
            kind = "integer" if "integer" in self.types else "number"
            article = "an" if kind == "integer" else "a"
            bounds = _interval(self.minimum, self.maximum, self.low_open, self.high_open)
            return f"{article} {'finite ' if finite else ''}{kind}{f' {bounds}' if bounds else ''}"
        parts = []
        for kind in self.types:
            if kind == "array" and self.item().types == ("table",):
                parts.append("an array of tables")
            elif kind == "array":
                parts.append("an array of them" if self.items is None else "an array")
            elif kind == "string" and self.choices:
                parts.extend(map(repr, self.choices))
            else:
                parts.append(_KINDS[kind])
        return parts[0] if len(parts) == 1 else f"{', '.join(parts[:-1])} or {parts[-1]}"

    def check(self, value: Any, name: str, source: str = "") -> None:
        """Raise unless ``value`` is of a type and in the range this key takes.

        Parameters
        ----------
        value : object
            The value read.
        name : str
            Where it is in the file, as messages name it (``"[run] runs"``).
        source : str, optional
            The file, the start of every message.

        Raises
        ------
        ConfigError
            Naming the file, ``name``, what the key takes and the value given; for a table
            of :data:`CONFIG_SCHEMA`, the first of its keys that is unknown or wrong.
        """
        where = f"{source}: {name}" if source else name
        kind = _kind(value)
        taken = kind in self.types or ("number" in self.types and kind in ("integer", "float"))
        if not taken or (kind == "array" and not value):
            got = "an empty array" if taken else _KINDS.get(kind, kind)
            raise ConfigError(f"{where} must be {self.wanted()}, got {_shown(value)} ({got})")
        if kind == "string" and self.choices and value not in self.choices:
            raise ConfigError(f"{where} must be {self.wanted()}, got {_shown(value)}")
        if kind in ("integer", "float"):
            finite = math.isfinite(value)
            if not (finite and _within(value, self.minimum, self.maximum, self.low_open,
                                       self.high_open, allow_inf=False)):  # fmt: skip
                wanted = self.wanted(ranged=True, finite=not finite)
                raise ConfigError(f"{where} must be {wanted}, got {_shown(value)}")
        elif kind == "array":
            item = self.item()
            for i, entry in enumerate(value):
                item.check(entry, f"{name} #{i + 1}", source)
        elif kind == "table" and self.table is not None:
            _check_table(value, self.table, name, source)


#: The TOML types of :class:`ConfigKey`, and of the values a message says were given.
_KINDS = {
    "string": "a string", "integer": "an integer", "number": "a number", "float": "a float",
    "boolean": "a boolean", "table": "a table", "array": "an array", "date": "a date or time",
}  # fmt: skip


def _kind(value: Any) -> str:
    """The TOML type of a value read (a key of :data:`_KINDS`, else its Python type's name):
    NumPy numbers and tuples count as what they hold, for a mapping built in Python."""
    if isinstance(value, bool):
        return "boolean"
    if is_integer(value):
        return "integer"
    if isinstance(value, numbers.Real):
        return "float"
    if isinstance(value, str):
        return "string"
    if isinstance(value, Mapping):
        return "table"
    if isinstance(value, (list, tuple)):
        return "array"
    if isinstance(value, (datetime.date, datetime.time)):  # a datetime is a date
        return "date"
    return type(value).__name__


def _shown(value: Any, width: int = 24) -> str:
    """``repr(value)``, cut to about ``width`` characters so a message stays one short line."""
    text = value.isoformat() if isinstance(value, (datetime.date, datetime.time)) else repr(value)
    return text if len(text) <= width else f"{text[: width - 3]}..."


def _check_table(table: Mapping[str, Any], schema: str, name: str, source: str) -> None:
    """Check every key of a table against its entry of :data:`CONFIG_SCHEMA`, in order.

    ``name`` is how messages name the table (``"[data]"``, ``"[[optimisers]] #2"``); the
    keys of the top level are named as TOML writes them (``name``, ``[data]``,
    ``[[optimisers]]``).
    """
    keys = CONFIG_SCHEMA[schema]
    top = schema == "top level"
    unknown = [k for k in table if k not in keys]
    if unknown:
        where = f"{source}: " if source else ""
        raise ConfigError(
            f"{where}unknown key(s) {', '.join(map(repr, unknown))} in "
            f"{'[top level]' if top else name}; {_allowed(unknown, keys)}"
        )
    for k, value in table.items():
        key = keys[k]
        if not top:
            label = f"{name} {k}"
        elif key.table is not None:
            label = f"[{k}]"
        elif key.items is not None and key.items.table is not None:
            label = f"[[{k}]]"
        else:
            label = k
        key.check(value, label, source)


def _allowed(unknown: list[str], keys: Mapping[str, ConfigKey], room: int = 56) -> str:
    """The keys the user may have meant: the close match of a misspelt key, else the keys of
    the table, the likeliest first when they do not all fit in ``room`` characters."""
    close = difflib.get_close_matches(unknown[0], list(keys), n=1)
    if len(unknown) == 1 and close:
        return f"did you mean {close[0]!r}?"
    names = list(keys)
    if len(", ".join(names)) > room:
        likeness = {k: difflib.SequenceMatcher(None, unknown[0], k).ratio() for k in names}
        names.sort(key=lambda k: -likeness[k])
        while len(", ".join(names)) > room - 5:
            names.pop()
        names.append("...")
    return f"allowed: {', '.join(names)}"


def check_config(config: Mapping[str, Any], source: str = "config") -> None:
    """Check a parsed configuration against :data:`CONFIG_SCHEMA`: every key known, every
    value of a type and in a range its key takes.

    Parameters
    ----------
    config : mapping
        The parsed TOML (or an equivalent dict).
    source : str
        Where it comes from (the file), the start of every message.

    Raises
    ------
    ConfigError
        For the first unknown key or wrong value, in one line naming the file, the table and
        the key: ``"bad.toml: [run] runs must be an integer in [1, 10000], got 99999"``.
    """
    ConfigKey(("table",), table="top level").check(config, "the configuration", source)


# The largest values of the counts, each far beyond any experiment that ends, so a typo (or
# 2**63 - 1) is refused at once instead of running until it is killed or memory runs out.
# Runs are the seeds of one comparison: the paper's have 20, and 10,000 runs of each optimiser
# are days of computing at its budgets.
_MAX_RUNS = 10_000
# FE of one run: the paper's largest budget is 50,050 and the schedule cap 2,000,000; a run
# records one history row per iteration, as many as its FE for the one-evaluation methods
# (Nelder-Mead, Powell...), about 100 bytes each: 10 million rows are a gigabyte.
_MAX_FE = 10_000_000
# Samples of a record: 10 million is some 80 MB a channel, and every FE of a search is a pass
# over the whole record (a tenth of a second or more at that length): hours per run already.
_MAX_SAMPLES = 10_000_000
# A polynomial order: the paper's are 5 and 8; an order of a thousand is a search space of
# thousands of dimensions, which no budget above explores.
_MAX_ORDER = 1_000

_STRING = ConfigKey(("string",))
_TABLE = ConfigKey(("table",))  # free names, checked by the code that takes them
_SEED = ConfigKey(("integer",), minimum=0)  # NumPy's seeds are non-negative
_ORDER = ConfigKey(("integer",), minimum=0, maximum=_MAX_ORDER)
_ORDERS = ConfigKey(("integer", "array"), minimum=0, maximum=_MAX_ORDER)  # or one per input
_COLUMNS = ConfigKey(("string", "integer", "array"), minimum=0)  # by name or 0-based index
_RUNS = ConfigKey(("integer",), minimum=1, maximum=_MAX_RUNS)
_BUDGET = ConfigKey(("integer", "string"), minimum=1, maximum=_MAX_FE, choices=(SCHEDULE,))
_FE = ConfigKey(("integer",), minimum=1, maximum=_MAX_FE)
_UNIT = {"minimum": 0, "maximum": 1, "low_open": True, "high_open": True}
_OPTIMISERS = ConfigKey(("array",), items=ConfigKey(("table",), table="optimisers"))

#: The one schema of a configuration file: table -> key -> :class:`ConfigKey`.  "top level"
#: is the file itself; "optimisers" and "comparison" are each table of ``[[optimisers]]``
#: and ``[[comparison]]`` (a comparison's ``optimisers`` too).  :func:`check_config` checks
#: every key of a file against it before anything is built; a key not in it is refused.
CONFIG_SCHEMA: dict[str, dict[str, ConfigKey]] = {
    "top level": {
        "name": _STRING,
        "description": _STRING,
        **{t: ConfigKey(("table",), table=t)
           for t in ("data", "model", "cost", "search", "run", "validation", "compare")},
        "optimisers": _OPTIMISERS,
        "comparison": ConfigKey(("array",), items=ConfigKey(("table",), table="comparison")),
    },
    "data": {
        "plant": _STRING,
        "preset": _STRING,
        "signal": _STRING,
        "n_samples": ConfigKey(("integer",), minimum=2, maximum=_MAX_SAMPLES),
        "seed": _SEED,
        "noise_std": ConfigKey(("number", "string", "array"), minimum=0),  # or "p%"
        "signal_options": _TABLE,
        "plant_params": _TABLE,
        "sensors": _STRING,
        "file": ConfigKey(("string", "array")),
        "validation": _STRING,
        "inputs": _COLUMNS,
        "outputs": _COLUMNS,
        "dt": ConfigKey(("number",), minimum=0, low_open=True),
        "output": ConfigKey(("string", "integer"), minimum=0),
        # a share or a sample index, or two ranges: [start, stop] (negative from the end) or
        # "start:stop"
        "split": ConfigKey(("number", "string", "array"), minimum=0, low_open=True,
                           items=ConfigKey(("string", "array"), items=ConfigKey(("integer",)))),
        "detrend": ConfigKey(("boolean", "string")),
    },
    "model": {
        "na": _ORDER,
        "nb": _ORDERS,
        "nk": ConfigKey(("integer", "array"), minimum=0, maximum=_MAX_SAMPLES),  # samples
        "structure": _STRING,
        "nc": _ORDER,
        "nd": _ORDER,
        "nf": _ORDERS,
        "greybox": _STRING,
        "parameters": _TABLE,
        "options": _TABLE,
    },
    "cost": {
        "metric": _STRING,
        "predictor": _STRING,
        "weight": ConfigKey(("number",), minimum=0),
        "penalty": ConfigKey(("number",), minimum=0),
        "initial": _STRING,
    },
    "search": {
        # "auto", a half-width, [low, high] or a table of half-widths (flexid.search_box)
        "bounds": ConfigKey(("string", "number", "table", "array"),
                            items=ConfigKey(("number",))),
        "parametrisation": _STRING,
        "penalty": _STRING,
        "init": _STRING,
        "r_max": ConfigKey(("number",), **_UNIT),
        "real_pairs": _ORDER,
        "k_max": ConfigKey(("number",), **_UNIT),
        "numerator": _STRING,
    },
    "run": {
        "runs": _RUNS,
        "seed": _SEED,
        "budget": replace(_BUDGET, types=(*_BUDGET.types, "array")),  # a list: a comparison each
        "schedule_cap": _FE,
        "targets": ConfigKey(("array",), items=ConfigKey(("number",), minimum=0, low_open=True)),
    },
    "validation": {
        "max_lag": ConfigKey(("integer",), minimum=1, maximum=_MAX_SAMPLES),
        "initial": _STRING,
        "alpha": ConfigKey(("number",)),  # a level in (0, 1): flexid._validate.level checks it
    },
    "compare": {
        "run_timeout": ConfigKey(("number",), minimum=0, low_open=True),  # seconds
    },
    "optimisers": {"name": _STRING, "params": _TABLE, "label": _STRING},
    "comparison": {
        "name": _STRING,
        "budget": _BUDGET,
        "runs": _RUNS,
        "seed": _SEED,
        "optimisers": _OPTIMISERS,
        "schedule_cap": _FE,
    },
}  # fmt: skip


def _optimiser_specs(entries: list, where: str) -> tuple[OptimiserSpec, ...]:
    optimisers = []
    for i, item in enumerate(entries):
        if "name" not in item:
            raise ConfigError(f"{where} #{i + 1} needs a 'name'")
        params = dict(item.get("params", {}))
        optimisers.append(OptimiserSpec(item["name"], params, item.get("label")))
    return tuple(optimisers)


def spec_from_mapping(config: Mapping[str, Any], *, source: str = "config") -> list[ComparisonSpec]:
    """Comparison specs from a parsed configuration.

    The top level describes one comparison; a list of budgets gives one comparison per
    budget.  ``[[comparison]]`` tables describe several comparisons that share the top-level
    data, model, cost, search, validation and ``[compare]`` settings, each with its own
    ``name``, ``budget``, ``runs``, ``seed`` and ``optimisers`` (defaults from the top level).

    Parameters
    ----------
    config : mapping
        The parsed TOML (or an equivalent dict).
    source : str
        Where the mapping comes from, named in error messages.

    Returns
    -------
    list of ComparisonSpec
        One spec per comparison.

    Raises
    ------
    ConfigError
        For a key :data:`CONFIG_SCHEMA` does not have or a value it refuses, or settings
        that do not go together; the message starts with ``source``.
    """
    check_config(config, source)
    try:
        return _specs(config, source)
    except ConfigError as exc:  # a check of the specs: say which file it is about
        raise ConfigError(f"{source}: {exc}") from None


def _specs(top: Mapping[str, Any], source: str) -> list[ComparisonSpec]:
    """:func:`spec_from_mapping` of a configuration :func:`check_config` has passed."""
    if "data" in top:
        data = DataSpec(**top["data"])
    else:
        data = DataSpec(plant="manipulator", preset="paper-manipulator")
    model = ModelSpec(**top.get("model", {}))
    cost = CostSpec(**top.get("cost", {}))
    search = dict(top.get("search", {}))
    bounds = search.pop("bounds", "auto")
    if isinstance(bounds, list):
        bounds = tuple(bounds)
    search_spec = SearchSpec(**search)
    run = dict(top.get("run", {}))
    validation = top.get("validation", {})
    if "optimisers" in top:
        optimisers = _optimiser_specs(top["optimisers"], "[[optimisers]]")
    else:
        optimisers = tuple(OptimiserSpec(n) for n in DEFAULT_OPTIMISERS)
    budgets = run.pop("budget", COMPARE_BUDGET)
    budgets = list(budgets) if isinstance(budgets, (list, tuple)) else [budgets]
    if "targets" in run:
        run["targets"] = tuple(run["targets"])
    name = top.get("name", Path(source).stem if source != "config" else "comparison")
    common = {
        "data": data,
        "model": model,
        "cost": cost,
        "search": search_spec,
        "bounds": bounds,
        "max_lag": validation.get("max_lag", 25),
        "alpha": validation.get("alpha", VALIDATION_ALPHA),
        "validate_initial": validation.get("initial", "estimate"),
        **top.get("compare", {}),
    }
    specs = []
    if "comparison" in top:
        for i, entry in enumerate(top["comparison"]):
            item = dict(entry)
            opts = (
                _optimiser_specs(item.pop("optimisers"), f"[[comparison]] #{i + 1} optimisers")
                if "optimisers" in item
                else optimisers
            )
            budget = item.pop("budget", budgets[0])
            label = item.pop("name", f"{name} #{i + 1}")
            specs.append(
                ComparisonSpec(
                    name=label, optimisers=opts, budget=budget, **common, **{**run, **item}
                )
            )
        return specs
    for b in budgets:
        label = (
            name
            if len(budgets) == 1
            else f"{name} @ {'paper loops' if b == SCHEDULE else f'{b} FE'}"
        )
        specs.append(ComparisonSpec(name=label, optimisers=optimisers, budget=b, **common, **run))
    return specs


def _toml_text(raw: bytes, path: Path) -> str:
    """The text of a configuration file: UTF-8, as TOML is, after a byte-order mark if the
    editor wrote one (the CSV records are read past one too).

    Raises
    ------
    ConfigError
        For bytes that are not UTF-8, naming the first one, its offset, line and column.
    """
    start = len(codecs.BOM_UTF8) if raw.startswith(codecs.BOM_UTF8) else 0
    try:
        return raw[start:].decode("utf-8")
    except UnicodeDecodeError as exc:
        offset = start + exc.start
        line = raw.count(b"\n", 0, offset) + 1
        line_start = raw.rfind(b"\n", 0, offset) + 1
        column = len(raw[line_start:offset].decode("utf-8", errors="replace")) + 1
        raise ConfigError(
            f"{path}: not UTF-8 text: byte 0x{raw[offset]:02x} at offset {offset} "
            f"(line {line}, column {column})"
        ) from None


def load_config(path: str | os.PathLike) -> list[ComparisonSpec]:
    """Read a TOML comparison configuration.

    Parameters
    ----------
    path : str or os.PathLike
        The TOML file.

    Returns
    -------
    list of ComparisonSpec
        One spec per comparison the file describes.

    Raises
    ------
    ConfigError
        For a missing or malformed file, an unknown section or key, or an invalid value.
    """
    path = Path(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise ConfigError(f"{path}: no such configuration file") from None
    except IsADirectoryError:
        raise ConfigError(f"{path}: is a directory, not a configuration file") from None
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read ({exc.strerror or exc})") from None
    try:
        config = tomllib.loads(_toml_text(raw, path))
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: malformed TOML ({exc})") from None
    specs = spec_from_mapping(config, source=str(path))
    # a relative data file is relative to the configuration file
    out = []
    for spec in specs:
        if spec.data.file is not None:
            def beside(name: str) -> str:
                return name if Path(name).is_absolute() else str((path.parent / name).resolve())

            files = spec.data.file
            files = [beside(f) for f in files] if isinstance(files, list) else beside(files)
            val = spec.data.validation
            data = replace(spec.data, file=files, validation=None if val is None else beside(val))
            spec = replace(spec, data=data)
        reference = spec.model.greybox or ""
        file_part = reference.rpartition(":")[0]
        if file_part.endswith(".py") and not Path(file_part).is_absolute():
            # so is a grey-box model's file
            where = str((path.parent / file_part).resolve())
            model = replace(spec.model, greybox=f"{where}:{reference.rpartition(':')[2]}")
            spec = replace(spec, model=model)
        out.append(spec)
    return out


def default_spec(
    *,
    plant: str = "manipulator",
    optimisers: Sequence[str] | None = None,
    runs: int = COMPARE_RUNS,
    budget: int | str = COMPARE_BUDGET,
    seed: int = 0,
    na: int | None = None,
    nb: Any = None,
    nk: Any = 1,
    cost: CostSpec | None = None,
    search: SearchSpec | None = None,
    structure: str | None = None,
    nc: int | None = None,
    nd: int | None = None,
    nf: Any = None,
    greybox: str | None = None,
    parameters: Mapping[str, Any] | None = None,
    data_seed: int = 0,
) -> ComparisonSpec:
    """The built-in comparison: the paper's experiment on a simulated plant, small by default.

    Parameters
    ----------
    plant : str
        A registered plant with a built-in comparison
        (:attr:`flexid.data.plants.Plant.comparison`: its record and default model):
        ``"manipulator"`` (the end-point acceleration, paper preset; by default output error
        OE(16,16,1), the structure that passes validation there) or ``"twin-rotor"`` (the
        pitch, vertical channel, paper preset; by default the paper's ARX(5,5,1)).
    optimisers : sequence of str, optional
        Registry names (default: hbcsd, bfa, sda, pso, de).
    runs : int, optional
        Runs per optimiser (default 5).
    budget : int or "schedule", optional
        Function evaluations per run (default 10,000), or the optimisers' own loop counts.
    seed : int, optional
        Seed of the runs (default 0): their initial populations and random draws.
    na : int, optional
        Number of ``A`` coefficients.  Orders given without ``structure`` are ARX's, with
        ``na`` defaulting to the paper's order (8 manipulator, 5 twin rotor); with no orders
        and no structure the plant's default model is used.
    nb : int, list of int or None, optional
        Number of ``B`` coefficients (default ``na``).
    nk : int or list of int, optional
        Input delay in samples (default 1).
    cost : CostSpec, optional
        The cost (default :class:`CostSpec`; its ``"auto"`` initial-condition rule becomes
        ``"zero"`` for structures other than ARX, since the built-in records start at rest).
    search : SearchSpec, optional
        The search space (default :class:`SearchSpec`).
    structure : {"arx", "armax", "oe", "bj"}, optional
        The model structure; its orders are ``na``, ``nb``, ``nc``, ``nd``, ``nf``, ``nk`` as
        that structure takes them.  Default: the plant's own model (see ``plant``), or ARX
        when ARX orders are given.
    nc, nd : int, optional
        Orders of ``C`` and ``D``.
    nf : int or list of int, optional
        Order of ``F``.
    greybox : str, optional
        The grey-box model of ``structure="greybox"`` (see :class:`ModelSpec`); the record is
        the plant's paper preset for a one-output model, else the plant's record with the
        model's outputs.
    parameters : mapping, optional
        Its parameter changes (see :class:`ModelSpec`).
    data_seed : int, optional
        Seed of the simulated record (its input signal and sensor noise; default 0).

    Returns
    -------
    ComparisonSpec
        The comparison, named ``"<plant>-default"``.

    Raises
    ------
    UnknownNameError
        For an unknown ``plant``.
    ConfigError
        For a plant without a built-in comparison.
    """
    from .data.plants import get_plant

    built_in = get_plant(plant).comparison  # UnknownNameError for an unknown plant
    if not built_in:
        raise ConfigError(
            f"plant {plant!r} has no built-in comparison (its record's 'comparison' is "
            "empty): describe one in a configuration file"
        )
    preset, order = built_in["preset"], built_in["arx_order"]
    model = ModelSpec(**built_in["model"])
    orders = {"na": na, "nb": nb, "nc": nc, "nd": nd, "nf": nf}
    data = DataSpec(plant=plant, preset=preset, seed=data_seed)
    if greybox is not None and structure in (None, GREYBOX):
        given = sorted(k for k, v in orders.items() if v is not None)
        if given or nk != 1:
            raise ConfigError(f"a grey-box model has no orders; remove {given or ['nk']}")
        spec_model = ModelSpec(
            structure=GREYBOX, greybox=greybox, parameters=dict(parameters or {})
        )
        outputs = spec_model.greybox_model().outputs
        if len(outputs) > 1:  # the paper presets record one output
            data = DataSpec(plant=plant, seed=data_seed, outputs=list(outputs))
    elif structure == GREYBOX or parameters:
        raise ConfigError("structure 'greybox' takes the model's name (greybox=...), and "
                          "parameters belong to it")
    elif structure is None and all(v is None for v in orders.values()):
        spec_model = model  # the plant's own default: a structure that passes validation
    else:
        structure = structure or "arx"  # orders without a structure are ARX's, as in identify
        if structure == "arx" and na is None:
            orders["na"] = order
        spec_model = ModelSpec(structure=structure, nk=nk, **orders)
    cost = cost or CostSpec()
    if cost.initial == "auto" and spec_model.structure != "arx":
        # the built-in plants' records start at rest, so "zero" is their exact initial state
        # (and the cheapest rule: no initial state to fit per candidate)
        cost = replace(cost, initial="zero")
    names = list(optimisers) if optimisers else list(DEFAULT_OPTIMISERS)
    return ComparisonSpec(
        name=f"{plant}-default",
        data=data,
        model=spec_model,
        cost=cost,
        search=search or SearchSpec(),
        optimisers=tuple(OptimiserSpec(n) for n in names),
        runs=runs,
        seed=seed,
        budget=budget,
    )


def with_optimiser_params(spec: ComparisonSpec, params: Mapping[str, Any]) -> ComparisonSpec:
    """``spec`` with hyper-parameters set on its optimisers.

    Parameters
    ----------
    spec : ComparisonSpec
    params : mapping
        ``"OPTIMISER.NAME" -> value`` (an optimiser's label or name, then the
        hyper-parameter), or ``"NAME" -> value`` when the comparison has one optimiser.

    Returns
    -------
    ComparisonSpec

    Raises
    ------
    ConfigError
        A bare name with several optimisers, or an optimiser the comparison does not have.
    """
    by_label = {o.display: o for o in spec.optimisers}
    changes: dict[str, dict[str, Any]] = {}
    for key, value in params.items():
        label, dot, name = key.rpartition(".")
        if not dot:
            if len(by_label) != 1:
                raise ConfigError(
                    f"--param {key}=... is ambiguous with {len(by_label)} optimisers: write "
                    f"OPTIMISER.{key}=VALUE (one of {', '.join(by_label)})"
                )
            label = next(iter(by_label))
        elif label not in by_label:
            raise ConfigError(
                f"--param {key}: {label!r} is not an optimiser of this comparison "
                f"({', '.join(by_label)})"
            )
        changes.setdefault(label, {})[name] = value
    optimisers = tuple(
        replace(o, params={**o.params, **changes[o.display]}) if o.display in changes else o
        for o in spec.optimisers
    )
    return replace(spec, optimisers=optimisers)


def command_specs(
    config: str | os.PathLike | None = None,
    *,
    plant: str | None = None,
    optimisers: Sequence[str] | None = None,
    runs: int | None = None,
    budget: int | None = None,
    seed: int | None = None,
    data_seed: int | None = None,
    model: Mapping[str, Any] | None = None,
    cost: Mapping[str, Any] | None = None,
    search: Mapping[str, Any] | None = None,
    params: Mapping[str, Any] | None = None,
    alpha: float | None = None,
) -> list[ComparisonSpec]:
    """The comparisons a command asks for: a configuration file's, or the built-in one.

    What is not given keeps the file's value, or :func:`default_spec`'s default.

    Parameters
    ----------
    config : path, optional
        A TOML configuration (:func:`load_config`); without it, the built-in comparison of
        ``plant``.
    plant : str, optional
        The built-in comparison's plant (not with ``config``).
    optimisers : sequence of str, optional
        Registry names, replacing the comparison's optimisers.
    runs, budget, seed : int, optional
        Runs per optimiser, FE per run, seed of the runs.
    data_seed : int, optional
        Seed of the built-in comparison's record (not with ``config``: a file sets its own).
    model : mapping, optional
        Of the built-in comparison: ``structure``, ``na``, ``nb``, ``nc``, ``nd``, ``nf``,
        ``nk``, ``greybox`` and ``parameters`` (not with ``config``: a file has its
        ``[model]`` table).
    cost, search : mapping, optional
        Fields of :class:`CostSpec` and :class:`SearchSpec` to change.
    params : mapping, optional
        Hyper-parameters (see :func:`with_optimiser_params`).
    alpha : float, optional
        Family-wise level of the validation verdicts, replacing the comparisons'.

    Returns
    -------
    list of ComparisonSpec

    Raises
    ------
    ConfigError
        Options that do not go together, or whatever the file or the specs refuse.
    """
    model = {k: v for k, v in (model or {}).items() if v not in (None, {}, [])}
    cost, search = dict(cost or {}), dict(search or {})
    if config is not None:
        if plant:
            raise ConfigError("give either a CONFIG file or --plant, not both")
        if model:
            raise ConfigError(
                f"{', '.join(sorted(model))} set the built-in comparison's model; a CONFIG "
                "file names its structure, orders, grey-box model and parameters in its "
                "[model] table"
            )
        if data_seed is not None:
            raise ConfigError(
                "--data-seed applies to the built-in comparison (--plant); a CONFIG file sets "
                "its record's seed in its [data] table"
            )
        changes: dict[str, Any] = {
            k: v for k, v in (("runs", runs), ("budget", budget), ("seed", seed)) if v is not None
        }
        if optimisers:
            changes["optimisers"] = tuple(OptimiserSpec(n) for n in optimisers)
        specs = [
            replace(
                s,
                **changes,
                **({"search": replace(s.search, **search)} if search else {}),
                **({"cost": replace(s.cost, **cost)} if cost else {}),
            )
            for s in load_config(config)
        ]
    else:
        given = {
            "plant": plant, "optimisers": optimisers, "runs": runs, "budget": budget,
            "seed": seed, "data_seed": data_seed,
        }
        specs = [
            default_spec(
                **{k: v for k, v in given.items() if v is not None},
                **model,
                cost=CostSpec(**cost),
                search=SearchSpec(**search),
            )
        ]
    if params:
        specs = [with_optimiser_params(spec, params) for spec in specs]
    if alpha is not None:
        specs = [replace(spec, alpha=alpha) for spec in specs]
    return specs
