"""Every optimiser on the twin rotor's pitch grey-box, against the gradient reference.

The record: the paper-twin-rotor preset (lab encoder, data seed 0), 3,000 samples; the first
2,000 estimate, the last 1,000 validate.  The model:
:func:`flexid.models.greybox_library.twin_rotor_pitch` (six parameters estimated, searched
in their log-scaled box).  Each optimiser runs ``--runs`` times (seeds 0, 1, ...) at
``--budget`` evaluations on the same cost (:class:`flexid.GreyBoxCost`, the package's
default metric) with the initial populations every optimiser shares for a seed
(:func:`flexid.minimize`).  The reference is :func:`flexid.greyest` from the manual's values
and 3 random starts; a second reference run starts from the manual's values with ``Mg`` 3x
and ``T11`` 1/3x off, alone, to show whether local search finds the optimum from there.

Printed per optimiser: the median and best final cost over the reference's, the runs that
reach it (within 0.1 %), the median held-out simulation fit (:func:`flexid.validate`,
``split=2/3``, the model run on through the estimation part) and the median over runs of
the largest relative parameter error.  Finished runs are appended at once to a JSON-lines
file (``--out``, default ``greybox-comparison.jsonl``), so a rerun skips them.

Run:  python benchmarks/greybox_comparison.py [--runs 10] [--budget 10000]
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np

import flexid
from flexid.costs.greybox import GreyBoxCost
from flexid.envs.twin_rotor_physics import TwinRotorParameters
from flexid.models.greybox_library import twin_rotor_pitch

OPTIMISERS = ("hbcsd", "bfa", "sda", "pso", "de", "cmaes", "random-search")
REACH = 1e-3  # a run "reaches" the reference within 0.1 % of its cost


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=10)
    parser.add_argument("--budget", type=int, default=10_000)
    parser.add_argument("--optimisers", default=",".join(OPTIMISERS))
    parser.add_argument("--out", type=Path, default=Path("greybox-comparison.jsonl"))
    args = parser.parse_args()

    data = flexid.generate("twin-rotor", preset="paper-twin-rotor", n_samples=3000, seed=0)
    est = data[:2000]
    model = twin_rotor_pitch()
    cost = GreyBoxCost(model, est)
    problem = cost.problem()
    true = np.array([getattr(TwinRotorParameters(), n) for n in model.free])

    def describe(values: np.ndarray) -> dict:
        fitted = model.with_parameters(**dict(zip(model.free, values.tolist())))
        report = flexid.validate(fitted, data, split=2 / 3)
        return {
            "cost": float(cost(values)[0]),
            "fit": report.fit_simulation,
            "passed": bool(report.passed),
            "error": float(np.max(np.abs(values / true - 1.0))),
        }

    reference = flexid.greyest(est, model, starts=3, seed=0)
    ref = describe(np.array([reference.values[n] for n in model.free]))
    off = flexid.greyest(
        est, model, starts=0, x0=[true[0] * 3, *true[1:5], true[5] / 3]
    )
    off_row = describe(np.array([off.values[n] for n in model.free]))

    done = {}
    if args.out.exists():
        for line in args.out.read_text().splitlines():
            row = json.loads(line)
            done[(row["optimiser"], row["seed"], row["budget"])] = row
    for name in args.optimisers.split(","):
        for seed in range(args.runs):
            if (name, seed, args.budget) in done:
                continue
            t0 = time.perf_counter()
            result = flexid.minimize(name, problem, args.budget, seed=seed)
            values = np.clip(model.from_search(result.x), cost.lower, cost.upper)
            row = {"optimiser": name, "seed": seed, "budget": args.budget,
                   "nfev": int(result.nfev), "seconds": time.perf_counter() - t0,
                   **describe(values)}
            done[(name, seed, args.budget)] = row
            with args.out.open("a") as fh:  # each finished run at once
                fh.write(json.dumps(row) + "\n")
            print(f"{name} seed {seed}: cost/ref {row['cost'] / ref['cost']:.4g}, "
                  f"{row['seconds']:.1f} s", flush=True)

    print(f"\nreference: cost {ref['cost']:.6g}, held-out fit {ref['fit']:.2f} %, tests "
          f"{'pass' if ref['passed'] else 'FAIL'}, largest parameter error {ref['error']:.2%}, "
          f"{reference.nfev} simulations")
    print(f"reference from Mg 3x, T11 1/3x: cost/ref {off_row['cost'] / ref['cost']:.6g}, "
          f"{'local minimum' if off.local_minimum else 'NOT a minimum'}, {off.nfev} simulations")
    print("\n| optimiser | median cost / ref | best | reach | median held-out fit | "
          "tests pass | median largest parameter error |")
    print("|---|---|---|---|---|---|---|")
    for name in args.optimisers.split(","):
        rows = [r for (n, s, b), r in done.items() if n == name and b == args.budget
                and s < args.runs]
        if not rows:
            continue
        ratio = np.array([r["cost"] / ref["cost"] for r in rows])
        print(f"| {name} | {np.median(ratio):.4g} | {ratio.min():.4g} | "
              f"{int(np.sum(ratio <= 1 + REACH))}/{len(rows)} | "
              f"{np.median([r['fit'] for r in rows]):.2f} % | "
              f"{sum(r['passed'] for r in rows)}/{len(rows)} | "
              f"{np.median([r['error'] for r in rows]):.2%} |")


if __name__ == "__main__":
    main()
