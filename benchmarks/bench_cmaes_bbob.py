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
every optimiser, or ``--seed N`` for every run (a replicate with other random numbers);
``--optimisers`` restricts flexid's variants (``cmaes-bipop`` for a quick replicate).

Reported per dimension and optimiser: the median over the (function, instance) runs of
``log10(f_best - f_opt)`` with the error floored at 1e-8 (the "solved" target: pycma stops a
run at ``tolfun`` 1e-11, so smaller errors only measure its stop rule), the number solved to
1e-8, the head-to-head against pycma (win / tie / loss; a tie is both errors below 1e-8 or
within a factor 10 of each other) and the overhead in ms per 1,000 FE: wall time minus the
time spent inside the objective.  The runs and the table are those of ``benchmarks/bbob.py``
(the general BBOB runner), restricted to the CMA-ES variants and pycma.
"""

from __future__ import annotations

import argparse

from bbob import SOLVED, markdown_table, run_suite, summary_rows

FLEXID = ("cmaes", "cmaes-ipop", "cmaes-bipop")
PYCMA = "pycma-bipop"
SUBSET = (1, 2, 3, 8, 10, 11, 12, 13, 15, 20, 21, 24)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--full", action="store_true", help="all 24 functions, instances 1-3")
    parser.add_argument("--dims", default="5,20", help="comma-separated dimensions")
    parser.add_argument("--instances", default="1,2", help="instances (the subset's default)")
    parser.add_argument("--functions", default=None, help="comma-separated BBOB function ids")
    parser.add_argument("--budget-per-dim", type=int, default=1000)
    parser.add_argument(
        "--seed", type=int, default=None, help="every run's seed (default: the instance number)"
    )
    parser.add_argument(
        "--optimisers",
        default=",".join(FLEXID),
        help="comma-separated flexid variants (default all three)",
    )
    args = parser.parse_args(argv)
    fids = (
        list(range(1, 25))
        if args.full
        else [int(f) for f in args.functions.split(",")]
        if args.functions
        else list(SUBSET)
    )
    instances = [1, 2, 3] if args.full else [int(i) for i in args.instances.split(",")]
    dims = [int(d) for d in args.dims.split(",")]
    names = [*args.optimisers.split(","), PYCMA]
    print(
        f"BBOB f{','.join(map(str, fids))}, instances {instances}, budget "
        f"{args.budget_per_dim} x d; error floored at {SOLVED:g}; seed "
        f"{'the instance number' if args.seed is None else args.seed}"
    )
    records = run_suite(names, fids, instances, dims, args.budget_per_dim, seed=args.seed)
    for dim in dims:
        print(
            f"\nd = {dim}, budget {args.budget_per_dim * dim} FE, "
            f"{len(fids) * len(instances)} runs each\n"
        )
        print(markdown_table(summary_rows(records, dim, names, [PYCMA]), [PYCMA], overhead=True))


if __name__ == "__main__":
    main()
