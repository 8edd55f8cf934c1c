"""Compare optimisers on identical ARX problems, with a resumable result store.

Run:  python examples/compare_optimisers.py

Every optimiser gets the same data, the same initial population and the same FE budget over
several seeds; least squares is the reference row.  Results go to an SQLite store, so a rerun
(or a rerun after Ctrl-C) skips the finished runs.
"""

from __future__ import annotations

from flexid import ComparisonSpec, CostSpec, DataSpec, ModelSpec, OptimiserSpec, compare


def main() -> None:
    spec = ComparisonSpec(
        name="twin-rotor ARX(5,5,1), 4,000 FE",
        data=DataSpec(plant="twin-rotor", preset="paper-twin-rotor", seed=0),
        model=ModelSpec(na=5, nb=5, nk=1),
        cost=CostSpec(metric="paper", predictor="one-step"),
        optimisers=(
            OptimiserSpec("hbcsd-paper-trs", label="HBCSD"),
            OptimiserSpec("bfa-paper-trs", label="BFA"),
            OptimiserSpec("sda-paper-trs", label="SDA"),
            OptimiserSpec("de", label="DE"),
            OptimiserSpec("cmaes", label="CMA-ES"),
        ),
        runs=10,
        seed=1,
        budget=4_000,
    )
    result = compare(spec, store="flexid-results/example.sqlite", workers=1)
    print(result.summary())
    try:
        from flexid.report.plots import comparison_figures

        for path in comparison_figures(result, "flexid-results", prefix="example-"):
            print("figure:", path)
    except ImportError:
        print("(install the 'plot' extra for figures)")


if __name__ == "__main__":
    main()
