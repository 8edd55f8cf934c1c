"""Speed of the flexible-manipulator physics and environments.

Run: ``/work/venv/bin/python benchmarks/bench_manipulator.py``.  Prints a table of

* ``beam.simulate`` for a 2,300-sample random +-0.3 N m torque at 1 ms (n = 40 sections):
  first call (builds and caches the ZOH model and impulse response) and cached calls;
  a batch of 64 such runs; the Coulomb-friction (stepped) path;
* single-environment step rate (``FlexibleManipulatorEnv.step``, no wrappers);
* vector-environment throughput (env-steps/s) for 1, 16 and 256 environments.
"""

from __future__ import annotations

import os

# Small (82 x 82) matrix products: multi-threaded BLAS only adds overhead, and much more of
# it on a shared machine.  Respect a user setting, default to one thread.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import time  # noqa: E402

import numpy as np  # noqa: E402
from _table import print_table  # noqa: E402

from flexid.envs import beam  # noqa: E402
from flexid.envs.manipulator import (  # noqa: E402
    FlexibleManipulatorEnv,
    FlexibleManipulatorVectorEnv,
)


def _best(fn, repeat: int = 5) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    rng = np.random.default_rng(0)
    u = rng.uniform(-0.3, 0.3, 2300)
    rows: list[tuple[str, str]] = []

    beam._discrete.cache_clear()
    beam._continuous.cache_clear()
    beam._modes.cache_clear()
    beam._fd_matrices.cache_clear()
    t0 = time.perf_counter()
    beam.simulate(u)
    rows.append(("simulate 2300 samples, first call (model build)",
                 f"{1e3 * (time.perf_counter() - t0):8.2f} ms"))  # fmt: skip
    rows.append(("simulate 2300 samples, cached model",
                 f"{1e3 * _best(lambda: beam.simulate(u), 20):8.2f} ms"))  # fmt: skip
    ub = rng.uniform(-0.3, 0.3, (64, 2300))
    rows.append(("simulate batch 64 x 2300, cached",
                 f"{1e3 * _best(lambda: beam.simulate(ub)):8.2f} ms"))  # fmt: skip
    pc = beam.BeamParameters(hub_coulomb_friction=0.02)
    beam.simulate(u, pc)
    rows.append(("simulate 2300, Coulomb friction (stepped)",
                 f"{1e3 * _best(lambda: beam.simulate(u, pc), 3):8.2f} ms"))  # fmt: skip

    env = FlexibleManipulatorEnv()
    env.reset(seed=0)
    actions = rng.uniform(-0.3, 0.3, (5000, 1))

    def run_single():
        for a in actions:
            env.step(a)

    t = _best(run_single, 3)
    rows.append(("single env step rate", f"{len(actions) / t:10.0f} steps/s"))

    for n in (1, 16, 256):
        venv = FlexibleManipulatorVectorEnv(n, max_episode_steps=10**9)
        venv.reset(seed=0)
        a = rng.uniform(-0.3, 0.3, (n, 1))
        steps = max(200, 20000 // n)

        def run_vec(venv=venv, a=a, steps=steps):
            for _ in range(steps):
                venv.step(a)

        t = _best(run_vec, 3)
        rows.append((f"vector env, {n:3d} envs", f"{n * steps / t:10.0f} env-steps/s"))

    print_table(rows, f"BLAS threads: OPENBLAS_NUM_THREADS={os.environ['OPENBLAS_NUM_THREADS']}")


if __name__ == "__main__":
    main()
