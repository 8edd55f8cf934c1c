"""Spiral dynamics algorithm (SDA) of Tamura and Yasuda (2011)."""

from __future__ import annotations

import numpy as np

from .base import Optimiser, Param, SearchSpace
from .registry import register, register_variant
from .rotation import rotation_matrix

__all__ = ["SpiralDynamics"]


@register
class SpiralDynamics(Optimiser):
    """Spiral dynamics optimisation: ``x_i <- x* + r R(theta) (x_i - x*)``.

    Every point follows a logarithmic spiral about the best point found so far ``x*``,
    rotating by ``theta`` in the Tamura-Yasuda composite rotation and shrinking by ``r`` per
    iteration.  The rotation matrix is built once; an iteration is one GEMM.  The centre
    changes only when a point beats it (elitist form; equal to the 2011 wording while the
    centre is in the population).  The centre row is re-evaluated each iteration and
    counted (``m`` FE per iteration), as in the papers.

    Deviation: ``clip=True`` (default False) clips moved points to the box.
    ``k_max=None`` iterates until the budget.
    """

    name = "sda"
    reference = "Tamura & Yasuda, JACIII 15(8):1116-1122, 2011"
    points = Param(int, 50, "search points m", low=2)
    radius = Param(float, 0.95, "convergence rate r", low=0.0, high=1.0, low_open=True)
    angle = Param(float, np.pi / 4, "rotation angle theta (rad)", low=0.0, high=2 * np.pi,
                  high_open=True)
    k_max = Param(int, None, "iterations (None: until the budget)", low=1, none_ok=True)
    clip = Param(bool, False, "clip moved points to the box (deviation)")

    def search(self, space: SearchSpace, rng: np.random.Generator):
        X = space.initial_population(self.points)
        F = yield X
        b = int(np.argmin(F))
        xs, fs = X[b].copy(), F[b]
        Rt = rotation_matrix(space.dim, self.angle).T
        k = 0
        while self.k_max is None or k < self.k_max:
            X = xs + self.radius * ((X - xs) @ Rt)
            if self.clip:
                X = space.clip(X)
            F = yield X
            b = int(np.argmin(F))
            if F[b] < fs:
                xs, fs = X[b].copy(), F[b]
            k += 1


register_variant(
    "sda-paper-manipulator", "sda",
    "Nasir & Tokhi 2014 section 5, manipulator: r=0.99, theta=0.381; m=50, k_max=1000 assumed",
    points=50, radius=0.99, angle=0.381, k_max=1000,
)
register_variant(
    "sda-paper-trs", "sda",
    "Nasir & Tokhi 2014 section 5, twin rotor: r=0.98, theta=0.72; m=10, k_max=200 assumed",
    points=10, radius=0.98, angle=0.72, k_max=200,
)
