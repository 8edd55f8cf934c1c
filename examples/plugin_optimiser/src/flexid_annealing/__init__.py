"""An optimiser that lives in its own package and plugs into flexid.

Install it next to flexid (``pip install ./examples/plugin_optimiser``) and it appears in
``flexid list optimisers`` and can be used by name everywhere flexid takes an optimiser::

    flexid identify record.csv --na 4 --optimiser annealing --param temperature=0.5
"""

from __future__ import annotations

import numpy as np

from flexid.optimisers import Optimiser, Param, SearchGenerator, SearchSpace


class PopulationAnnealing(Optimiser):
    """Simulated annealing run on a population of independent chains, all evaluated at once.

    Each chain proposes a Gaussian step (scaled to the box), accepts it by the Metropolis
    rule at temperature ``T_k = temperature * cooling**k`` and the step shrinks with the
    temperature.  The search is a generator: ``F = yield X`` hands a population to flexid,
    which evaluates it, counts the evaluations and keeps the best point.

    References
    ----------
    Kirkpatrick, Gelatt & Vecchi, "Optimization by simulated annealing", Science 220 (1983).
    """

    name = "annealing"
    reference = "Kirkpatrick, Gelatt & Vecchi, Science 220(4598):671-680, 1983"
    bounds = "clip"
    bounds_note = "Every proposal is clipped to the box."
    stays_in_box = True
    chains = Param(int, 20, "number of parallel chains", low=1)
    temperature = Param(float, 1.0, "initial temperature (cost units)", low=0.0, low_open=True)
    cooling = Param(
        float, 0.99, "temperature factor per iteration", low=0.0, high=1.0, low_open=True
    )
    step = Param(float, 0.1, "initial step as a fraction of the box width", low=0.0, low_open=True)

    def search(self, space: SearchSpace, rng: np.random.Generator) -> SearchGenerator:
        X = space.initial_population(self.chains)
        F = yield X
        width = space.upper - space.lower
        T, scale = self.temperature, self.step
        while True:
            proposal = space.clip(X + scale * width * rng.standard_normal(X.shape))
            G = yield proposal
            with np.errstate(over="ignore", invalid="ignore"):
                accept = (G <= F) | (rng.random(F.size) < np.exp(-(G - F) / T))
            X[accept], F[accept] = proposal[accept], G[accept]
            T *= self.cooling
            scale = max(scale * np.sqrt(self.cooling), 1e-6)
