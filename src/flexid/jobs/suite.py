"""A versioned suite of identification problems: COCO's benchmarking, for identification.

A comparison (:func:`flexid.compare`) is one problem: one record, one structure, one cost.
A suite is a fixed, named list of them, so that an optimiser is judged on identification as
a whole, as COCO and IOHprofiler judge one on BBOB:

* **problems**: plants and real records x structures (ARX, OE, BJ, grey-box) x costs
  (one-step, simulation) x instances (data seeds; for the simulated plants also noise
  levels).  Each problem is a :class:`~flexid.config.ComparisonSpec` without its optimisers,
  and carries its groups (``plant``, ``structure``, ``cost``);
* **reference and targets**: each problem's reference is the one its comparison computes
  (least squares where it is the exact optimum, else the gradient reference), once, stored
  with the runs.  Targets are ``reference * (1 + d)`` for the precisions ``d`` of
  :data:`PRECISIONS` (100 down to 1e-4, five to a decade).  A reference that is not at a
  verified local minimum is marked; a run below it reaches every target (news, not an
  error), and :meth:`SuiteResult.table` counts such runs;
* **budget**: ``budget_per_dim`` times the dimension of the search vector the optimisers see;
* **version**: :attr:`Suite.version` hashes every problem's definition (its data, model,
  cost and search specification, and a record file's bytes) with :data:`SUITE_FORMAT`; the
  runs of a version are stored under comparison names ``suite:<suite>@<version>/<problem>``,
  so runs of two versions never mix.  :attr:`SuiteResult.version` adds the references'
  digest: results say which version, and which references, they ran.

Running (:func:`run_suite`) is a comparison per problem into one store, so it is resumable
and every finished run is written at once; the references and runs of every problem share
one pool of worker processes, or one dask task graph.  :func:`load_suite` reads a store back as a
:class:`SuiteResult`: the runtime distribution (the ECDF of (problem, target, run) triples
against FE / dimension) aggregated over the suite or per group, a table per problem, the
ranking, and an IOHprofiler export with one function per problem.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from .._validate import checked_keywords, positive_int
from ..errors import ConfigError, DataError, StoreError, UnknownNameError
from ..models.specs import CostSpec, DataSpec, ModelSpec
from ..models.vocabulary import LEAST_SQUARES
from ._compare import _checked_context, _compare_contexts
from ._comparison_result import ComparisonResult
from .specs import ComparisonSpec, OptimiserSpec
from .statistics import fe_to_target
from .store import ResultStore

__all__ = [
    "GROUPS",
    "PRECISIONS",
    "SETTINGS",
    "SUITE_FORMAT",
    "Suite",
    "SuiteProblem",
    "SuiteResult",
    "SuiteVersionError",
    "get_suite",
    "load_suite",
    "run_suite",
]

#: Changes whenever what a problem's definition means changes (the version hashes it too).
SUITE_FORMAT = 1
#: The suite's name (the IOHprofiler ``suite`` field, and the prefix of its comparisons).
SUITE_NAME = "flexid-sysid"
#: Target precisions ``d`` of the runtime distribution: targets ``reference * (1 + d)``.
PRECISIONS: tuple[float, ...] = tuple(float(d) for d in np.logspace(2, -4, 31))
#: The groups a problem belongs to, by which the ECDF is also drawn.
GROUPS = ("plant", "structure", "cost")
#: The settings: the instances, runs and budget of a suite.
SETTINGS = ("small", "full")
_PREFIX = "suite:"


class SuiteVersionError(ConfigError):
    """A store's runs belong to another version of the suite than the one asked for."""


# ================================================================================ problems
@dataclass(frozen=True)
class SuiteProblem:
    """One problem of a suite: a comparison without its optimisers.

    Attributes
    ----------
    name : str
        ``<plant>/<structure>/<cost>/<instance>``, unique in the suite.
    plant, structure, cost, instance : str
        Its groups (the plant or record, the structure such as ``"oe(8,8,1)"`` reduced to its
        kind ``"oe"``, the predictor of the cost) and its instance (``"seed0"``...).
    spec : ComparisonSpec
        Data, model, cost and search of the problem (its optimisers, runs and budget are the
        suite run's).
    file_sha256 : str or None
        SHA-256 of a record file's bytes when the problem was made (None for a simulated
        plant's record, which its data specification defines).
    """

    name: str
    plant: str
    structure: str
    cost: str
    instance: str
    spec: ComparisonSpec = field(repr=False)
    file_sha256: str | None = None

    @property
    def groups(self) -> dict[str, str]:
        """``{"plant": ..., "structure": ..., "cost": ...}``."""
        return {"plant": self.plant, "structure": self.structure, "cost": self.cost}

    def definition(self) -> dict[str, Any]:
        """What defines the problem, as JSON-safe values (what the version hashes).

        Returns
        -------
        dict
            The name, the groups, the instance, and the data, model, cost, search and bounds
            of its specification; a record file adds the SHA-256 of its bytes.
        """
        d = self.spec.to_dict()
        out = {"name": self.name, "groups": self.groups, "instance": self.instance}
        out.update({k: d[k] for k in ("data", "model", "cost", "search", "bounds") if k in d})
        if self.file_sha256 is not None:
            out["file_sha256"] = self.file_sha256
        return out


def _file_digest(path: Path) -> str:
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError as exc:
        raise DataError(f"{path}: cannot read the record ({exc.strerror or exc})") from None


@dataclass(frozen=True)
class Suite:
    """A named, versioned list of identification problems with its budget and runs.

    Attributes
    ----------
    setting : str
        ``"small"`` or ``"full"`` (:data:`SETTINGS`).
    problems : tuple of SuiteProblem
    budget_per_dim : int
        Function evaluations per dimension of the search vector, per run.
    runs : int
        Runs of each optimiser on each problem (seeds ``0 .. runs - 1``).
    """

    setting: str
    problems: tuple[SuiteProblem, ...]
    budget_per_dim: int
    runs: int

    @cached_property
    def version(self) -> str:
        """Digest (12 hex digits) of :data:`SUITE_FORMAT` and every problem's definition."""
        text = json.dumps(
            {"format": SUITE_FORMAT, "problems": [p.definition() for p in self.problems]},
            sort_keys=True,
            allow_nan=False,
        )
        return hashlib.sha256(text.encode()).hexdigest()[:12]

    @property
    def label(self) -> str:
        """``flexid-sysid-<setting>``: the suite's name."""
        return f"{SUITE_NAME}-{self.setting}"

    def comparison_name(self, problem: SuiteProblem) -> str:
        """The name the runs of ``problem`` are stored under (version included).

        Parameters
        ----------
        problem : SuiteProblem

        Returns
        -------
        str
            ``suite:<label>@<version>/<problem name>``.
        """
        return f"{_PREFIX}{self.label}@{self.version}/{problem.name}"

    def subset(self, names: Iterable[str] | None) -> Suite:
        """The problems named, or in a group named (``"oe"``, ``"twin-rotor"``, ...).

        The version stays the whole suite's: a subset's runs are the suite's runs of those
        problems.

        Parameters
        ----------
        names : iterable of str, optional
            Problem names (or unique prefixes of them) and group values; None: all.

        Returns
        -------
        Suite

        Raises
        ------
        UnknownNameError
            For a name that is neither a problem, a prefix of one, nor a group value.
        """
        if names is None:
            return self
        names = [names] if isinstance(names, str) else list(names)
        chosen: list[SuiteProblem] = []
        for name in names:
            found = [
                p
                for p in self.problems
                if p.name == name or p.name.startswith(f"{name}/") or name in p.groups.values()
            ]
            if not found:
                groups = sorted({v for p in self.problems for v in p.groups.values()})
                raise UnknownNameError(f"problem or group of suite {self.label}", name, groups)
            chosen += [p for p in found if p not in chosen]
        out = replace(self, problems=tuple(chosen))
        out.__dict__["version"] = self.version
        return out


def _problem(
    plant: str, model: ModelSpec, predictor: str, data: DataSpec, instance: str
) -> SuiteProblem:
    kind = model.structure
    if kind == "greybox":
        shape = model.greybox
    elif kind == "ss":  # its order and modes
        shape = f"ss({model.options['order']},{model.options.get('modes', '')})".replace(",)", ")")
    else:
        orders = [v for v in (model.na, model.nb, model.nc, model.nd, model.nf, model.nk)
                  if v is not None and v != 0]  # fmt: skip
        shape = f"{kind}({','.join(str(v) for v in orders)})"
    name = f"{plant}/{shape}/{predictor}/{instance}"
    spec = ComparisonSpec(
        name=name,
        data=data,
        model=model,
        cost=CostSpec(predictor=predictor),
        optimisers=(OptimiserSpec("random-search"),),
    )
    return SuiteProblem(name, plant, kind, predictor, instance, spec)


#: The simulated plants' models in a suite: (plant, model, predictor of the cost, what its
#: record has beyond the plant's own).  The state-space models take several sensors at once:
#: the manipulator's hub angle and end-point acceleration (order 16: its four flexible modes
#: among 7, the rigid body and the hub friction as 2 real poles), the twin rotor's pitch and
#: yaw driven by both rotors (its yaw free: the plant's default record, means removed).
_PLANT_MODELS = (
    ("manipulator", ModelSpec(na=8, nb=8, nk=1), "one-step", {}),
    ("manipulator", ModelSpec(na=8, nb=8, nk=1), "simulation", {}),
    ("manipulator", ModelSpec(structure="oe", nb=8, nf=8, nk=1), "simulation", {}),
    ("manipulator", ModelSpec(structure="bj", nb=8, nc=2, nd=2, nf=8, nk=1), "one-step", {}),
    ("manipulator", ModelSpec(structure="ss", options={"order": 16, "modes": 7}), "simulation",
     {"outputs": ["hub_angle", "tip_acceleration"]}),
    ("twin-rotor", ModelSpec(na=5, nb=5, nk=1), "one-step", {}),
    ("twin-rotor", ModelSpec(structure="oe", nb=4, nf=4, nk=1), "simulation", {}),
    ("twin-rotor", ModelSpec(structure="greybox", greybox="twin-rotor-pitch"), "simulation", {}),
    ("twin-rotor", ModelSpec(structure="ss", options={"order": 6, "modes": 1}), "simulation",
     {"preset": None, "outputs": ["pitch", "yaw"], "detrend": True}),
)  # fmt: skip
#: Each plant's record: its lab preset (the twin rotor's cut to 3,000 samples, 5 minutes).
_PLANT_DATA = {
    "manipulator": {"plant": "manipulator", "preset": "paper-manipulator"},
    "twin-rotor": {"plant": "twin-rotor", "preset": "paper-twin-rotor", "n_samples": 3000},
}


def _plant_problems(seeds: Sequence[int], noise: Sequence[Any]) -> list[SuiteProblem]:
    """The simulated plants' problems: their lab presets, each seed and noise level."""
    out = []
    for seed in seeds:
        for level in noise:
            instance = f"seed{seed}" + ("" if level is None else f"-noise{level}")
            for plant, model, predictor, record in _PLANT_MODELS:
                data = DataSpec(**{**_PLANT_DATA[plant], **record}, seed=seed, noise_std=level)
                out.append(_problem(plant, model, predictor, data, instance))
    return out


#: Real records a suite can read from a folder (``records``): file name, columns, models.
_RECORDS = {
    "robot-arm": (
        "robot_arm.csv",
        {"inputs": ["u"], "outputs": ["y"]},
        [(ModelSpec(na=8, nb=8, nk=1), "one-step"),
         (ModelSpec(structure="oe", nb=8, nf=8, nk=1), "simulation")],
    ),
}  # fmt: skip


def _record_problems(records: str | os.PathLike) -> list[SuiteProblem]:
    folder = Path(records)
    if not folder.is_dir():
        raise DataError(f"records: {folder} is not a folder of records")
    out = []
    for plant, (file, columns, models) in _RECORDS.items():
        path = folder / file
        if not path.exists():
            continue
        data = DataSpec(file=str(path.resolve()), **columns)
        digest = _file_digest(path)
        out += [
            replace(_problem(plant, model, predictor, data, "record"), file_sha256=digest)
            for model, predictor in models
        ]
    if not out:
        raise DataError(
            f"records: {folder} holds none of the suite's records "
            f"({', '.join(f for f, _, _ in _RECORDS.values())})"
        )
    return out


@checked_keywords
def get_suite(setting: str = "small", *, records: str | os.PathLike | None = None) -> Suite:
    """The suite of a setting.

    ``"small"``: the manipulator (ARX(8,8,1) one-step and simulation, OE(8,8,1), BJ(8,2,2,8,1),
    and a state-space model of order 16 of its hub angle and end-point acceleration) and the
    twin rotor (ARX(5,5,1), OE(4,4,1), the pitch grey-box model, and a state-space model of
    order 6 of its pitch and yaw) of their lab presets, data seeds 0 and 1, 3 runs at 500 FE
    per dimension.  ``"full"``: data seeds 0-4, each at
    the preset's noise and at 5 %, 5 runs at 2,000 FE per dimension.

    Parameters
    ----------
    setting : {"small", "full"}
    records : path-like, optional
        A folder with real records (``robot_arm.csv``, DaISy 96-009): their problems join.

    Returns
    -------
    Suite

    Raises
    ------
    UnknownNameError
        For another setting.
    DataError
        When ``records`` is not a folder or holds none of the suite's records.
    """
    if setting not in SETTINGS:
        raise UnknownNameError("suite setting", setting, SETTINGS)
    if setting == "small":
        problems = _plant_problems(seeds=(0, 1), noise=(None,))
        budget_per_dim, runs = 500, 3
    else:
        problems = _plant_problems(seeds=range(5), noise=(None, "5%"))
        budget_per_dim, runs = 2000, 5
    if records is not None:
        problems += _record_problems(records)
    return Suite(setting, tuple(problems), budget_per_dim, runs)


# ================================================================================ running
@checked_keywords
def run_suite(
    suite: Suite,
    optimisers: Sequence[str | OptimiserSpec],
    *,
    store: str | os.PathLike | ResultStore,
    workers: int = 1,
    scheduler: str | Any | None = None,
    progress: bool | Callable[[dict], Any] = False,
) -> SuiteResult:
    """Run (or resume) optimisers on every problem of a suite, into one store.

    Each problem is a :func:`flexid.compare` of the optimisers with the suite's runs and a
    budget of ``budget_per_dim`` times its dimension: the same data, initial populations and
    budgets for every optimiser, every finished run written at once, runs already in the
    store skipped.  The tasks of every problem (its reference, then its runs) share one pool
    of ``workers`` processes or one dask task graph, so the workers stay busy across
    problems.  Every problem is checked (its record built, its optimisers known) before the
    store is opened.

    Parameters
    ----------
    suite : Suite
        From :func:`get_suite` (or a :meth:`Suite.subset`).
    optimisers : sequence of str or OptimiserSpec
        Registered names (plugins and ``ng:``/``pymoo:`` adapters included).
    store : path-like or ResultStore
        The SQLite store of the results.
    workers : int
        Worker processes for the whole suite (the numbers do not depend on it).
    scheduler : str or distributed.Client, optional
        A dask scheduler (address or client) to run on instead.
    progress : bool or callable
        Show a progress bar over the suite's runs (``True``), or call ``progress(record)``
        after each finished run.

    Returns
    -------
    SuiteResult
        The results of the problems run (:func:`load_suite` of the store and the suite).

    Raises
    ------
    ConfigError, UnknownOptimiserError, HyperParameterError, DataError
        Before anything is written, for an empty or unknown optimiser, or a problem that
        cannot run.
    """
    if isinstance(optimisers, (str, OptimiserSpec)):
        optimisers = [optimisers]
    specs = [o if isinstance(o, OptimiserSpec) else OptimiserSpec(o) for o in optimisers or []]
    if not specs:
        raise ConfigError("run_suite: give at least one optimiser")
    workers = positive_int(workers, "workers", error=ConfigError)
    contexts = []
    for problem in suite.problems:
        ctx = _checked_context(replace(problem.spec, optimisers=tuple(specs), runs=suite.runs))
        dim = int(ctx.estimation.problem.dim)
        contexts.append(ctx.respecified(name=suite.comparison_name(problem),
                                        budget=suite.budget_per_dim * dim))  # fmt: skip
    _compare_contexts(contexts, store=store, workers=workers, scheduler=scheduler,
                      progress=progress, title=suite.label)  # fmt: skip
    return load_suite(store, suite)


# ================================================================================ results
@dataclass
class SuiteResult:
    """A suite's runs read back from a store.

    Attributes
    ----------
    suite : Suite
    results : dict
        Problem name -> :class:`~flexid.ComparisonResult` (the problems with runs).
    dims : dict
        Problem name -> dimension of its search vector.
    """

    suite: Suite
    results: dict[str, ComparisonResult]
    dims: dict[str, int]

    @property
    def labels(self) -> list[str]:
        """The optimisers, in the order of the first problem's comparison."""
        out: list[str] = []
        for result in self.results.values():
            out += [label for label in result.records if label not in out]
        return out

    @property
    def version(self) -> str:
        """``<suite version>+<references' digest>``: the definitions and the references run."""
        refs = {name: _significant(r.reference_cost) for name, r in sorted(self.results.items())}
        digest = hashlib.sha256(json.dumps(refs, sort_keys=True).encode()).hexdigest()[:8]
        return f"{self.suite.version}+{digest}"

    def verified(self, name: str) -> bool:
        """Whether a problem's reference is at a verified local minimum.

        Parameters
        ----------
        name : str
            A problem name.

        Returns
        -------
        bool
            True for least squares on the one-step cost of ARX (its exact optimum) and for a
            gradient reference that measured first-order optimality off the pole-radius cap.
        """
        result = self.results[name]
        ref = result.reference
        oe = ref.get("output_error") or {}
        if oe and oe.get("cost") == result.reference_cost:
            return bool(oe.get("local_minimum")) and not oe.get("on_cap")
        return result.spec.model.structure == "arx" and result.spec.cost.predictor == "one-step"

    def runtimes(
        self, label: str, group: Mapping[str, str] | None = None
    ) -> tuple[np.ndarray, int]:
        """FE / dimension at which each (problem, target, run) triple was reached.

        Parameters
        ----------
        label : str
            An optimiser.
        group : mapping, optional
            Only the problems with these group values (``{"structure": "oe"}``).

        Returns
        -------
        runtimes : ndarray, shape (M,)
            FE / dimension of the reached triples (every triple with a finished run).
        total : int
            Number of triples (reached or not): the ECDF's denominator.
        """
        reached: list[float] = []
        total = 0
        for problem in self.suite.problems:
            if problem.name not in self.results:
                continue
            if group and any(problem.groups[k] != v for k, v in group.items()):
                continue
            result = self.results[problem.name]
            dim = self.dims[problem.name]
            targets = result.reference_cost * (1.0 + np.asarray(PRECISIONS))
            for r in result.records.get(label, []):
                total += len(targets)
                if r["status"] != "ok" or not r.get("history"):
                    continue
                fe = np.array([fe_to_target(r["history"], t) for t in targets])
                reached += (fe[np.isfinite(fe)] / dim).tolist()
        return np.asarray(reached), total

    def ecdf(self, group: Mapping[str, str] | None = None) -> dict[str, dict[str, Any]]:
        """The runtime distribution of each optimiser (COCO's aggregated ECDF).

        Parameters
        ----------
        group : mapping, optional
            Only the problems of a group (``{"plant": "twin-rotor"}``).

        Returns
        -------
        dict
            ``label -> {"x": ndarray (K,), "fraction": ndarray (K,), "triples": int,
            "area": float}``: ``x`` the FE / dimension at which the fraction of (problem,
            target, run) triples reached steps up, ``area`` the area under the ECDF over
            ``log10(FE / dim)`` from 0 to ``log10(budget_per_dim)``, divided by that width
            (1 is every target at the first evaluation).
        """
        out = {}
        width = math.log10(self.suite.budget_per_dim)
        for label in self.labels:
            times, total = self.runtimes(label, group)
            x = np.sort(times)
            fraction = np.arange(1, x.size + 1) / total if total else np.zeros(0)
            logs = np.clip(np.log10(np.maximum(x, 1e-300)), 0.0, width)
            area = float(np.sum(width - logs) / (total * width)) if total and width > 0 else 0.0
            out[label] = {"x": x, "fraction": fraction, "triples": total, "area": area}
        return out

    def table(self) -> list[dict[str, Any]]:
        """One row per problem and optimiser.

        Returns
        -------
        list of dict
            ``problem``, ``dim``, ``reference`` (cost), ``verified`` (bool), ``label``,
            ``median`` (median final cost over the reference), ``solved`` (runs within
            1e-3 of the reference, of ``runs``), ``below`` (runs that end below the reference
            by more than 1e-9 of it), ``runs``.
        """
        rows = []
        for name, result in self.results.items():
            ref = result.reference_cost
            for label, records in result.records.items():
                costs = np.array([r["cost"] for r in records if r["status"] == "ok"], float)
                rows.append({
                    "problem": name,
                    "dim": self.dims[name],
                    "reference": ref,
                    "verified": self.verified(name),
                    "label": label,
                    "median": float(np.median(costs) / ref) if costs.size else math.nan,
                    "solved": int(np.sum(costs <= ref * (1 + 1e-3))),
                    "below": int(np.sum(costs < ref * (1 - 1e-9))),
                    "runs": len(records),
                })  # fmt: skip
        return rows

    def ranking(self) -> list[dict[str, Any]]:
        """Optimisers ranked by their mean rank over the problems (median final cost).

        Each problem that every optimiser finished runs on ranks them by their median final
        cost (ties share the mean rank); the best mean rank is compared with every other
        optimiser by a Wilcoxon signed-rank test over the problems (paired by problem),
        Holm-corrected.

        Returns
        -------
        list of dict
            Best first: ``label``, ``mean_rank``, ``problems`` (how many were ranked),
            ``area`` (of the aggregated ECDF), ``p_holm`` (NaN for the first, and where fewer
            than two problems differ), ``significant`` (at 5 %).
        """
        from scipy import stats

        labels = self.labels
        medians = np.array([
            [_median_cost(result, label) for label in labels]
            for result in self.results.values()
        ]).reshape(-1, len(labels))  # fmt: skip
        medians = medians[np.isfinite(medians).all(axis=1)]  # problems every optimiser ran
        if medians.size == 0:
            return []
        ranks = np.array([stats.rankdata(np.where(np.isfinite(m), m, np.inf)) for m in medians])
        mean = ranks.mean(axis=0)
        order = np.argsort(mean, kind="stable")
        area = {label: v["area"] for label, v in self.ecdf().items()}
        best = order[0]
        p_raw = []
        for j in order[1:]:
            diff = medians[:, j] - medians[:, best]
            diff = diff[np.isfinite(diff) & (diff != 0)]
            p_raw.append(stats.wilcoxon(diff).pvalue if diff.size >= 2 else math.nan)
        p_holm = _holm(p_raw)
        rows = [{"label": labels[best], "mean_rank": float(mean[best]), "p_holm": math.nan}]
        rows += [
            {"label": labels[j], "mean_rank": float(mean[j]), "p_holm": float(p)}
            for j, p in zip(order[1:], p_holm)
        ]
        for row in rows:
            row["problems"] = int(medians.shape[0])
            row["area"] = area.get(row["label"], math.nan)
            row["significant"] = bool(row["p_holm"] < 0.05)
        return rows

    def export_ioh(self, outdir: str | os.PathLike) -> Path:
        """Write the runs in the IOHprofiler format, one function per problem.

        One folder per optimiser under ``<outdir>/<suite label>-<version>/``, each with one
        ``IOHprofiler_f<i>_<problem>.json`` and its data per problem: ``i`` is the problem's
        place in the whole suite (1-based, the same in every subset), its name the problem's
        name made file-safe, its dimension the search vector's (the layout of
        :func:`flexid.report.export_ioh`, which IOHanalyzer and ``iohinspector`` read).  The
        folder is built next to its place and renamed into it once complete.

        Parameters
        ----------
        outdir : path-like
            Folder that receives the export (created).

        Returns
        -------
        pathlib.Path
            The export folder.

        Raises
        ------
        StoreError
            When no problem has a finished run.
        """
        import shutil
        import tempfile

        from ._ioh import _name, _replace_dir, _runs_of, _write_algorithm

        ids = {p.name: i + 1 for i, p in enumerate(get_suite(self.suite.setting).problems)}
        ids.update({p.name: len(ids) + i + 1 for i, p in enumerate(self.suite.problems)
                    if p.name not in ids})  # fmt: skip
        outdir = Path(outdir)
        outdir.mkdir(parents=True, exist_ok=True)
        final = outdir / f"{self.suite.label}-{self.suite.version}"
        staged = Path(tempfile.mkdtemp(prefix=f".{final.name}.tmp-", dir=outdir))
        written = 0
        try:
            for name, result in self.results.items():
                for label in result.records:
                    runs = _runs_of(result, label)
                    if not runs:
                        continue
                    folder = staged / _name(label)
                    folder.mkdir(exist_ok=True)
                    _write_algorithm(
                        folder, result, label, runs, "json", self.dims[name],
                        function_id=ids[name], function_name=name, suite=self.suite.label,
                    )  # fmt: skip
                    written += 1
            if not written:
                raise StoreError("no finished run of the suite to export")
            _replace_dir(staged, final)
        except BaseException:
            shutil.rmtree(staged, ignore_errors=True)
            raise
        return final

    def summary(self) -> str:
        """A plain-text account: the suite, the ranking and the problems with marked
        references.

        Returns
        -------
        str
        """
        lines = [
            f"Suite {self.suite.label}, version {self.version} "
            f"({len(self.results)} of {len(self.suite.problems)} problems with runs; "
            f"{self.suite.runs} runs of {self.suite.budget_per_dim} FE per dimension)",
            "",
        ]
        ranking = self.ranking()
        if ranking:
            lines.append(
                f"Ranked over the {ranking[0]['problems']} problem(s) every optimiser ran "
                "(median final cost; Wilcoxon signed-rank against the first, Holm)"
            )
        lines.append(f"{'optimiser':<16} {'mean rank':>9} {'ECDF area':>9} {'p (Holm)':>9}")
        for row in ranking:
            p = "" if math.isnan(row["p_holm"]) else f"{row['p_holm']:.3g}"
            lines.append(f"{row['label']:<16} {row['mean_rank']:>9.2f} {row['area']:>9.3f} {p:>9}")
        unverified = [n for n in self.results if not self.verified(n)]
        if unverified:
            lines += ["", "References not at a verified local minimum (runs below them are "
                      "news): " + ", ".join(unverified)]  # fmt: skip
        return "\n".join(lines)


def _median_cost(result: ComparisonResult, label: str) -> float:
    costs = [r["cost"] for r in result.records.get(label, []) if r["status"] == "ok"]
    return float(np.median(costs)) if costs else math.nan


def _holm(p: Sequence[float]) -> list[float]:
    """Holm's step-down adjustment (NaN stays NaN and is not counted)."""
    p = np.asarray(p, float)
    out = np.full(p.shape, np.nan)
    ok = np.flatnonzero(np.isfinite(p))
    order = ok[np.argsort(p[ok], kind="stable")]
    running = 0.0
    for i, j in enumerate(order):
        running = max(running, min(1.0, (len(order) - i) * p[j]))
        out[j] = running
    return out.tolist()


def _significant(value: float) -> str:
    """A reference cost to 8 significant digits: what the results' version hashes (the last
    bits differ between machines, the digits do not)."""
    return f"{value:.8g}" if math.isfinite(value) else str(value)


@checked_keywords
def load_suite(store: str | os.PathLike | ResultStore, suite: Suite) -> SuiteResult:
    """A suite's runs read from a store.

    Parameters
    ----------
    store : path-like or ResultStore
        A store written by :func:`run_suite`.
    suite : Suite
        The suite (or subset) to read.

    Returns
    -------
    SuiteResult
        The problems of ``suite`` with runs in the store.

    Raises
    ------
    SuiteVersionError
        When the store holds runs of this suite's setting but only under other versions.
    StoreError
        For a missing or unreadable store.
    """
    if not isinstance(store, ResultStore) and not Path(store).exists():
        raise StoreError(f"{store}: no such result store")
    db = store if isinstance(store, ResultStore) else ResultStore(store, readonly=True)
    try:
        entries = db.comparisons()
        wanted = {suite.comparison_name(p): p for p in suite.problems}
        found = [e for e in entries if e["name"] in wanted]
        if not found:
            _refuse_other_versions(db, entries, suite)
        results, dims = {}, {}
        for entry in found:
            read = _problem_result(db, entry, suite)
            if read is not None:
                name = wanted[entry["name"]].name
                results[name], dims[name] = read
    finally:
        if db is not store:
            db.close()
    order = [p.name for p in suite.problems if p.name in results]
    return SuiteResult(suite, {n: results[n] for n in order}, {n: dims[n] for n in order})


def _refuse_other_versions(db: ResultStore, entries: list[dict], suite: Suite) -> None:
    """Raise SuiteVersionError when the store holds other versions of the suite."""
    mine = f"{_PREFIX}{suite.label}@"
    others = sorted({e["name"][len(mine):].split("/")[0] for e in entries
                     if e["name"].startswith(mine)})  # fmt: skip
    if others:
        raise SuiteVersionError(
            f"{db.path}: the store holds suite {suite.label} version(s) {', '.join(others)}, "
            f"not {suite.version} (the problems' definitions changed); run the suite again "
            "into another store"
        )


def _problem_result(
    db: ResultStore, entry: Mapping[str, Any], suite: Suite
) -> tuple[ComparisonResult, int] | None:
    """A stored problem's result and dimension; None when it ran at another budget per
    dimension (another experiment on the problem)."""
    records = db.runs(entry["key"])
    dim = _dimension_of(records, entry["key"])
    spec = ComparisonSpec.from_dict(entry["spec"])
    if spec.budget != suite.budget_per_dim * dim:
        return None
    # every optimiser ever run on the problem, not only the last run's list
    labels: dict[str, OptimiserSpec] = {}
    for r in records:
        if r["label"] != LEAST_SQUARES and r["label"] not in labels:
            label = None if r["label"] == r["optimiser"] else r["label"]
            labels[r["label"]] = OptimiserSpec(r["optimiser"], dict(r["params"]), label)
    spec = replace(spec, optimisers=tuple(labels.values()), runs=suite.runs)
    return ComparisonResult.from_records(spec, entry["key"], records), dim


def _dimension_of(records: Sequence[Mapping[str, Any]], key: str) -> int:
    """The search dimension of a stored comparison (the length of its runs' best points)."""
    for r in records:
        if r.get("x") is not None:
            return len(r["x"])
    raise StoreError(f"comparison {key[:8]}: no run stores its search point")
