"""The ``flexid`` command: generate, identify, compare, select, greybox, frf, report, list.

Every user error (a missing or malformed file, an unknown name, bad orders, invalid
hyper-parameters or configuration keys) prints one line on stderr and exits with status 2;
``--debug`` shows the traceback instead.  Ctrl-C (SIGINT) and SIGTERM end a command with one
line and status 130 or 143 (128 + the signal's number); a comparison's worker processes end
with it and its finished runs are in the store.
"""

from __future__ import annotations

import argparse
import json
import math
import signal
import sys
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, NoReturn

from ._table import wrapped
from ._validate import integer
from ._version import __version__
from .costs.metrics import METRICS
from .data.plants import PLANTS, all_presets
from .errors import ConfigError, DataFileError, FlexidError, FlexidWarning
from .jobs.specs import keyword
from .models.vocabulary import (
    COMPARE_BUDGET,
    COMPARE_RUNS,
    DEFAULT_OPTIMISERS,
    IDENTIFY_BUDGET,
    LEAST_SQUARES,
    OUTPUT_ERROR,
    PREDICTION_ERROR,
    REFERENCES,
    STATE_SPACE,
    STRUCTURE_NAMES,
    SUBSPACE,
    VALIDATION_ALPHA,
)

__all__ = ["DEFAULT_OUT", "build_parser", "main"]

DEFAULT_OUT = Path("flexid-results")


class _UsageError(Exception):
    """argparse error, reported in one line."""


class _Terminated(KeyboardInterrupt):
    """SIGTERM, raised where the program is so that it ends as Ctrl-C ends it: the worker
    processes stopped, the finished runs kept."""


def _raise_terminated(signum: int, frame: Any) -> NoReturn:
    # a second SIGTERM would cut short the ending of the worker processes this one starts
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    raise _Terminated


class _Formatter(argparse.RawDescriptionHelpFormatter):
    """Help with each option's default (where it has one the help does not already give),
    and the examples of the epilog kept as written."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        default = action.default
        if (
            "default" in text.lower()
            or default is None
            or default is False
            or default is argparse.SUPPRESS
            or not action.option_strings
        ):
            return text
        return f"{text} (default {default})"


# What each subcommand does and one example of it (its --help shows both)
_SUBCOMMANDS = {
    "suite": (
        "The benchmark suite of identification problems (plants and records x structures x "
        "costs x instances): list its problems, run optimisers on all or some of them "
        "(resumable, stored), report the runtime distributions, ranking and an IOHprofiler "
        "export.",
        "flexid suite run --optimisers de,pso,cmaes --workers 2 && flexid suite report",
    ),
    "generate": (
        "Simulate a plant (its Gymnasium environment) and write the record with its metadata.",
        "flexid generate manipulator --preset paper-manipulator --seed 0 -o man.csv",
    ),
    "identify": (
        "Identify a polynomial model (ARX, ARMAX, OE, BJ) or a grey-box model's physical "
        "parameters from a record by the structure's reference or a registered optimiser, and "
        "validate it on the held-out part.",
        "flexid identify man.csv --structure oe --nb 16 --nf 16 --nk 1",
    ),
    "compare": (
        "Compare optimisers on identical problems: the same record, initial populations and "
        "FE budget, several seeds; every finished run is stored at once, a rerun resumes.",
        "flexid compare --plant twin-rotor --optimisers de,pso,cmaes --runs 10 --budget 5000",
    ),
    "select": (
        "Fit a grid of structures and orders and recommend the best held-out simulation fit "
        "among those that pass every correlation test (AIC, FPE and MDL are reported).",
        "flexid select man.csv --structures arx,oe --orders nb=8,16 --orders nf=8,16",
    ),
    "greybox": (
        "Fit the physical parameters of a grey-box model (the twin rotor's equations, or your "
        "own as path/to/file.py:NAME) to a record or a simulated twin rotor by the gradient "
        "reference or a registered optimiser, then validate it (identify --structure greybox "
        "on a record does the same).",
        "flexid greybox --plant twin-rotor --model twin-rotor-pitch --set Mg=0.5",
    ),
    "frf": (
        "Estimate a record's frequency response from every input to every output (H1 from "
        "Welch's cross-spectra, Blackman-Tukey or the smoothed empirical transfer function) "
        "with each output's coherence and a confidence band; print the settings and the "
        "resonance peaks, draw the Bode figure.",
        "flexid frf man.csv --figure man_frf.png",
    ),
    "report": (
        "Write a Markdown or HTML report (tables and figures) of a result store, or export it "
        "in the IOHprofiler format.",
        "flexid report flexid-results/results.sqlite --format html",
    ),
    "list": (
        "List the registered optimisers, excitation signals, plants, presets, grey-box models "
        "or Gymnasium environments.",
        "flexid list optimisers --long",
    ),
}


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:
        # the help of the (sub)command that refused the arguments, not the top level's
        raise _UsageError(f"{self.prog}: {message} (see {self.prog} --help)")


# ============================================================================ option parsing
def _value(text: str) -> Any:
    """A command-line value: JSON when it parses (numbers, true/false, lists), else a string."""
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        lowered = text.strip().lower()
        if lowered in ("true", "false"):
            return lowered == "true"
        if lowered in ("none", "null"):
            return None
        return text


def _key_values_raw(items: Sequence[str] | None, what: str) -> dict[str, Any]:
    """``["a-b=1", "c=x"]`` -> ``{"a-b": 1, "c": "x"}``: names as written."""
    out: dict[str, Any] = {}
    for item in items or []:
        key, sep, text = item.partition("=")
        if not sep or not key.strip():
            raise ConfigError(f"{what} must look like NAME=VALUE, got {item!r}")
        out[key.strip()] = _value(text.strip())
    return out


def _key_values(items: Sequence[str] | None, what: str) -> dict[str, Any]:
    """``["a-b=1", "c=x"]`` -> ``{"a_b": 1, "c": "x"}``: names with ``-`` read as ``_``."""
    return {k.replace("-", "_"): v for k, v in _key_values_raw(items, what).items()}


def _names(text: str | None) -> list[str] | None:
    if text is None:
        return None
    names = [n.strip() for n in text.split(",") if n.strip()]
    if not names:
        raise ConfigError("expected a comma-separated list of names")
    return names


def _int_list(text: str | None, what: str) -> Any:
    if text is None:
        return None
    try:
        values = [int(v) for v in text.split(",")]
    except ValueError:
        raise ConfigError(
            f"{what} must be an integer or a comma-separated list of integers, got {text!r}"
        ) from None
    return values[0] if len(values) == 1 else values


_SPLIT_HELP = (
    "estimation share in (0, 1) (default 2/3), a sample index, or the two parts as sample "
    "ranges START:STOP,START:STOP (e.g. 0:1000,1000:); with --validation, one range of the "
    "record to estimate on"
)


def _split(text: str | None) -> Any:
    """``--split``: a fraction, a sample index, or sample ranges (kept as text)."""
    if text is None or ":" in text:
        return text
    try:
        value = float(text)
    except ValueError:
        raise ConfigError(f"--split must be a fraction, a sample index or sample ranges "
                          f"START:STOP,START:STOP, got {text!r}") from None  # fmt: skip
    if value > 1:
        if not value.is_integer():
            raise ConfigError(
                f"--split must be a fraction in (0, 1) or a sample index, got {text}"
            )
        return int(value)
    return value


def _add_validation(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--split", help=_SPLIT_HELP)
    parser.add_argument(
        "--validation", metavar="FILE",
        help="validate on this record (read with the same channel and sample-time options) "
        "and estimate on all of the first, or on its --split range (default: the held-out "
        "part of the first)",
    )


def _delays(text: str | None, what: str) -> Any:
    """``--nk``: a delay, one per input, or ``auto`` (estimated from the record)."""
    if text is not None and text.strip().lower() == "auto":
        return "auto"
    return _int_list(text, what)


def _columns(text: str | None) -> Any:
    """Column names or 0-based indices, comma-separated."""
    if text is None:
        return None
    items: list[Any] = []
    for part in text.split(","):
        part = part.strip()
        items.append(int(part) if part.lstrip("-").isdigit() else part)
    return items


def _check_positive(value: int | None, option: str) -> None:
    """An integer option that must be >= 1, named as the user typed it."""
    integer(value, option, error=ConfigError, minimum=1, none_ok=True)


def _bounds(text: str) -> Any:
    if text == "auto":
        return "auto"
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        raise ConfigError(
            f"--bounds must be 'auto', a half-width S or LOW,HIGH, got {text!r}"
        ) from None
    if len(values) == 1:
        return values[0]
    if len(values) == 2:
        return tuple(values)
    raise ConfigError(f"--bounds must be 'auto', a half-width S or LOW,HIGH, got {text!r}")


# ============================================================================ commands
def _cmd_generate(args: argparse.Namespace) -> int:
    from .data.datasets import generate

    if args.out is None:
        raise ConfigError("give the file to write: -o/--out FILE (.csv or .npz)")
    path = Path(args.out)  # checked before the (possibly long) simulation
    if path.suffix.lower() not in (".csv", ".npz"):
        raise ConfigError(f"--out must end in .csv or .npz, got {args.out!r}")
    if path.is_dir():
        raise ConfigError(f"--out {args.out!r} is a folder; give a .csv or .npz file name")
    options: dict[str, Any] = {"seed": args.seed}
    if args.preset:
        options["preset"] = args.preset
    if args.signal:
        options["signal"] = args.signal
    if args.samples is not None:
        options["n_samples"] = args.samples
    if args.dt is not None:
        options["dt"] = args.dt
    if args.outputs:
        options["outputs"] = _names(args.outputs)
    if args.noise is not None:
        options["noise_std"] = _value(args.noise)
    signal_options = _key_values(args.signal_option, "--signal-option")
    if signal_options:
        options["signal_options"] = signal_options
    plant_params = _key_values(args.param, "--param")
    if plant_params:
        options["plant_params"] = plant_params
    options["sensors"] = args.sensors
    data = generate(args.plant, **options)
    if path.parent and not path.parent.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
    data.save(path)
    print(f"wrote {path}: {data.describe().splitlines()[0]}")
    return 0


def _cmd_identify(args: argparse.Namespace) -> int:
    from .jobs._identify import identify

    _check_positive(args.budget, "--budget")
    _check_positive(args.iterations, "--iterations")
    load_options: dict[str, Any] = {}
    if args.inputs is not None:
        load_options["inputs"] = _columns(args.inputs)
    if args.outputs is not None:
        load_options["outputs"] = _columns(args.outputs)
    if args.dt is not None:
        load_options["dt"] = args.dt
    if args.variable is not None:
        for file in args.file:
            if Path(file).suffix.lower() != ".mat":
                raise ConfigError(f"--variable is for MATLAB .mat files, not {file!r}")
        load_options["variable"] = args.variable
    split = _split(args.split)
    budget: Any = args.budget
    if args.iterations is not None:
        budget = {"max_fe": args.budget, "max_iter": args.iterations}
    model = _greybox_from_args(args, _greybox_name(args))
    ident = identify(
        args.file[0] if len(args.file) == 1 else args.file,
        args.na,
        _int_list(args.nb, "--nb"),
        _delays(args.nk, "--nk") if args.nk is not None else None,
        structure=model if model is not None else args.structure,
        nc=args.nc,
        nd=args.nd,
        nf=_int_list(args.nf, "--nf"),
        initial=args.initial,
        validate_initial=args.validate_initial,
        optimiser=args.optimiser,
        params=_key_values(args.param, "--param"),
        cost=args.cost,
        predictor=args.predictor,
        bounds=_bounds(args.bounds),
        budget=budget,
        seed=args.seed,
        split=split,
        validation=args.validation,
        output=_one_or_more(_columns(args.output)) if args.output is not None else None,
        detrend=args.detrend,
        max_lag=args.max_lag,
        **({} if args.alpha is None else {"alpha": args.alpha}),
        load_options=load_options,
        order=args.order,
        modes=args.modes,
        frequency=_pair(args.frequency, "--frequency"),
        damping=_pair(args.damping, "--damping"),
        feedthrough=args.feedthrough,
        parametrisation=args.parametrisation,
        penalty_kind=args.penalty,
        init=args.init,
        numerator=args.numerator,
        callback=_identify_progress(args),
    )
    unwritten = None
    if args.figures:
        from .report.plots import identification_figures

        try:
            paths = identification_figures(ident, args.figures)
        except DataFileError as exc:  # the results are printed all the same: nothing lost
            unwritten = exc
        else:
            if not args.json:
                print(f"figures: {len(paths)} PNG files in {args.figures}")
    if args.json:
        print(json.dumps(ident.to_dict(), indent=2, allow_nan=False))
    else:
        print(ident.summary())
    if unwritten is not None:
        raise DataFileError(f"{unwritten}; results printed above")
    return 0


def _optimiser_params(items: Sequence[str] | None) -> dict[str, Any]:
    """``["de.weight=0.7", "F=1"]`` -> ``{"de.weight": 0.7, "F": 1}``: the optimiser's label
    as written, the hyper-parameter's name with ``-`` read as ``_``."""
    out: dict[str, Any] = {}
    for key, value in _key_values_raw(items, "--param").items():
        label, dot, name = key.rpartition(".")
        out[f"{label}{dot}{name.replace('-', '_')}"] = value
    return out


def _identify_progress(args: argparse.Namespace):
    if args.json or args.no_progress or args.optimiser in REFERENCES or not sys.stderr.isatty():
        return None
    from .jobs.progress import ProgressBar

    # a bar on a terminal only (checked above), and only for runs longer than a second
    bar = ProgressBar(args.budget, f"{args.optimiser}", unit="FE", delay=1.0)
    state = {"fe": 0}

    def callback(info) -> None:
        bar.update(info.fe - state["fe"], f"best {info.best:.5g}")
        state["fe"] = info.fe
        if info.max_fe is not None and info.fe >= info.max_fe:
            bar.close()

    return callback


def _cost_overrides(args: argparse.Namespace) -> dict[str, str]:
    given = {"metric": args.cost, "predictor": args.predictor}
    return {k: v for k, v in given.items() if v is not None}


def _search_overrides(args: argparse.Namespace) -> dict[str, str]:
    given = {
        "parametrisation": args.parametrisation,
        "penalty": args.penalty,
        "init": args.init,
        "numerator": args.numerator,
    }
    return {k: v for k, v in given.items() if v is not None}


def _add_search_options(p: argparse.ArgumentParser) -> None:
    for option in ("--parametrisation", "--penalty", "--init", "--numerator"):
        _add_keyword_option(p, option)


def _add_keyword_option(p: argparse.ArgumentParser, option: str) -> None:
    """An option of a cost or search setting, its help from the one keyword table."""
    p.add_argument(option, help=keyword(option).help)


def _add_alpha(p: argparse.ArgumentParser, config: bool = False) -> None:
    default = f"the config's, else {VALIDATION_ALPHA:g}" if config else f"{VALIDATION_ALPHA:g}"
    p.add_argument(
        "--alpha", type=float,
        help="level of the validation verdicts: a true model fails its residual tests in at "
        f"most this share of records (default {default})",
    )


def _cmd_compare(args: argparse.Namespace) -> int:
    from .jobs._compare import check_spec, compare
    from .jobs.config_file import command_specs
    from .jobs.specs import _check_run_timeout

    _check_positive(args.budget, "--budget")
    _check_positive(args.runs, "--runs")
    _check_positive(args.workers, "--workers")
    _check_run_timeout(args.run_timeout, "--run-timeout")
    orders = {
        "structure": args.structure, "na": args.na, "nb": _int_list(args.nb, "--nb"),
        "nc": args.nc, "nd": args.nd, "nf": _int_list(args.nf, "--nf"),
        "nk": _int_list(args.nk, "--nk"), "greybox": _greybox_name(args),
        "parameters": _parameter_changes(args),
    }
    specs = command_specs(
        args.config, plant=args.plant, optimisers=_names(args.optimisers), runs=args.runs,
        budget=args.budget, seed=args.seed, data_seed=args.data_seed, model=orders,
        cost=_cost_overrides(args), search=_search_overrides(args),
        params=_optimiser_params(args.param), alpha=args.alpha,
    )
    if len(specs) > 1:  # compare() checks its own spec before it opens the store; check the
        for spec in specs:  # others too before the first comparison writes anything
            check_spec(spec)
    store = Path(args.store) if args.store else DEFAULT_OUT / "results.sqlite"
    outputs = []
    for spec in specs:
        result = compare(
            spec,
            store=store,
            workers=args.workers,
            scheduler=args.scheduler,
            progress=not (args.no_progress or args.json),
            retry_failed=args.retry_failed,
            run_timeout=args.run_timeout,
        )
        outputs.append(result)
        if not args.json:
            print(result.summary())
            n_runs = sum(len(runs) for runs in result.records.values())
            print(
                f"\n{n_runs} optimiser run{'' if n_runs == 1 else 's'} "
                f"(+ the {result.start_label} row) in store {store} "
                f"({result.elapsed:.1f} s this time)"
            )
        if not args.no_figures:
            from .report.plots import PlottingUnavailable, comparison_figures
            from .report.writer import figure_prefix

            figdir = Path(args.figures) if args.figures else store.parent
            prefix = figure_prefix(result)
            try:
                paths = comparison_figures(result, figdir, prefix=prefix)
            except PlottingUnavailable as exc:
                if not args.json:
                    print(f"(no figures: {exc})")
            except DataFileError as exc:
                n_runs = sum(len(runs) for runs in result.records.values())
                runs = "1 run" if n_runs == 1 else f"{n_runs} runs"
                raise DataFileError(f"{exc}; {runs} stored in {store}") from None
            else:
                if not args.json:  # one short line, whatever the names' length
                    print(f"figures: {len(paths)} PNG files in {figdir} ({prefix}*.png)")
        if not args.json:
            print()
    if args.json:
        print(json.dumps([r.to_dict() for r in outputs], indent=2, allow_nan=False))
    return 0


def _order_grid(items: Sequence[str] | None) -> dict[str, list[int]] | None:
    """``["nb=4,8,16", "nf=4,8,16"]`` -> ``{"nb": [4, 8, 16], "nf": [4, 8, 16]}``."""
    if not items:
        return None
    grid: dict[str, list[int]] = {}
    for item in items:
        key, sep, text = item.partition("=")
        if not sep or not key.strip():
            raise ConfigError(f"--orders must look like NAME=V1,V2,..., got {item!r}")
        grid[key.strip()] = _int_list(text, f"--orders {key.strip()}")
    return grid


def _add_record_or_plant(parser: argparse.ArgumentParser, plant_help: str) -> None:
    """The record a command reads, or a plant whose simulated record of a seed it reads."""
    parser.add_argument("file", nargs="?", help="record: .csv, .npz, .dat or .mat")
    parser.add_argument("--plant", help=f"{plant_help} instead (default: none, the FILE)")
    parser.add_argument(
        "--data-seed", type=int, default=0,
        help="seed of the simulated record (default 0)",
    )


def _add_detrend(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--detrend", nargs="?", const="constant", choices=("constant", "linear"),
        help="remove the estimation record's means (constant, the value without one) or its "
        "least-squares line (linear) (default: neither; a warning says when an offset or "
        "drift dominates a channel)",
    )


def _select_records(args: argparse.Namespace) -> tuple[Any, Any, Any]:
    """The estimation and validation records of ``select`` and, for a simulated plant, its
    known delay (None for a record file)."""
    from .data.records import load

    if (args.file is None) == (args.plant is None):
        raise ConfigError("give a record file or --plant (a simulated record), not both")
    given = (("inputs", _columns(args.inputs)), ("outputs", _columns(args.outputs)))
    options = {k: v for k, v in (*given, ("dt", args.dt)) if v is not None}
    plant_nk = None
    if args.plant is not None:
        from .data.datasets import generate
        from .jobs.specs import default_spec

        builtin = default_spec(plant=args.plant)  # the built-in comparison's record
        data = generate(args.plant, preset=builtin.data.preset, seed=args.data_seed)
        # a simulated plant's delay is known: its comparison's model says it
        plant_nk = builtin.model.nk if builtin.model.nk is not None else 1
    else:
        data = load(args.file, **options)
    validation = None if args.validation is None else load(args.validation, **options)
    if args.output is not None:
        data = data.select(outputs=[_columns(args.output)[0]])
        if validation is not None:
            validation = validation.select(outputs=[_columns(args.output)[0]])
    return data, validation, plant_nk


def _select_nk(args: argparse.Namespace, plant_nk: Any) -> Any:
    """``--nk``, else a simulated plant's known delay, else ``"auto"``."""
    if args.nk is not None:
        return _delays(args.nk, "--nk")
    return "auto" if args.plant is None else plant_nk


def _select_figures(result: Any, figure: str) -> list:
    """Write the selection's figure, Bode figure and stabilisation diagram (those it has)
    beside ``figure``; the paths written."""
    from .report.plots import _save, selection_bode, selection_figure, stabilisation_diagram

    written = [selection_figure(result, figure)]
    base = Path(figure)
    for name, fig in (("bode", selection_bode(result)),
                      ("stabilisation", stabilisation_diagram(result))):  # fmt: skip
        if fig is not None:
            written.append(_save(fig, base.with_name(f"{base.stem}_{name}{base.suffix}")))
    return written


def _cmd_select(args: argparse.Namespace) -> int:
    from .jobs.selection import select

    data, validation, plant_nk = _select_records(args)
    grid = _order_grid(args.orders)
    result = select(
        data,
        structures=tuple(_names(args.structures) or ("arx", "oe")),
        orders=grid,
        nk=_select_nk(args, plant_nk),
        initial=args.initial,
        criterion=args.criterion,
        max_lag=args.max_lag,
        **({} if args.alpha is None else {"alpha": args.alpha}),
        detrend=args.detrend,
        split=_split(args.split),
        validation=validation,
        progress=not (args.json or args.no_progress) and sys.stderr.isatty(),
    )
    written = _select_figures(result, args.figure) if args.figure else []
    if args.json:
        print(json.dumps(result.to_dict(), indent=2, allow_nan=False))
    else:
        print(result.summary())
        if written:
            print(f"figures: {', '.join(str(p) for p in written)}")
    return 0


def _parameter_changes(args: argparse.Namespace) -> dict[str, dict[str, Any]]:
    """``--set NAME=VALUE``, ``--fix A,B`` and ``--free C`` as grey-box parameter changes."""
    changes: dict[str, dict[str, Any]] = {}
    for name, value in _key_values_raw(args.set, "--set").items():  # names as spelled
        changes.setdefault(name, {})["value"] = value
    for option, fixed in ((args.fix, True), (args.free, False)):
        for name in _names(option) or []:
            changes.setdefault(name, {})["fixed"] = fixed
    return changes


def _greybox_from_args(args: argparse.Namespace, name: str | None) -> Any:
    """The grey-box model ``name`` with the command line's parameter changes, or None."""
    changes = _parameter_changes(args)
    channels = getattr(args, "channels", None)
    if name is None:
        if changes or channels:
            raise ConfigError("--set, --fix, --free and --channels are a grey-box model's: "
                              "give --structure greybox --greybox NAME")
        return None
    from .models.greybox_library import greybox_model

    model = greybox_model(name)
    model = model.with_parameters(**changes) if changes else model
    columns = _channel_columns(channels)
    return model.reading(**columns) if columns else model


def _channel_columns(text: str | None) -> dict[str, tuple[str, float]]:
    """``--channels main_rotor=u,pitch=y*0.0174533`` as ``{channel: (column, factor)}``."""
    out: dict[str, tuple[str, float]] = {}
    for item in _names(text) or []:
        channel, sep, rhs = item.partition("=")
        column, star, factor = rhs.partition("*")
        try:
            value = float(factor) if star else 1.0
        except ValueError:
            value = math.nan
        if not (sep and channel.strip() and column.strip()) or not math.isfinite(value):
            raise ConfigError(
                f"--channels: {item!r} is not CHANNEL=COLUMN or CHANNEL=COLUMN*FACTOR (e.g. "
                "pitch=y*0.0174533 for a pitch logged in degrees)"
            )
        out[channel.strip()] = (column.strip(), value)
    return out


def _greybox_name(args: argparse.Namespace) -> str | None:
    """``--greybox NAME`` checked against ``--structure``."""
    if args.structure == "greybox" and args.greybox is None:
        raise ConfigError(
            "--structure greybox needs --greybox NAME (flexid list greybox), e.g. "
            "--greybox twin-rotor-pitch or --greybox path/to/model.py:MODEL"
        )
    if args.greybox is not None and args.structure not in (None, "greybox"):
        raise ConfigError(f"--greybox is the model of --structure greybox, not {args.structure}")
    return args.greybox


def _cmd_greybox(args: argparse.Namespace) -> int:
    from .jobs._identify import identify

    if (args.file is None) == (args.plant is None):
        raise ConfigError("give a record file or --plant (a simulated record), not both")
    model = _greybox_from_args(args, args.model)
    if args.plant is not None:
        from .data.datasets import generate

        if args.plant != "twin-rotor":
            raise ConfigError(
                f"the built-in grey-box models are the twin rotor's, not {args.plant!r}'s"
            )
        if len(model.outputs) == 1:
            data = generate(args.plant, preset="paper-twin-rotor", seed=args.data_seed)
        else:
            data = generate(args.plant, outputs=list(model.outputs), seed=args.data_seed)
    else:
        data = args.file
    options = {"dt": args.dt} if args.dt is not None else {}
    if args.optimiser not in REFERENCES:
        _check_positive(args.budget, "--budget")
    ident = identify(
        data, structure=model, optimiser=args.optimiser, budget=args.budget, seed=args.seed,
        split=args.split, load_options=options, callback=_identify_progress(args),
    )
    if args.json:
        print(json.dumps(ident.to_dict(), indent=2, allow_nan=False))
    else:
        print(ident.summary())
    return 0


def _cmd_frf(args: argparse.Namespace) -> int:
    from .data.records import load
    from .validation.frequency import frf

    figure = Path(args.figure) if args.figure is not None else None
    if figure is not None:
        if figure.suffix.lower() not in (".png", ".pdf", ".svg"):
            raise ConfigError(f"--figure {args.figure!r}: a .png, .pdf or .svg file")
        if not figure.parent.is_dir():
            raise ConfigError(f"--figure {args.figure!r}: no folder {str(figure.parent)!r}")
    options: dict[str, Any] = {}
    for key in ("inputs", "outputs"):
        if getattr(args, key) is not None:
            options[key] = _columns(getattr(args, key))
    if args.dt is not None:
        options["dt"] = args.dt
    data = load(args.file, **options)
    estimate = frf(
        data, args.method, segment=args.segment, lag_width=args.lag_width, width=args.width,
        resolution=args.resolution, level=args.level,
    )  # fmt: skip
    if figure is not None:
        import io

        from .data._files import write_bytes
        from .report.plots import _plt, plot_bode

        fig = plot_bode(estimate, title=f"{Path(args.file).name}: frequency response")
        buffer = io.BytesIO()
        fig.savefig(buffer, format=figure.suffix[1:].lower(), dpi=110, bbox_inches="tight")
        _plt().close(fig)
        write_bytes(figure, buffer.getvalue())  # whole or not at all
    if args.json:
        print(json.dumps(estimate.to_dict(), allow_nan=False))
    else:
        print(estimate.summary())
        if figure is not None:
            print(f"figure: {figure}")
    return 0


def _cmd_report(args: argparse.Namespace) -> int:
    from .report.writer import write_report

    outdir = (
        Path(args.out) if args.out else Path(args.store).with_suffix("").parent / "report"
    )
    if args.format in ("ioh", "ioh-info"):
        from .report.writer import export_ioh

        layout = "json" if args.format == "ioh" else "info"
        folders = export_ioh(args.store, outdir, key=args.key, layout=layout)
        print(f"wrote {', '.join(str(f) for f in folders)} (IOHprofiler, {layout} layout)")
        return 0
    path = write_report(
        args.store, outdir, fmt=args.format, key=args.key, figures=not args.no_figures
    )
    print(f"wrote {path}")
    return 0


def _list_optimisers(args: argparse.Namespace) -> None:
    from ._json import jsonable
    from .optimisers import available, describe
    from .optimisers.external import library_notes

    entries = [describe(name) for name in available()]
    if args.json:
        print(json.dumps(jsonable(entries), indent=2, allow_nan=False, default=str))
        return
    width = max(len(e["name"]) for e in entries)
    bwidth = max(len(e["bounds"]["kind"]) for e in entries)
    if not args.long:
        print(f"{'name':<{width}}  {'at the bounds':<{bwidth}}  summary")
    for e in entries:
        origin = f" (variant of {e['variant_of']})" if e["variant_of"] else ""
        src = "" if e["source"] == "flexid" else f" [{e['source']}]"
        bounds = e["bounds"]["kind"]
        if not args.long:  # the name, the bounds and the first sentence, continued under it
            first = e["summary"].split(". ")[0].rstrip(".")
            print(wrapped(f"{e['name']:<{width}}  {bounds:<{bwidth}}  {first}{origin}{src}",
                          hang=" " * (width + bwidth + 4)))  # fmt: skip
            continue
        print(wrapped(f"{e['name']}{origin}{src}: {e['summary']}"))
        note = e["bounds"]["note"]
        print(wrapped(f"at the bounds: {bounds}" + (f": {note}" if note else ""), indent="    "))
        for pname, p in e["hyperparameters"].items():
            print(wrapped(f"{pname} = {p['default']!r}  ({p['type']}, {p['range']}) {p['doc']}",
                          indent="    "))  # fmt: skip
    if not args.long:
        print("\n(--long: every optimiser's hyper-parameters, defaults and ranges)")
    print("\nOptimisers of other libraries (flexid's FE budget, initial population and seed):")
    for line in library_notes():
        print(f"  {line}")


def _list_signals(args: argparse.Namespace) -> None:
    from .data.signals import describe_signals

    print(describe_signals())


def _list_plants(args: argparse.Namespace) -> None:
    for plant in PLANTS.values():
        print(wrapped(
            f"{plant.name:12s} {', '.join(plant.input_names)} -> "
            f"{', '.join(plant.output_names)}; dt {plant.dt:g} s; gymnasium id {plant.env_id}",
            hang=" " * 13,
        ))  # fmt: skip


def _list_presets(args: argparse.Namespace) -> None:
    from ._json import jsonable

    for name, preset in all_presets().items():  # its description, then its settings
        settings = {k: v for k, v in jsonable(preset).items() if k != "description"}
        print(wrapped(f"{name}: {preset.get('description', '')}"))
        for k, v in settings.items():  # as in a config's [data] table
            print(wrapped(f"{k} = {json.dumps(v, allow_nan=False, default=str)}", indent="    "))


def _list_greybox(args: argparse.Namespace) -> None:
    from .models.greybox_library import available_greybox_models, greybox_model

    for name in available_greybox_models():
        try:
            model = greybox_model(name)
        except FlexidError as exc:  # an installed model that fails to load says so
            print(f"{name}: cannot be loaded ({exc})")
            continue
        print(wrapped(
            f"{name}: {', '.join(model.inputs)} -> {', '.join(model.outputs)}; estimated "
            f"{', '.join(model.free)}"
        ))  # fmt: skip
    print("and any path/to/file.py:NAME (a GreyBoxModel, or a function returning one)")


def _list_environments(args: argparse.Namespace) -> None:
    import gymnasium

    for env_id in sorted(k for k in gymnasium.envs.registry if k.startswith("flexid/")):
        print(env_id)


#: What ``flexid list`` lists, and how.
_LISTS = {
    "optimisers": _list_optimisers,
    "signals": _list_signals,
    "plants": _list_plants,
    "presets": _list_presets,
    "greybox": _list_greybox,
    "environments": _list_environments,
}


_SUITE_STORE = DEFAULT_OUT / "suite.sqlite"


def _suite_of(args: argparse.Namespace) -> Any:
    """The suite (setting, records, subset, runs and budget) the options name."""
    from dataclasses import replace

    from .jobs.suite import get_suite

    _check_positive(args.runs, "--runs")
    _check_positive(args.budget_per_dim, "--budget-per-dim")
    suite = get_suite(args.setting, records=args.records)
    changes = {k: v for k, v in (("runs", args.runs), ("budget_per_dim", args.budget_per_dim))
               if v is not None}  # fmt: skip
    if changes:  # runs and budget are the experiment's: the version stays the problems'
        suite = replace(suite, **changes)
    return suite.subset(args.problems)


def _cmd_suite(args: argparse.Namespace) -> int:
    from .jobs.suite import load_suite, run_suite

    suite = _suite_of(args)
    store = Path(args.store) if args.store else _SUITE_STORE
    if args.action == "list":
        rows = [{"name": p.name, **p.groups, "instance": p.instance} for p in suite.problems]
        if args.json:
            print(json.dumps({"suite": suite.label, "version": suite.version,
                              "budget_per_dim": suite.budget_per_dim, "runs": suite.runs,
                              "problems": rows}, indent=2))  # fmt: skip
            return 0
        print(f"{suite.label} version {suite.version}: {len(rows)} problems, {suite.runs} runs "
              f"of {suite.budget_per_dim} FE per dimension")  # fmt: skip
        for row in rows:
            print(f"  {row['name']}")
        return 0
    if args.action == "run":
        _check_positive(args.workers, "--workers")
        names = _names(args.optimisers)
        if not names:
            raise ConfigError("flexid suite run needs --optimisers NAME[,NAME...]")
        result = run_suite(
            suite, names, store=store, workers=args.workers, scheduler=args.scheduler,
            progress=not (args.no_progress or args.json),
        )  # fmt: skip
    else:
        result = load_suite(store, suite)
    if args.json:
        print(json.dumps({"version": result.version, "ranking": result.ranking(),
                          "table": result.table()}, indent=2, default=float))  # fmt: skip
    else:
        print(result.summary())
    out = Path(args.out) if args.out else store.parent / "suite-report"
    _write_suite_report(result, out, figures=not args.no_figures, by=args.by)
    if not args.json:
        print(f"\nreport: {out}")
    return 0


def _write_suite_report(result: Any, out: Path, *, figures: bool, by: str) -> None:
    """The suite's table, summary, ECDF figure and IOHprofiler export in ``out``, built in a
    folder next to it and renamed into place once whole."""
    import shutil
    import tempfile

    from .jobs._ioh import _replace_dir

    if not result.results:
        raise ConfigError(f"no problem of {result.suite.label} has runs in the store")
    out.parent.mkdir(parents=True, exist_ok=True)
    staged = Path(tempfile.mkdtemp(prefix=f".{out.name}.tmp-", dir=out.parent))
    try:
        lines = ["| problem | dim | reference | optimiser | median / reference | solved 1e-3 "
                 "| below reference | runs |", "|---|---|---|---|---|---|---|---|"]  # fmt: skip
        for row in result.table():
            mark = "" if row["verified"] else " *"
            lines.append(
                f"| {row['problem']} | {row['dim']} | {row['reference']:.6g}{mark} | "
                f"{row['label']} | {row['median']:.4g} | {row['solved']} | {row['below']} | "
                f"{row['runs']} |"
            )
        lines += ["", "\\* the reference is not at a verified local minimum: a run below it "
                  "is news, not an error."]  # fmt: skip
        (staged / "problems.md").write_text("\n".join(lines) + "\n", encoding="utf-8")
        (staged / "summary.txt").write_text(result.summary() + "\n", encoding="utf-8")
        result.export_ioh(staged / "ioh")
        if figures:
            from .report.plots import PlottingUnavailable, suite_figure

            try:
                suite_figure(result, staged / "ecdf.png", by=by)
            except PlottingUnavailable:
                pass
        _replace_dir(staged, out)
    except BaseException:
        shutil.rmtree(staged, ignore_errors=True)
        raise


def _pair(text: str | None, option: str) -> tuple[float, float] | None:
    """``"lo,hi"`` as two numbers, or None."""
    if text is None:
        return None
    parts = text.split(",")
    try:
        if len(parts) != 2:
            raise ValueError
        return float(parts[0]), float(parts[1])
    except ValueError:
        raise ConfigError(f"{option} takes two numbers LO,HI, got {text!r}") from None


def _one_or_more(names: list) -> Any:
    """One channel as itself, several as the list."""
    return names[0] if len(names) == 1 else names


def _cmd_list(args: argparse.Namespace) -> int:
    _LISTS[args.what](args)
    return 0


# ============================================================================ parser
def _structure_options(p: argparse.ArgumentParser, default: str, scope: str = "",
                       state_space: bool = False) -> None:  # fmt: skip
    """``--structure`` and its orders, alike on every command that takes a model (with
    ``state_space``, the state-space model too: its orders are the command's own)."""
    tail = f"; {scope}" if scope else ""
    names = " | ".join((*STRUCTURE_NAMES, "greybox", *((STATE_SPACE,) if state_space else ())))
    extra = f", --order for {STATE_SPACE}" if state_space else ""
    p.add_argument(
        "--structure",
        help=f"model structure: {names} ({default}); give its orders, or --greybox for "
        f"greybox{extra}",
    )
    p.add_argument(
        "--greybox", metavar="NAME",
        help="grey-box model of --structure greybox: twin-rotor-pitch, twin-rotor-coupled, "
        "an installed one (flexid list greybox) or path/to/file.py:NAME (default: none)",
    )
    _parameter_options(p)
    p.add_argument(
        "--na", type=int,
        help=f"order of A (arx, armax{tail}; no default for armax; arx: 8 in compare)",
    )
    p.add_argument("--nb", help=f"B coefficients per input (arx default: na{tail})")
    p.add_argument("--nc", type=int, help=f"order of C (armax, bj{tail}; no default)")
    p.add_argument("--nd", type=int, help=f"order of D (bj{tail}; no default)")
    p.add_argument("--nf", help=f"order of F per input (oe, bj{tail}; no default)")
    p.add_argument(
        "--nk",
        help=f"input delay in samples per input (default 1{tail}); identify also takes 'auto', "
        "the delay estimated from the estimation record (MATLAB delayest)",
    )


_DT_HELP = (
    "sample time in seconds if the file lacks it (default: from a time column, else 1 s, said "
    "in the output)"
)


def _record_options(p: argparse.ArgumentParser, *, mat: bool = False) -> None:
    """The channels and sample time of a record file, alike on every command that reads one."""
    what = "columns or .mat variables" if mat else "columns"
    p.add_argument(
        "--inputs",
        help=f"input {what} (names or 0-based indices; default: a flexid file's own, else "
        "columns u, u1, ...)",
    )
    p.add_argument(
        "--outputs",
        help=f"output {what} (names or 0-based indices; default: a flexid file's own, else "
        "columns y, y1, ...)",
    )
    if mat:
        p.add_argument(
            "--variable",
            help=".mat file: the structure to read, or the matrix whose columns indices name "
            "(default: the only one)",
        )
    p.add_argument(
        "--output", help="which output to model when there are several (default: the only one)"
    )
    p.add_argument("--dt", type=float, help=_DT_HELP)


def _channels_option(p: argparse.ArgumentParser) -> None:
    """``--channels``: where a grey-box model reads its channels in a record file."""
    p.add_argument(
        "--channels",
        metavar="CHANNEL=COLUMN[*FACTOR],..",
        help="the record's column each grey-box channel is read from, and the factor to the "
        "model's unit, e.g. main_rotor=u,pitch=y*0.0174533 (default: the columns named as "
        "the model's channels, unscaled)",
    )


def _parameter_options(p: argparse.ArgumentParser) -> None:
    """``--set``, ``--fix`` and ``--free``: a grey-box model's parameters."""
    p.add_argument(
        "--set", action="append", metavar="NAME=VALUE",
        help="grey-box parameter's value (the start, or its value when fixed); repeatable "
        "(default: the model's values)",
    )
    p.add_argument(
        "--fix",
        help="grey-box parameters to hold at their values, comma-separated (default: the "
        "model's)",
    )
    p.add_argument(
        "--free",
        help="grey-box parameters to estimate, comma-separated (default: the model's)",
    )


_COST_HELP = f"cost metric: {' | '.join(METRICS)} (default {METRICS[0]}; see flexid.costs.metrics)"


def _compared() -> list[str]:
    """The plants with a built-in comparison (``compare --plant``)."""
    return [name for name, plant in PLANTS.items() if plant.comparison]


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``flexid`` command and its subcommands.

    Returns
    -------
    argparse.ArgumentParser
        A parser whose usage errors :func:`main` reports in one line (exit status 2).
    """
    parser = _Parser(
        prog="flexid",
        description="Flexible-plant simulators, ARX identification with pluggable optimisers, "
        "and fair optimiser comparison.",
    )
    parser.add_argument("--version", action="version", version=f"flexid {__version__}")
    parser.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)

    g = sub.add_parser("generate", help="write a synthetic dataset from a simulated plant")
    g.add_argument("plant", help=f"the plant: {' | '.join(PLANTS)}")
    g.add_argument(
        "--preset",
        help=f"a preset record: {' | '.join(all_presets())} (default: none, the plant's own "
        "defaults)",
    )
    g.add_argument(
        "--sensors",
        choices=("lab", "ideal"),
        default="lab",
        help="read the plant through its measurement chain (lab, default) or exactly (ideal)",
    )
    g.add_argument(
        "--signal",
        help="excitation signal (flexid list signals; default: the preset's, else the plant's)",
    )
    g.add_argument(
        "--samples", type=int,
        help="number of samples (default: the preset's, else the plant's)",
    )
    g.add_argument("--seed", type=int, default=0, help="seed (default 0)")
    g.add_argument("--dt", type=float, help="sample time in seconds (default: the plant's)")
    g.add_argument(
        "--outputs",
        help="output channels to keep, comma-separated (default: all the plant's)",
    )
    g.add_argument(
        "--noise",
        help="measurement noise std per output, or e.g. 1%% of each output's std (default: "
        "the preset's, else none beyond the sensors')"
    )
    g.add_argument(
        "--signal-option", action="append", metavar="NAME=VALUE",
        help="signal option (repeatable; default: the signal's own)",
    )
    g.add_argument(
        "--param", action="append", metavar="NAME=VALUE",
        help="plant parameter (repeatable; default: the plant's values)",
    )
    g.add_argument("--out", "-o", help="the file to write, .csv or .npz (required)")
    # the former spelling, easily confused with --outputs (channels): still read
    g.add_argument("--output", dest="out", help=argparse.SUPPRESS)
    g.set_defaults(func=_cmd_generate)

    i = sub.add_parser("identify", help="identify a polynomial model (ARX, ARMAX, OE, BJ)")
    i.add_argument(
        "file", nargs="+",
        help="record: .csv, .npz, .dat or .mat; several: estimation records of one system, "
        "fitted together, each with its own initial state (then --validation FILE is needed)",
    )
    _structure_options(i, "default arx", state_space=True)
    i.add_argument("--order", type=int,
                   help="number of poles of --structure ss, a state-space model of every "
                   "output (or those --output names) with the modes searched (no default)")
    i.add_argument("--modes", type=int,
                   help="lightly damped modes among them (--structure ss; default order // 2)")
    i.add_argument("--frequency", metavar="LO,HI",
                   help="bounds of the modes' frequencies in Hz (--structure ss; default: the "
                   "record's resolution 1/(N dt) to Nyquist)")
    i.add_argument("--damping", metavar="LO,HI",
                   help="bounds of the modes' damping ratios (--structure ss; default 1e-4,1)")
    i.add_argument("--feedthrough", action="store_true", default=None,
                   help="estimate the direct term D (--structure ss; default: none)")
    _channels_option(i)
    i.add_argument(
        "--optimiser",
        default=PREDICTION_ERROR,
        help=f"registered optimiser (e.g. hbcsd, the paper's), {LEAST_SQUARES!r} (least "
        f"squares) or {PREDICTION_ERROR!r}, the default: the structure's gradient reference "
        f"(least squares for the one-step ARX cost; {OUTPUT_ERROR!r}: its old spelling); "
        f"{SUBSPACE!r} for --structure ss: subspace identification",
    )
    _add_keyword_option(i, "--initial")
    i.add_argument(
        "--validate-initial",
        default="estimate",
        help="initial state in the validation: estimate (default) | zero | measured",
    )
    i.add_argument(
        "--param", action="append", metavar="NAME=VALUE",
        help="optimiser hyper-parameter (repeatable; default: the optimiser's, flexid list "
        "optimisers --long)",
    )
    i.add_argument("--cost", help=_COST_HELP)
    _add_keyword_option(i, "--predictor")
    i.add_argument("--bounds", default="auto", help="auto, a half-width S, or LOW,HIGH")
    _add_search_options(i)
    i.add_argument(
        "--budget", type=int, default=IDENTIFY_BUDGET, help="function evaluations"
    )
    i.add_argument(
        "--iterations", type=int,
        help="also stop after this many iterations (default: no limit)",
    )
    i.add_argument("--seed", type=int, default=0, help="seed (default 0)")
    _add_validation(i)
    _record_options(i, mat=True)
    _add_detrend(i)
    i.add_argument("--max-lag", type=int, default=25, help="lags of the correlation tests")
    _add_alpha(i)
    i.add_argument(
        "--figures",
        help="write the paper's figures (PNG) to this folder (default: none)",
    )
    i.add_argument("--json", action="store_true", help="print a machine-readable result")
    i.add_argument("--no-progress", action="store_true", help="no progress bar")
    i.set_defaults(func=_cmd_identify)

    c = sub.add_parser("compare", help="compare optimisers on identical problems")
    c.add_argument("config", nargs="?", help="comparison configuration (.toml)")
    c.add_argument(
        "--plant",
        help=f"the built-in comparison of a plant: {' | '.join(_compared())} (default "
        "manipulator)",
    )
    c.add_argument(
        "--optimisers",
        help=f"comma-separated optimiser names (default {','.join(DEFAULT_OPTIMISERS)}, or "
        "the config's)",
    )
    c.add_argument(
        "--runs", type=int,
        help=f"runs (seeds) per optimiser (default {COMPARE_RUNS}, or the config's)",
    )
    c.add_argument(
        "--budget", type=int,
        help=f"function evaluations per run (default {COMPARE_BUDGET}, or the config's)",
    )
    c.add_argument(
        "--seed", type=int,
        help="seed of the runs: their initial populations and random draws (default 0, or "
        "the config's)",
    )
    c.add_argument(
        "--data-seed", type=int,
        help="seed of the simulated record (input signal, sensor noise) of the built-in "
        "comparison (--plant; default 0)",
    )
    c.add_argument(
        "--param", action="append", metavar="[OPTIMISER.]NAME=VALUE",
        help="an optimiser's hyper-parameter (default: the optimiser's, flexid list optimisers "
        "--long), e.g. de.weight=0.7; "
        "the optimiser's name may be left out when there is one; repeatable",
    )
    _structure_options(
        c,
        "built-in comparison; default: the plant's own model, arx when only orders are given",
        scope="built-in comparison",
    )
    c.add_argument("--cost", help=_COST_HELP)
    _add_alpha(c, config=True)
    _add_keyword_option(c, "--predictor")
    _add_search_options(c)
    c.add_argument("--store", help=f"SQLite result store (default {DEFAULT_OUT}/results.sqlite)")
    c.add_argument("--workers", type=int, default=1, help="parallel processes (default 1)")
    c.add_argument(
        "--run-timeout",
        type=float,
        metavar="SECONDS",
        help="end a run that takes longer and record it as failed; the comparison goes on "
        "(default: [compare] run_timeout of the CONFIG, else no limit)",
    )
    c.add_argument(
        "--scheduler",
        help="dask.distributed scheduler address (default: none, local processes)",
    )
    c.add_argument("--figures", help="folder for the figures (default: next to the store)")
    c.add_argument("--no-figures", action="store_true", help="do not draw figures")
    c.add_argument("--retry-failed", action="store_true", help="run failed runs again")
    c.add_argument("--json", action="store_true", help="print machine-readable results")
    c.add_argument("--no-progress", action="store_true", help="no progress bar")
    c.set_defaults(func=_cmd_compare)

    se = sub.add_parser(
        "select", help="choose a structure and its orders (AIC, FPE, MDL, held-out tests)"
    )
    _add_record_or_plant(se, "select on a simulated record of this plant")
    se.add_argument(
        "--structures",
        help=f"comma-separated: {', '.join(STRUCTURE_NAMES)}, greybox:NAME (default arx,oe)",
    )
    se.add_argument(
        "--orders",
        action="append",
        metavar="NAME=V1,V2,..",
        help="a grid of one order (repeatable: a product grid), e.g. nb=8,16 nf=8,16 (default: "
        "each structure's default grid)",
    )
    se.add_argument(
        "--nk",
        help="input delay in samples per input, or auto: the grid at nk = 1 and at the delays "
        "estimated from the estimation record by MATLAB's delayest and by the prewhitened "
        "cross-correlation (default auto for a record file; with --plant, the plant's known "
        "delay)",
    )
    se.add_argument("--criterion", default="simulation", help="simulation | aic | fpe | mdl")
    se.add_argument("--initial", default="estimate", help="estimate | zero | measured")
    _record_options(se)
    _add_detrend(se)
    _add_validation(se)
    se.add_argument("--max-lag", type=int, default=25, help="lags of the correlation tests")
    _add_alpha(se)
    se.add_argument("--figure", help="write the selection figure (PNG) here, and beside it "
                    "NAME_bode.png and NAME_stabilisation.png (the held-out record's frequency "
                    "response with the best candidates; their modes against the order) "
                    "(default: none)")  # fmt: skip
    se.add_argument("--json", action="store_true", help="print a machine-readable result")
    se.add_argument("--no-progress", action="store_true", help="no progress bar")
    se.set_defaults(func=_cmd_select)

    r = sub.add_parser("report", help="write a Markdown/HTML report of a result store")
    r.add_argument("store", help="SQLite result store")
    r.add_argument("--out", "-o", help="report folder (default: report/ next to the store)")
    r.add_argument("--output", dest="out", help=argparse.SUPPRESS)  # the former spelling
    r.add_argument(
        "--format",
        default="md",
        choices=["md", "html", "ioh", "ioh-info"],
        help="md, html, or the runs for IOHanalyzer: ioh (JSON meta-data), ioh-info (.info)",
    )
    r.add_argument(
        "--key",
        help="only the comparison with this key (prefix; default: every comparison in the store)",
    )
    r.add_argument("--no-figures", action="store_true", help="tables only")
    r.set_defaults(func=_cmd_report)

    gb = sub.add_parser(
        "greybox", help="fit a grey-box model (a plant's own physics) and validate it"
    )
    _add_record_or_plant(gb, "fit a simulated record of this plant (twin-rotor)")
    gb.add_argument(
        "--model", default="twin-rotor-pitch",
        help="built-in grey-box model: twin-rotor-pitch (default) | twin-rotor-coupled",
    )
    gb.add_argument(
        "--optimiser", default="pem",
        help="pem (default: Levenberg-Marquardt from several starts, with standard errors) or "
        "a registered optimiser",
    )
    gb.add_argument(
        "--budget", type=int, default=IDENTIFY_BUDGET, help="function evaluations of an optimiser"
    )
    gb.add_argument("--starts", type=int, default=3, help="random starts of pem (default 3)")
    gb.add_argument("--seed", type=int, default=0, help="seed of the starts or the run (default 0)")
    _parameter_options(gb)
    _channels_option(gb)
    gb.add_argument("--json", action="store_true", help="machine-readable result")
    gb.add_argument("--no-progress", action="store_true", help="no progress bar")
    gb.add_argument("--split", type=_value, help="estimation share (default 2/3) or split index")
    gb.add_argument("--dt", type=float, help=_DT_HELP)
    gb.set_defaults(func=_cmd_greybox)

    fr = sub.add_parser(
        "frf", help="a record's frequency response with coherence and confidence band"
    )
    fr.add_argument("file", help="record: .csv, .npz, .dat or .mat")
    fr.add_argument("--method", default="tfestimate", choices=["tfestimate", "spa", "etfe"],
                    help="tfestimate (default: H1 from Welch's cross-spectra), spa "
                    "(Blackman-Tukey) or etfe (smoothed DFT ratio)")  # fmt: skip
    fr.add_argument("--segment", type=int,
                    help="tfestimate: samples per segment (default N/4.5: 8 segments)")
    fr.add_argument("--lag-width", type=int,
                    help="spa: lag window width M in samples (default min(N/10, 30))")
    fr.add_argument("--width", type=int,
                    help="etfe: smoothing width in DFT bins, odd (default 11)")
    fr.add_argument("--resolution", type=float,
                    help="frequency resolution in Hz instead of --segment, --lag-width or "
                    "--width (default: none)")
    fr.add_argument("--level", type=float, default=0.95,
                    help="confidence level of the band")
    fr.add_argument("--inputs", help="input columns (names or 0-based indices; default: a "
                    "flexid file's own, else columns u, u1, ...)")
    fr.add_argument("--outputs", help="output columns (names or 0-based indices; default: a "
                    "flexid file's own, else columns y, y1, ...)")
    fr.add_argument("--dt", type=float, help=_DT_HELP)
    fr.add_argument("--figure", help="write the Bode figure here (.png, .pdf or .svg; "
                    "default: none)")
    fr.add_argument("--json", action="store_true", help="print the estimate as JSON")
    fr.set_defaults(func=_cmd_frf)

    su = sub.add_parser("suite", help="the benchmark suite: list, run or report")
    su.add_argument("action", choices=["list", "run", "report"], help="what to do")
    su.add_argument("--setting", default="small", choices=["small", "full"],
                    help="the suite's setting (default small)")  # fmt: skip
    su.add_argument("--records", help="folder of real records whose problems join (default: "
                    "none; e.g. ../shared/data/real)")  # fmt: skip
    su.add_argument(
        "--problems", nargs="+", metavar="NAME",
        help="only these problems or groups (default: all; see suite list)",
    )
    su.add_argument("--optimisers", help="run: comma-separated registered names (required)")
    su.add_argument("--runs", type=int, help="runs per optimiser and problem (default: the "
                    "setting's)")  # fmt: skip
    su.add_argument("--budget-per-dim", type=int, help="FE per dimension of a run (default: the "
                    "setting's)")  # fmt: skip
    su.add_argument("--store", help=f"SQLite result store (default {_SUITE_STORE})")
    su.add_argument("--workers", type=int, default=1, help="worker processes (default 1)")
    su.add_argument("--scheduler", help="dask scheduler address (default: none, local)")
    su.add_argument(
        "--out", "-o", help="run, report: the report's folder (default suite-report/ next to the "
        "store)",
    )
    su.add_argument("--by", default="structure", choices=["structure", "plant", "cost"],
                    help="the ECDF's group panels (default structure)")  # fmt: skip
    su.add_argument("--no-figures", action="store_true", help="no ECDF figure")
    su.add_argument("--no-progress", action="store_true", help="no progress lines")
    su.add_argument("--json", action="store_true", help="machine-readable output")
    su.set_defaults(func=_cmd_suite)

    li = sub.add_parser("list", help="list optimisers, signals, plants, presets or environments")
    li.add_argument(
        "what", choices=list(_LISTS)
    )
    li.add_argument("--json", action="store_true", help="machine-readable (optimisers)")
    li.add_argument(
        "--long", action="store_true",
        help="optimisers with their hyper-parameters, defaults, ranges and the assumptions "
        "made where a paper gives no value (default: one line each)",
    )
    li.set_defaults(func=_cmd_list)
    for name, sp in sub.choices.items():
        what, example = _SUBCOMMANDS[name]
        sp.description = what
        sp.epilog = f"example:\n  {example}"
        sp.formatter_class = _Formatter
    return parser


def _paragraph_warnings(show: Callable) -> Callable:
    """``warnings.showwarning`` that prints flexid's warnings (store, data, identification)
    as one paragraph on stderr: ``flexid: warning: ...``, continued lines indented."""

    def show_warning(message, category, filename, lineno, file=None, line=None) -> None:
        if issubclass(category, FlexidWarning):  # one paragraph, at a terminal's width
            print(wrapped(f"flexid: warning: {message}", hang="  "), file=file or sys.stderr)
        else:
            show(message, category, filename, lineno, file, line)

    return show_warning


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; return the exit status (0 ok, 2 user error, 130 Ctrl-C, 143
    SIGTERM).

    Parameters
    ----------
    argv : sequence of str, optional
        The arguments after the program name; default ``sys.argv[1:]``.

    Returns
    -------
    int
        The exit status.
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    debug = "--debug" in argv
    shown = warnings.showwarning
    warnings.showwarning = _paragraph_warnings(shown)
    terminate = _on_sigterm(_raise_terminated)
    try:
        args, extra = parser.parse_known_args(argv)
        if extra:  # name the subcommand whose options these are not
            where = f"flexid {args.command}" if args.command else "flexid"
            raise _UsageError(
                f"{where}: unrecognized arguments: {' '.join(extra)} (see {where} --help)"
            )
        if args.command is None:
            parser.print_help()
            return 2
        return int(args.func(args) or 0)
    except _UsageError as exc:
        print(exc, file=sys.stderr)
        return 2
    except FlexidError as exc:
        if debug:
            raise
        print(f"flexid: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        what, status = ("terminated", 143) if isinstance(exc, _Terminated) else ("interrupted", 130)
        print(f"flexid: {what} (finished runs are in the store; rerun to resume)", file=sys.stderr)
        return status
    except BrokenPipeError:
        return 0
    finally:
        warnings.showwarning = shown
        _on_sigterm(terminate)


def _on_sigterm(handler: Any) -> Any:
    """Install ``handler`` for SIGTERM and return the one it replaces.

    Only the main thread can set a signal handler; elsewhere (``main`` called from a
    thread) nothing is changed and None is returned.
    """
    if handler is None or not hasattr(signal, "SIGTERM"):
        return None
    try:
        return signal.signal(signal.SIGTERM, handler)
    except ValueError:  # not the main thread
        return None


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
