"""Is a failed correlation test the model's or the record's?  Validate on a long continuation.

The manipulator's lab preset (2,300 samples) is generated with a long continuation from the
same seed; OE(16,16,1) is fitted by the prediction-error reference on the preset's estimation
part (its first 2/3) and validated twice: on the preset's held-out third, as ``flexid
select`` does, and on the next 30,000 samples.  A test that fails on the short record
because of the model fails on the long one by far more (its statistic grows like ``N``);
one that failed by chance passes there.  Each test is printed with its p-value and the
largest lag in standard deviations of the null.

Run:  python benchmarks/long_record_validation.py [--seeds 0 1 2] [--continuation 30000]
"""

from __future__ import annotations

import argparse
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np
from _table import print_table

import flexid
from flexid.models.polynomial import structure

PRESET_SAMPLES = 2300  # the paper-manipulator preset's length
ESTIMATION = 1533  # its first 2/3, select's default split


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--continuation", type=int, default=30_000)
    args = parser.parse_args()
    rows = []
    for seed in args.seeds:
        data = flexid.generate(
            "manipulator",
            preset="paper-manipulator",
            seed=seed,
            n_samples=PRESET_SAMPLES + args.continuation,
        )
        model = flexid.pem(data[:ESTIMATION], structure("oe", nb=16, nf=16, nk=1)).model
        parts = {
            "held-out third": data[ESTIMATION:PRESET_SAMPLES],
            f"next {args.continuation:,}": data[PRESET_SAMPLES:],
        }
        for name, part in parts.items():
            report = flexid.validate(model, part, estimated_on=data[:ESTIMATION])
            tests = report.correlation_tests + report.nonlinear_tests
            cells = [
                f"{t.name}: p {t.p_value:.2g} "
                f"{np.max(np.abs(t.values[t.counted])) * np.sqrt(t.n_samples):.1f}sd "
                f"{'pass' if t.passed else 'FAIL'}"
                for t in tests
            ]
            rows.append((f"seed {seed}, {name}", "; ".join(cells)))
    print_table(rows, "OE(16,16,1) by flexid.pem on the preset's first 2/3, lab sensors")


if __name__ == "__main__":
    main()
