"""Benchmark of the modal state-space cost against the ARX simulation cost, per candidate.

The issue's target: a modal model of the manipulator (4 modes, hub angle and end-point
acceleration together, N = 1,500) costs at most 3 times an ARX(16, 16, 1) simulation of
one output per candidate.  The ARX cost is timed in the stable pole space with its numerator
searched (one recursion per candidate) and fitted (variable projection, as the modal cost
fits its gains).  Both on the same record (the manipulator's paper preset with both
outputs, its first 1,500 samples), population 50 of points drawn in each space's own box,
timed in turn (``bench_costs.interleaved_medians``), on one thread and on every core.

Also timed: the modal cost under ``initial="zero"`` (no free response, no shared initial
state) and with one output, to show what each part costs.

Run:  python benchmarks/bench_modal.py [--simd avx2]
(``--simd``: the compiled kernels' instruction set, default the best this CPU has.)
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # small matrices: threads only cost

import platform

import numpy as np
from _simd import simd_from_arguments
from bench_costs import interleaved_medians

from flexid import kernels
from flexid.config import CostSpec, SearchSpec
from flexid.costs.modal import ModalCost
from flexid.data.datasets import generate
from flexid.fit.estimation import build_problem
from flexid.fit.statespace_fit import ModalBox
from flexid.models.arx import ARXStructure
from flexid.models.statespace import StateSpaceStructure

N = 1500
P = int(os.environ.get("BENCH_P", 50))


def main() -> None:
    simd = simd_from_arguments(__doc__.splitlines()[0])
    record = generate("manipulator", preset="paper-manipulator", seed=0,
                      outputs=["hub_angle", "tip_acceleration"])  # fmt: skip
    record = record.split(index=N)[0]
    record = record.replace(u=record.u - record.u.mean(0), y=record.y - record.y.mean(0))
    rng = np.random.default_rng(0)

    modal = StateSpaceStructure(8, 1, 2)  # 4 modes
    box = ModalBox.on(modal, record.dt, N)
    X = box.physical(box.lower + rng.random((P, box.lower.size)) * (box.upper - box.lower))
    two = ModalCost(record, modal)
    zero = ModalCost(record, modal, initial="zero")
    one_record = record.select(outputs=["tip_acceleration"])
    one = ModalCost(one_record, StateSpaceStructure(8, 1, 1))

    def population(numerator: str):
        problem = build_problem(one_record, ARXStructure(16, 16, 1),
                                CostSpec(predictor="simulation"),
                                SearchSpec(parametrisation="poles", numerator=numerator)).problem
        lo, hi = problem.lower, problem.upper
        Z = lo + rng.random((P, lo.size)) * (hi - lo)
        return lambda: problem.objective(Z)

    fns = {
        "ARX(16,16,1) simulation, 1 output": population("search"),
        "ARX(16,16,1) simulation, numerator fitted": population("fit"),
        "modal, 4 modes, 2 outputs, x0 estimated": lambda: two(X),
        "modal, 4 modes, 2 outputs, from rest": lambda: zero(X),
        "modal, 4 modes, 1 output, x0 estimated": lambda: one(X),
    }
    machine = platform.processor() or platform.machine()
    print(f"flexid modal cost benchmark: N = {N}, population {P}, kernels {kernels.BACKEND} "
          f"({simd}), {machine}, {os.cpu_count()} cores")  # fmt: skip
    for threads in (1, None):
        kernels.set_threads(threads)
        times = interleaved_medians(fns)
        base = times["ARX(16,16,1) simulation, 1 output"]
        print(f"\n{kernels.threads()} thread(s)")
        print(f"{'cost':<44} {'us / candidate':>15} {'x ARX':>7}")
        for name, t in times.items():
            print(f"{name:<44} {1e6 * t / P:>15.1f} {t / base:>7.2f}")
    kernels.set_threads(None)


if __name__ == "__main__":
    main()
