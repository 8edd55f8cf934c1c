"""Your own physics as a grey-box model: a mass on a spring with viscous and Coulomb friction.

Run:  python examples/greybox_mass_spring.py

The model is two Python functions over a *population* of parameter sets (``x`` of shape
``(P, 2)``, each parameter a ``(P,)`` array), so one RK4 step advances every candidate an
optimiser proposes.  A record is made from the model itself at known parameters with
position-sensor noise; the gradient reference (``flexid.greyest``) and differential
evolution (through the cost's problem, as any registered optimiser would run it) then
estimate the stiffness, the viscous and the Coulomb friction with the mass fixed (the record
holds the force-to-position dynamics only up to a common scale of m, k, c and the Coulomb
force: one of them must be fixed).  The script checks that both end near the truth.

The model then runs where the built-in ones do, named ``examples/greybox_mass_spring.py:MODEL``
(a file and the name of a model in it): through ``flexid.identify`` (``structure=MODEL``) and
``flexid.compare`` (``ModelSpec(structure="greybox", greybox="<path>:MODEL")``) here, and on
the command line with the record this script writes::

    flexid identify flexid-data/mass_spring.csv --structure greybox \
        --greybox examples/greybox_mass_spring.py:MODEL --optimiser de --budget 3000

(``flexid.register_greybox_model`` or a package's ``flexid.greybox_models`` entry point give
it a name of its own instead, as an optimiser plugin gets one.)
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

import flexid
from flexid import GreyBoxCost, GreyBoxModel, GreyParameter


def derivatives(x: np.ndarray, u: np.ndarray, p) -> np.ndarray:
    """``m x'' = F - k x - c x' - Fc sgn(x')``, sgn smoothed over 1 cm/s; (P, 2) -> (P, 2)."""
    position, velocity = x[:, 0], x[:, 1]
    force = u[:, 0] - p.k * position - p.c * velocity - p.fc * np.tanh(velocity / 1e-2)
    return np.column_stack([velocity, force / p.m])


def position(x: np.ndarray, u: np.ndarray, p) -> np.ndarray:
    """What the sensor reads: the position [m], (P, 1)."""
    return x[:, :1]


MODEL = GreyBoxModel(
    "mass-spring-coulomb",
    derivatives,
    position,
    states=("position", "velocity"),
    inputs=("force",),
    outputs=("position",),
    parameters=(
        GreyParameter("m", 2.0, 0.1, 10.0, "kg", fixed=True, description="moving mass"),
        GreyParameter("k", 50.0, 1.0, 1000.0, "N/m", description="spring stiffness"),
        GreyParameter("c", 1.0, 0.01, 50.0, "N s/m", description="viscous friction"),
        GreyParameter("fc", 0.5, 0.0, 5.0, "N", description="Coulomb friction force"),
    ),
    substep=5e-3,
)
TRUE = {"k": 80.0, "c": 1.5, "fc": 0.3}


def main() -> None:
    rng = np.random.default_rng(0)
    dt = 0.02
    force = np.repeat(rng.uniform(-3.0, 3.0, 30), 10)  # steps held 0.2 s, 6 s in all
    truth = MODEL.with_parameters(**TRUE)
    y = truth.simulate(truth.nominal, force, dt)[0, :, 0]
    y = y + 1e-4 * rng.standard_normal(y.size)  # 0.1 mm of sensor noise
    data = flexid.IOData(force, y, dt=dt, input_names=["force"], output_names=["position"])

    fit = flexid.greyest(data, MODEL, starts=2, seed=1)
    print(fit.summary())
    cost = GreyBoxCost(MODEL, data)
    run = flexid.minimize("de", cost.problem(), 3000, seed=0)
    found = dict(zip(MODEL.free, MODEL.from_search(run.x).tolist()))
    print("DE, 3,000 evaluations:", {name: round(value, 4) for name, value in found.items()})
    for name, value in TRUE.items():
        within = abs(fit.values[name] - value) <= 4 * fit.std_errors[name]
        print(f"reference {name} within 4 standard errors of {value}: {within}")
        if not within:
            raise SystemExit(1)
        close = abs(found[name] - value) <= 0.05 * value
        print(f"DE {name} within 5 % of {value}: {close}")
        if not close:
            raise SystemExit(1)

    # the same model through identify (fit on the first 2/3, validated on the rest) ...
    ident = flexid.identify(data, structure=MODEL, optimiser="pem")
    print(ident.summary().splitlines()[0])
    held_out = ident.validation.fit_simulation
    print(f"identify: held-out simulation fit {held_out:.2f} % above 99 %: {held_out > 99}")
    if held_out <= 99:
        raise SystemExit(1)

    # ... and through compare, from the record written as a CSV file, as the command line
    # reads it (its columns are the model's input and output names)
    folder = Path("flexid-data")
    folder.mkdir(exist_ok=True)
    record = folder / "mass_spring.csv"
    data.to_csv(record)
    spec = flexid.ComparisonSpec(
        name="mass-spring",
        data=flexid.DataSpec(file=str(record)),
        model=flexid.ModelSpec(structure="greybox", greybox=f"{Path(__file__).resolve()}:MODEL"),
        optimisers=(flexid.OptimiserSpec("de"), flexid.OptimiserSpec("pso")),
        runs=2,
        budget=3000,
    )
    result = flexid.compare(spec, store=None, progress=False)
    print(result.cost_table())
    best = min(s["best"] for s in result.stats.values())
    close = best <= 1.01 * result.reference_cost
    print(f"compare: the best run within 1 % of the reference cost: {close}")
    if not close:
        raise SystemExit(1)


if __name__ == "__main__":
    main()
