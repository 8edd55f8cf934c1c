"""How far the modal cost's sum of squares read from the normal equations is from the errors'.

``ModalCost`` reads each candidate's sum of squares from its normal equations, ``|y|^2 - 2
c'phi'y + c'Gc``, where a rounding bound allows, and sums its errors elsewhere
(:meth:`flexid.costs.modal.ModalCost._expanded_sse`).  On the manipulator's record (the
population of ``bench_modal.py``: 4 modes, hub angle and end-point acceleration, N = 1,500),
for a population drawn in the modal box and populations around ``ssest``'s minimum, this
prints the share of candidates whose errors are summed (the bound exceeded the tolerance)
and, over the others, the relative distance of the expansion from the sum of the same
coefficients' errors (:func:`flexid.kernels.modal_residual`), median and largest.

Run:  python benchmarks/modal_expansion.py
"""

from __future__ import annotations

import numpy as np

from flexid import kernels
from flexid.costs import modal as modal_cost
from flexid.costs.modal import ModalCost
from flexid.data.datasets import generate
from flexid.fit.statespace_fit import ModalBox, ssest
from flexid.models.statespace import StateSpaceStructure

N, P = 1500, 50


def main() -> None:
    record = generate("manipulator", preset="paper-manipulator", seed=0,
                      outputs=["hub_angle", "tip_acceleration"])  # fmt: skip
    record = record.split(index=N)[0]
    record = record.replace(u=record.u - record.u.mean(0), y=record.y - record.y.mean(0))
    structure = StateSpaceStructure(8, 1, 2)
    cost = ModalCost(record, structure)
    rng = np.random.default_rng(0)
    box = ModalBox.on(structure, record.dt, N)
    best = np.asarray(ssest(record, 8).x)
    spread = {"around ssest's minimum, spread 10 %": 0.1,
              "around ssest's minimum, spread 0.1 %": 1e-3}  # fmt: skip
    populations = {"drawn in the box": box.physical(box.lower + rng.random((P, box.lower.size))
                                                    * (box.upper - box.lower))}  # fmt: skip
    for name, size in spread.items():
        populations[name] = best * (1 + size * rng.standard_normal((P, best.size)))
    if kernels.BACKEND != "c":
        raise SystemExit("the expansion is the compiled route's; build the kernels")
    print(f"tolerance {modal_cost.EXPANSION_TOLERANCE:g}")
    print(f"{'population':<40} {'summed':>7} {'median':>9} {'largest':>9}")
    for name, X in populations.items():
        a, p = structure.denominators(X, record.dt)
        poles = np.concatenate([a.reshape(len(X), -1), p], axis=1)
        job = (poles, cost.u, cost._target, structure.n_modes, False, True)
        fitted = kernels.modal_fit(*job, ridge=modal_cost.RIDGE, rounding=modal_cost.SUM_ROUNDING,
                                   tolerance=np.inf)  # fmt: skip
        used, expanded = fitted[3], fitted[5]
        guarded = kernels.modal_fit(*job, ridge=modal_cost.RIDGE,
                                    rounding=modal_cost.SUM_ROUNDING,
                                    tolerance=modal_cost.EXPANSION_TOLERANCE)[5]  # fmt: skip
        direct = kernels.modal_residual(*job[:3], used, *job[3:], want_residual=False)[1]
        rel = np.abs(expanded - direct) / direct  # the same coefficients, two sums
        served = ~np.isnan(guarded)
        print(f"{name:<40} {1 - served.mean():>7.0%} {np.median(rel[served]):>9.1e} "
              f"{np.max(rel[served]):>9.1e}")  # fmt: skip


if __name__ == "__main__":
    main()
