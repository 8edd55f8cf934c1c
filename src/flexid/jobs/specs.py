"""The specifications of the jobs: an optimiser with its hyper-parameters
(:class:`OptimiserSpec`), a whole comparison (:class:`ComparisonSpec`), the built-in
defaults (:func:`default_spec`), and the table of the keywords a user types into
``identify`` (:data:`KEYWORDS`).

:mod:`flexid.config` shows them to users.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace
from typing import Any

from .._validate import integer, level, real
from ..errors import ConfigError
from ..models.specs import CostSpec, DataSpec, ModelSpec, SearchSpec
from ..models.vocabulary import (
    COMPARE_BUDGET,
    COMPARE_RUNS,
    CORRELATION_LAGS,
    DEFAULT_OPTIMISERS,
    GREYBOX,
    LEAST_SQUARES,
    SCHEDULE,
    VALIDATION_ALPHA,
    auto_initial,
)
from .config_schema import CONFIG_SCHEMA

__all__ = [
    "KEYWORDS",
    "ComparisonSpec",
    "Keyword",
    "OptimiserSpec",
    "default_spec",
    "keyword",
    "specs_from_keywords",
    "with_optimiser_params",
]


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
    from ..errors import UnknownNameError

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
            from ..errors import UnknownNameError

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
    from ..data.plants import get_plant

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
        spec_model, data = _default_greybox(plant, greybox, parameters, orders, nk, data,
                                            data_seed)  # fmt: skip
    elif structure == GREYBOX or parameters:
        raise ConfigError("structure 'greybox' takes the model's name (greybox=...), and "
                          "parameters belong to it")
    else:
        spec_model = _default_black_box(model, structure, orders, nk, order)
    cost = _default_cost(cost, spec_model)
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


def _default_greybox(
    plant: str, greybox: str, parameters: Mapping[str, Any] | None,
    orders: Mapping[str, Any], nk: Any, data: DataSpec, data_seed: int,
) -> tuple[ModelSpec, DataSpec]:
    """The grey-box model of :func:`default_spec` and its record (the plant's own record
    with the model's outputs when it has more than one)."""
    given = sorted(k for k, v in orders.items() if v is not None)
    if given or nk != 1:
        raise ConfigError(f"a grey-box model has no orders; remove {given or ['nk']}")
    spec_model = ModelSpec(
        structure=GREYBOX, greybox=greybox, parameters=dict(parameters or {})
    )
    outputs = spec_model.greybox_model().outputs
    if len(outputs) > 1:  # the paper presets record one output
        data = DataSpec(plant=plant, seed=data_seed, outputs=list(outputs))
    return spec_model, data


def _default_black_box(
    model: ModelSpec, structure: str | None, orders: dict[str, Any], nk: Any, order: int,
) -> ModelSpec:
    """The black-box model of :func:`default_spec`: the plant's own, or the structure and
    orders given."""
    if structure is None and all(v is None for v in orders.values()):
        return model  # the plant's own default: a structure that passes validation
    structure = structure or "arx"  # orders without a structure are ARX's, as in identify
    if structure == "arx" and orders["na"] is None:
        orders["na"] = order
    return ModelSpec(structure=structure, nk=nk, **orders)


def _default_cost(cost: CostSpec | None, spec_model: ModelSpec) -> CostSpec:
    """The cost of :func:`default_spec`, with ``"auto"`` initial conditions made ``"zero"``
    for structures other than ARX."""
    cost = cost or CostSpec()
    if cost.initial == "auto" and spec_model.structure != "arx":
        # the built-in plants' records start at rest, so "zero" is their exact initial state
        # (and the cheapest rule: no initial state to fit per candidate)
        cost = replace(cost, initial="zero")
    return cost


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
