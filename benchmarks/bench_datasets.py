"""Benchmark of dataset generation and the twin-rotor environments.

Times ``generate(preset=...)`` for both paper presets (first call, which builds and caches
the manipulator model, and warm calls), every signal generator for 10^5 samples, and the
twin-rotor environment step rate (single and batched vector environment).  The manipulator
environment rates are in ``bench_manipulator.py``.

Run:  python benchmarks/bench_datasets.py
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import time

import numpy as np

from flexid.data.datasets import generate
from flexid.data.signals import make_signal
from flexid.envs.twin_rotor import TwinRotorEnv, TwinRotorVectorEnv


def timed(fn, repeat=5):
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return float(np.median(times))


def main() -> None:
    t = time.perf_counter()
    generate("manipulator", preset="paper-manipulator", seed=0)
    first = time.perf_counter() - t
    warm = timed(lambda: generate("manipulator", preset="paper-manipulator", seed=1), 10)
    trs = timed(lambda: generate("twin-rotor", preset="paper-twin-rotor", seed=0), 3)
    print(f"{'dataset':45s} {'time':>10s}  target")
    print(f"{'paper-manipulator (2,300 samples), first call':45s} {first * 1e3:8.1f} ms")
    print(f"{'paper-manipulator (2,300 samples), warm':45s} {warm * 1e3:8.1f} ms  < 20 ms")
    print(f"{'paper-twin-rotor (8,000 samples, RK4 10 ms)':45s} {trs * 1e3:8.1f} ms  < 1000 ms")
    print()
    rng = np.random.default_rng(0)
    options = {"multisine": {"band": (1.0, 100.0)}, "chirp": {"f0": 1.0, "f1": 100.0}}
    for name in ("prbs", "random", "uniform", "aprbs", "multisine", "chirp", "bang_bang"):
        dt = timed(lambda n=name: make_signal(n, 100_000, 1e-3, rng=rng, **options.get(n, {})))
        print(f"signal {name:12s} 10^5 samples  {dt * 1e3:8.2f} ms")
    print()
    env = TwinRotorEnv()
    env.reset(seed=0)
    a = np.array([0.3, -0.1])
    n = 2000
    t = time.perf_counter()
    for _ in range(n):
        env.step(a)
    single = n / (time.perf_counter() - t)
    print(f"twin rotor single env: {single:,.0f} steps/s ({single * 0.1:,.0f}x real time)")
    for num in (16, 256):
        vec = TwinRotorVectorEnv(num, max_episode_steps=10_000)
        vec.reset(seed=0)
        acts = np.tile(a, (num, 1))
        steps = 200
        t = time.perf_counter()
        for _ in range(steps):
            vec.step(acts)
        rate = steps * num / (time.perf_counter() - t)
        print(f"twin rotor vector env, {num:3d} envs: {rate:,.0f} env-steps/s")


if __name__ == "__main__":
    main()
