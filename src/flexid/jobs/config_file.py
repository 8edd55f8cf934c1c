"""Configuration files: TOML read into :class:`~flexid.config.ComparisonSpec` objects
(:func:`load_config`, :func:`spec_from_mapping`), and the specs of the command line
(:func:`command_specs`).
"""

from __future__ import annotations

import codecs
import os
import sys
from collections.abc import Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

from ..errors import ConfigError, _unreadable

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on Python 3.10 only
    import tomli as tomllib
from ..models.specs import CostSpec, DataSpec, ModelSpec, SearchSpec
from ..models.vocabulary import COMPARE_BUDGET, DEFAULT_OPTIMISERS, SCHEDULE, VALIDATION_ALPHA
from .config_schema import check_config
from .specs import ComparisonSpec, OptimiserSpec, default_spec, with_optimiser_params

__all__ = [
    "command_specs",
    "load_config",
    "spec_from_mapping",
]


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
    except OSError as exc:
        kind = "configuration file"
        raise _unreadable(path, exc, error=ConfigError, kind=kind, missing=kind) from None
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


def _check_file_options(
    plant: str | None, model: Mapping[str, Any], data_seed: int | None
) -> None:
    """Refuse the options of :func:`command_specs` that only the built-in comparison takes."""
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


def _file_specs(
    config: str | os.PathLike,
    optimisers: Sequence[str] | None,
    runs: int | None,
    budget: int | None,
    seed: int | None,
    cost: Mapping[str, Any],
    search: Mapping[str, Any],
) -> list[ComparisonSpec]:
    """A configuration file's comparisons with the options of :func:`command_specs` that
    were given."""
    changes: dict[str, Any] = {
        k: v for k, v in (("runs", runs), ("budget", budget), ("seed", seed)) if v is not None
    }
    if optimisers:
        changes["optimisers"] = tuple(OptimiserSpec(n) for n in optimisers)
    return [
        replace(
            s,
            **changes,
            **({"search": replace(s.search, **search)} if search else {}),
            **({"cost": replace(s.cost, **cost)} if cost else {}),
        )
        for s in load_config(config)
    ]


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
        _check_file_options(plant, model, data_seed)
        specs = _file_specs(config, optimisers, runs, budget, seed, cost, search)
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
