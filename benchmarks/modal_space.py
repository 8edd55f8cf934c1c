"""Every optimiser in the modal state-space space, against the subspace route and ssest.

For each plant, one record (seed 0, lab sensors, several outputs), split 2/3 : 1/3; the
twin rotor's estimation means are removed from both parts (it works about an operating
point), the manipulator's are not (its torque and hub angle have a physical zero, and a
removed torque mean would be integrated twice by the rigid body).  Rows:

* ``n4sid``: subspace identification (:func:`flexid.n4sid`), its own gains and initial state;
* ``ssest``: the reference (:func:`flexid.fit.statespace_fit.ssest`'s Levenberg-Marquardt from the
  subspace poles and 3 random starts), one run;
* every optimiser of ``--optimisers``, ``--runs`` runs (seeds 0, 1, ...) at ``--budget`` FE in
  the modal space (log frequency and damping of each mode, log corner of each real pole, the
  gains and initial state fitted for each candidate), the same posed problem and the same
  initial population for every optimiser at a seed.

Each run's model is validated on the held-out part, output by output (initial state
estimated).  Printed per row: the cost over the reference's (median), each output's
held-out simulation fit (median) and share of runs whose model passes that output's
correlation tests, and for the manipulator the share of runs that found each flexible mode
of the simulated beam (its finite-difference model's own frequencies,
:func:`flexid.envs.beam.natural_frequencies`) within 1 %, with the median damping found.

Plants and structures:

* ``manipulator``: the paper-manipulator preset with hub angle and end-point acceleration,
  order 16 with 7 modes (two real poles: the rigid body and the hub friction);
* ``manipulator-tip``: the end-point acceleration alone, the same order: the main job's
  record (``flexid compare``'s OE(16,16,1)), for a like-for-like comparison;
* ``twin-rotor``: both rotors to pitch and yaw (the plant's own excitation, 3,000 samples),
  order 6 with 1 mode.

Each finished run is appended at once to ``--out`` (JSON lines, default
``modal-space.jsonl``; an existing file is refused, nothing is mixed).

    python benchmarks/modal_space.py [--runs 10] [--budget 10000] [--plants manipulator]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # small matrices: threads only cost

import argparse
import json
import platform
import subprocess
import time
from pathlib import Path

import numpy as np

from flexid import minimize, n4sid
from flexid.config import CostSpec, SearchSpec
from flexid.data.datasets import generate
from flexid.envs import beam
from flexid.fit.estimation import build_problem
from flexid.fit.statespace_fit import ssest
from flexid.models.statespace import StateSpaceStructure
from flexid.validation import validate

OPTIMISERS = ("hbcsd", "bfa", "sda", "pso", "de", "cmaes", "lshade", "random-search")
PLANTS = {
    "manipulator": dict(preset="paper-manipulator", outputs=["hub_angle", "tip_acceleration"],
                        order=16, modes=7, detrend=False),
    "manipulator-tip": dict(plant="manipulator", preset="paper-manipulator",
                            outputs=["tip_acceleration"], order=16, modes=7, detrend=False),
    "twin-rotor": dict(outputs=["pitch", "yaw"], order=6, modes=1, detrend=True),
}  # fmt: skip
FOUND = 0.01  # a mode is found within 1 % of its frequency


def records(plant: str) -> tuple:
    cfg = PLANTS[plant]
    options = {"preset": cfg["preset"]} if "preset" in cfg else {}
    data = generate(cfg.get("plant", plant), seed=0, outputs=cfg["outputs"], **options)
    n_est = (2 * data.n_samples) // 3
    est, val = data.split(index=n_est)
    if cfg["detrend"]:
        mu_u, mu_y = est.u.mean(0), est.y.mean(0)
        est = est.replace(u=est.u - mu_u, y=est.y - mu_y)
        val = val.replace(u=val.u - mu_u, y=val.y - mu_y)
    return est, val, StateSpaceStructure(cfg["order"], est.n_inputs, est.n_outputs,
                                         n_modes=cfg["modes"])  # fmt: skip


def truth(plant: str) -> tuple[np.ndarray, np.ndarray] | None:
    if not plant.startswith("manipulator"):
        return None
    p = beam.BeamParameters()
    f = beam.natural_frequencies(p, n_modes=4)
    return f, np.array([p.damping_ratio(k) for k in range(1, 5)])


def row(model, est, val, cost_value: float, reference: float, modes_true) -> dict:
    names = list(est.output_names)
    model = model.named(est.input_names, names)
    reports = [validate(model, val, output=o) for o in names]
    out = {
        "cost_ratio": cost_value / reference,
        "fit": {o: float(r.fit_simulation) for o, r in zip(names, reports)},
        "passed": {o: bool(r.passed) for o, r in zip(names, reports)},
        "modes": [(m.frequency, m.damping) for m in model.modes() if m.kind == "pair"],
    }
    if modes_true is not None:
        found = []
        for f in modes_true[0]:
            near = [(abs(fm - f) / f, z) for fm, z in out["modes"]]
            best = min(near, default=(np.inf, np.nan))
            found.append([bool(best[0] <= FOUND), float(best[1]) if best[0] <= FOUND else None])
        out["found"] = found
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=10)
    ap.add_argument("--budget", type=int, default=10000)
    ap.add_argument("--plants", default="manipulator,twin-rotor")
    ap.add_argument("--optimisers", default=",".join(OPTIMISERS))
    ap.add_argument("--out", default="modal-space.jsonl")
    args = ap.parse_args()
    out = Path(args.out)
    if out.exists():
        raise SystemExit(f"{out} exists: give another --out (runs are never mixed)")
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True, cwd=Path(__file__).parent).stdout.strip()  # fmt: skip
    print(f"modal space: runs {args.runs}, budget {args.budget} FE, commit {commit}, "
          f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores")  # fmt: skip
    with out.open("x") as sink:
        for plant in args.plants.split(","):
            est, val, structure = records(plant)
            modes_true = truth(plant)
            problem = build_problem(est, structure, CostSpec(predictor="simulation"),
                                    SearchSpec())  # fmt: skip
            t = time.perf_counter()
            ref = ssest(est, structure.order, modes=structure.n_modes, seed=0)
            ref_cost = float(problem.cost(ref.x[None])[0])
            results = {"ssest": [row(ref.model, est, val, ref_cost, ref_cost, modes_true)]}
            results["ssest"][0]["seconds"] = time.perf_counter() - t
            t = time.perf_counter()
            sub = n4sid(est, structure.order)
            e = (est.y - sub.model.simulate(est.u)) / problem.cost.scale
            sub_cost = float(problem.cost.score(float(np.sum(e * e))))
            results["n4sid"] = [row(sub.model, est, val, sub_cost, ref_cost, modes_true)]
            results["n4sid"][0]["seconds"] = time.perf_counter() - t
            for name in ("ssest", "n4sid"):
                sink.write(json.dumps({"plant": plant, "row": name, **results[name][0]}) + "\n")
            for name in args.optimisers.split(","):
                results[name] = []
                for seed in range(args.runs):
                    t = time.perf_counter()
                    res = minimize(name, problem.problem, args.budget, seed=seed)
                    model = structure.model(problem.theta(res.x), est.dt)
                    r = row(model, est, val, float(res.fun), ref_cost, modes_true)
                    r["seconds"] = time.perf_counter() - t
                    results[name].append(r)
                    sink.write(json.dumps({"plant": plant, "row": name, "seed": seed, **r}) + "\n")
                    sink.flush()
            report(plant, est, results, modes_true)


def report(plant: str, est, results: dict, modes_true) -> None:
    names = list(est.output_names)
    print(f"\n{plant}: outputs {names}")
    head = f"{'row':<14} {'cost/ref':>9} " + " ".join(f"{'fit ' + o:>18}" for o in names)
    head += " " + " ".join(f"{'pass ' + o[:10]:>16}" for o in names)
    if modes_true is not None:
        head += " " + " ".join(f"{f:>9.2f}Hz" for f in modes_true[0])
    print(head + f" {'s/run':>6}")
    for name, rows in results.items():
        line = f"{name:<14} {np.median([r['cost_ratio'] for r in rows]):>9.4g} "
        line += " ".join(f"{np.median([r['fit'][o] for r in rows]):>18.1f}" for o in names)
        line += " " + " ".join(f"{np.mean([r['passed'][o] for r in rows]):>16.0%}" for o in names)
        if modes_true is not None:
            for k in range(len(modes_true[0])):
                hits = [r["found"][k] for r in rows]
                share = np.mean([h[0] for h in hits])
                z = [h[1] for h in hits if h[0]]
                line += f" {share:>4.0%} {np.median(z) if z else float('nan'):>6.3f}"
        line += f" {np.median([r['seconds'] for r in rows]):>6.2f}"
        print(line)
    if modes_true is not None:
        print("truth damping " + " ".join(f"{z:.4f}" for z in modes_true[1]))


if __name__ == "__main__":
    main()
