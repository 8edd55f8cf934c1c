"""flexid's CMA-ES variants against pycma with restarts on the BBOB functions (IOHexperimenter).

Run: ``.venv/bin/python benchmarks/bench_cmaes_bbob.py`` (a subset, a few minutes on two
cores) or ``--full`` (the 24 functions, instances 1-3, dimensions 5 and 20).  Needs ``ioh``
and ``cma`` (the ``dev`` extra).

Every run gets ``--budget-per-dim`` x d FE (default 1,000 d) on ``ioh.get_problem(fid,
instance, d, BBOB)`` over its box [-5, 5]^d, counted exactly: flexid's driver truncates the
last batch; pycma (``cma.fmin2`` with ``restarts=9, bipop=True``, ``bounds`` [-5, 5],
``maxfevals`` = budget, ``sigma0`` = 0.3 x 10 like flexid's, ``x0`` uniform in the box at
every restart, seeded) evaluates through a wrapper that raises once the budget is spent, so
its last population is cut where flexid's is.  The run's seed is the instance number for
every optimiser.

Reported per dimension and optimiser: the median over the (function, instance) runs of
``log10(f_best - f_opt)`` with the error floored at 1e-8 (the "solved" target: pycma stops a
run at ``tolfun`` 1e-11, so smaller errors only measure its stop rule), the number solved to
1e-8, the head-to-head against pycma (win / tie / loss; a tie is both errors below 1e-8 or
within a factor 10 of each other) and the overhead in ms per 1,000 FE: wall time minus the
time spent inside the objective.
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

from flexid.optimisers import Problem, minimize

FLEXID = ("cmaes", "cmaes-ipop", "cmaes-bipop")
PYCMA = "pycma-bipop"
SUBSET = (1, 2, 3, 8, 10, 11, 12, 13, 15, 20, 21, 24)
SOLVED = 1e-8


class _Spent(Exception):
    """Raised inside pycma's objective once the budget is spent."""


class Counted:
    """A BBOB problem that counts evaluations, keeps the best and times itself.

    Parameters
    ----------
    problem : ioh problem
        ``ioh.get_problem(fid, instance, dim, ioh.ProblemClass.BBOB)``.
    budget : int
        FE allowed; evaluation ``budget + 1`` raises :class:`_Spent`.
    """

    def __init__(self, problem, budget: int) -> None:
        self.problem = problem
        self.budget = budget
        self.f_opt = float(problem.optimum.y)
        self.nfev = 0
        self.best = np.inf
        self.seconds = 0.0

    def batch(self, X: np.ndarray) -> np.ndarray:
        """Costs of the rows of ``X`` (shape (P, d)) -> shape (P,)."""
        t = time.perf_counter()
        F = np.asarray(self.problem(np.asarray(X, dtype=float)), dtype=float).reshape(-1)
        self.seconds += time.perf_counter() - t
        self.nfev += F.size
        self.best = min(self.best, float(F.min()))
        return F

    def single(self, x: np.ndarray) -> float:
        """Cost of one point (pycma's interface); raises once the budget is spent."""
        if self.nfev >= self.budget:
            raise _Spent
        return float(self.batch(np.asarray(x, dtype=float)[None, :])[0])

    @property
    def error(self) -> float:
        return self.best - self.f_opt


def run_one(name: str, fid: int, instance: int, dim: int, budget: int) -> tuple[float, float, int]:
    """(error, overhead seconds, FE used) of one run of optimiser ``name``."""
    import ioh

    counted = Counted(ioh.get_problem(fid, instance, dim, ioh.ProblemClass.BBOB), budget)
    t = time.perf_counter()
    if name == PYCMA:
        import cma

        rng = np.random.default_rng(instance)
        options = {"bounds": [-5, 5], "maxfevals": budget, "verbose": -9, "seed": instance}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                cma.fmin2(counted.single, lambda: rng.uniform(-5, 5, dim), 3.0, options,
                          restarts=9, bipop=True)
            except _Spent:
                pass
    else:
        problem = Problem(counted.batch, -5 * np.ones(dim), 5 * np.ones(dim))
        minimize(name, problem, budget, seed=instance)
    wall = time.perf_counter() - t
    return counted.error, wall - counted.seconds, counted.nfev


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--full", action="store_true", help="all 24 functions, instances 1-3")
    parser.add_argument("--dims", default="5,20", help="comma-separated dimensions")
    parser.add_argument("--instances", default="1,2", help="instances (the subset's default)")
    parser.add_argument("--functions", default=None, help="comma-separated BBOB function ids")
    parser.add_argument("--budget-per-dim", type=int, default=1000)
    args = parser.parse_args(argv)
    fids = (list(range(1, 25)) if args.full else
            [int(f) for f in args.functions.split(",")] if args.functions else list(SUBSET))
    instances = [1, 2, 3] if args.full else [int(i) for i in args.instances.split(",")]
    dims = [int(d) for d in args.dims.split(",")]
    names = (*FLEXID, PYCMA)
    print(f"BBOB f{','.join(map(str, fids))}, instances {instances}, budget "
          f"{args.budget_per_dim} x d; error floored at {SOLVED:g}")
    for dim in dims:
        budget = args.budget_per_dim * dim
        err = {name: {} for name in names}
        over = {name: [] for name in names}
        fe = {name: 0 for name in names}
        for fid in fids:
            for inst in instances:
                for name in names:
                    e, o, used = run_one(name, fid, inst, dim, budget)
                    err[name][fid, inst] = e
                    over[name].append(o)
                    fe[name] += used
                line = "  ".join(f"{n} {np.log10(max(err[n][fid, inst], SOLVED)):6.2f}"
                                 for n in names)
                print(f"d={dim} f{fid:<2} i{inst}: {line}", flush=True)
        print(f"\nd = {dim}, budget {budget} FE, {len(fids) * len(instances)} runs each")
        print(f"{'optimiser':<12} {'median log10 err':>16} {'solved':>7} "
              f"{'W/T/L vs pycma':>15} {'overhead ms/1000 FE':>20}")
        for name in names:
            e = np.array(list(err[name].values()))
            logs = np.log10(np.maximum(e, SOLVED))
            solved = int(np.sum(e < SOLVED))
            if name == PYCMA:
                wtl = "-"
            else:
                w = t = lo = 0
                for key, mine in err[name].items():
                    ref = err[PYCMA][key]
                    a, b = max(mine, SOLVED), max(ref, SOLVED)
                    if (mine < SOLVED and ref < SOLVED) or max(a, b) <= 10 * min(a, b):
                        t += 1
                    elif a < b:
                        w += 1
                    else:
                        lo += 1
                wtl = f"{w}/{t}/{lo}"
            ms = 1e3 * sum(over[name]) / fe[name] * 1000
            print(f"{name:<12} {np.median(logs):16.2f} {solved:>4}/{e.size:<2} {wtl:>15} "
                  f"{ms:20.1f}")
        print()


if __name__ == "__main__":
    main()
