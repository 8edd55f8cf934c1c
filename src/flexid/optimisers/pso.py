"""Particle swarm optimisation (global best, constriction coefficients)."""

from __future__ import annotations

import numpy as np

from ._params import Optimiser, Param, SearchGenerator
from ._problem import SearchSpace
from .registry import register

__all__ = ["ParticleSwarm"]


@register
class ParticleSwarm(Optimiser):
    """Global-best particle swarm with Clerc-Kennedy constriction.

    Update of particle ``i`` (all particles at once, vectorised)::

        v <- w v + c1 r1 (p_i - x) + c2 r2 (g - x),   x <- x + v

    with ``r1, r2 ~ U(0, 1)^n`` per particle and coordinate, ``p_i`` the particle's best
    point and ``g`` the swarm's best.  The defaults ``w = 0.7298``, ``c1 = c2 = 1.49618`` are
    the constriction coefficients of Clerc & Kennedy (2002) (``chi = 0.7298`` multiplying
    the whole update with ``phi = 4.1``), written as an inertia-weight PSO; set ``inertia``,
    ``cognitive`` and ``social`` for the inertia-weight variant (e.g. ``w = 0.72``,
    ``c = 1.49``, Shi & Eberhart 1998).

    Parameters
    ----------
    population : int
        Swarm size (FE per iteration), default 50 (also accepted as ``particles``).  The
        initial positions are the shared initial population; initial velocities are uniform
        in ``[-v_max, v_max]`` times the box width.
    inertia, cognitive, social : float
        ``w``, ``c1`` and ``c2``.
    v_max : float
        Velocity clamp per coordinate as a fraction of the box width (default 0.2).

    Notes
    -----
    Boundary handling: absorbing walls.  A position that leaves the box is put back on the
    violated face and that velocity component is set to zero, so no FE is spent outside
    the box.  One iteration is one swarm update (``population`` FE).
    """

    name = "pso"
    reference = "Kennedy & Eberhart 1995; Clerc & Kennedy, IEEE TEC 6(1):58-73, 2002"
    bounds = "clip"
    bounds_note = (
        "A position outside the box is clipped to it and the velocity of each "
        "clipped coordinate is set to 0."
    )
    stays_in_box = True
    population = Param(int, 50, "swarm size", low=2, aliases=("particles",))
    inertia = Param(float, 0.7298, "inertia weight w", low=0.0)
    cognitive = Param(float, 1.49618, "cognitive coefficient c1", low=0.0)
    social = Param(float, 1.49618, "social coefficient c2", low=0.0)
    v_max = Param(float, 0.2, "velocity clamp as a fraction of the box width", low=0.0,
                  low_open=True)

    def search(self, space: SearchSpace, rng: np.random.Generator) -> SearchGenerator:
        n, P = space.dim, self.population
        width = space.upper - space.lower
        vmax = self.v_max * width
        X = space.initial_population(P)
        V = rng.uniform(-1.0, 1.0, (P, n)) * vmax
        F = yield X
        pbest, pcost = X.copy(), F.copy()
        while True:
            g = pbest[int(np.argmin(pcost))]
            r1 = rng.random((P, n))
            r2 = rng.random((P, n))
            V = (self.inertia * V + self.cognitive * r1 * (pbest - X)
                 + self.social * r2 * (g - X))
            np.clip(V, -vmax, vmax, out=V)
            X = X + V
            out = (X < space.lower) | (X > space.upper)
            V[out] = 0.0
            X = space.clip(X)
            F = yield X
            better = F < pcost
            pbest[better], pcost[better] = X[better], F[better]
