"""Does ``flexid select`` recommend a model that passes at the stated level, seed by seed?

On the manipulator's lab preset (2,300 samples), for each data seed: ``select`` over OE with
``nb, nf`` in {8, 16} (the grid of the selection measurement), its recommendation and
verdict at ``alpha``, the failing test when no candidate passes; then the recommended model
validated on the next 30,000 samples of the same seed, which confirms a failure that is the
model's (it fails there by far more) or refutes one that was the record's (it passes there).
At 5 %, a correct procedure passes in at least 17 of 20 seeds (a binomial 20 x 0.95 draw is
below 17 in 1.6 % of experiments).

Run:  python benchmarks/selection_level.py [--seeds 20] [--alpha 0.05] [--continuation 30000]
"""

from __future__ import annotations

import argparse
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from _table import print_table

import flexid

PRESET_SAMPLES = 2300  # the paper-manipulator preset's length


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--alpha", type=float, default=0.05)
    parser.add_argument("--continuation", type=int, default=30_000)
    args = parser.parse_args()
    rows, passing = [], 0
    for seed in range(args.seeds):
        data = flexid.generate("manipulator", preset="paper-manipulator", seed=seed,
                               n_samples=PRESET_SAMPLES + args.continuation)  # fmt: skip
        lab = data[:PRESET_SAMPLES]
        result = flexid.select(lab, structures=["oe"], orders={"nb": [8, 16], "nf": [8, 16]},
                               nk=1, alpha=args.alpha)  # fmt: skip
        best = result.best
        passing += bool(best.passed)
        cells = [best.label, f"{best.fit_simulation:.2f} %", "pass" if best.passed else "FAIL"]
        if not best.passed:
            cells.append(best.report.verdict())
            longer = flexid.validate(best.model, data[PRESET_SAMPLES:], alpha=args.alpha,
                                     estimated_on=lab[:result.n_estimation])  # fmt: skip
            cells.append(f"next {args.continuation:,}: {longer.verdict()}")
        rows.append((f"seed {seed}", "; ".join(cells)))
    rows.append(("recommendation passes", f"{passing} of {args.seeds} seeds"))
    print_table(rows, f"flexid select on the manipulator's lab preset, OE nb, nf in {{8, 16}}, "
                      f"verdicts at {100 * args.alpha:g} %")  # fmt: skip


if __name__ == "__main__":
    main()
