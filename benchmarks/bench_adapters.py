"""Hidden cost of the library adapters: overhead per FE against flexid's own algorithm.

Run: ``.venv/bin/python benchmarks/bench_adapters.py [--budget 3000] [--repeats 2]``

Pairs, all measured in the same run: ``ng:CMA`` and ``cma:CMA-ES`` against flexid's
``cmaes``; ``ng:DE`` and ``pymoo:DE`` against flexid's ``de`` (population 50 for both DE
adapters that have one; nevergrad at its defaults, one candidate per ask).  Two objectives:
a cheap batched 16-D sphere, and the paper's cost of ARX(8,8,1) on the simulated
manipulator (one-step predictor, the paper's search box).  The time spent inside the
objective is measured and subtracted, so "overhead" is what the optimiser, its library and
flexid's driver cost per FE; "total" includes the objective.  The ratios divide by flexid's
own implementation on the same objective in the same run (best of ``--repeats``).
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

import flexid
from flexid.config import PAPER_SEARCH, CostSpec
from flexid.data import prepare_data
from flexid.fit.estimation import build_problem, model_structure
from flexid.optimisers import Problem, minimize

PAIRS = {
    "cmaes": ["ng:CMA", "cma:CMA-ES"],
    "de": ["ng:DE", "pymoo:DE"],
}
PARAMS = {"de": {"population": 50}, "pymoo:DE": {"population": 50}}


class Timed:
    """An objective that accumulates its own wall time."""

    def __init__(self, f) -> None:
        self.f = f
        self.seconds = 0.0

    def __call__(self, X: np.ndarray) -> np.ndarray:
        t = time.perf_counter()
        F = self.f(X)
        self.seconds += time.perf_counter() - t
        return F


def objectives():
    yield "sphere 16-D", (lambda X: ((X - 0.1) ** 2).sum(axis=1)), -5 * np.ones(16), 5 * np.ones(16)
    data = flexid.generate("manipulator", preset="paper-manipulator", seed=0, sensors="ideal")
    est, _ = prepare_data(data)
    ep = build_problem(est, model_structure(8, 8, 1, est.n_inputs), CostSpec(), PAPER_SEARCH)
    yield "ARX(8,8,1) paper cost", ep.problem.objective, ep.problem.lower, ep.problem.upper


def bench(name: str, f, lower, upper, budget: int, repeats: int) -> tuple[float, float]:
    """Best-of-``repeats`` overhead and total time per FE (us)."""
    over, total = np.inf, np.inf
    for rep in range(repeats):
        timed = Timed(f)
        t = time.perf_counter()
        r = minimize(name, Problem(timed, lower, upper), budget, seed=rep,
                     params=PARAMS.get(name))
        wall = time.perf_counter() - t
        over = min(over, (wall - timed.seconds) / r.nfev * 1e6)
        total = min(total, wall / r.nfev * 1e6)
    return over, total


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--budget", type=int, default=3000)
    ap.add_argument("--repeats", type=int, default=2)
    args = ap.parse_args()
    warnings.simplefilter("ignore")  # pycma's injection warnings under nevergrad's CMA
    print(f"budget {args.budget} FE, best of {args.repeats}; us per FE")
    print(f"{'objective':24s} {'optimiser':12s} {'overhead':>10s} {'ratio':>7s} "
          f"{'total':>10s} {'ratio':>7s}")
    for oname, f, lower, upper in objectives():
        for ref, adapters in PAIRS.items():
            base = bench(ref, f, lower, upper, args.budget, args.repeats)
            print(f"{oname:24s} {ref:12s} {base[0]:10.1f} {1:7.1f} {base[1]:10.1f} {1:7.1f}")
            for name in adapters:
                try:
                    o, t = bench(name, f, lower, upper, args.budget, args.repeats)
                except Exception as exc:  # a missing library or a failing one: say so, go on
                    print(f"{oname:24s} {name:12s} {type(exc).__name__}: {exc}")
                    continue
                print(f"{oname:24s} {name:12s} {o:10.1f} {o / base[0]:7.1f} {t:10.1f} "
                      f"{t / base[1]:7.1f}")


if __name__ == "__main__":
    main()
