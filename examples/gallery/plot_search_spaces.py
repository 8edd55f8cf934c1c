"""
Posing identification for a metaheuristic: search spaces
========================================================

How the search problem is posed decides more than the optimiser. HBCSD runs here on the same
manipulator record, with the same budget and seed, in three search spaces:

* the paper's coefficient box ``|a_k| <= C(na, k)`` with the flat ``1e9`` penalty for an
  unstable candidate, a uniform initial population and ``b`` searched;
* the same box with the graded penalty and a stable initial population;
* flexid's default: stable pole pairs, ``b`` fitted by least squares for each denominator.

Almost all of the paper's box is unstable: a uniform population starts at the penalty, and
under a flat penalty nothing tells it where the stable region lies.
"""

# %%
import matplotlib.pyplot as plt

import flexid
from flexid.report.plots import plot_convergence, plot_pole_zero

data = flexid.generate("manipulator", preset="paper-manipulator", seed=0, n_samples=1500)
settings = {
    "paper box, flat penalty": dict(
        parametrisation="coefficients", penalty_kind="flat", init="uniform", numerator="search"
    ),
    "box, graded penalty, stable start": dict(
        parametrisation="coefficients", penalty_kind="graded", init="stable", numerator="search"
    ),
    "poles, b fitted (default)": dict(parametrisation="poles", numerator="fit"),
}
runs = {
    label: flexid.identify(
        data, na=8, nb=8, nk=1, optimiser="hbcsd", budget=4_000, seed=1, **options
    )
    for label, options in settings.items()
}
reference = next(iter(runs.values())).cost_ls
for label, ident in runs.items():
    print(f"{label:34} final cost / least squares {ident.cost_value / reference:10.4g}, "
          f"largest pole radius {ident.model.max_pole_radius:.4f}")

# %%
# Convergence in each space
# -------------------------
# The penalty is ``1e9``: a line that stays near it never found a stable candidate.
plot_convergence({label: ident.history for label, ident in runs.items()}, reference=reference)

# %%
# Where the final models' poles are
# ---------------------------------
fig, axes = plt.subplots(1, 3, figsize=(11.0, 4.0), layout="constrained")
for ax, (label, ident) in zip(axes, runs.items()):
    plot_pole_zero(ident.model.poles(), ident.model.zeros(), ax=ax, title=label)
for ax in axes[:-1]:  # one legend, right of the last map, says what x and o are
    ax.get_legend().remove()

# sphinx_gallery_thumbnail_number = 2
