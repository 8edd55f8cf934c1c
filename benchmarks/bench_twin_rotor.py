"""Speed of the twin-rotor environments and dataset, as ratios to reference environments.

Run: ``.venv/bin/python benchmarks/bench_twin_rotor.py [--repeat 5]`` (the compiled route when
the kernels are built; ``FLEXID_KERNELS=numpy`` in the environment times the Python route).
Prints a table of

* single-environment step rate (``env.step``, no wrappers) of ``TwinRotorEnv`` (yaw free, the
  default) against gymnasium's ``Pendulum-v1`` and ``FlexibleManipulatorEnv``; the same
  through ``gymnasium.make`` (its default wrappers), and the locked-yaw configuration;
* vector throughput (env-steps/s) of ``TwinRotorVectorEnv`` with 64 environments against
  ``FlexibleManipulatorVectorEnv`` with 64, plus the locked yaw and 256 environments;
* the 8,000-sample ``paper-twin-rotor`` dataset, yaw free and yaw locked (the preset);
* the reference route (``reference_trajectory``: batched NumPy RK4 on one state) against the
  fast route (``simulate``) on the same 800 samples.

Every case is timed ``--repeat`` times, interleaved with the others, and the best time is
kept: on a shared machine other load only ever slows a run down, and interleaving exposes
every case to the same load, so the ratios are comparable within one run.
"""

from __future__ import annotations

import os

# Small matrix products: multi-threaded BLAS only adds overhead.  Respect a user setting.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402
from _table import print_table  # noqa: E402

import flexid  # noqa: E402
from flexid.envs.manipulator import (  # noqa: E402
    FlexibleManipulatorEnv,
    FlexibleManipulatorVectorEnv,
)
from flexid.envs.twin_rotor import TwinRotorEnv, TwinRotorVectorEnv  # noqa: E402
from flexid.envs.twin_rotor_physics import reference_trajectory  # noqa: E402
from flexid.envs.twin_rotor_steppers import simulate  # noqa: E402

N_ENVS = 64


def _single(env, actions: list) -> Callable[[], int]:
    env.reset(seed=0)

    def run() -> int:
        env.reset(seed=0)
        for a in actions:
            env.step(a)
        return len(actions)

    return run


def _vector(env, action: np.ndarray, steps: int) -> Callable[[], int]:
    env.reset(seed=0)

    def run() -> int:
        env.reset(seed=0)
        for _ in range(steps):
            env.step(action)
        return steps * env.num_envs

    return run


def _once(fn: Callable[[], object]) -> Callable[[], int]:
    def run() -> int:
        fn()
        return 1

    return run


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5, help="timed runs per case (best kept)")
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    twin_actions = list(rng.uniform(-1, 1, (1000, 2)))
    pendulum_actions = list(rng.uniform(-2, 2, (10000, 1)).astype(np.float32))
    manipulator_actions = list(rng.uniform(-0.3, 0.3, (10000, 1)))
    long = {"max_episode_steps": 10**9}
    short_record = rng.uniform(-1, 1, (800, 2))

    def twin_vec(n: int, **kwargs) -> Callable[[], int]:
        env = TwinRotorVectorEnv(n, max_episode_steps=10**9, **kwargs)
        return _vector(env, rng.uniform(-1, 1, (n, 2)), max(20, 6400 // n))

    def dataset(**params) -> Callable[[], int]:
        return _once(lambda: flexid.generate(
            "twin-rotor", preset="paper-twin-rotor", plant_params=params))  # fmt: skip

    cases: dict[str, tuple[Callable[[], int], str]] = {
        "Pendulum-v1": (_single(gym.make("Pendulum-v1").unwrapped, pendulum_actions), "steps/s"),
        "FlexibleManipulator-v0": (
            _single(FlexibleManipulatorEnv(), manipulator_actions), "steps/s"),
        "TwinRotor-v0": (_single(TwinRotorEnv(), twin_actions), "steps/s"),
        "TwinRotor-v0, lock_yaw": (_single(TwinRotorEnv(lock_yaw=True), twin_actions), "steps/s"),
        "Pendulum-v1, gymnasium.make": (
            _single(gym.make("Pendulum-v1", **long), pendulum_actions), "steps/s"),
        "TwinRotor-v0, gymnasium.make": (
            _single(gym.make("flexid/TwinRotor-v0", **long), twin_actions), "steps/s"),
        f"manipulator vector, {N_ENVS} envs": (
            _vector(FlexibleManipulatorVectorEnv(N_ENVS, **long),
                    rng.uniform(-0.3, 0.3, (N_ENVS, 1)), 1000), "env-steps/s"),
        f"twin rotor vector, {N_ENVS} envs": (twin_vec(N_ENVS), "env-steps/s"),
        f"twin rotor vector, {N_ENVS} envs, lock_yaw": (
            twin_vec(N_ENVS, lock_yaw=True), "env-steps/s"),
        "twin rotor vector, 256 envs": (twin_vec(256), "env-steps/s"),
        "dataset 8000 samples, yaw free": (dataset(lock_yaw=False), "s"),
        "dataset 8000 samples, lock_yaw (preset)": (dataset(), "s"),
        "simulate 800 samples (fast route)": (_once(lambda: simulate(short_record)), "s"),
    }
    best = {name: float("inf") for name in cases}
    work = {}
    for _ in range(args.repeat):
        for name, (fn, _unit) in cases.items():
            t0 = time.perf_counter()
            work[name] = fn()
            best[name] = min(best[name], time.perf_counter() - t0)
    # seconds per run: once is enough
    t0 = time.perf_counter()
    reference_trajectory(short_record)
    cases["reference_trajectory 800 samples"] = (lambda: 1, "s")
    best["reference_trajectory 800 samples"] = time.perf_counter() - t0
    work["reference_trajectory 800 samples"] = 1

    def rate(name: str) -> float:
        return work[name] / best[name]

    rows = []
    for name, (_fn, unit) in cases.items():
        value = best[name] if unit == "s" else rate(name)
        rows.append((name, f"{value:12.4g} {unit}"))
    ratios = (
        ("TwinRotor-v0 / Pendulum-v1 (target >= 0.6)", rate("TwinRotor-v0") / rate("Pendulum-v1")),
        ("same, through gymnasium.make",
         rate("TwinRotor-v0, gymnasium.make") / rate("Pendulum-v1, gymnasium.make")),
        ("TwinRotor-v0 / FlexibleManipulator-v0",
         rate("TwinRotor-v0") / rate("FlexibleManipulator-v0")),
        (f"twin rotor / manipulator vector, {N_ENVS} envs (target >= 0.5)",
         rate(f"twin rotor vector, {N_ENVS} envs") / rate(f"manipulator vector, {N_ENVS} envs")),
        ("reference route / fast route, 800 samples",
         best["reference_trajectory 800 samples"] / best["simulate 800 samples (fast route)"]),
    )  # fmt: skip
    rows += [(f"ratio {name}", f"{value:12.3f}") for name, value in ratios]
    print_table(rows, f"best of {args.repeat}; BLAS threads: "
                      f"OPENBLAS_NUM_THREADS={os.environ['OPENBLAS_NUM_THREADS']}")  # fmt: skip


if __name__ == "__main__":
    main()
