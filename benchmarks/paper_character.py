"""Do the paper presets give data of the paper's character?  Measured, by hand.

For each paper preset and 5 seeds: least squares with the paper's structure (ARX(8,8,1) on
the manipulator's tip acceleration, ARX(5,5,1) on the twin rotor's pitch) fitted on the first
two thirds and validated on the held-out third: one-step and simulation fits, the residual
auto- and cross-correlation tests, and the resonances of the model's frequency response
against the plant's (the beam's first three modes; the twin rotor's linearised pitch mode).
Run with ``--sensors ideal`` for the plants read without their measurement chain, and
``--orders`` to see which structure would pass.

    python benchmarks/paper_character.py [--sensors lab|ideal] [--seeds 5] [--orders 8,16,32]
"""

from __future__ import annotations

import argparse

import numpy as np
import scipy.signal

from flexid.arx import ARXStructure
from flexid.datasets import generate
from flexid.envs import beam, twin_rotor_physics
from flexid.validation import validate


def resonances(model, dt: float, band: tuple[float, float], n: int = 20_000) -> np.ndarray:
    """Frequencies [Hz] of the local maxima of |H| in ``band``, strongest first."""
    f = np.linspace(band[0], band[1], n)
    num = np.concatenate([np.zeros(model.structure.nk[0]), model.b[0]])
    _, h = scipy.signal.freqz(num, model.a, worN=f, fs=1.0 / dt)
    mag = np.abs(h)
    peaks, _ = scipy.signal.find_peaks(mag)
    return f[peaks[np.argsort(mag[peaks])[::-1]]]


def matched(found: np.ndarray, targets: np.ndarray, tol: float) -> list[bool]:
    return [bool(found.size) and bool(np.min(np.abs(found - t)) <= tol * t) for t in targets]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sensors", default="lab", choices=("lab", "ideal"))
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--orders", default="", help="extra ARX orders to try, e.g. 16,32")
    ap.add_argument("--plant", default="both", choices=("both", "manipulator", "twin-rotor"))
    args = ap.parse_args()
    cases = []
    if args.plant in ("both", "manipulator"):
        modes = beam.exact_frequencies(beam.BeamParameters(), 3)
        cases.append(("manipulator", "paper-manipulator", 8, modes, 0.05, (1.0, 150.0)))
    if args.plant in ("both", "twin-rotor"):
        f0, _ = twin_rotor_physics.pitch_linear_mode(twin_rotor_physics.TwinRotorParameters())
        cases.append(("twin-rotor", "paper-twin-rotor", 5, np.array([f0]), 0.03, (0.02, 2.0)))
    extra = [int(v) for v in args.orders.split(",") if v]
    for plant, preset, order, targets, tol, band in cases:
        print(f"{preset} ({args.sensors} sensors); plant resonances {np.round(targets, 3)} Hz")
        for n in [order, *extra]:
            rows = []
            for seed in range(args.seeds):
                data = generate(plant, preset=preset, seed=seed, sensors=args.sensors)
                train, test = data.split(2 / 3)
                model = ARXStructure(n, n, 1).least_squares(train.u, train.y, dt=data.dt)
                rep = validate(model, test)
                found = resonances(model, data.dt, band)
                hits = matched(found[: 2 * len(targets)], targets, tol)
                rows.append((rep.fit_one_step, rep.fit_simulation,
                             all(t.passed for t in rep.correlation_tests),
                             [t.n_outside for t in rep.correlation_tests], sum(hits), found[:3]))
            one = np.array([r[0] for r in rows])
            sim = np.array([r[1] for r in rows])
            print(f"  ARX({n},{n},1): one-step {one.mean():.1f} % (min {one.min():.1f}), "
                  f"simulation {sim.mean():.1f} % (min {sim.min():.1f}), "
                  f"correlation tests passed {sum(r[2] for r in rows)}/{len(rows)} "
                  f"(lags outside, auto/cross: {[r[3] for r in rows]}), "
                  f"resonances within {tol:.0%}: {[r[4] for r in rows]} of {len(targets)}; "
                  f"model peaks seed 0: {np.round(rows[0][5], 2)} Hz")


if __name__ == "__main__":
    main()
