"""flexid's optimisers and the reference implementations on the BBOB suite (IOHexperimenter).

Run from the repository (needs the ``dev`` extra: ``ioh``, ``cma``, ``nevergrad``)::

    .venv/bin/python benchmarks/bbob.py --quick                   # a few functions, d = 5
    .venv/bin/python benchmarks/bbob.py --optimisers lshade,de    # f1-f24, i1-3, d = 5, 20
    .venv/bin/python benchmarks/bbob.py --optimisers builtins --results /tmp/bbob.jsonl \
        --ioh-dir /tmp/bbob-ioh --against pycma-bipop,ng-NGOpt

Every run gets ``--budget-per-dim`` x d FE (default 1,000 d) on ``ioh.get_problem(fid,
instance, d, BBOB)`` over its box [-5, 5]^d and every evaluation goes through the ioh
problem (so the IOHprofiler logger sees them all).  Budgets are exact: flexid's driver cuts
the last batch; the peers evaluate through :class:`Counted`, which raises once the budget
is spent, so their last population is cut where flexid's is.  The run's seed is the instance
number for every optimiser.  The peers, each with its library's defaults:

* ``pycma-bipop``: ``cma.fmin2`` with ``restarts=9, bipop=True``, bounds [-5, 5],
  ``sigma0`` = 3 (0.3 of the side, like flexid's), ``x0`` uniform in the box at every
  restart;
* ``scipy-de``: ``scipy.optimize.differential_evolution`` (best1bin, popsize 15, Latin
  hypercube start, polish), ``maxiter`` large so that only the budget stops it;
* ``ng-<name>``: any optimiser of nevergrad's registry (``ng-TwoPointsDE``, ``ng-NGOpt``)
  on ``ng.p.Array(lower=-5, upper=5)`` with ``budget`` = the FE budget.

Reported per dimension and optimiser (a markdown table): the median over the (function,
instance) runs of ``log10(f_best - f_opt)`` with the error floored at 1e-8 (the "solved"
target: pycma stops a run at ``tolfun`` 1e-11, so smaller errors only measure stop rules),
the number of problems solved to 1e-8, and head to head against each ``--against`` peer
(win / tie / loss; a tie is both errors below 1e-8 or within a factor 10 of each other).

``--results FILE`` keeps one JSON line per run and skips the runs already in it, so a long
run can be resumed and tables of several invocations combined (``--table-only``).
``--ioh-dir DIR`` writes the IOHprofiler format (``ioh.logger.Analyzer``, one folder per
optimiser) for the runs made in this invocation; IOHanalyzer loads these folders (zipped)
beside the published BBOB data, and ``iohinspector`` reads them back (``--check-ioh``).
"""

from __future__ import annotations

import argparse
import json
import time
import warnings
from pathlib import Path

import numpy as np

from flexid.optimisers import Problem, available, get, minimize

PEERS = ("pycma-bipop", "scipy-de", "ng-TwoPointsDE", "ng-NGOpt")
QUICK = (1, 2, 8, 10, 15, 20)
SOLVED = 1e-8
HALF = 5.0  # the BBOB box is [-5, 5]^d


def builtins() -> list[str]:
    """flexid's own algorithms, without the paper-setting variants (``*-paper-*``) and
    ``scipy``, whose default method is ``nelder-mead``'s."""
    out = []
    for name in available():
        cls = get(name)
        module = cls.__module__
        if module.startswith("flexid.optimisers") and module != "flexid.optimisers.external":
            if "-paper-" not in name and name != "scipy":
                out.append(name)
    return out


class _Spent(Exception):
    """Raised inside a peer's objective once the budget is spent."""


class Counted:
    """A BBOB problem that counts evaluations, keeps the best and times itself.

    Parameters
    ----------
    problem : ioh problem
        ``ioh.get_problem(fid, instance, dim, ioh.ProblemClass.BBOB)``.
    budget : int
        FE allowed; evaluation ``budget + 1`` raises :class:`_Spent`.

    Attributes
    ----------
    nfev : int
        Evaluations so far.
    outside : int
        Evaluations of points outside the box [-5, 5]^d.
    best : float
        The lowest cost seen.
    seconds : float
        Time spent inside the objective.
    """

    def __init__(self, problem, budget: int) -> None:
        self.problem = problem
        self.budget = budget
        self.f_opt = float(problem.optimum.y)
        self.nfev = 0
        self.outside = 0
        self.best = np.inf
        self.seconds = 0.0

    def batch(self, X: np.ndarray) -> np.ndarray:
        """Costs of the rows of ``X`` (shape (P, d)) -> shape (P,); never beyond the budget."""
        X = np.asarray(X, dtype=float)
        room = self.budget - self.nfev
        if room <= 0:
            raise _Spent
        X = X[:room]
        t = time.perf_counter()
        F = np.asarray(self.problem(X), dtype=float).reshape(-1)
        self.seconds += time.perf_counter() - t
        self.nfev += F.size
        self.outside += int(np.sum(np.any(np.abs(X) > HALF, axis=1)))
        self.best = min(self.best, float(F.min()))
        return F

    def single(self, x: np.ndarray) -> float:
        """Cost of one point (the peers' interface); raises once the budget is spent."""
        return float(self.batch(np.asarray(x, dtype=float).reshape(1, -1))[0])

    @property
    def error(self) -> float:
        """``f_best - f_opt``."""
        return self.best - self.f_opt


def _run_peer(name: str, counted: Counted, dim: int, budget: int, seed: int) -> None:
    lo, hi = -HALF * np.ones(dim), HALF * np.ones(dim)
    if name == "pycma-bipop":
        import cma

        rng = np.random.default_rng(seed)
        options = {"bounds": [-HALF, HALF], "maxfevals": budget, "verbose": -9, "seed": seed}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            cma.fmin2(
                counted.single,
                lambda: rng.uniform(-HALF, HALF, dim),
                0.3 * 2 * HALF,
                options,
                restarts=9,
                bipop=True,
            )
    elif name == "scipy-de":
        from scipy.optimize import differential_evolution

        differential_evolution(counted.single, list(zip(lo, hi)), maxiter=10**9, tol=0, seed=seed)
    elif name.startswith("ng-"):
        import nevergrad as ng

        param = ng.p.Array(shape=(dim,), lower=lo, upper=hi)
        param.random_state = np.random.RandomState(seed)  # nevergrad draws from a RandomState
        opt = ng.optimizers.registry[name[3:]](parametrization=param, budget=budget)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            opt.minimize(counted.single)
    else:
        raise ValueError(f"unknown peer {name!r}; peers: {', '.join(PEERS)}")


def run_one(
    name: str,
    fid: int,
    instance: int,
    dim: int,
    budget: int,
    logger=None,
    seed: int | None = None,
) -> dict:
    """One run of optimiser or peer ``name`` on BBOB ``fid`` (instance, dimension).

    Parameters
    ----------
    name : str
        A registered flexid optimiser or a peer (:data:`PEERS`, or ``ng-<any>``).
    fid, instance, dim : int
        The BBOB problem.
    budget : int
        FE budget.
    logger : ioh logger, optional
        Attached to the problem for this run (IOHprofiler data).
    seed : int, optional
        The run's seed (default: the instance number).

    Returns
    -------
    dict
        ``optimiser, fid, instance, dim, budget, error, nfev, outside, overhead`` (s: wall
        time minus the time inside the objective).
    """
    import ioh

    problem = ioh.get_problem(fid, instance, dim, ioh.ProblemClass.BBOB)
    if logger is not None:
        problem.attach_logger(logger)
    counted = Counted(problem, budget)
    t = time.perf_counter()
    try:
        if name in PEERS or name.startswith(("ng-", "pycma", "scipy")):
            _run_peer(name, counted, dim, budget, instance if seed is None else seed)
        else:
            box = Problem(counted.batch, -HALF * np.ones(dim), HALF * np.ones(dim))
            minimize(name, box, budget, seed=instance if seed is None else seed)
    except _Spent:
        pass
    wall = time.perf_counter() - t
    if logger is not None:
        problem.reset()
        problem.detach_logger()
    return {
        "optimiser": name,
        "fid": fid,
        "instance": instance,
        "dim": dim,
        "budget": budget,
        "error": counted.error,
        "nfev": counted.nfev,
        "outside": counted.outside,
        "overhead": wall - counted.seconds,
    }


# ------------------------------------------------------------------------------- summary
def log_error(error: float) -> float:
    """``log10`` of the error floored at :data:`SOLVED`."""
    return float(np.log10(max(error, SOLVED)))


def head_to_head(mine: dict, ref: dict) -> tuple[int, int, int]:
    """Wins, ties and losses of ``mine`` against ``ref`` over their common problems.

    Parameters
    ----------
    mine, ref : dict
        ``{(fid, instance): error}``.

    Returns
    -------
    tuple of int
        A tie is both errors below :data:`SOLVED` or within a factor 10 of each other (after
        flooring at :data:`SOLVED`); otherwise the lower error wins.
    """
    w = t = lo = 0
    for key in sorted(set(mine) & set(ref)):
        a, b = max(mine[key], SOLVED), max(ref[key], SOLVED)
        if (mine[key] < SOLVED and ref[key] < SOLVED) or max(a, b) <= 10 * min(a, b):
            t += 1
        elif a < b:
            w += 1
        else:
            lo += 1
    return w, t, lo


def summary_rows(records: list[dict], dim: int, names: list[str], against: list[str]) -> list[dict]:
    """Median log10 error, solved, W/T/L against each peer, overhead and the fraction of
    evaluations outside the box, per optimiser."""
    err: dict[str, dict] = {}
    over: dict[str, list[float]] = {}
    fe: dict[str, int] = {}
    out: dict[str, int] = {}
    for r in records:
        if r["dim"] != dim:
            continue
        err.setdefault(r["optimiser"], {})[r["fid"], r["instance"]] = r["error"]
        over.setdefault(r["optimiser"], []).append(r["overhead"])
        fe[r["optimiser"]] = fe.get(r["optimiser"], 0) + r["nfev"]
        out[r["optimiser"]] = out.get(r["optimiser"], 0) + r["outside"]
    rows = []
    for name in names:
        if name not in err:
            continue
        e = np.array(list(err[name].values()))
        row = {
            "optimiser": name,
            "median": float(np.median([log_error(x) for x in e])),
            "solved": int(np.sum(e < SOLVED)),
            "runs": int(e.size),
            "ms_per_1000": 1e6 * sum(over[name]) / max(fe[name], 1),
            "outside": out[name] / max(fe[name], 1),
        }
        for peer in against:
            row[peer] = head_to_head(err[name], err[peer]) if peer in err and peer != name else None
        rows.append(row)
    return rows


def markdown_table(
    rows: list[dict], against: list[str], overhead: bool = False, outside: bool = False
) -> str:
    """The rows of :func:`summary_rows` as a markdown table."""
    head = ["optimiser", "median log10(f - f_opt)", "solved to 1e-8"]
    head += [f"W/T/L vs {p}" for p in against]
    if overhead:
        head.append("overhead ms / 1,000 FE")
    if outside:
        head.append("FE outside the box")
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        cells = [f"`{r['optimiser']}`", f"{r['median']:.2f}", f"{r['solved']}/{r['runs']}"]
        cells += ["-" if r[p] is None else "/".join(map(str, r[p])) for p in against]
        if overhead:
            cells.append(f"{r['ms_per_1000']:.1f}")
        if outside:
            cells.append(f"{100 * r['outside']:.0f} %")
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def load(path: Path | None) -> list[dict]:
    """The records of a results file (one JSON object per line); [] without one."""
    if path is None or not path.exists():
        return []
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


def check_ioh(folder: Path) -> str:
    """Read an IOHprofiler folder back with iohinspector; a one-line description."""
    import iohinspector

    manager = iohinspector.DataManager()
    manager.add_folder(str(folder))
    data = manager.load(monotonic=True, include_meta_data=True)
    return (
        f"{folder}: iohinspector read {data.height} rows, "
        f"{manager.overview.height} runs of {sorted(set(manager.overview['algorithm_name']))}"
    )


def run_suite(
    names: list[str],
    fids: list[int],
    instances: list[int],
    dims: list[int],
    budget_per_dim: int,
    results: Path | None = None,
    ioh_dir: Path | None = None,
    verbose: bool = True,
    seed: int | None = None,
) -> list[dict]:
    """Run every optimiser on every problem (skipping runs already in ``results``).

    ``seed`` is every run's seed (default: the instance number, see :func:`run_one`).

    Returns
    -------
    list of dict
        Every record (those loaded and the new ones), see :func:`run_one`.
    """
    import ioh

    records = load(results)
    done = {(r["optimiser"], r["fid"], r["instance"], r["dim"], r["budget"]) for r in records}
    loggers = {}
    try:
        for dim in dims:
            budget = budget_per_dim * dim
            for name in names:
                for fid in fids:
                    for inst in instances:
                        if (name, fid, inst, dim, budget) in done:
                            continue
                        logger = None
                        if ioh_dir is not None:
                            if name not in loggers:
                                loggers[name] = ioh.logger.Analyzer(
                                    root=str(ioh_dir),
                                    folder_name=name,
                                    algorithm_name=name,
                                    algorithm_info=f"flexid benchmarks/bbob.py, "
                                    f"{budget_per_dim} x d FE",
                                )
                            logger = loggers[name]
                        rec = run_one(name, fid, inst, dim, budget, logger, seed)
                        records.append(rec)
                        if results is not None:
                            with results.open("a") as fh:
                                fh.write(json.dumps(rec) + "\n")
                        if verbose:
                            print(
                                f"d={dim} {name:<16} f{fid:<2} i{inst}: "
                                f"{log_error(rec['error']):6.2f}  outside {rec['outside']}",
                                flush=True,
                            )
    finally:
        for logger in loggers.values():
            logger.close()
    return records


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--optimisers",
        default="lshade",
        help="comma-separated flexid optimisers; 'builtins' for all of "
        "flexid's own (default lshade)",
    )
    parser.add_argument(
        "--peers",
        default=",".join(PEERS),
        help=f"comma-separated peers (default {','.join(PEERS)}; '' for none)",
    )
    parser.add_argument(
        "--against",
        default="pycma-bipop",
        help="comma-separated peers for the head-to-head columns",
    )
    parser.add_argument(
        "--quick", action="store_true", help=f"f{','.join(map(str, QUICK))}, instance 1, d = 5"
    )
    parser.add_argument("--functions", default=None, help="comma-separated BBOB ids (1-24)")
    parser.add_argument("--instances", default=None, help="comma-separated (default 1,2,3)")
    parser.add_argument("--dims", default=None, help="comma-separated (default 5,20)")
    parser.add_argument("--budget-per-dim", type=int, default=1000)
    parser.add_argument("--results", type=Path, default=None, help="JSON-lines file of runs")
    parser.add_argument(
        "--ioh-dir",
        type=Path,
        default=None,
        help="write IOHprofiler data (one folder per optimiser) here",
    )
    parser.add_argument(
        "--check-ioh",
        action="store_true",
        help="read the IOHprofiler folders back with iohinspector",
    )
    parser.add_argument(
        "--table-only", action="store_true", help="print the table of --results without running"
    )
    parser.add_argument("--overhead", action="store_true", help="add the overhead column")
    parser.add_argument(
        "--outside", action="store_true", help="add the column of evaluations outside the box"
    )
    args = parser.parse_args(argv)

    def split(text: str | None, default, kind=str) -> list:
        return [kind(x) for x in text.split(",") if x] if text is not None else list(default)

    names = []
    for name in split(args.optimisers, []):
        names.extend(builtins() if name == "builtins" else [name])
    peers = split(args.peers, PEERS)
    against = split(args.against, [])
    fids = split(args.functions, QUICK if args.quick else range(1, 25), int)
    instances = split(args.instances, [1] if args.quick else [1, 2, 3], int)
    dims = split(args.dims, [5] if args.quick else [5, 20], int)
    everyone = list(dict.fromkeys([*names, *peers, *against]))
    if args.table_only:
        records = load(args.results)
    else:
        records = run_suite(
            everyone, fids, instances, dims, args.budget_per_dim, args.results, args.ioh_dir
        )
    keep = set(fids), set(instances)
    records = [
        r
        for r in records
        if r["fid"] in keep[0]
        and r["instance"] in keep[1]
        and r["budget"] == args.budget_per_dim * r["dim"]
    ]
    print(
        f"\nBBOB f{min(fids)}-f{max(fids)} ({len(fids)} functions), instances "
        f"{','.join(map(str, instances))}, {args.budget_per_dim} x d FE; error floored at "
        f"{SOLVED:g}"
    )
    for dim in dims:
        rows = summary_rows(records, dim, everyone, against)
        if rows:
            print(f"\nd = {dim}, {len(fids) * len(instances)} problems\n")
            print(markdown_table(rows, against, args.overhead, args.outside))
    if args.check_ioh and args.ioh_dir is not None:
        for folder in sorted(p for p in args.ioh_dir.iterdir() if p.is_dir()):
            print(check_ioh(folder))


if __name__ == "__main__":
    main()
