"""Benchmark of the batched ARX costs.

16-parameter ARX(8, 8, 1), 1,500 samples from a lightly damped 8th-order system driven by a
random +-0.3 input with small noise, population 50.  Compares, in the same run:

(a) the one-step paper cost with the stability test (batched) against a per-candidate loop
    of the residual vector ``y - Phi theta`` plus ``np.roots``;
(b) the simulation paper cost (batched) against a per-candidate loop of ``np.roots`` +
    ``scipy.signal.lfilter`` (+ cost), and against a loop of ``lfilter`` alone.

Run:  python benchmarks/bench_costs.py
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # small matrices: threads only cost

import time

import numpy as np
from scipy import signal

from flexid import kernels
from flexid.arx import ARXStructure
from flexid.objective import ARXCost
from flexid.stability import is_stable


def interleaved_medians(fns: dict, rounds: int = 15, budget: float = 0.02) -> dict:
    """Median time per call of each function, the functions timed in turn in every round.

    Timing them in turn (rather than one after the other) keeps the ratios honest on a
    shared machine whose speed drifts during the run.  Each function is called often
    enough per round to take about ``budget`` seconds.
    """
    numbers = {}
    for name, fn in fns.items():
        t = time.perf_counter()
        fn()
        numbers[name] = max(1, int(budget / max(time.perf_counter() - t, 1e-7)))
    times = {name: [] for name in fns}
    for _ in range(rounds):
        for name, fn in fns.items():
            n = numbers[name]
            t = time.perf_counter()
            for _ in range(n):
                fn()
            times[name].append((time.perf_counter() - t) / n)
    return {name: float(np.median(v)) for name, v in times.items()}


def main() -> None:
    rng = np.random.default_rng(0)
    ang = np.array([0.05, 0.3, 0.9, 2.0])
    poles = 0.99 * np.exp(1j * ang)
    a = np.poly(np.r_[poles, poles.conj()]).real
    b = rng.normal(size=8) * 0.1
    n = 1500
    u = rng.uniform(-0.3, 0.3, n)
    y = signal.lfilter(np.r_[0.0, b], a, u) + 1e-3 * rng.standard_normal(n)
    s = ARXStructure(8, 8, 1)
    P = 50
    one = ARXCost(s, (u, y), predictor="one-step")
    sim = ARXCost(s, (u, y), predictor="simulation")
    X = one.theta_ls + rng.normal(size=(P, 16)) * np.r_[np.full(8, 1e-5), np.full(8, 1e-2)]
    phi, target = s.regressors(u, y)
    k = target.size

    def loop_one_step():
        out = np.empty(P)
        for i, x in enumerate(X):
            e = target - phi @ x
            stable = np.abs(np.roots(np.r_[1.0, x[:8]])).max() < 1
            out[i] = 1e3 * np.sqrt(e @ e) / k + (0.0 if stable else 1e9)
        return out

    zi_state = y[:8][::-1]

    def loop_simulation():
        out = np.empty(P)
        for i, x in enumerate(X):
            den = np.r_[1.0, x[:8]]
            if np.abs(np.roots(den)).max() >= 1:
                out[i] = 1e9 + 1e3 * np.sqrt(target @ target) / k  # penalty + zero prediction
                continue
            forced = signal.lfilter(np.r_[0.0, x[8:]], [1.0], u)[8:]
            ys = signal.lfilter([1.0], den, forced, zi=signal.lfiltic([1.0], den, zi_state))[0]
            e = target - ys
            out[i] = 1e3 * np.sqrt(e @ e) / k
        return out

    def loop_lfilter_only():
        for x in X:
            signal.lfilter(np.r_[0.0, x[8:]], np.r_[1.0, x[:8]], u)

    np.testing.assert_allclose(one(X), loop_one_step(), rtol=1e-10)
    np.testing.assert_allclose(sim(X), loop_simulation(), rtol=1e-9)

    t = interleaved_medians(
        {
            "one": lambda: one(X),
            "one_loop": loop_one_step,
            "stab": lambda: is_stable(X[:, :8]),
            "sim": lambda: sim(X),
            "sim_loop": loop_simulation,
            "lf": loop_lfilter_only,
        }
    )
    t_one, t_one_loop, t_stab = t["one"], t["one_loop"], t["stab"]
    t_sim, t_sim_loop, t_lf = t["sim"], t["sim_loop"], t["lf"]
    rows = [
        ("one-step paper cost, batched (P=50)", t_one, P / t_one),
        ("  of which: Schur-Cohn stability test", t_stab, P / t_stab),
        ("one-step loop: residual + np.roots", t_one_loop, P / t_one_loop),
        ("simulation paper cost, batched", t_sim, P / t_sim),
        ("simulation loop: np.roots + lfilter + cost", t_sim_loop, P / t_sim_loop),
        ("loop of lfilter alone", t_lf, P / t_lf),
    ]
    n_stable = int(is_stable(X[:, :8]).sum())
    print(f"ARX(8,8,1), N = {n} samples (K = {k}), population {P} ({n_stable} stable)")
    print(f"kernels: {kernels.BACKEND} (set FLEXID_KERNELS=numpy for the reference path)")
    print(f"{'method':45s} {'time/call':>12s} {'candidates/s':>14s}")
    for name, t, rate in rows:
        print(f"{name:45s} {t * 1e3:9.3f} ms {rate:14,.0f}")
    print(f"one-step speed-up over its loop:          {t_one_loop / t_one:6.1f}x  (target >= 30x)")
    print(f"one-step candidate evaluations per second: {P / t_one:,.0f}  (target >= 500,000)")
    print(f"simulation speed-up over np.roots+lfilter: {t_sim_loop / t_sim:6.1f}x")
    print(f"simulation speed-up over lfilter alone:    {t_lf / t_sim:6.1f}x  (target >= 5x)")


if __name__ == "__main__":
    main()
