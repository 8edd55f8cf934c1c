"""The frequency-domain verdict and the mode errors, measured.

Three parts, each printed as a Markdown table:

* ``main-job``: the README's main job (``flexid compare`` on its built-in defaults: the
  paper's manipulator record, OE(16,16,1), 5 runs of HBCSD, BFA, SDA, PSO and DE at 20,000
  FE), its store in a temporary folder.  Per row (least squares read as the structure, the
  reference, each optimiser's median-cost run): the held-out record's share of trusted
  frequencies (coherence >= 0.9) inside the 95 % band, and each of the beam's first four
  flexible modes as the model found it (frequency error %, damping error; "missed" where
  no mode of the model lies within 10 %).
* ``suite``: the same table for each of the small suite's manipulator problems (ARX(8,8,1)
  one-step and simulation, OE(8,8,1), BJ(8,2,2,8,1); both instances), HBCSD, BFA, SDA, PSO
  and DE at the suite's budget (3 runs of 500 FE per dimension).
* ``coverage``: the band's coverage of a known system (the two-input system of
  ``tests/test_frequency.py``), 200 records per method: the share of frequencies where the
  analytic response lies inside the 95 % circle, mean and 2.5-97.5 % range over records.
* ``real``: the robot arm (DaISy 96-009, sample time not given: 1 s assumed, frequencies in
  cycles per sample) and the single-link flexible robot's swept-sine record (500 Hz,
  closed loop), read from ``../shared/data/real/`` when present: the record's confirmed
  peaks and the modes of least-squares ARX(8,8,1) and the reference OE(8,8,1) against them.

    python benchmarks/frequency_views.py [--parts main-job,suite,coverage,real]
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
from scipy import signal

import flexid
from flexid.config import default_spec
from flexid.data import IOData
from flexid.data.plants import get_plant
from flexid.jobs._compare import build_data, frequency_views
from flexid.validation.frequency import frf, mode_table, mode_table_text

REAL = Path(__file__).resolve().parents[2] / "shared" / "data" / "real"


def main_job() -> None:
    spec = default_spec(plant="manipulator")
    with tempfile.TemporaryDirectory() as folder:
        t0 = time.perf_counter()
        result = flexid.compare(spec, store=Path(folder) / "runs.sqlite", workers=2)
        print(f"compare: {time.perf_counter() - t0:.1f} s, key {result.key}")
        _views_table(result)


def suite() -> None:
    """The small suite's manipulator problems (both instances), the paper's optimisers."""
    from flexid.jobs.suite import get_suite, run_suite

    chosen = get_suite("small").subset(["manipulator"])
    with tempfile.TemporaryDirectory() as folder:
        t0 = time.perf_counter()
        done = run_suite(chosen, ["hbcsd", "bfa", "sda", "pso", "de"],
                         store=Path(folder) / "suite.sqlite", workers=2)  # fmt: skip
        print(f"suite {chosen.label} {chosen.version}: {time.perf_counter() - t0:.1f} s\n")
        for name, result in done.results.items():
            print(f"### {name}\n")
            _views_table(result)
            print()


def _views_table(result: flexid.ComparisonResult) -> None:
    """One row per model of a comparison (least squares read as the structure, the
    reference, each optimiser's median-cost run): the held-out share in band and the
    beam's first four flexible modes as the model found them."""
    estimate, models = frequency_views(result, run="median")
    record = build_data(result.spec)
    truth = get_plant("manipulator").true_modes(record.metadata["parameters"])
    f_true = truth[0][:4]
    oe = result.reference.get("output_error") or {}
    head = ["row", "held-out in band"] + [f"mode {k} ({f:.2f} Hz)" for k, f in
                                           enumerate(f_true, start=1)]  # fmt: skip
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for label, model in models.items():
        if label == result.start_label:
            share = result.reference["validation"].get("frequency_share")
        elif label == result.reference_label:
            share = oe.get("validation", {}).get("frequency_share")
        else:
            name = label.split(" (")[0]
            runs = sorted((r for r in result.records[name] if r["status"] == "ok"),
                          key=lambda r: r["cost"])  # fmt: skip
            share = runs[(len(runs) - 1) // 2]["validation"].get("frequency_share")
        cells = [label, "-" if share is None else f"{100 * share:.0f} %"]
        table = mode_table(model, estimate=estimate, truth=truth)
        for f in f_true:
            row = next((r for r in table if r.true_frequency == f), None)
            if row is None or not math.isfinite(row.frequency):
                cells.append("missed")
            else:
                cells.append(f"{row.frequency_error:+.3f} %, {row.damping_error:+.4f}")
        print("| " + " | ".join(cells) + " |")


B1, A1 = [0.0, 0.5], [1.0, -0.5]
B2, A2 = [0.0, 0.2, 0.1], [1.0, -0.3, 0.2]


def coverage(records: int = 200) -> None:
    print("| method | mean share inside | 2.5-97.5 % over records | equivalent averages |")
    print("|---|---|---|---|")
    for method in ("tfestimate", "spa", "etfe"):
        shares = []
        for seed in range(records):
            rng = np.random.default_rng(seed)
            u = rng.standard_normal((4000, 2))
            y = signal.lfilter(B1, A1, u[:, 0]) + signal.lfilter(B2, A2, u[:, 1])
            est = frf(IOData(u, y + 0.5 * rng.standard_normal(4000), dt=0.01), method)
            g1 = signal.freqz(B1, A1, worN=est.frequency, fs=100.0)[1]
            g2 = signal.freqz(B2, A2, worN=est.frequency, fs=100.0)[1]
            shares.append(est.inside(np.stack([g1, g2], axis=-1)[:, None, :]).mean())
        lo, hi = np.percentile(shares, [2.5, 97.5])
        print(f"| {method} | {100 * np.mean(shares):.2f} % | {100 * lo:.1f}-{100 * hi:.1f} % "
              f"| {est.averages:.1f} |")


def real() -> None:
    if not REAL.is_dir():
        print(f"(no real records at {REAL})")
        return
    cases = [
        ("robot_arm", {"dt": 1.0}),
        ("slfr_swept1", {"inputs": ["u"], "outputs": ["y"]}),
    ]
    for name, options in cases:
        record = flexid.load(REAL / f"{name}.csv", **options)
        estimate = frf(record)
        print(f"### {name}\n")
        print("```text")
        print(estimate.summary())
        for structure, orders, optimiser in (("arx", {"na": 8, "nb": 8}, "ls"),
                                             ("oe", {"nb": 8, "nf": 8}, "pem")):  # fmt: skip
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                ident = flexid.identify(record, structure=structure, nk=1,
                                        optimiser=optimiser, **orders)  # fmt: skip
            v = ident.validation
            print(f"\n{structure.upper()}(8,8,1) {optimiser}: held-out simulation fit "
                  f"{v.fit_simulation:.1f} %, inside the band {v.frequency_verdict}")  # fmt: skip
            print(mode_table_text(mode_table(ident.model, estimate=estimate)))
        print("```\n")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--parts", default="main-job,suite,coverage,real")
    args = parser.parse_args(argv)
    parts = {"main-job": main_job, "suite": suite, "coverage": coverage, "real": real}
    for part in args.parts.split(","):
        print(f"## {part}\n")
        parts[part]()
        print()
    return 0


if __name__ == "__main__":
    sys.exit(main())
