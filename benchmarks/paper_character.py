"""Do the paper presets give data of the paper's character?  Measured, by hand.

For each paper preset and 5 seeds: least squares with the paper's structure (ARX(8,8,1) on
the manipulator's tip acceleration, ARX(5,5,1) on the twin rotor's pitch) fitted on the first
two thirds and validated on the held-out third: one-step and simulation fits, the residual
auto- and cross-correlation tests, and the resonances of the model's frequency response
against the plant's (the beam's first three modes; the twin rotor's linearised pitch mode).
Run with ``--sensors ideal`` for the plants read without their measurement chain, and
``--orders`` to see which structure would pass.

``--structure oe`` or ``bj`` fits an output-error or Box-Jenkins model instead
(:func:`flexid.fit.prediction_error.pem`, the prediction-error reference, from rest:
``nb = nf = n``, ``nk = 1``, and ``nc``/``nd`` from ``--nc``/``--nd``).  Its held-out
numbers are computed with the filters run from rest at the start of the record over the
training two thirds into the held-out third (the model's state at the split is the one the
known past left), on every held-out sample: one-step fit of the predictor
``y - D/C (y - B/F u)``, simulation fit of ``B/F u``, the correlation tests of the held-out
prediction errors against ``u``, and the resonances of ``B/F``.

    python benchmarks/paper_character.py [--sensors lab|ideal] [--seeds 5] [--orders 8,16,32]
    python benchmarks/paper_character.py --structure oe|bj [--nc 2,4,8] [--orders 16]
        [--amplitude 0.2] [--plant-params '{"a1": 0, "B2psi": 0}']

``--structure plant`` scores the twin rotor's own model at its true parameters (the record
read without the chain, the encoder, with the same input): whether the tests can pass at all
with the right structure.

``--amplitude`` and ``--plant-params`` change the record (input range, physical
parameters) to see which nonlinearity of a plant a linear model's tests react to.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
import scipy.signal

from flexid.data.datasets import generate
from flexid.envs import beam, twin_rotor_physics
from flexid.models.arx import ARXStructure
from flexid.validation import validate
from flexid.validation.diagnostics import fit_percent, residual_tests


def peaks(
    num: np.ndarray, den: np.ndarray, dt: float, band: tuple[float, float], n: int = 20_000
) -> np.ndarray:
    """Frequencies [Hz] of the local maxima of ``|num/den|`` in ``band``, strongest first."""
    f = np.linspace(band[0], band[1], n)
    _, h = scipy.signal.freqz(num, den, worN=f, fs=1.0 / dt)
    mag = np.abs(h)
    found, _ = scipy.signal.find_peaks(mag)
    return f[found[np.argsort(mag[found])[::-1]]]


def resonances(model, dt: float, band: tuple[float, float], n: int = 20_000) -> np.ndarray:
    """Frequencies [Hz] of the local maxima of |H| in ``band``, strongest first."""
    num = np.concatenate([np.zeros(model.structure.nk[0]), model.b[0]])
    return peaks(num, model.a, dt, band, n)


def matched(found: np.ndarray, targets: np.ndarray, tol: float) -> list[bool]:
    return [bool(found.size) and bool(np.min(np.abs(found - t)) <= tol * t) for t in targets]


def _orders_list(text: str) -> list[int]:
    return [int(v) for v in text.split(",") if v]


def run_arx(data, n: int, targets: np.ndarray, tol: float, band: tuple[float, float]) -> tuple:
    train, test = data.split(2 / 3)
    model = ARXStructure(n, n, 1).least_squares(train.u, train.y, dt=data.dt)
    rep = validate(model, test)
    found = resonances(model, data.dt, band)
    hits = matched(found[: 2 * len(targets)], targets, tol)
    return (
        rep.fit_one_step,
        rep.fit_simulation,
        all(t.passed for t in rep.correlation_tests),
        [t.n_outside for t in rep.correlation_tests],
        sum(hits),
        found[:3],
    )


def run_pem(
    data, n: int, nc: int, nd: int, targets: np.ndarray, tol: float, band: tuple[float, float]
) -> dict:
    """One seed of an output-error / Box-Jenkins model: fit on 2/3, numbers on the last 1/3."""
    from flexid.fit.prediction_error import pem
    from flexid.models.polynomial import structure

    train, _ = data.split(2 / 3)
    m = train.n_samples
    u, y = data.u, data.y[:, 0]
    s = structure("bj", nb=n, nc=nc, nd=nd, nf=n) if nc or nd else structure("oe", nb=n, nf=n)
    fit = pem(train, s, initial="zero")
    model = fit.model
    # the filters run on from rest at t = 0 through the training part into the held-out one
    y1 = model.predict(u, y, initial="zero")[m:]
    ysim = model.simulate(u)[m:]
    u_te, y_te = u[m:, 0], y[m:]
    tests = residual_tests(y_te - y1, u_te)
    num = np.concatenate([np.zeros(s.nk[0]), model.b[0]])
    found = peaks(num, model.f[0], data.dt, band)
    hits = matched(found[: 2 * len(targets)], targets, tol)
    return {
        "one": fit_percent(y_te, y1),
        "sim": fit_percent(y_te, ysim),
        "auto": tests[0].passed,
        "cross": tests[1].passed,
        "outside": [t.n_outside for t in tests],
        "hits": sum(hits),
        "peaks": found[:3],
        "time": fit.wall_time,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sensors", default="lab", choices=("lab", "ideal"))
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--orders", default="", help="extra orders to try (nb = nf), e.g. 16,32")
    ap.add_argument("--plant", default="both", choices=("both", "manipulator", "twin-rotor"))
    ap.add_argument("--structure", default="arx", choices=("arx", "oe", "bj", "plant"))
    ap.add_argument("--nc", default="2", help="bj: orders of C to try, e.g. 2,4,8")
    ap.add_argument("--nd", default="", help="bj: orders of D, one per --nc (default = nc)")
    ap.add_argument(
        "--amplitude",
        type=float,
        default=None,
        help="input range +-A instead of the preset's (+-0.3 N m, +-1 V)",
    )
    ap.add_argument(
        "--plant-params",
        default="{}",
        help='physical overrides as JSON, e.g. \'{"a1": 0, "B2psi": 0}\'',
    )
    args = ap.parse_args()
    cases = []
    if args.plant in ("both", "manipulator"):
        modes = beam.exact_frequencies(beam.BeamParameters(), 3)
        cases.append(("manipulator", "paper-manipulator", 8, modes, 0.05, (1.0, 150.0)))
    if args.plant in ("both", "twin-rotor"):
        f0, _ = twin_rotor_physics.pitch_linear_mode(twin_rotor_physics.TwinRotorParameters())
        cases.append(("twin-rotor", "paper-twin-rotor", 5, np.array([f0]), 0.03, (0.02, 2.0)))
    extra = _orders_list(args.orders)
    overrides = json.loads(args.plant_params)
    level = {} if args.amplitude is None else {"low": -args.amplitude, "high": args.amplitude}
    if args.structure == "bj":
        ncs = _orders_list(args.nc)
        nds = _orders_list(args.nd) or ncs
        if len(nds) != len(ncs):
            ap.error("--nd needs one order per --nc")
        noise = list(zip(ncs, nds))
    else:
        noise = [(0, 0)]
    for plant, preset, order, targets, tol, band in cases:
        note = ("; " + args.plant_params if overrides else "") + (
            f"; input +-{args.amplitude}" if level else ""
        )
        print(
            f"{preset} ({args.sensors} sensors{note}); plant resonances {np.round(targets, 3)} Hz"
        )

        def record(seed: int, plant: str = plant, preset: str = preset, sensors=args.sensors):
            return generate(
                plant,
                preset=preset,
                seed=seed,
                sensors=sensors,
                plant_params=overrides,
                signal_options=level,
            )

        seeds = range(args.seeds)
        if args.structure == "plant" and plant != "twin-rotor":
            # the manipulator's chain has dynamics of its own: the record read without it is
            # not the model of the record read with it
            print("  plant's own model: twin rotor only (its chain is the encoder alone)")
            continue
        if args.structure == "plant":
            # the plant's own (nonlinear) model at its true parameters: its output is the
            # record read without the chain, the same input (the seeds of the signal and of
            # the noise are separate), so the residual is what the chain adds
            rows = []
            for seed in seeds:
                data = record(seed)
                model = record(seed, sensors="ideal")
                if not np.array_equal(data.u, model.u):
                    raise SystemExit("the ideal-sensor record has another input")
                k = int(2 / 3 * data.y.shape[0])
                e = data.y[k:, 0] - model.y[k:, 0]
                tests = residual_tests(e, data.u[k:, 0])
                rows.append((fit_percent(data.y[k:, 0], model.y[k:, 0]), tests))
            fits = np.array([r[0] for r in rows])
            print(
                f"  plant's own model, true parameters: simulation fit {fits.mean():.2f} % "
                f"(min {fits.min():.2f}), correlation tests passed "
                f"{sum(all(t.passed for t in r[1]) for r in rows)}/{len(rows)} "
                f"(lags outside, auto/cross: {[[t.n_outside for t in r[1]] for r in rows]})"
            )
            continue
        if args.structure == "arx":
            for n in [order, *extra]:
                rows = [run_arx(record(seed), n, targets, tol, band) for seed in seeds]
                one = np.array([r[0] for r in rows])
                sim = np.array([r[1] for r in rows])
                print(
                    f"  ARX({n},{n},1): one-step {one.mean():.1f} % (min {one.min():.1f}), "
                    f"simulation {sim.mean():.1f} % (min {sim.min():.1f}), "
                    f"correlation tests passed {sum(r[2] for r in rows)}/{len(rows)} "
                    f"(lags outside, auto/cross: {[r[3] for r in rows]}), "
                    f"resonances within {tol:.0%}: {[r[4] for r in rows]} of {len(targets)}; "
                    f"model peaks seed 0: {np.round(rows[0][5], 2)} Hz"
                )
            continue
        for n in [order, *extra]:
            for nc, nd in noise:
                t0 = time.perf_counter()
                rows = [run_pem(record(seed), n, nc, nd, targets, tol, band) for seed in seeds]
                one = np.array([r["one"] for r in rows])
                sim = np.array([r["sim"] for r in rows])
                name = (
                    f"OE({n},{n},1)"
                    if args.structure == "oe"
                    else f"BJ(nb={n},nc={nc},nd={nd},nf={n},nk=1)"
                )
                k = len(rows)
                print(
                    f"  {name}: one-step {one.mean():.1f} % (min {one.min():.1f}; "
                    f"seeds {np.round(one, 1).tolist()}), "
                    f"simulation {sim.mean():.1f} % (min {sim.min():.1f}; "
                    f"seeds {np.round(sim, 1).tolist()}), "
                    f"auto test passed {sum(r['auto'] for r in rows)}/{k}, "
                    f"cross test passed {sum(r['cross'] for r in rows)}/{k}, "
                    f"both {sum(r['auto'] and r['cross'] for r in rows)}/{k} "
                    f"(lags outside, auto/cross: {[r['outside'] for r in rows]}), "
                    f"resonances within {tol:.0%}: {[r['hits'] for r in rows]} of "
                    f"{len(targets)}; model peaks seed 0: {np.round(rows[0]['peaks'], 2)} Hz; "
                    f"{time.perf_counter() - t0:.0f} s"
                )


if __name__ == "__main__":
    main()
