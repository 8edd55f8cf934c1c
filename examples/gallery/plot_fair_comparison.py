"""
Compare optimisers fairly: convergence bands and FE to target
=============================================================

A small comparison on identical plants: every optimiser gets the same twin-rotor record,
the same ARX(5, 5, 1) problem, the same initial population in each run and the same budget
of function evaluations (FE), over several seeds. Least squares is the reference row. The
result lives in memory here; give ``compare`` a ``store`` path to keep every finished run
in an SQLite file, so that an interrupted comparison resumes.

The budget (1,500 FE, 4 runs) is kept small so that the documentation builds quickly; the
measured paper experiments (:doc:`/measurements/paper-experiments`) use 20 runs and the
paper's budgets.
"""

# %%
from flexid import ComparisonSpec, CostSpec, DataSpec, ModelSpec, OptimiserSpec, compare
from flexid.report.plots import plot_comparison_convergence, plot_fe_to_target

spec = ComparisonSpec(
    name="twin rotor ARX(5,5,1), 1,500 FE",
    data=DataSpec(plant="twin-rotor", preset="paper-twin-rotor", seed=0),
    model=ModelSpec(na=5, nb=5, nk=1),
    cost=CostSpec(metric="paper", predictor="one-step"),
    optimisers=(
        OptimiserSpec("hbcsd", label="HBCSD"),
        OptimiserSpec("bfa", label="BFA"),
        OptimiserSpec("sda", label="SDA"),
        OptimiserSpec("de", label="DE"),
    ),
    runs=4,
    seed=1,
    budget=1_500,
    targets=(0.1, 0.01),
)
result = compare(spec)
print(result.summary())

# %%
# Convergence over the runs
# -------------------------
# The median best cost (line) and its quartiles (band) against FE; the dashed line is the
# reference. Every optimiser stops at exactly the same FE.
plot_comparison_convergence(result)

# %%
# Function evaluations to reach a target
# --------------------------------------
# The share of runs that reached the reference cost times 1.1, against the FE they needed;
# a curve that stays below 1 counts the runs that never reached it.
plot_fe_to_target(result, 0.1)
