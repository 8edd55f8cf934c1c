"""Bacterial foraging algorithm (BFA) of Passino (2002)."""

from __future__ import annotations

import numpy as np

from .base import Optimiser, Param, SearchSpace
from .registry import register, register_variant

__all__ = ["BacterialForaging", "swarming_cost", "tumble_directions"]


def tumble_directions(rng: np.random.Generator, size: int, dim: int) -> np.ndarray:
    """Passino's tumble: components uniform in [-1, 1], normalised to unit length.

    Returns
    -------
    ndarray, shape (size, dim)
        Unit rows (not isotropic: they lean to the diagonals, as in the paper).
    """
    delta = rng.uniform(-1.0, 1.0, (size, dim))
    norm = np.linalg.norm(delta, axis=1)
    norm[norm == 0] = 1.0
    return delta / norm[:, None]


def swarming_cost(X: np.ndarray, d_attract: float, w_attract: float, h_repellant: float,
                  w_repellant: float) -> np.ndarray:
    """Passino's cell-to-cell term ``J_cc`` of every bacterium, shape (S,) (no FE)."""
    d2 = np.sum((X[:, None, :] - X[None, :, :]) ** 2, axis=2)
    return np.sum(-d_attract * np.exp(-w_attract * d2) + h_repellant * np.exp(-w_repellant * d2),
                  axis=1)


@register
class BacterialForaging(Optimiser):
    """Bacterial foraging optimisation as Passino published it.

    Elimination-dispersal ⊃ reproduction ⊃ chemotaxis loops.  Chemotaxis: a tumble of step
    ``C`` in a random unit direction (always taken), then up to ``N_s`` swims in the same
    direction while the cost improves; no revert.  Reproduction after ``N_c`` steps: the
    healthier half (lowest summed cost) splits, the other half dies.  Elimination-dispersal
    after each reproduction block: each bacterium moves to a random point with probability
    ``p_ed`` (evaluated at once).  The optional cell-to-cell term ``J_cc`` is off by default.

    flexid deviations, all documented in ``algorithms.md``: the start-of-step cost is cached
    (Passino re-evaluates it), so a chemotactic step costs ``S`` to ``S (N_s + 1)`` FE; the
    bacteria move all at once (identical in distribution without ``J_cc``, a Jacobi update
    with it); no dispersal after the last block (it cannot change the result);
    ``n_elim_disp=None`` keeps cycling until the FE budget; ``clip=True`` clips to the box.
    One iteration is one chemotactic step of the whole population.
    """

    name = "bfa"
    auto_iterations = False
    reference = "Passino, IEEE Control Systems Magazine 22(3):52-67, 2002"
    bacteria = Param(int, 50, "population S (even)", low=2)
    n_chemotactic = Param(int, 100, "chemotactic steps N_c per reproduction", low=1)
    n_swim = Param(int, 4, "swim length N_s", low=0)
    n_reproduction = Param(int, 4, "reproduction steps N_re", low=1)
    n_elim_disp = Param(int, 2, "elimination-dispersal events N_ed (None: until the budget)",
                        low=1, none_ok=True)
    p_ed = Param(float, 0.25, "elimination-dispersal probability", low=0.0, high=1.0)
    step_size = Param(float, 0.1, "chemotactic step C", low=0.0, low_open=True)
    swarming = Param(bool, False, "add Passino's cell-to-cell term J_cc")
    d_attract = Param(float, 0.1, "J_cc attractant depth", low=0.0)
    w_attract = Param(float, 0.2, "J_cc attractant width", low=0.0)
    h_repellant = Param(float, 0.1, "J_cc repellant height", low=0.0)
    w_repellant = Param(float, 10.0, "J_cc repellant width", low=0.0)
    clip = Param(bool, False, "clip moved points to the box (deviation)")

    def check(self) -> None:
        from ..errors import HyperParameterError

        if self.bacteria % 2:
            raise HyperParameterError(
                f"bfa: bacteria must be even (half of them split), got {self.bacteria}"
            )

    def _jcc(self, X: np.ndarray) -> np.ndarray | float:
        if not self.swarming:
            return 0.0
        return swarming_cost(X, self.d_attract, self.w_attract, self.h_repellant,
                             self.w_repellant)

    def search(self, space: SearchSpace, rng: np.random.Generator):
        S, C = self.bacteria, self.step_size
        X = space.initial_population(S)
        J = (yield X).copy()
        event = 0
        while self.n_elim_disp is None or event < self.n_elim_disp:
            event += 1
            for _ in range(self.n_reproduction):
                health = np.zeros(S)
                for _ in range(self.n_chemotactic):
                    T = J + self._jcc(X)
                    health += T
                    j_last = T.copy()
                    U = tumble_directions(rng, S, space.dim)
                    X = X + C * U
                    if self.clip:
                        X = space.clip(X)
                    J = (yield X).copy()
                    T = J + self._jcc(X)
                    swim = np.ones(S, dtype=bool)
                    for _ in range(self.n_swim):
                        swim &= T < j_last
                        if not swim.any():
                            break
                        j_last[swim] = T[swim]
                        moved = X[swim] + C * U[swim]
                        if self.clip:
                            moved = space.clip(moved)
                        X[swim] = moved
                        J[swim] = yield moved
                        T = J + self._jcc(X)
                    space.end_iteration("chemotaxis")
                health += J + self._jcc(X)
                keep = np.argsort(health, kind="stable")[: S // 2]
                X = np.concatenate([X[keep], X[keep]])
                J = np.concatenate([J[keep], J[keep]])
            if self.n_elim_disp is not None and event >= self.n_elim_disp:
                break
            move = rng.random(S) < self.p_ed
            if move.any():
                X[move] = space.uniform(int(move.sum()), rng)
                J[move] = yield X[move]


register_variant(
    "bfa-paper-manipulator", "bfa",
    "Nasir & Tokhi 2014 section 5, manipulator: N_s=4, N_c=30, N_re=6, N_ed=6, C=0.01; "
    "S=50 and p_ed=0.25 assumed",
    bacteria=50, n_swim=4, n_chemotactic=30, n_reproduction=6, n_elim_disp=6, step_size=0.01,
    p_ed=0.25,
)
register_variant(
    "bfa-paper-trs", "bfa",
    "Nasir & Tokhi 2014 section 5, twin rotor: N_s=4, N_c=30, N_re=4, N_ed=4, C=0.0175; "
    "S=10 and p_ed=0.25 assumed",
    bacteria=10, n_swim=4, n_chemotactic=30, n_reproduction=4, n_elim_disp=4, step_size=0.0175,
    p_ed=0.25,
)
