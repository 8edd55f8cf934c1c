"""How right a reported fit is: the well-conditioned realisation against the exact model.

For lightly damped OE(n, n, 1) models (n = 4 .. 24, damping ratios 0.001-0.05, modes
clustered in frequency) and a 400-sample record, the held-out simulation fit as flexid reports
it (second-order sections from polished roots, the initial state in a modal basis) against the
exact model's (its direct form at 100 digits, ``mpmath``), and the float64 direct form's error
for comparison, under both rules that count every sample.  The models and the exact reference
are those of ``tests/test_realisation.py``.

    python benchmarks/fit_accuracy.py [--seeds 5]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from flexid.models.polynomial import PolynomialStructure, run_predictor
from flexid.validation.diagnostics import fit_percent
from test_realisation import (
    exact_fit,
    exact_polynomials,
    exact_predictor,
    lightly_damped,
    record,
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5, help="models per order (default 5)")
    args = parser.parse_args()
    print("| order | rule | models | max error, flexid [points] | max error, float64 direct "
          "form [points] |")
    print("|---|---|---|---|---|")
    t0 = time.perf_counter()
    for order in (4, 8, 12, 16, 20, 24):
        errors: dict[str, list[tuple[float, float]]] = {"estimate": [], "zero": []}
        for seed in range(args.seeds):
            rng = np.random.default_rng(1000 * order + seed)
            f = lightly_damped(rng, order)
            model = PolynomialStructure.oe(order, order, 1).model(
                np.concatenate([1e-3 * rng.normal(size=order), f[1:]])
            )
            u, y = record(rng, model)
            polys = exact_polynomials(model, np.inf)
            den, num_y, nums = model.predictor_polynomials(np.inf)
            for rule in errors:
                exact = exact_fit(y, exact_predictor(*polys, u, y, 0, rule), 0)
                ours = fit_percent(y, model.simulate(u, y, initial=rule))
                # the direct form, counted the same way where it can be (from rest); under
                # "estimate" its own rule (the state at start) against the exact one
                if rule == "zero":
                    direct = run_predictor(den, num_y, nums, u, y, 0, "zero")[0]
                    dfit, dexact = fit_percent(y, direct), exact
                else:
                    s = model.structure.start
                    direct = run_predictor(den, num_y, nums, u, y, s, "estimate")[0]
                    ref = exact_predictor(*polys, u, y, s, "estimate-start")
                    dfit, dexact = fit_percent(y[s:], direct[s:]), exact_fit(y, ref, s)
                errors[rule].append((abs(ours - exact), abs(dfit - dexact)))
        for rule, pairs in errors.items():
            ours, direct = np.max(pairs, axis=0)
            print(f"| {order} | {rule} | {len(pairs)} | {ours:.1e} | {direct:.1e} |")
    print(f"\n{time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
