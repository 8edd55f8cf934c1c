"""Framework + algorithm overhead per function evaluation, for every registered optimiser.

Run: ``/work/venv/bin/python benchmarks/bench_optimisers.py [--n 16] [--budget 50000]``

The objective is a cheap 16-D sphere; the time spent inside it is measured and subtracted,
so the table shows what the optimiser and the driver cost per FE (microseconds), at a
population of 50 wherever the optimiser has a population hyper-parameter.  Paper variants
are skipped (same code as their base).  Targets: <= 5 us/FE for SDA, PSO and DE, <= 20 us/FE
for BFA and HBCSD.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from flexid.optimisers import Problem, available, get, minimize

POP_PARAMS = ("points", "bacteria", "particles", "population")
TARGET_US = {"sda": 5.0, "pso": 5.0, "de": 5.0, "bfa": 20.0, "hbcsd": 20.0}


class TimedSphere:
    """``sum((x - 0.1)^2)`` that accumulates its own wall time and row count."""

    def __init__(self) -> None:
        self.seconds = 0.0
        self.rows = 0

    def __call__(self, X: np.ndarray) -> np.ndarray:
        t = time.perf_counter()
        F = ((X - 0.1) ** 2).sum(axis=1)
        self.seconds += time.perf_counter() - t
        self.rows += X.shape[0]
        return F


def bench(name: str, n: int, budget: int, repeats: int) -> tuple[float, float, int]:
    """Best-of-``repeats`` overhead and objective time per FE (us), and FE used."""
    spec = get(name).hyperparameters()
    params = {p: 50 for p in POP_PARAMS if p in spec}
    best_over, best_obj, fe = np.inf, np.inf, 0
    for rep in range(repeats):
        f = TimedSphere()
        problem = Problem(f, -5 * np.ones(n), 5 * np.ones(n))
        t = time.perf_counter()
        res = minimize(name, problem, budget, seed=rep, params=params)
        wall = time.perf_counter() - t
        fe = res.nfev
        best_over = min(best_over, (wall - f.seconds) / fe * 1e6)
        best_obj = min(best_obj, f.seconds / fe * 1e6)
    return best_over, best_obj, fe


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=16)
    ap.add_argument("--budget", type=int, default=50_000)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    print(f"sphere n={args.n}, budget={args.budget} FE, population 50, best of {args.repeats}")
    print(f"{'optimiser':<16}{'FE':>8}{'overhead us/FE':>16}{'objective us/FE':>17}{'target':>8}")
    for name in available():
        if "-paper-" in name or name == "scipy":
            continue
        try:
            over, obj, fe = bench(name, args.n, args.budget, args.repeats)
        except Exception as exc:  # a baseline that does not run here must not stop the table
            print(f"{name:<16}  failed: {type(exc).__name__}: {exc}")
            continue
        target = TARGET_US.get(name)
        mark = "" if target is None else f"{target:g}" + (" ok" if over <= target else " MISS")
        print(f"{name:<16}{fe:>8}{over:>16.2f}{obj:>17.2f}{mark:>8}")


if __name__ == "__main__":
    main()
