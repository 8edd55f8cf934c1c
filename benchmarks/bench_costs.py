"""Benchmark of the batched ARX costs.

16-parameter ARX(8, 8, 1), 1,500 samples from a lightly damped 8th-order system driven by a
random +-0.3 input with small noise, population 50.  Compares, in the same run:

(a) the one-step paper cost with the stability test (batched) against a per-candidate loop
    of the residual vector ``y - Phi theta`` plus ``np.roots``;
(b) the simulation paper cost (batched) against a per-candidate loop of ``np.roots`` +
    ``scipy.signal.lfilter`` (+ cost), and against a loop of ``lfilter`` alone;
(c) an FE with the fitted numerator (``ARXCost.fitted``, what the optimisers call with
    ``numerator="fit"``) against a plain one, and the route of ``nb + 1`` recursions it
    replaced;
(d) the simulation cost and the fitted one of a larger population (P = 128), and a whole DE
    run (population 64, the simulation cost with the fitted numerator), on one thread and on
    every core this process may use (``flexid.kernels.set_threads``).

Next to each cost: the multiply-adds one candidate needs, the rate this core's FMA
throughput allows for them (benchmarks/roofline.py, measured at the start of the run) and
the share of that bound reached.

Run:  python benchmarks/bench_costs.py
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # small matrices: threads only cost

import time

import numpy as np
import roofline
from scipy import signal

from flexid import kernels
from flexid.config import CostSpec, SearchSpec
from flexid.costs.arx import ARXCost
from flexid.data import IOData
from flexid.fit.estimation import build_problem
from flexid.models.arx import ARXStructure
from flexid.models.stability import is_stable
from flexid.optimisers import minimize


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

    P_big = 128
    X_big = one.theta_ls + rng.normal(size=(P_big, 16)) * np.r_[np.full(8, 1e-5), np.full(8, 1e-2)]
    cores = kernels.threads() if "FLEXID_THREADS" in os.environ else len(os.sched_getaffinity(0))

    def on_threads(n, fn):
        def run():
            kernels.set_threads(n)
            return fn()

        return run

    # a whole run as identify starts it: DE (population 64) on the simulation cost with the
    # fitted numerator, where a generation's own work (Python) comes between the calls
    problem = build_problem(IOData(u[:, None], y[:, None]), s, CostSpec(predictor="simulation"),
                            SearchSpec()).problem  # fmt: skip

    def de_run():
        return minimize("de", problem, 64 * 60, seed=1, params={"population": 64}).fun

    roof = roofline.measure()
    t = interleaved_medians(
        {
            "one": on_threads(1, lambda: one(X)),
            "one_loop": loop_one_step,
            "stab": lambda: is_stable(X[:, :8]),
            "sim": on_threads(1, lambda: sim(X)),
            "sim_loop": loop_simulation,
            "lf": loop_lfilter_only,
            # an FE of the optimisers' objective with numerator="fit": ARXCost.fitted
            "fit": on_threads(1, lambda: sim.fitted(X[:, :8])[1]),
            # the route of nb + 1 recursions it replaced, and then the plain cost
            "fit_old": on_threads(1, lambda: sim(np.hstack([
                X[:, :8], sim._simulation_numerators_refined(X[:, :8], 0, sim._state)]))),
        }
        | (  # threads only split the compiled kernels' work
            {
                "big1": on_threads(1, lambda: sim(X_big)),
                "bigN": on_threads(cores, lambda: sim(X_big)),
                "bigfit1": on_threads(1, lambda: sim.fitted(X_big[:, :8])[1]),
                "bigfitN": on_threads(cores, lambda: sim.fitted(X_big[:, :8])[1]),
                "de1": on_threads(1, de_run),
                "deN": on_threads(cores, de_run),
            }
            if kernels.BACKEND == "c"
            else {}
        )
    )
    kernels.set_threads(None)
    t_one, t_one_loop, t_stab = t["one"], t["one_loop"], t["stab"]
    t_sim, t_sim_loop, t_lf = t["sim"], t["sim_loop"], t["lf"]
    # multiply-adds per candidate: n = 16 parameters, na = nb = 8, K samples
    na, nb, nparam = 8, 8, 16
    f_stab = na * (na - 1)  # Schur-Cohn: (m - 1) pairs of updates at each step m
    f_one = nparam * nparam + nparam + f_stab  # R (theta - theta*), its norm, the test
    f_sim = k * (nparam + 1)  # recursion na, input part nb, squared error 1 per sample
    f_roots = 10 * na**3  # np.roots: eigenvalues of the companion matrix, ~10 n^3
    f_lf = n * (na + 1 + nb + 1)  # lfilter: the numerator and denominator taps per sample
    # fitted numerator (docs/identification.rst, "The numerator"), by lag sums: two
    # recursions (v, h), the lag sums of v, h and the target for the basis of nb + L delays
    # (L = na here; the nb - 1 sums of h with later v from the recursion instead), the plain
    # recursion at the solution; the
    # route it replaced: nb + 1 recursions, the (nb, nb) Gram matrix and right-hand side
    # twice (refinement), the residual, then the plain cost
    f_fit = k * (2 * na + 3 * (nb + na) - 1 - (nb - 1)) + f_sim + f_stab
    f_fit_old = k * ((nb + 1) * na + 2 * (nb * (nb + 1) // 2 + nb) + nb) + f_sim + 2 * f_stab
    rows = [
        ("one-step paper cost, batched (P=50)", t_one, P, f_one),
        ("  of which: Schur-Cohn stability test", t_stab, P, f_stab),
        ("one-step loop: residual + np.roots", t_one_loop, P, k * (nparam + 1) + f_roots),
        ("simulation paper cost, batched", t_sim, P, f_sim + f_stab),
        ("simulation loop: np.roots + lfilter + cost", t_sim_loop, P, f_sim + f_roots),
        ("loop of lfilter alone", t_lf, P, f_lf),
        ("simulation cost with fitted numerator", t["fit"], P, f_fit),
        ("  by nb + 1 recursions (the former route)", t["fit_old"], P, f_fit_old),
    ]
    if "big1" in t:
        rows += [
            (f"simulation cost, P={P_big}, 1 thread", t["big1"], P_big, f_sim + f_stab),
            (f"simulation cost, P={P_big}, {cores} threads", t["bigN"], P_big, f_sim + f_stab),
            (f"fitted numerator, P={P_big}, 1 thread", t["bigfit1"], P_big, f_fit),
            (f"fitted numerator, P={P_big}, {cores} threads", t["bigfitN"], P_big, f_fit),
        ]
    n_stable = int(is_stable(X[:, :8]).sum())
    print(f"ARX(8,8,1), N = {n} samples (K = {k}), population {P} ({n_stable} stable)")
    print(f"kernels: {kernels.BACKEND} (set FLEXID_KERNELS=numpy for the reference path)"
          + (f", {kernels._c.simd()[0]}" if kernels.BACKEND == "c" else ""))  # fmt: skip
    if roof:
        print(f"roofline ({roof['isa']}): FMA latency {roof['latency'] * 1e9:.2f} ns, throughput "
              f"{roof['throughput'] * 1e-9:.1f} double FMAs/ns on one core, "
              f"{roof['throughput_all'] * 1e-9:.1f} on {roof['cores']} at once")  # fmt: skip
    print(f"{'method':45s} {'time/call':>12s} {'candidates/s':>14s} {'FMA/cand':>9s} "
          f"{'bound/s':>12s} {'share':>6s}")  # fmt: skip
    for name, tt, p, fmas in rows:
        rate = p / tt
        all_cores = cores > 1 and name.endswith(f"{cores} threads")
        bound = 1 / roofline.bound(fmas, roof, all_cores) if roof else float("nan")
        print(f"{name:45s} {tt * 1e3:9.3f} ms {rate:14,.0f} {fmas:9,d} {bound:12,.0f} "
              f"{rate / bound:6.1%}")  # fmt: skip
    print(f"one-step speed-up over its loop:          {t_one_loop / t_one:6.1f}x  (target >= 30x)")
    print(f"one-step candidate evaluations per second: {P / t_one:,.0f}  (target >= 500,000)")
    print(f"simulation speed-up over np.roots+lfilter: {t_sim_loop / t_sim:6.1f}x")
    print(f"simulation speed-up over lfilter alone:    {t_lf / t_sim:6.1f}x  (target >= 35x)")
    if roof:
        best = t_lf / (P * roofline.bound(f_sim + f_stab, roof))
        print(f"  the most one core's FMA throughput allows: {best:6.1f}x")
        # a step of the recursion waits for the previous output: a chain of na dependent FMAs
        # in the direct form (the former kernel: 16 candidates in flight), of one FMA in the
        # transposed form with the state in registers (4 candidates per chain)
        lat = roof["latency"]
        print(f"  latency bounds of the recursion: {16 / (k * na * lat):,.0f} candidates/s "
              f"(direct form, 16 lanes), {4 / (k * lat):,.0f} (transposed, 4 lanes)")  # fmt: skip
    print(f"fitted numerator over a plain evaluation:  {t['fit'] / t_sim:6.1f}x  (target <= 3x; "
          f"the former route {t['fit_old'] / t_sim:.1f}x)")  # fmt: skip
    if "big1" in t:
        print(f"simulation, P={P_big}: {cores} threads over 1:  {t['big1'] / t['bigN']:6.2f}x "
              "(target >= 1.7x on 2 cores)")  # fmt: skip
        print(f"fitted numerator, P={P_big}: {cores} threads over 1:  "
              f"{t['bigfit1'] / t['bigfitN']:6.2f}x")  # fmt: skip
        print(f"DE run (P=64, 60 generations), {cores} threads over 1: "
              f"{t['de1'] / t['deN']:6.2f}x  ({t['de1'] * 1e3:.0f} ms on 1 thread; "
              "target >= 1.7x)")  # fmt: skip


if __name__ == "__main__":
    main()
