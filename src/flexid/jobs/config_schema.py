"""The one schema of a configuration file: every table and key, its TOML types, range
and choices (:data:`CONFIG_SCHEMA`), checked before any work (:func:`check_config`).
"""

from __future__ import annotations

import datetime
import difflib
import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

from .._validate import _interval, _within, is_integer
from ..errors import ConfigError
from ..models.vocabulary import SCHEDULE

__all__ = [
    "CONFIG_SCHEMA",
    "ConfigKey",
    "check_config",
]


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
