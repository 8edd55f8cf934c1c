"""HBCSD with its loop counts scaled to the FE budget, so that both phases run at any budget.

The algorithm is Nasir & Tokhi's hybrid bacteria-chemotaxis spiral-dynamic algorithm
(A. N. K. Nasir and M. O. Tokhi, "A novel hybrid bacteria-chemotaxis spiral-dynamic
algorithm with application to modelling of flexible systems", Engineering Applications of
Artificial Intelligence 33:31-46, 2014), as :class:`~flexid.optimisers.hbcsd.HBCSD` runs it;
only the number of chemotactic steps changes.  The paper fixes the loop counts (``N_c``
chemotactic steps, ``k_max`` spiral iterations) for its budgets; at a smaller budget a
faithful run spends it all in phase 1 (on BBOB at d = 5 and 5,000 FE, 45 of the default 100
chemotactic steps) and never reaches the spiral phase.  Registered as ``"hbcsd-scaled"``;
``"hbcsd"`` stays the paper's algorithm.
"""

from __future__ import annotations

import math

import numpy as np

from ._params import Param, SearchGenerator
from ._problem import SearchSpace
from .bfa import chemotactic_step
from .hbcsd import HBCSD
from .registry import register

__all__ = ["HBCSDScaled"]

# chemotactic steps when the run has no FE budget to scale to (HBCSD's default N_c)
UNSCALED_STEPS = 100


@register
class HBCSDScaled(HBCSD):
    """HBCSD (Nasir & Tokhi 2014) with the chemotactic phase scaled to the FE budget.

    The rule: with an FE budget ``B`` and ``m`` bacteria, phase 1 (chemotaxis) gets the
    share ``s = floor(phase1_share (B - m))`` of the evaluations left after the initial
    population, and phase 2 (the adaptive spiral) the rest, up to the budget.  Phase 1 runs
    chemotactic steps, as many as fit: it ends before the first batch (a tumble or a swim)
    that would take its evaluations beyond ``s``; a step cut there keeps the personal bests
    of the batches it evaluated.  So ``N_c`` grows with the budget (at ``m = 50`` and
    ``N_s = 4`` a step costs ``m`` to ``5 m`` FE) and both phases run whenever
    ``B >= m + m / min(phase1_share, 1 - phase1_share)`` (both shares hold a batch of
    ``m``: ``B >= 3 m``, 150 FE, at the defaults).  HBCSD has no reproduction or
    elimination-dispersal loops (the paper's hybrid keeps only the chemotaxis of BFA), so
    there is nothing else to scale; ``k_max = None`` runs the spiral to the budget.

    Parameters
    ----------
    phase1_share : float
        Fraction of the evaluations after the initial population given to phase 1, in
        (0, 1); default 0.5 (the paper's manipulator setting gives both phases the same
        number of iterations, 500 and 500).
    n_chemotactic : int or None
        Chemotactic steps when the run has no FE budget (default None: 100, HBCSD's
        default); ignored when it has one.
    population : int
        Bacteria / spiral points ``m``, 50 (also accepted as ``points``).
    n_swim : int
        Swim length ``N_s``, 4.
    step_size : float
        Chemotactic step ``C`` (units of the search box), 0.05.
    k_max : int or None
        Spiral iterations; ``None`` (default) continues phase 2 until the FE budget.
    r_lower, r_upper, c1_r, c2_r : float
        The radius law, as in :class:`~flexid.optimisers.hbcsd.HBCSD` (0.9, 0.99, 1, 1).
    angle : float or None
        Fixed angle (rad); ``None`` (default) uses the adaptive angle law.
    theta_lower, theta_upper, c1_theta, c2_theta : float
        The angle law, as in :class:`~flexid.optimisers.hbcsd.HBCSD` (pi/4, pi/4, 1, 1).
    clip : bool
        Clip moved points to the box (an extension of the paper), False.

    Notes
    -----
    Bounds as in the paper: moved points are evaluated wherever they land (``clip=True``
    clips them).  The history's phases are ``"chemotaxis"`` (a step cut by the share counts
    as one) then ``"spiral"``.
    """

    name = "hbcsd-scaled"
    n_chemotactic = Param(int, None, "chemotactic steps without an FE budget (None: 100)",
                          low=0, none_ok=True)
    phase1_share = Param(float, 0.5, "share of the FE budget for phase 1 (chemotaxis)",
                         low=0.0, high=1.0, low_open=True, high_open=True)

    def search(self, space: SearchSpace, rng: np.random.Generator) -> SearchGenerator:
        """Phase 1 within its share of the FE budget, then the spiral to the budget.

        Parameters
        ----------
        space : SearchSpace
            The run's space (its ``max_fe`` sets the share).
        rng : numpy.random.Generator
            The run's only source of randomness.

        Yields
        ------
        ndarray, shape (P, n)
            The initial population, the chemotactic batches, then the spiral's points; the
            driver sends back their costs, shape (P,).
        """
        X, J, Pb, Jb, personal_bests = yield from self.start(space)
        if space.max_fe is None:
            share, steps = math.inf, (
                UNSCALED_STEPS if self.n_chemotactic is None else self.n_chemotactic
            )
        else:
            share = math.floor(self.phase1_share * (space.max_fe - X.shape[0]))
            steps = None
        spent = 0
        done = 0
        # ---- phase 1: chemotaxis with personal bests, within its FE share
        while steps is None or done < steps:
            step = chemotactic_step(
                space, rng, X, J, J, self.step_size, self.n_swim, self.clip,
                evaluated=personal_bests,
            )
            batch = next(step)
            evaluated = False
            try:
                while True:
                    if spent + batch.shape[0] > share:
                        break
                    costs = yield batch
                    spent += batch.shape[0]
                    evaluated = True
                    batch = step.send(costs)
            except StopIteration as finished:
                X, J, _ = finished.value
                done += 1
                continue
            step.close()  # the share is spent: this step ends here
            if evaluated:
                space.end_iteration("chemotaxis")
            break
        # ---- phase 2: adaptive spiral from the personal bests, to the budget
        yield from self.spiral(space, Pb, Jb)
