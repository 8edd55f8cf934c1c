"""IOHprofiler export of a comparison's runs, and the ECDF of (run, target) pairs against FE.

Two things that read the same data, the per-run histories of best-so-far cost against
function evaluations (FE) kept in a :class:`~flexid.jobs.store.ResultStore`:

* :func:`export_ioh` writes them in the IOHprofiler format that IOHanalyzer loads, so a
  comparison can be studied there (fixed-target and fixed-budget views, ERT, ECDFs);
* :func:`ecdf_fraction` and :func:`comparison_ecdf` compute the empirical cumulative
  distribution of the runtimes over (run, target) pairs, as COCO and IOHanalyzer draw it,
  with the comparison's reference cost as the target; the report draws and tabulates it.

The format followed
-------------------
The ``json`` layout is the one IOHexperimenter's default logger writes
(``ioh::logger::Analyzer``, namespace ``analyzer::v2`` in
``include/ioh/logger/analyzer.hpp``, with the header ``evaluations raw_y`` of its
``default_properties_``).  Per optimiser, one folder holds::

    IOHprofiler_f1_<name>.json
    data_f1_<name>/IOHprofiler_f1_DIM<d>.dat

The JSON has the keys ``version``, ``suite``, ``function_id``, ``function_name``,
``maximization``, ``algorithm`` (``name``, ``info``), ``experiment_attributes`` (a list of
one-key objects with string values), ``run_attributes``, ``attributes`` (the data columns)
and ``scenarios``: one per dimension with ``dimension``, ``path`` (relative to the JSON) and
``runs``, each run ``{"instance", "evals", "best": {"evals", "y", "x"}, <run
attributes>}``.  The ``.dat`` file has one block per run, each starting with the line
``evaluations raw_y``, columns separated by one space.

The ``info`` layout is IOHexperimenter's older ``analyzer::v1`` output as the IOHanalyzer
data-format page describes it: ``IOHprofiler_f1_<name>.info`` with three lines per
dimension (``key = "value"`` pairs with ``funcId``, ``DIM``, ``algId`` and
``maximization = "F"``; a ``%`` comment line; the data path followed by
``instance:evals|best`` per run) and the two-column ``.dat`` blocks headed
``"function evaluation" "best-so-far f(x)"``.  Every IOHanalyzer version reads it (the older
ones read no JSON), so it is the layout to choose when a JSON export does not load.

How flexid maps onto it
-----------------------
* one export folder per comparison, one problem per comparison (``function_id`` 1, the
  comparison's name as ``function_name``), one sub-folder per optimiser (the label is the
  algorithm name; its registered name and hyper-parameters are the algorithm ``info``);
* the dimension is the length of the search vector the optimisers saw (``na`` when the
  numerator is fitted, ``na + sum(nb)`` when it is searched), minimisation;
* the instance is the run index of the store (0, 1, ...), the same for every optimiser, as
  run ``r`` of every optimiser starts from the same population; its seed is a run attribute;
* the rows are the store's history, exact to the evaluation: one row per evaluation that
  lowered the best-so-far cost, at its FE count (the first is FE 1 whenever the first point's
  cost is finite), as IOHexperimenter's default ``on_improvement`` trigger writes, and each
  run's block ends with its last FE (IOHanalyzer needs it to count an unsuccessful run's
  runtime).  ``raw_y`` is the best-so-far cost (also on the last line, where
  IOHexperimenter writes the last evaluated value: the store does not keep it).  Readers
  that split a ``.dat`` file into runs where ``evaluations == 1`` (iohinspector) rely on the
  first row;
* ``best`` holds the FE at which the final best was found, its cost and ``x``, the best
  point in the search space the optimisers saw (not the ARX coefficients it maps to, which
  the store keeps as ``theta``);
* failed runs have no history and are left out; the folder's ``README.md`` lists them;
* the costs are written with Python's shortest round-trip representation, so reading the
  files back gives the stored numbers bit for bit.

IOHanalyzer has no field for a target.  The reference cost (the comparison's
``reference_cost``: least squares when its model is stable, see
:class:`~flexid.ComparisonResult`) is written as the experiment attribute
``reference_cost`` (JSON; ``reference_cost = "..."`` on the ``.info`` header line) and in the
folder's ``README.md``; in IOHanalyzer type it (or ``reference x (1 + t)``) as the target.
"""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import tempfile
from collections.abc import Mapping, Sequence
from itertools import pairwise
from pathlib import Path
from typing import Any

import numpy as np

from .._json import jsonable
from ..errors import ConfigError, StoreError
from ._compare import load_result
from ._comparison_result import ComparisonResult
from .statistics import best_at
from .store import ResultStore

__all__ = [
    "IOH_LAYOUTS",
    "check_histories",
    "comparison_ecdf",
    "ecdf_fraction",
    "ecdf_targets",
    "export_ioh",
]

IOH_LAYOUTS = ("json", "info")
FUNCTION_ID = 1
SUITE = "flexid"
# The JSON's "version": the IOHexperimenter (python ``ioh``) release whose Analyzer logger
# writes this layout, as that logger fills the field; readers use it to pick a parser.
IOH_VERSION = "0.3.22"
_JSON_HEADER = "evaluations raw_y"
_INFO_HEADER = '"function evaluation" "best-so-far f(x)"'
# Relative-precision targets per decade, as COCO's 51 targets over ten decades.
TARGETS_PER_DECADE = 5


# ================================================================================ ECDF
def ecdf_targets(
    reference: float,
    initial_best: Sequence[float],
    hardest: float,
    *,
    per_decade: int = TARGETS_PER_DECADE,
) -> np.ndarray:
    """Target costs of the ECDF: ``reference * (1 + d)``, ``d`` log-spaced.

    The precisions ``d`` run from the easiest, the worst (largest) first cost of any run
    relative to the reference (``max(initial_best) / reference - 1``), down to the hardest,
    ``hardest`` (the comparison's smallest relative target), ``per_decade`` to a decade, as
    COCO places its targets relative to the best known value.  Every run reaches the easiest
    target with its first evaluation, and a run's ECDF reaches 1 when it gets within
    ``reference * (1 + hardest)``.

    Parameters
    ----------
    reference : float
        Reference cost (> 0), in the cost's units.
    initial_best : sequence of float
        Each run's first best cost (that of its first evaluation), in the cost's units.
    hardest : float
        Smallest relative precision (> 0), dimensionless.
    per_decade : int, optional
        Targets per decade of precision (at least 2 targets in all unless the range is
        empty).

    Returns
    -------
    ndarray, shape (T,)
        Target costs, decreasing (easiest first); empty if the reference is not a finite
        positive number or no run has a finite first cost.

    Raises
    ------
    ConfigError
        If ``hardest`` or ``per_decade`` is not positive.
    """
    if not (isinstance(hardest, (int, float)) and hardest > 0):
        raise ConfigError(f"ecdf_targets: hardest precision must be > 0, got {hardest!r}")
    if isinstance(per_decade, bool) or not isinstance(per_decade, int) or per_decade < 1:
        raise ConfigError(f"ecdf_targets: per_decade must be an integer >= 1, got {per_decade!r}")
    initial = np.asarray(initial_best, dtype=float)
    initial = initial[np.isfinite(initial)]
    if not (math.isfinite(reference) and reference > 0) or initial.size == 0:
        return np.empty(0)
    easiest = float(initial.max()) / reference - 1.0
    if easiest <= hardest:
        precisions = np.array([float(hardest)])
    else:
        decades = math.log10(easiest / hardest)
        n = max(2, math.ceil(decades * per_decade) + 1)
        precisions = np.geomspace(easiest, hardest, n)
    return reference * (1.0 + precisions)


def ecdf_fraction(
    histories: Sequence[Mapping[str, Sequence[float]]],
    targets: Sequence[float],
    fe: Any,
) -> np.ndarray:
    """Fraction of (run, target) pairs reached after ``fe`` evaluations.

    A pair (run, target) is reached at ``fe`` when the run's best-so-far cost after ``fe``
    evaluations is ``<= target`` (the history is a step function, see
    :func:`flexid.jobs.statistics.best_at`).

    Parameters
    ----------
    histories : sequence of mapping
        One ``{"fe": [...], "best": [...]}`` per run (non-decreasing ``fe``).
    targets : sequence of float
        Target costs, in the cost's units.
    fe : array_like, shape (K,)
        Evaluation counts.

    Returns
    -------
    ndarray, shape (K,)
        Values in [0, 1]; ``nan`` where there is no run or no target.
    """
    fe = np.atleast_1d(np.asarray(fe, dtype=float))
    targets = np.asarray(targets, dtype=float).ravel()
    if not histories or targets.size == 0:
        return np.full(fe.shape, np.nan)
    reached = np.zeros(fe.shape)
    for history in histories:
        best = best_at(history, fe)  # (K,)
        reached += (best[:, None] <= targets[None, :]).sum(axis=1)
    return reached / (len(histories) * targets.size)


def comparison_ecdf(
    result: ComparisonResult,
    *,
    targets: Sequence[float] | None = None,
    per_decade: int = TARGETS_PER_DECADE,
) -> dict[str, Any]:
    """The ECDF of (run, target) pairs against FE for every optimiser of a comparison.

    Parameters
    ----------
    result : ComparisonResult
        A comparison (from :func:`flexid.compare` or :func:`flexid.load_result`).
    targets : sequence of float, optional
        Target costs; default :func:`ecdf_targets` from the reference cost, the runs' first
        best costs and the comparison's smallest relative target.
    per_decade : int, optional
        Targets per decade for the default targets.

    Returns
    -------
    dict
        ``targets`` (ndarray, target costs), ``reference`` (float), ``curves``:
        ``label -> {"fe": ndarray (K,), "fraction": ndarray (K,), "runs": int}``: the exact
        step function (its value changes only at the FE counts of the runs' histories;
        ``fe`` starts at 1, the first evaluation).  Only finished runs count (failed
        runs have no history; the cost table lists them).
    """
    histories = {
        label: [r["history"] for r in records if r["status"] == "ok" and r.get("history")]
        for label, records in result.records.items()
    }
    if targets is None:
        firsts = [h["best"][0] for hs in histories.values() for h in hs if h["best"]]
        hardest = min(result.spec.targets)
        targets = ecdf_targets(result.reference_cost, firsts, hardest, per_decade=per_decade)
    targets = np.asarray(targets, dtype=float)
    curves = {}
    for label, hs in histories.items():
        points = sorted({1.0} | {float(v) for h in hs for v in h["fe"]})
        fe = np.asarray(points)
        curves[label] = {"fe": fe, "fraction": ecdf_fraction(hs, targets, fe), "runs": len(hs)}
    return {"targets": targets, "reference": float(result.reference_cost), "curves": curves}


# ================================================================================ export
def _name(text: str) -> str:
    """A file-name-safe function or folder name (IOHprofiler puts it in file names)."""
    return re.sub(r"[^A-Za-z0-9]+", "-", text).strip("-") or "comparison"


def _number(value: float) -> str:
    """Shortest text that reads back as the same double (``inf`` for infinity)."""
    return repr(float(value))


def _dimension(result: ComparisonResult, runs: Mapping[str, Sequence[Mapping]]) -> int:
    """Length of the search vector the optimisers saw (that of every run's best point)."""
    where = f"comparison {result.spec.name!r} [{result.key[:8]}]"
    sizes = set()
    for label, records in runs.items():
        for r in records:
            x = r.get("x")
            if not x:
                raise StoreError(
                    f"{where}: {label!r} run {r['run']} has no best search point (recorded by "
                    "an older flexid); run the comparison again into a new store to export it"
                )
            sizes.add(len(x))
    if len(sizes) != 1:
        raise StoreError(f"{where}: the runs' search points differ in length {sorted(sizes)}")
    return sizes.pop()


def _runs_of(result: ComparisonResult, label: str) -> list[dict[str, Any]]:
    """Finished runs of ``label`` (their histories checked by :func:`check_histories`)."""
    return [r for r in result.records[label] if r["status"] == "ok"]


def check_histories(store: str | os.PathLike, key: str | None = None) -> None:
    """Raise if a finished run of the store has no usable history of FE and best cost.

    Checked on the raw records, before :func:`flexid.load_result` computes statistics from
    the histories.

    Parameters
    ----------
    store : path-like
        A result store.
    key : str, optional
        Only the comparison with this key (a unique prefix).

    Raises
    ------
    StoreError
        Naming the store, the comparison, the optimiser and the run.
    """
    with ResultStore(store, readonly=True) as db:
        entries = [db.comparison(key)] if key else db.comparisons()
        for entry in entries:
            where = f"{store}: comparison {entry['name']!r} [{entry['key'][:8]}]"
            for r in db.iter_runs(entry["key"]):
                if r.get("status") != "ok":
                    continue
                h = r.get("history") or {}
                fe, best = h.get("fe") or [], h.get("best") or []
                if not fe or len(fe) != len(best):
                    raise StoreError(
                        f"{where}: {r['label']!r} run {r['run']} has no history of FE and "
                        "best cost"
                    )
                if any(later < earlier for earlier, later in pairwise(fe)):
                    raise StoreError(
                        f"{where}: {r['label']!r} run {r['run']}: the history's FE decrease"
                    )


def _best_evals(history: Mapping[str, Sequence[float]]) -> tuple[int, float]:
    """FE at which the final best cost was first reached, and that cost."""
    best = [float(b) for b in history["best"]]
    final = best[-1]
    first = next((i for i, b in enumerate(best) if b == final), len(best) - 1)
    return int(history["fe"][first]), final


def _algorithm_info(result: ComparisonResult, label: str) -> str:
    for opt in result.spec.optimisers:
        if opt.display == label:
            params = json.dumps(dict(opt.params), sort_keys=True)
            return f"{opt.name} {params}"
    return label  # pragma: no cover (labels come from the specification)


def _attributes(result: ComparisonResult) -> list[tuple[str, str]]:
    from .._version import __version__

    spec = result.spec
    return [
        ("model", spec.model.describe()),
        (
            "cost",
            f"{spec.cost.metric}, {spec.cost.predictor} predictor, initial state "
            f"{spec.cost.initial}",
        ),
        ("reference_cost", _number(result.reference_cost)),
        ("reference", result.reference_note),
        ("target_rule", "reference x (1 + t), t > 0 (minimisation)"),
        ("targets_t", " ".join(f"{t:g}" for t in result.spec.targets)),
        ("flexid_key", result.key),
        ("flexid_version", __version__),
        ("budget_fe", str(result.spec.max_fe)),
    ]


def _dat_text(runs: Sequence[Mapping[str, Any]], header: str) -> str:
    lines = []
    for r in runs:
        lines.append(header)
        h = r["history"]
        if int(h["fe"][0]) != 1:
            # the first evaluation's cost was not finite (flexid counts it as +inf); the row
            # is written all the same, as readers start a run at evaluation 1
            lines.append(f"1 {_number(math.inf)}")
        lines += [f"{int(fe)} {_number(b)}" for fe, b in zip(h["fe"], h["best"])]
    return "\n".join(lines) + "\n"


def _write_algorithm(
    folder: Path, result: ComparisonResult, label: str, runs: list, layout: str, dim: int,
    *, function_id: int = FUNCTION_ID, function_name: str | None = None, suite: str = SUITE,
) -> None:
    """Write one optimiser's runs on one function (a comparison) into ``folder``."""
    fname = _name(function_name or result.spec.name)
    fid = function_id
    data_dir = f"data_f{fid}_{fname}"
    dat = f"{data_dir}/IOHprofiler_f{fid}_DIM{dim}.dat"
    (folder / data_dir).mkdir(parents=True, exist_ok=True)
    header = _JSON_HEADER if layout == "json" else _INFO_HEADER
    (folder / dat).write_text(_dat_text(runs, header), encoding="utf-8")
    info = _algorithm_info(result, label)
    attrs = _attributes(result)
    if layout == "json":
        run_entries = []
        for r in runs:
            evals, y = _best_evals(r["history"])
            run_entries.append(
                {
                    "instance": int(r["run"]),
                    "evals": int(r["history"]["fe"][-1]),
                    "best": {"evals": evals, "y": jsonable(y), "x": jsonable(r["x"])},
                    "seed": int(r["seed"]),
                }
            )
        meta = {
            "version": IOH_VERSION,
            "suite": suite,
            "function_id": fid,
            "function_name": fname,
            "maximization": False,
            "algorithm": {"name": label, "info": info},
            "experiment_attributes": [{k: v} for k, v in attrs],
            "run_attributes": ["seed"],
            "attributes": _JSON_HEADER.split(),
            "scenarios": [{"dimension": dim, "path": dat, "runs": run_entries}],
        }
        path = folder / f"IOHprofiler_f{fid}_{fname}.json"
        path.write_text(json.dumps(meta, indent=2, allow_nan=False) + "\n", encoding="utf-8")
        return
    head = [
        f'suite = "{suite}"',
        f"funcId = {fid}",
        f'funcName = "{fname}"',
        f"DIM = {dim}",
        'maximization = "F"',
        f'algId = "{_quote(label)}"',
        f'algInfo = "{_quote(info)}"',
    ] + [f'{k} = "{_quote(v)}"' for k, v in attrs]
    entries = [
        f"{int(r['run'])}:{int(r['history']['fe'][-1])}|{_number(_best_evals(r['history'])[1])}"
        for r in runs
    ]
    text = ", ".join(head) + "\n%\n" + ", ".join([dat, *entries]) + "\n"
    (folder / f"IOHprofiler_f{fid}_{fname}.info").write_text(text, encoding="utf-8")


def _quote(text: str) -> str:
    """A value for a ``key = "value"`` pair of an ``.info`` line: no double quotes or commas
    (IOHanalyzer splits the line on commas, quotes aside only in its newer readers)."""
    return text.replace('"', "'").replace(",", ";")


def _readme(result: ComparisonResult, labels: Sequence[str], layout: str, dim: int) -> str:
    failed = [
        f"{label} run {r['run']} ({r.get('error') or 'failed'})"
        for label, records in result.records.items()
        for r in records
        if r["status"] != "ok"
    ]
    return "\n".join(
        [
            f"# IOHprofiler export of the flexid comparison {result.spec.name!r}",
            "",
            f"Store key `{result.key}`; layout `{layout}`; minimisation; function id "
            f"{FUNCTION_ID} named `{_name(result.spec.name)}`; dimension "
            f"{dim} (the search vector); one folder per optimiser: "
            + ", ".join(f"`{_name(label)}`" for label in labels)
            + ".",
            "",
            f"Target: the reference cost {_number(result.reference_cost)} "
            f"({result.reference_note}); the comparison's targets are reference x (1 + t), "
            f"t in {list(result.spec.targets)}.  IOHanalyzer has no target field: enter these "
            "values as the targets there.",
            "",
            "Rows: the best-so-far cost at each evaluation that improved it (exact FE "
            "count, FE 1 first), and each run's last FE.  Instance = run index; the seed is "
            "a run attribute; `best.x` is the best point in the search space.",
            "",
            "Failed runs (not exported): " + ("; ".join(failed) if failed else "none") + ".",
            "",
        ]
    )


def _replace_dir(staged: Path, final: Path) -> None:
    """Move ``staged`` to ``final``; an existing ``final`` is replaced, never half-kept."""
    if final.exists():
        old = Path(tempfile.mkdtemp(prefix=f".{final.name}.old-", dir=final.parent))
        os.replace(final, old / final.name)
        try:
            os.replace(staged, final)
        except OSError:
            os.replace(old / final.name, final)
            raise
        finally:
            shutil.rmtree(old, ignore_errors=True)
    else:
        os.replace(staged, final)


def export_ioh(
    store: str | os.PathLike,
    outdir: str | os.PathLike,
    *,
    key: str | None = None,
    layout: str = "json",
) -> list[Path]:
    """Write the runs of a store's comparisons in the IOHprofiler format (for IOHanalyzer).

    One folder per comparison, ``<outdir>/<name>-<key[:8]>/``, with one sub-folder per
    optimiser (see the module documentation for the files and how flexid maps onto them)
    and a ``README.md`` naming the reference cost to use as the target.  Every folder is
    built in a temporary folder next to it and renamed into place once complete, and every
    comparison is checked before the first is written, so an error leaves no half-made
    export (an export of the same comparison already there is replaced).

    Parameters
    ----------
    store : path-like
        A result store written by :func:`flexid.compare`.
    outdir : path-like
        Folder that receives the export folders (created).
    key : str, optional
        Only the comparison with this key (a unique prefix).
    layout : {"json", "info"}
        IOHexperimenter's current JSON meta-data, or the older ``.info`` files.

    Returns
    -------
    list of Path
        The comparison folders written.

    Raises
    ------
    ConfigError
        For an unknown layout or a store without comparisons.
    StoreError
        For a missing or unreadable store, or a finished run without a history or without
        its best search point.
    """
    if layout not in IOH_LAYOUTS:
        raise ConfigError(f"IOHprofiler layout must be one of {IOH_LAYOUTS}, got {layout!r}")
    check_histories(store, key)
    results = load_result(store, key)
    if not results:
        raise ConfigError(f"{store}: the store holds no comparison to export")
    plans = []
    for result in results:
        where = f"{store}: comparison {result.spec.name!r} [{result.key[:8]}]"
        per_label = {label: _runs_of(result, label) for label in result.records}
        per_label = {label: runs for label, runs in per_label.items() if runs}
        if not per_label:
            raise StoreError(f"{where}: no finished optimiser run to export")
        dim = _dimension(result, per_label)
        folders = [_name(label) for label in per_label]
        if len(set(folders)) != len(folders):
            raise StoreError(f"{where}: optimiser labels {list(per_label)} collide as folder names")
        plans.append((result, per_label, dim))
    outdir = Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    written = []
    for result, per_label, dim in plans:
        final = outdir / f"{_name(result.spec.name)}-{result.key[:8]}"
        staged = Path(tempfile.mkdtemp(prefix=f".{final.name}.tmp-", dir=outdir))
        try:
            for label, runs in per_label.items():
                folder = staged / _name(label)
                folder.mkdir()
                _write_algorithm(folder, result, label, runs, layout, dim)
            (staged / "README.md").write_text(
                _readme(result, list(per_label), layout, dim), encoding="utf-8"
            )
            _replace_dir(staged, final)
        except BaseException:
            shutil.rmtree(staged, ignore_errors=True)
            raise
        written.append(final)
    return written
