"""Spiral dynamics algorithm (SDA) of Tamura and Yasuda (2011), registered as ``"sda"``."""

from __future__ import annotations

import numpy as np

from ._params import Optimiser, Param, SearchGenerator
from ._problem import SearchSpace
from .registry import register, register_variant
from .rotation import rotation_matrix

__all__ = ["SpiralDynamics"]


@register
class SpiralDynamics(Optimiser):
    """Spiral dynamics algorithm (SDA) of Tamura and Yasuda (2011).

    ``m`` search points follow logarithmic spirals about the best point found so far,
    rotating by ``theta`` and shrinking by ``r`` at every iteration; the same spiral map is
    applied to every point.

    Parameters
    ----------
    population : int
        Number of search points ``m`` (>= 2), default 50 (also accepted as ``points``).
    radius : float
        Convergence rate ``r`` in (0, 1], default 0.95.
    angle : float
        Rotation angle ``theta`` in [0, 2 pi) (rad), default pi / 4.
    k_max : int or None
        Number of spiral iterations; ``None`` (default) iterates until the FE budget.
    clip : bool
        Clip moved points to the box (deviation, default False).

    Notes
    -----
    Update of point ``i`` at iteration ``k`` (Tamura & Yasuda 2011, eq. of the n-D model)::

        x_i(k+1) = S_n(r, theta) x_i(k) - (S_n(r, theta) - I_n) x*
                 = x* + r R^(n)(theta) (x_i(k) - x*)

    with the composite rotation ``R^(n)(theta) = prod_{i=1}^{n-1} prod_{j=1}^{i}
    R_{n-i, n+1-j}(theta)`` (:func:`~flexid.optimisers.rotation.rotation_matrix`).  The
    centre ``x*`` is replaced when a point beats it (elitist form).  ``R`` is built once per
    run; an iteration is one ``(m, n) @ (n, n)`` product.

    FE: ``m`` for the initial population, then ``m`` per iteration (the centre point is
    re-evaluated and counted, as in the papers); ``m (1 + k_max)`` in all.  The history has
    one row per iteration (phase ``"sda"``).

    Deviations from the paper:

    * Elitist centre: equal to the 2011 wording ("best of the current population") while the
      centre is a member of the population, which it is because it is a fixed point of the
      map; it also holds with ``clip=True``.
    * ``clip=True`` is not in the paper (the paper's search is unconstrained).
    * ``k_max=None`` runs until the FE budget.

    References
    ----------
    K. Tamura and K. Yasuda, "Spiral dynamics inspired optimization", Journal of Advanced
    Computational Intelligence and Intelligent Informatics 15(8):1116-1122, 2011.
    """

    name = "sda"
    reference = "Tamura & Yasuda, JACIII 15(8):1116-1122, 2011"
    bounds = "leaves the box (paper)"
    bounds_note = (
        "The paper's search is unconstrained: rotated points are evaluated "
        "wherever they land, inside the box or not (clip=True clips them to "
        "the box, a deviation)."
    )
    stays_in_box = False
    population = Param(int, 50, "search points m", low=2, aliases=("points",))
    radius = Param(float, 0.95, "convergence rate r", low=0.0, high=1.0, low_open=True)
    angle = Param(float, np.pi / 4, "rotation angle theta (rad)", low=0.0, high=2 * np.pi,
                  high_open=True)
    k_max = Param(int, None, "iterations (None: until the budget)", low=1, none_ok=True)
    clip = Param(bool, False, "clip moved points to the box (deviation)")

    def search(self, space: SearchSpace, rng: np.random.Generator) -> SearchGenerator:
        X = space.initial_population(self.population)
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
    "Nasir & Tokhi 2014 section 5, manipulator: r=0.99, theta=0.381; m=50, k_max=1000 assumed.",
    population=50, radius=0.99, angle=0.381, k_max=1000,
)
register_variant(
    "sda-paper-trs", "sda",
    "Nasir & Tokhi 2014 section 5, twin rotor: r=0.98, theta=0.72; m=10, k_max=200 assumed.",
    population=10, radius=0.98, angle=0.72, k_max=200,
)
