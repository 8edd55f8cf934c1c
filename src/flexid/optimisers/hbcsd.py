"""Hybrid bacteria-chemotaxis spiral-dynamic algorithm (HBCSD) of Nasir & Tokhi (2014).

Registered as ``"hbcsd"`` with the paper's settings as ``hbcsd-paper-manipulator`` and
``hbcsd-paper-trs``.
"""

from __future__ import annotations

from collections.abc import Generator

import numpy as np

from ._params import Optimiser, Param, SearchGenerator
from ._problem import SearchSpace
from .bfa import chemotactic_step
from .registry import register, register_variant
from .rotation import rotate_rows, rotation_matrix

__all__ = ["HBCSD", "adaptive_weight"]


def adaptive_weight(F: np.ndarray, c1: float, c2: float) -> np.ndarray:
    """``g = c2 |f| / (c2 |f| + c1)`` in [0, 1): the weight of the linear adaptive law.

    ``r = r_u + (r_l - r_u) g`` is eq. 1 of the paper, ``(r_l - r_u) / (1 + c1 / (c2 |f|))
    + r_u``, written so that it is defined at ``f = 0`` (g = 0).  Non-finite costs give
    ``g = 1``.

    Parameters
    ----------
    F : ndarray, shape (P,)
        Costs of the points.
    c1 : float
        Law constant ``c1``, in cost units (>= 0).
    c2 : float
        Law constant ``c2`` (> 0).

    Returns
    -------
    ndarray, shape (P,)
        The weights ``g``.
    """
    F = np.asarray(F, dtype=float)
    a = c2 * np.abs(F)
    with np.errstate(invalid="ignore", divide="ignore"):
        g = np.where(a + c1 > 0, a / (a + c1), 0.0)
    return np.where(np.isfinite(F), g, 1.0)


@register
class HBCSD(Optimiser):
    """Hybrid bacteria-chemotaxis spiral-dynamic algorithm (HBCSD) of Nasir & Tokhi (2014).

    Phase 1, exploration: ``N_c`` steps of Passino's bacterial chemotaxis (tumble and swim,
    no reproduction, elimination-dispersal or ``J_cc``); every bacterium keeps its personal
    best.  Phase 2, exploitation: an adaptive spiral dynamics search started from the
    personal bests, with a radius and an angle per point that depend linearly (through a
    saturating weight) on the point's cost.

    Parameters
    ----------
    population : int
        Bacteria / spiral points ``m``, 50 (also accepted as ``points``).
    n_chemotactic : int
        Chemotactic steps ``N_c`` of phase 1, 100 (0 skips phase 1).
    n_swim : int
        Swim length ``N_s``, 4.
    step_size : float
        Chemotactic step ``C`` (units of the search box), 0.05.
    k_max : int or None
        Spiral iterations; ``None`` (default) continues phase 2 until the FE budget.
    r_lower, r_upper : float
        Radius ``r_l`` for large costs (0.9) and ``r_u`` for small costs (0.99), in (0, 1].
    c1_r, c2_r : float
        Radius law constants ``c1`` (cost units) and ``c2``, 1 and 1.
    angle : float or None
        Fixed angle (rad), shared by all points (manipulator setting); ``None`` (default)
        uses the adaptive angle law with ``theta_lower``, ``theta_upper``, ``c1_theta``,
        ``c2_theta``.
    theta_lower, theta_upper : float
        Angle ``theta_l`` for large costs and ``theta_u`` for small costs (rad), pi/4.
    c1_theta, c2_theta : float
        Angle law constants ``c1`` (cost units) and ``c2``, 1 and 1.
    clip : bool
        Clip moved points to the box (an extension of the paper), False.

    Notes
    -----
    Phase 1 per bacterium and step: ``x_i <- x_i + C Delta_i / |Delta_i|`` with
    ``Delta_i ~ U[-1, 1]^n``, then up to ``N_s`` further steps along the same direction while
    the cost keeps falling; ``P_i, J_i`` <- the position and cost if it beats the personal
    best.  The step is BFA's (:func:`~flexid.optimisers.bfa.chemotactic_step`, shared).
    Phase 2 starts at ``Y = P``, ``x* = argmin J`` (no FE) and iterates::

        r_i(k)     = (r_l - r_u) / (1 + c1_r / (c2_r |f(y_i(k))|)) + r_u           (eq. 1)
        theta_i(k) = (theta_l - theta_u) / (1 + c1_t / (c2_t |f(y_i(k))|)) + theta_u
        y_i(k+1)   = x* + r_i(k) R^(n)(theta_i(k)) (y_i(k) - x*)

    computed as ``r = r_u + (r_l - r_u) g`` with ``g = c2 |f| / (c2 |f| + c1)``
    (:func:`adaptive_weight`), defined at ``f = 0``.  A fixed angle is one GEMM per
    iteration; per-point angles use the per-row Givens sweep
    (:func:`~flexid.optimisers.rotation.givens_sweep`), never ``m`` separate matrices.
    ``x*`` changes only when a point beats it.  The result is the best point of both phases.

    FE: ``m`` initially; ``m`` to ``m (N_s + 1)`` per chemotactic step; ``m`` per spiral
    iteration.  Iterations (history phases ``"chemotaxis"`` then ``"spiral"``):
    ``N_c + k_max``.

    Deviations from the paper and decisions where it is silent:

    * Unguided tumble (plain Passino chemotaxis); the start-of-step cost is cached.
    * ``theta_l = theta_1``, ``theta_u = theta_2`` of the paper (unverified, could be
      swapped); the adaptive laws use the cost of the current position, unnormalised, so
      ``c1 / c2`` is in cost units; a non-finite cost gives ``g = 1``.
    * ``k_max=None`` (until the budget) and ``clip=True`` are extensions.

    References
    ----------
    A. N. K. Nasir and M. O. Tokhi, "A novel hybrid bacteria-chemotaxis spiral-dynamic
    algorithm with application to modelling of flexible systems", Engineering Applications
    of Artificial Intelligence 33:31-46, 2014.
    """

    name = "hbcsd"
    auto_iterations = False
    reference = "Nasir & Tokhi, Eng. Appl. Artif. Intell. 33:31-46, 2014"
    bounds = "leaves the box (paper)"
    bounds_note = (
        "The paper's search is unconstrained: chemotactic and spiral moves "
        "are evaluated wherever they land (clip=True clips them to the box, a "
        "deviation)."
    )
    stays_in_box = False
    population = Param(int, 50, "bacteria / spiral points m", low=1, aliases=("points",))
    n_chemotactic = Param(int, 100, "chemotactic steps N_c (phase 1)", low=0)
    n_swim = Param(int, 4, "swim length N_s", low=0)
    step_size = Param(float, 0.05, "chemotactic step C", low=0.0, low_open=True)
    k_max = Param(int, None, "spiral iterations (None: until the budget)", low=0, none_ok=True)
    r_lower = Param(float, 0.9, "radius r_l for large costs", low=0.0, high=1.0,
                    low_open=True)
    r_upper = Param(float, 0.99, "radius r_u for small costs", low=0.0, high=1.0,
                    low_open=True)
    c1_r = Param(float, 1.0, "radius law c1 (cost units, with c2)", low=0.0)
    c2_r = Param(float, 1.0, "radius law c2", low=0.0, low_open=True)
    angle = Param(float, None, "fixed angle theta (rad); None: adaptive", low=0.0,
                  high=2 * np.pi, high_open=True, none_ok=True)
    theta_lower = Param(float, np.pi / 4, "angle theta_l for large costs (rad)", low=0.0,
                        high=2 * np.pi)
    theta_upper = Param(float, np.pi / 4, "angle theta_u for small costs (rad)", low=0.0,
                        high=2 * np.pi)
    c1_theta = Param(float, 1.0, "angle law c1", low=0.0)
    c2_theta = Param(float, 1.0, "angle law c2", low=0.0, low_open=True)
    clip = Param(bool, False, "clip moved points to the box (deviation)")

    def start(self, space: SearchSpace) -> Generator[np.ndarray, np.ndarray, tuple]:
        """The initial population and its costs, and the personal bests phase 1 keeps.

        Parameters
        ----------
        space : SearchSpace

        Returns
        -------
        tuple
            ``(X, J, Pb, Jb, personal_bests)`` (``yield from`` it): the population and its
            costs, the personal bests and their costs, and the callback that updates them
            from every evaluated batch.

        Yields
        ------
        ndarray, shape (P, n)
            The shared initial population (its costs are sent back).
        """
        X = space.initial_population(self.population)
        J = (yield X).copy()
        Pb, Jb = X.copy(), J.copy()

        def personal_bests(X: np.ndarray, J: np.ndarray) -> None:
            upd = J < Jb
            Pb[upd], Jb[upd] = X[upd], J[upd]

        return X, J, Pb, Jb, personal_bests

    def search(self, space: SearchSpace, rng: np.random.Generator) -> SearchGenerator:
        X, J, Pb, Jb, personal_bests = yield from self.start(space)
        # ---- phase 1: chemotaxis with personal bests
        for _ in range(self.n_chemotactic):
            X, J, _ = yield from chemotactic_step(
                space, rng, X, J, J, self.step_size, self.n_swim, self.clip,
                evaluated=personal_bests,
            )
        # ---- phase 2: adaptive spiral from the personal bests
        yield from self.spiral(space, Pb, Jb)

    def spiral(self, space: SearchSpace, Y: np.ndarray, F: np.ndarray) -> SearchGenerator:
        """The adaptive SDA phase from points ``Y`` with known costs ``F`` (no FE to start).

        Runs until ``k_max`` iterations (phase ``"spiral"``) or, when ``k_max`` is None,
        until the driver stops the run.

        Parameters
        ----------
        space : SearchSpace
            The search's space.
        Y : ndarray, shape (m, n)
            Starting points in the unit box (not modified).
        F : ndarray, shape (m,)
            Their costs.

        Yields
        ------
        ndarray, shape (m, n)
            The points of each spiral iteration; the search sends back their costs, shape
            (m,).
        """
        Y, F = Y.copy(), F.copy()
        b = int(np.argmin(F))
        xs, fs = Y[b].copy(), F[b]
        fixed = self.angle is not None
        Rt = rotation_matrix(space.dim, self.angle).T if fixed else None
        k = 0
        while self.k_max is None or k < self.k_max:
            r = self.r_upper + (self.r_lower - self.r_upper) * adaptive_weight(
                F, self.c1_r, self.c2_r
            )
            D = Y - xs
            if fixed:
                D = D @ Rt
            else:
                th = self.theta_upper + (self.theta_lower - self.theta_upper) * adaptive_weight(
                    F, self.c1_theta, self.c2_theta
                )
                D = rotate_rows(D, th)
            Y = xs + r[:, None] * D
            if self.clip:
                Y = space.clip(Y)
            F = (yield Y).copy()
            b = int(np.argmin(F))
            if F[b] < fs:
                xs, fs = Y[b].copy(), F[b]
            k += 1
            space.end_iteration("spiral")


register_variant(
    "hbcsd-paper-manipulator", "hbcsd",
    "Nasir & Tokhi 2014 section 5, manipulator: m=50, N_s=4, C=0.01, N_c=500, k_max=500, "
    "theta=0.34 fixed, r_l=0.99, r_u=1, c1_r=0.1, c2_r=0.3.",
    population=50, n_swim=4, step_size=0.01, n_chemotactic=500, k_max=500, angle=0.34,
    r_lower=0.99, r_upper=1.0, c1_r=0.1, c2_r=0.3,
)
register_variant(
    "hbcsd-paper-trs", "hbcsd",
    "Nasir & Tokhi 2014 section 5, twin rotor: m=10, N_s=4, C=0.04, N_c=50, k_max=150, "
    "r_l=0.65, r_u=0.99, c1_r=996, c2_r=0.97, theta_1=1.03, theta_2=1.8, c1=110, c2=0.98; "
    "theta_l=theta_1 and theta_u=theta_2 assumed.",
    population=10, n_swim=4, step_size=0.04, n_chemotactic=50, k_max=150, r_lower=0.65,
    r_upper=0.99, c1_r=996.0, c2_r=0.97, angle=None, theta_lower=1.03, theta_upper=1.8,
    c1_theta=110.0, c2_theta=0.98,
)
