"""How much of a whole identification run is the optimiser's own work, not the cost's.

One run of each optimiser at a population of 64 on the README's main-job problem (the
manipulator's paper record, OE(16,16,1), poles searched, ``b`` fitted), 10,000 FE, on one
and on two kernel threads.  The cost's time is measured inside the run, around the batched
fitted cost itself (``PolynomialCost.fitted_costs``); everything else (the optimiser's
update, the map from poles to coefficients, the driver) is the optimiser's share.

    python benchmarks/optimiser_share.py [--optimisers de,pso,cmaes] [--fe 10000]
"""

from __future__ import annotations

import argparse
import os
import sys
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # the kernels' threads, not BLAS's

import flexid
from flexid import kernels
from flexid.config import CostSpec, SearchSpec
from flexid.data import prepare_data
from flexid.fit.estimation import build_problem
from flexid.models.polynomial import structure
from flexid.optimisers import minimize


def one_run(name: str, fe: int, threads: int) -> tuple[float, float, float]:
    """Wall time of the run, of its cost, and the run's final cost."""
    record = flexid.generate("manipulator", preset="paper-manipulator", seed=0)
    estimation, _ = prepare_data(record)
    posed = build_problem(estimation, structure("oe", nb=16, nf=16, nk=1), CostSpec(),
                          SearchSpec())  # fmt: skip
    cost = posed.cost
    inner = cost.fitted_costs
    spent = [0.0]

    def timed(theta):
        t0 = time.perf_counter()
        try:
            return inner(theta)
        finally:
            spent[0] += time.perf_counter() - t0

    cost.fitted_costs = timed  # the instance's attribute: the problem calls it by name
    old = kernels.set_threads(threads)
    try:
        t0 = time.perf_counter()
        result = minimize(name, posed.problem, fe, 0, params={"population": 64})
        wall = time.perf_counter() - t0
    finally:
        kernels.set_threads(old)
    return wall, spent[0], float(result.fun)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--optimisers", default="de,pso,cmaes")
    parser.add_argument("--fe", type=int, default=10_000)
    args = parser.parse_args(argv)
    print("| optimiser | threads | run [s] | cost [s] | optimiser's share | final cost |")
    print("|---|---|---|---|---|---|")
    for name in args.optimisers.split(","):
        for threads in (1, 2):
            wall, spent, fun = one_run(name, args.fe, threads)
            print(f"| {name} | {threads} | {wall:.2f} | {spent:.2f} | "
                  f"{100 * (wall - spent) / wall:.1f} % | {fun:.4g} |")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
