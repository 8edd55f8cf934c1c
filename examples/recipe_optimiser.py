"""Recipe: a new optimiser in one module, as ``docs/architecture.md`` ("A new optimiser") says.

Run:  python examples/recipe_optimiser.py

The module is what the recipe asks for and nothing more: a class with a numpydoc docstring,
its hyper-parameters as ``Param`` (each checks its own values), what it does at the bounds,
and a ``search`` generator that yields populations and receives their costs.  It never counts
evaluations: the driver does, and cuts the last population so that the budget is exact.
Registered with ``@register``, it runs everywhere a built-in does (``minimize``,
``identify``, ``compare``, the command line).  The script then checks what the conformance
suite checks of every registered optimiser: the same seed gives the same run, the budget is
exact, and it beats random search on a sphere at an equal budget.  Inside flexid the module
goes to ``src/flexid/optimisers/`` with its name in ``registry._BUILTIN_MODULES``, and its
golden seeds are added with ``python tests/test_golden_seeds.py --add``.
"""

from __future__ import annotations

import numpy as np

import flexid
from flexid.optimisers import (
    Optimiser,
    Param,
    Problem,
    SearchGenerator,
    SearchSpace,
    minimize,
    register,
)

__all__ = ["LocalWalk"]


@register
class LocalWalk(Optimiser):
    """Gaussian steps around the best point found, a population at a time.

    Parameters
    ----------
    population : int
        Candidates per iteration (default 10).
    step : float
        Standard deviation of a step as a fraction of the box width (default 0.1).
    """

    name = "local-walk"
    reference = "textbook random local search"
    bounds = "clip"
    bounds_note = "Every step is clipped to the box."
    stays_in_box = True
    population = Param(int, 10, "candidates per iteration", low=1)
    step = Param(float, 0.1, "step as a fraction of the box width", low=0.0, low_open=True)

    def search(self, space: SearchSpace, rng: np.random.Generator) -> SearchGenerator:
        X = space.initial_population(self.population)
        F = yield X  # flexid evaluates, counts and stops the run
        best, f_best = X[np.argmin(F)], F.min()
        width = space.upper - space.lower
        while True:
            X = space.clip(best + self.step * width * rng.standard_normal(X.shape))
            F = yield X
            if F.min() < f_best:
                best, f_best = X[np.argmin(F)], F.min()


def main() -> None:
    """Run the checks the docstring at the top of the file describes, one line each."""
    sphere = Problem(lambda X: ((X - 0.3) ** 2).sum(axis=1), -np.ones(5), np.ones(5))
    first = minimize("local-walk", sphere, 1003, seed=4)
    again = minimize("local-walk", sphere, 1003, seed=4)
    print(f"same seed, same run: {np.array_equal(first.x, again.x) and first.fun == again.fun}")
    print(f"budget exact (1003 FE): {first.nfev == 1003}")
    walk = [minimize("local-walk", sphere, 1000, seed=s).fun for s in range(5)]
    rand = [minimize("random-search", sphere, 1000, seed=s).fun for s in range(5)]
    print(f"median {np.median(walk):.2e} below random search's {np.median(rand):.2e}: "
          f"{np.median(walk) < np.median(rand)}")
    print(f"listed with the built-ins: {'local-walk' in flexid.optimisers.available()}")


if __name__ == "__main__":
    main()
