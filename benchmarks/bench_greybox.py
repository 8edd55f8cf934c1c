"""Speed of the pitch grey-box cost: a batched population against a loop of single rotors.

A 2,000-sample pitch record (paper-twin-rotor preset, lab encoder); P = 64 parameter sets
drawn in the model's search box.  Rows, in the same run (interleaved medians):

* the batched cost (:class:`flexid.GreyBoxCost`): the population in the plant's compiled
  RK4, one parameter row per rotor, four rotors per SIMD vector;
* a loop over the 64 candidates of today's fastest single-rotor route,
  :func:`flexid.envs.twin_rotor_steppers.simulate` (the same compiled RK4, one rotor), plus
  its squared error;
* the batched cost by the NumPy route (the reference), on 8 candidates.

Then the end-to-end rate of a DE run of 3,000 evaluations on the batched cost.

Run:  python benchmarks/bench_greybox.py
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import time

import numpy as np
from _table import print_table
from bench_costs import interleaved_medians

import flexid
from flexid import kernels
from flexid.costs.greybox import GreyBoxCost
from flexid.envs import twin_rotor_physics as trs
from flexid.envs import twin_rotor_steppers
from flexid.models.greybox_library import twin_rotor_pitch

P = 64
N = 2000


def main() -> None:
    data = flexid.generate("twin-rotor", preset="paper-twin-rotor", n_samples=N, seed=0)
    model = twin_rotor_pitch()
    cost = GreyBoxCost(model, data)
    lower, upper = model.search_bounds()
    Z = lower + (upper - lower) * np.random.default_rng(0).random((P, model.n_free))
    X = model.from_search(Z)
    theta = model.full(X)
    u, y = data.u[:, 0], data.y[:, 0]

    def loop() -> np.ndarray:
        out = np.empty(P)
        for i, row in enumerate(theta):
            params = trs.TwinRotorParameters(
                lock_yaw=True, encoder_counts=None, **dict(zip(model.names, row.tolist()))
            )
            e = y - twin_rotor_steppers.simulate(u, params, data.dt)[:, 0]
            out[i] = e @ e
        return out

    def reference() -> np.ndarray:
        return model.simulate_reference(theta[:8], data.u, data.dt)

    times = interleaved_medians(
        {"batched": lambda: cost(X), "loop": loop, "numpy": reference}, rounds=5, budget=0.5
    )
    batched = times["batched"] / P
    rows = [
        ("batched cost, P = 64", f"{batched * 1e3:7.3f} ms/candidate"),
        (
            "loop of the single-rotor route",
            f"{times['loop'] / P * 1e3:7.3f} ms/candidate  ({times['loop'] / P / batched:.2f}x "
            "the batched cost's time)",
        ),
        ("NumPy route, P = 8", f"{times['numpy'] / 8 * 1e3:7.3f} ms/candidate"),
    ]
    t0 = time.perf_counter()
    result = flexid.minimize("de", cost.problem(), 3000, seed=0)
    seconds = time.perf_counter() - t0
    rows.append(("DE, 3,000 evaluations", f"{result.nfev / seconds:7.0f} evaluations/s"))
    print_table(rows, f"pitch grey-box, N = {N}, kernels {kernels.BACKEND}")


if __name__ == "__main__":
    main()
