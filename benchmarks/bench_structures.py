"""Benchmark of the structures' batched costs against ARX's, per candidate, in the same run.

The issue's target: an OE(16,16,1) and a BJ(16,2,2,16,1) cost per candidate at most 3x the
ARX(16,16,1) simulation cost per candidate, N = 1,500 (ARMAX(16,16,2,1) timed beside them).
Data: a lightly damped 16th-order
system (8 modes, radii 0.99) driven by a random +-0.3 input, coloured output noise;
population 50, every candidate stable (drawn in the pole space, the default search space).

Rows (microseconds per candidate, and the ratio to the ARX simulation cost of the same kind,
on one thread and on the default threads, ``flexid.kernels.threads()``):

* evaluation at given parameters (``cost(theta)``: what ``numerator = "search"`` costs);
* with the numerator fitted (variable projection, the default search space:
  ``ARXCost.fit_numerator`` then ``cost``, against ``PolynomialCost.fitted_costs``), for
  candidates drawn in the pole space and for candidates next to the plant's own poles;

each under the initial-condition rules the cost has (ARX: ``measured``; the structures:
``zero``, ``estimate`` and ``measured``).  Under ``estimate`` at given parameters the
structures' rows time the one-pass fit of the initial state
(:func:`flexid.kernels.initial_state_fit`).

Run:  python benchmarks/bench_structures.py [--simd avx2]
(``--simd``: the compiled kernels' instruction set, default the best this CPU has.)
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # small matrices: threads only cost

import numpy as np
from _simd import simd_from_arguments
from _table import print_table
from bench_costs import interleaved_medians
from scipy import signal

from flexid import kernels
from flexid.costs.arx import ARXCost
from flexid.costs.polynomial import PolynomialCost
from flexid.fit.polynomial_space import PolynomialSpace
from flexid.models.arx import ARXStructure
from flexid.models.polynomial import structure

N = 1500
P = 50


ANGLES = np.array([0.05, 0.15, 0.3, 0.6, 0.9, 1.4, 2.0, 2.6])
_POLES = 0.99 * np.exp(1j * ANGLES)
A_TRUE = np.poly(np.r_[_POLES, _POLES.conj()]).real  # the plant's denominator


def record(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    a = A_TRUE
    b = rng.normal(size=16) * 0.05
    u = rng.uniform(-0.3, 0.3, N)
    noise = signal.lfilter([1.0, 0.5], [1.0, -0.9], 0.01 * rng.standard_normal(N))
    return u, signal.lfilter(np.r_[0.0, b], a, u) + noise


def stable_population(struct, rng: np.random.Generator) -> np.ndarray:
    space = PolynomialSpace(struct, "poles", "search", b_lower=-0.1, b_upper=0.1, r_max=0.999)
    Z = space.lower + (space.upper - space.lower) * rng.random((P, space.n_search))
    return space.to_theta(Z)


def main() -> None:
    simd = simd_from_arguments(__doc__.splitlines()[0])
    rng = np.random.default_rng(0)
    u, y = record(rng)
    arx = ARXStructure(16, 16, 1)
    arx_cost = ARXCost(arx, (u, y), predictor="simulation", metric="rmse")
    X_arx = stable_population(structure("arx", na=16, nb=16, nk=1), rng)
    fns = {
        "ARX(16,16,1) simulation, measured": lambda: arx_cost(X_arx),
        "ARX(16,16,1) simulation, measured, b fitted": lambda: arx_cost(
            arx_cost.fit_numerator(X_arx[:, :16])
        ),
    }
    cases = {
        "OE(16,16,1)": structure("oe", nb=16, nf=16, nk=1),
        "BJ(16,2,2,16,1)": structure("bj", nb=16, nc=2, nd=2, nf=16, nk=1),
        "ARMAX(16,16,2,1)": structure("armax", na=16, nb=16, nc=2, nk=1),
    }
    for name, struct in cases.items():
        X = stable_population(struct, rng)
        for rule in ("zero", "estimate", "measured"):
            cost = PolynomialCost(struct, (u, y), metric="rmse", initial=rule)
            fns[f"{name} one-step, {rule}"] = lambda c=cost, X=X: c(X)
            fns[f"{name} one-step, {rule}, b fitted"] = lambda c=cost, X=X: c.fitted_costs(X)
    # where a search ends: F near the plant's own lightly damped denominator, the case in
    # which shifted regressors are numerically dependent (the orthogonal basis is used)
    oe = cases["OE(16,16,1)"]
    X = np.zeros((P, oe.n_params))
    X[:, 16:] = A_TRUE[1:] + 1e-7 * rng.standard_normal((P, 16))
    for rule in ("zero", "estimate", "measured"):
        cost = PolynomialCost(oe, (u, y), metric="rmse", initial=rule)
        ok = cost._admissible(X)
        near = X[ok]
        fns[f"OE(16,16,1) near the plant's poles, {rule}, b fitted"] = (
            lambda c=cost, X=near: c.fitted_costs(X)
        )
    # every row on one thread and on the default threads, interleaved: the ratios differ
    # because a call's fixed Python work is not split and weighs more on the cheaper ARX row
    counts = sorted({1, kernels.threads()})

    def on_threads(n, fn):
        def run():
            kernels.set_threads(n)
            return fn()

        return run

    timed = {(name, n): on_threads(n, fn) for name, fn in fns.items() for n in counts}
    times = interleaved_medians(timed, rounds=7, budget=0.05)
    rows = []
    for name in fns:
        fitted = ", b fitted" if name.endswith("fitted") else ""
        base = "ARX(16,16,1) simulation, measured" + fitted
        cells = [
            f"{times[name, n] / P * 1e6:7.1f} us {times[name, n] / times[base, n]:5.2f}x"
            for n in counts
        ]
        rows.append((name, "   ".join(cells)))
    print_table(
        rows,
        f"N = {N}, population {P}, kernels {kernels.BACKEND} ({simd}); per candidate and the "
        "ratio to the ARX row of the same kind (given parameters, or b fitted), on "
        + " and ".join(f"{n} thread{'s' * (n > 1)}" for n in counts),
    )


if __name__ == "__main__":
    main()
