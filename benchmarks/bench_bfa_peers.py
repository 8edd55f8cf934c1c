"""flexid's BFA side by side with mealpy's BFO and niapy's BFO at the same FE budget.

Run (the peers live in a separate venv so the main one stays clean)::

    python3 -m venv /work/venv-peers
    /work/venv-peers/bin/pip install mealpy==3.0.3 niapy==2.7.1
    /work/venv-peers/bin/pip install -e /work/main
    /work/venv-peers/bin/python benchmarks/bench_bfa_peers.py [--budget 10000] [--seeds 10]

A peer that is not installed is skipped.  Every implementation gets Passino's defaults
(S = 50, C = 0.1, N_s = 4, N_c = 100, N_re = 4, N_ed = 2, p_ed = 0.25) where it has them, the
same objective (16-D shifted sphere or Rastrigin on [-5, 5]^16) and the same FE budget.  FE
are counted by a wrapper around the objective (the peers evaluate one vector at a time);
mealpy checks its budget only between epochs and overshoots, which the table shows.

Known problems of the peer implementations, which the table shows:

* mealpy 3.0.3 ``OriginalBFO`` passes ``Ci`` through ``check_int``: any ``Ci < 1`` becomes a
  step of 0, so its bacteria never move and progress comes only from re-initialisation and
  selection.  It also draws tumble directions from U(lb, ub) and reproduces/disperses after
  every chemotactic step.  It is reported as "mealpy BFO", not as a faithful BFA.
* niapy 2.7.1 has ``swarming=True`` by default (Euclidean, not squared, distance in J_cc) and
  never updates ``j_last`` during a swim; it is run with swarming on and off.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from flexid.optimisers import Problem, minimize

N = 16
SHIFT = np.linspace(-1.0, 1.0, N)
LOW, HIGH = -5.0, 5.0


def batch_sphere(X: np.ndarray) -> np.ndarray:
    return ((X - SHIFT) ** 2).sum(axis=1)


def batch_rastrigin(X: np.ndarray) -> np.ndarray:
    Z = X - SHIFT
    return 10 * Z.shape[1] + (Z**2 - 10 * np.cos(2 * np.pi * Z)).sum(axis=1)


FUNCTIONS = {"sphere": batch_sphere, "rastrigin": batch_rastrigin}


class Counter:
    """Per-vector objective for the peers, counting calls."""

    def __init__(self, batch) -> None:
        self.batch, self.calls = batch, 0

    def __call__(self, x) -> float:
        self.calls += 1
        return float(self.batch(np.asarray(x, dtype=float)[None, :])[0])


def run_flexid(batch, budget: int, seed: int) -> tuple[float, int]:
    rows = [0]

    def f(X):
        rows[0] += X.shape[0]
        return batch(X)

    res = minimize("bfa", Problem(f, LOW * np.ones(N), HIGH * np.ones(N)), budget, seed=seed)
    assert res.nfev == rows[0]
    return res.fun, rows[0]


def run_mealpy(batch, budget: int, seed: int) -> tuple[float, int]:
    from mealpy import BFO, FloatVar

    f = Counter(batch)
    model = BFO.OriginalBFO(epoch=100_000, pop_size=50, Ci=0.1, Ped=0.25, Nc=5, Ns=4)
    problem = {"bounds": FloatVar(lb=[LOW] * N, ub=[HIGH] * N), "obj_func": f, "minmax": "min",
               "log_to": None}
    best = model.solve(problem, seed=seed, termination={"max_fe": budget})
    return float(best.target.fitness), f.calls


def make_niapy(swarming: bool):
    def run_niapy(batch, budget: int, seed: int) -> tuple[float, int]:
        from niapy.algorithms.basic import BacterialForagingOptimization
        from niapy.problems import Problem as NiaProblem
        from niapy.task import Task

        f = Counter(batch)

        class Wrapped(NiaProblem):
            def __init__(self) -> None:
                super().__init__(dimension=N, lower=LOW, upper=HIGH)

            def _evaluate(self, x):
                return f(x)

        algo = BacterialForagingOptimization(
            population_size=50, n_chemotactic=100, n_swim=4, n_reproduction=4,
            n_elimination=2, prob_elimination=0.25, step_size=0.1, swarming=swarming,
            seed=seed,
        )
        _, best = algo.run(Task(problem=Wrapped(), max_evals=budget))
        return float(best), f.calls

    return run_niapy


def available(module: str) -> bool:
    try:
        __import__(module)
    except ImportError:
        return False
    return True


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--budget", type=int, default=10_000)
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--function", choices=sorted(FUNCTIONS), default="sphere")
    args = ap.parse_args()
    batch = FUNCTIONS[args.function]

    runners = [("flexid bfa", run_flexid, True)]
    runners.append(("mealpy BFO (Ci=0.1 -> 0)", run_mealpy, available("mealpy")))
    runners.append(("niapy BFO swarming=True", make_niapy(True), available("niapy")))
    runners.append(("niapy BFO swarming=False", make_niapy(False), available("niapy")))

    print(f"{N}-D shifted {args.function} on [{LOW:g}, {HIGH:g}]^{N}, budget {args.budget} FE, "
          f"{args.seeds} seeds")
    header = f"{'implementation':<28}{'median best':>13}{'IQR':>21}{'FE used':>15}"
    print(header + f"{'s/run':>9}{'time/flexid':>13}")
    base_time = None
    for label, run, ok in runners:
        if not ok:
            print(f"{label:<28}  skipped (not installed)")
            continue
        best, fe, secs = [], [], []
        for seed in range(args.seeds):
            t = time.perf_counter()
            b, used = run(batch, args.budget, seed)
            secs.append(time.perf_counter() - t)
            best.append(b)
            fe.append(used)
        wall = float(np.median(secs))
        if base_time is None:
            base_time = wall
        q1, q3 = np.percentile(best, [25, 75])
        fe_text = f"{min(fe)}-{max(fe)}" if min(fe) != max(fe) else str(fe[0])
        print(f"{label:<28}{np.median(best):>13.4g}{f'[{q1:.3g}, {q3:.3g}]':>21}"
              f"{fe_text:>15}{wall:>9.3f}{wall / base_time:>13.1f}")


if __name__ == "__main__":
    main()
