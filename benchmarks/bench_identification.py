"""Identification quality by search space: optimisers x parametrisations x costs x problems.

Run by hand (several minutes on 2 cores; ``--seeds`` and ``--fe`` make it shorter)::

    python benchmarks/bench_identification.py --seeds 10 --fe 20000 --out bench-ident.json
    python benchmarks/bench_identification.py --spaces "poles (b fitted)" --problems robot

Problems: the simulated manipulator (``paper-manipulator``, ARX(8,8,1)), the simulated twin
rotor (``paper-twin-rotor``, ARX(5,5,1)) and the DaISy robot arm (ARX(8,8,0)) when
``../shared/data/real/robot_arm.csv`` is present.  For each cost (one-step, simulation) the
reference is least squares (one-step) or the best of least squares and the output-error
reference (simulation).  For every optimiser and search space it reports the median and best
final cost over the reference, the share of stable final models and the median FE to reach
1 % of the reference (runs that never reach it count as missing).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

import flexid
from flexid.config import PAPER_SEARCH, CostSpec, SearchSpec
from flexid.data import prepare_data
from flexid.fit.estimation import build_problem, model_structure
from flexid.models.stability import is_stable
from flexid.optimisers import minimize

ROBOT_ARM = Path(__file__).resolve().parents[2] / "shared" / "data" / "real" / "robot_arm.csv"
OPTIMISERS = ("hbcsd", "bfa", "sda", "pso", "de", "cmaes", "random-search")
SPACES = {
    "coefficients (paper: flat, uniform)": PAPER_SEARCH,
    "coefficients (graded, stable init)": SearchSpec(
        parametrisation="coefficients", numerator="search"
    ),
    "poles": SearchSpec(parametrisation="poles", numerator="search"),
    "reflection": SearchSpec(parametrisation="reflection", numerator="search"),
    "poles (b fitted)": SearchSpec(parametrisation="poles", numerator="fit"),
    "reflection (b fitted)": SearchSpec(parametrisation="reflection", numerator="fit"),
}


def problems():
    # docs/measurements/search-spaces.md was measured on the plants without their measurement chain
    man = flexid.generate("manipulator", preset="paper-manipulator", seed=0, sensors="ideal")
    yield "manipulator ARX(8,8,1)", man, (8, 8, 1)
    trs = flexid.generate(
        "twin-rotor", preset="paper-twin-rotor", seed=0, sensors="ideal", noise_std="1%"
    )
    yield "twin rotor ARX(5,5,1)", trs, (5, 5, 1)
    if ROBOT_ARM.exists():
        arm = flexid.load(ROBOT_ARM, inputs=["u"], outputs=["y"], dt=0.01)
        yield "robot arm ARX(8,8,0)", arm, (8, 8, 0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--fe", type=int, default=20_000)
    ap.add_argument("--optimisers", default=",".join(OPTIMISERS))
    ap.add_argument("--predictors", default="one-step,simulation")
    ap.add_argument("--spaces", default=";".join(SPACES), help="space names, separated by ;")
    ap.add_argument("--problems", default="", help="substrings of problem names (default all)")
    ap.add_argument("--out", default="bench-identification.json")
    args = ap.parse_args()
    rows = []
    spaces = {name: SPACES[name] for name in args.spaces.split(";")}
    wanted = [w for w in args.problems.split(",") if w]
    for pname, data, (na, nb, nk) in problems():
        if wanted and not any(w in pname for w in wanted):
            continue
        est, _ = prepare_data(data)
        structure = model_structure(na, nb, nk, est.n_inputs)
        for predictor in args.predictors.split(","):
            cost = CostSpec(predictor=predictor)
            for sname, search in spaces.items():
                ep = build_problem(est, structure, cost, search)
                ref, ref_name = ep.reference_cost()
                for opt in args.optimisers.split(","):
                    t0 = time.perf_counter()
                    finals, stable, to_1pc = [], [], []
                    for seed in range(args.seeds):
                        r = minimize(opt, ep.problem, args.fe, seed=seed)
                        theta = ep.theta(r.x)
                        finals.append(float(r.fun) / ref)
                        stable.append(bool(is_stable(theta[None, : structure.na])[0]))
                        fe = r.history.fe_to_reach(ref * 1.01)
                        to_1pc.append(np.nan if fe is None else fe)
                    row = {
                        "problem": pname,
                        "predictor": predictor,
                        "space": sname,
                        "optimiser": opt,
                        "reference": ref,
                        "reference_name": ref_name,
                        "median_over_ref": float(np.median(finals)),
                        "best_over_ref": float(np.min(finals)),
                        "stable_share": float(np.mean(stable)),
                        "reached_1pc": int(np.sum(np.isfinite(to_1pc))),
                        "median_fe_to_1pc": float(np.nanmedian(to_1pc))
                        if np.isfinite(to_1pc).any()
                        else None,
                        "seconds": time.perf_counter() - t0,
                    }
                    rows.append(row)
                    print(
                        f"{pname:24s} {predictor:10s} {sname:36s} {opt:13s} "
                        f"median {row['median_over_ref']:.4g} best {row['best_over_ref']:.4g} "
                        f"stable {row['stable_share']:.0%} 1%: {row['reached_1pc']}/{args.seeds}",
                        flush=True,
                    )
                Path(args.out).write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
