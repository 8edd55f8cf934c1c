"""Bacterial foraging algorithm (BFA) of Passino (2002), registered as ``"bfa"``."""

from __future__ import annotations

from collections.abc import Callable, Generator

import numpy as np

from ._params import Optimiser, Param, SearchGenerator
from ._problem import SearchSpace
from .registry import register, register_variant

__all__ = ["BacterialForaging", "chemotactic_step", "swarming_cost", "tumble_directions"]


def tumble_directions(rng: np.random.Generator, size: int, dim: int) -> np.ndarray:
    """Passino's tumble: components uniform in [-1, 1], normalised to unit length.

    Parameters
    ----------
    rng : numpy.random.Generator
        The run's generator (draws ``size * dim`` uniforms).
    size : int
        Number of directions ``S``.
    dim : int
        Dimension ``n`` of the search space.

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
    """Passino's cell-to-cell term ``J_cc`` of every bacterium, shape (S,) (no FE).

    Parameters
    ----------
    X : ndarray, shape (S, n)
        Positions of the bacteria (search-box units).
    d_attract, w_attract : float
        Depth and width (1 / units squared) of the attractant term.
    h_repellant, w_repellant : float
        Height and width (1 / units squared) of the repellant term.

    Returns
    -------
    ndarray, shape (S,)
        ``J_cc`` of every bacterium, in cost units.
    """
    d2 = np.sum((X[:, None, :] - X[None, :, :]) ** 2, axis=2)
    return np.sum(-d_attract * np.exp(-w_attract * d2) + h_repellant * np.exp(-w_repellant * d2),
                  axis=1)


def chemotactic_step(
    space: SearchSpace,
    rng: np.random.Generator,
    X: np.ndarray,
    J: np.ndarray,
    T: np.ndarray,
    step: float,
    n_swim: int,
    clip: bool,
    decide: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
    evaluated: Callable[[np.ndarray, np.ndarray], None] | None = None,
) -> Generator[np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """One chemotactic step of every bacterium (Passino's tumble and swim), as a generator.

    Shared by BFA and HBCSD: a search runs it with
    ``X, J, T = yield from chemotactic_step(...)``.  It yields the tumbled population, then
    each batch of swimming bacteria, marks the end of the iteration (phase ``"chemotaxis"``)
    and returns the new positions, their costs and their deciding costs.

    Parameters
    ----------
    space : SearchSpace
        The search's space.
    rng : numpy.random.Generator
        The search's random generator (the tumble draws its directions from it).
    X, J : ndarray, shapes (S, n) and (S,)
        Positions and their costs (``X`` is not modified; ``J`` is not kept).
    T : ndarray, shape (S,)
        The cost that decides the swims at the start of the step: ``J``, or ``J + J_cc``.
    step : float
        Chemotactic step ``C``.
    n_swim : int
        Swim length ``N_s``.
    clip : bool
        Clip moved bacteria to the box.
    decide : callable, optional
        ``decide(X, J) -> T`` after every batch (BFA: ``J + J_cc``); default ``T = J``.
    evaluated : callable, optional
        ``evaluated(X, J)`` after every batch (HBCSD: personal bests).

    Returns
    -------
    X : ndarray, shape (S, n)
        The new positions, in the unit box.
    J : ndarray, shape (S,)
        Their costs.
    T : ndarray, shape (S,)
        Their deciding costs, ``decide(X, J)`` (``J`` itself without ``decide``): the ``T`` of
        the next step while the population stays as it is.

    Yields
    ------
    ndarray, shape (S, n) or (k, n)
        The tumbled population, then the ``k`` bacteria that swim on; the search sends
        back their costs, shape (S,) or (k,).

    Notes
    -----
    Bacterium ``i`` moves ``x_i <- x_i + C u_i`` with the tumble direction ``u_i`` (always
    taken), then, up to ``N_s`` times, while its deciding cost is lower than ``J_last`` (the
    cost before the tumble, following every improvement) takes another step ``C u_i``.
    FE: ``S`` for the tumble plus one per swim step.
    """
    j_last = T.copy()
    U = tumble_directions(rng, X.shape[0], space.dim)
    X = X + step * U
    if clip:
        X = space.clip(X)
    J = (yield X).copy()
    if evaluated is not None:
        evaluated(X, J)
    T = J if decide is None else decide(X, J)
    swim = np.ones(X.shape[0], dtype=bool)
    for _ in range(n_swim):
        swim &= T < j_last
        if not swim.any():
            break
        j_last[swim] = T[swim]
        moved = X[swim] + step * U[swim]
        if clip:
            moved = space.clip(moved)
        X[swim] = moved
        J[swim] = yield moved
        if evaluated is not None:
            evaluated(X, J)
        T = J if decide is None else decide(X, J)
    space.end_iteration("chemotaxis")
    return X, J, T


@register
class BacterialForaging(Optimiser):
    """Bacterial foraging algorithm (BFA) of Passino (2002).

    ``S`` bacteria climb the cost surface by chemotaxis (tumble and swim); every ``N_c``
    chemotactic steps the healthier half reproduces; every ``N_re`` reproductions each
    bacterium is dispersed to a random point with probability ``p_ed``.  Loops, outermost
    first: elimination-dispersal ``l = 1..N_ed`` > reproduction ``k = 1..N_re`` > chemotaxis
    ``j = 1..N_c`` > bacteria.

    Parameters
    ----------
    population : int
        Population ``S`` (even), 50 (also accepted as ``bacteria``).  The defaults of all
        hyper-parameters are those of Passino's paper and program.
    n_chemotactic : int
        Chemotactic steps ``N_c`` per reproduction, 100.
    n_swim : int
        Swim length ``N_s``, 4.
    n_reproduction : int
        Reproduction steps ``N_re``, 4.
    n_elim_disp : int or None
        ``N_ed`` = 2.  ``None`` keeps cycling (reproduction blocks and dispersals) until the
        FE budget; with an int the run ends after Passino's finite schedule even if FE are
        left (``result.stop == "converged"``).
    p_ed : float
        Elimination-dispersal probability, 0.25.
    step_size : float
        Chemotactic step ``C`` (box units), 0.1.
    swarming : bool
        Add the cell-to-cell term ``J_cc`` (off, as in Passino's program, ``flag = 2``).
    d_attract, w_attract, h_repellant, w_repellant : float
        ``J_cc`` attractant depth and width, repellant height and width: 0.1, 0.2, 0.1, 10
        (widths in 1 / box units squared).
    clip : bool
        Clip moved bacteria to the box (an extension of the paper), False.

    Notes
    -----
    Chemotaxis of bacterium ``i``: draw ``Delta_i`` uniform in ``[-1, 1]^n`` and move
    ``theta_i <- theta_i + C Delta_i / sqrt(Delta_i' Delta_i)`` (always taken); then, up to
    ``N_s`` times, while the new cost is lower than ``J_last`` (which starts at the cost
    before the tumble and follows every improvement) take another step ``C phi_i`` in the
    same direction.  No revert.  With ``swarming`` every decision uses ``J + J_cc``, where
    ``J_cc(theta) = sum_j -d exp(-w_a |theta - theta_j|^2) + h exp(-w_r |theta - theta_j|^2)``.
    One step of every bacterium is :func:`chemotactic_step` (HBCSD's phase 1 runs it too).

    Reproduction: ``health_i = sum_{j=1}^{N_c + 1} J(i, j)`` (cost at the start of every
    chemotactic step plus the cost at the end); the ``S / 2`` healthiest bacteria (lowest
    health, stable order) split into two at their current position; costs are copied.

    FE: ``S`` initially; each chemotactic step (one iteration, phase ``"chemotaxis"``) costs
    ``S`` (tumble) plus one per swim step, ``S`` to ``S (N_s + 1)``; reproduction costs
    none; each dispersal costs the number of dispersed bacteria.  Paper-style iteration
    count: ``N_c N_re N_ed``.

    Deviations from Passino's paper and program:

    * The start-of-step cost is cached (Passino's program re-evaluates it, ``S`` more FE
      per step); the result is the same.
    * All bacteria move at once (vectorised).  Without ``J_cc`` this has exactly Passino's
      distribution; with ``J_cc`` it is a Jacobi instead of a Gauss-Seidel update.
    * No dispersal after the last reproduction block (it cannot change the result).
    * ``n_elim_disp=None`` (until the budget) and ``clip=True`` are extensions.
    * The best point ever evaluated is reported (Passino's program only plotted paths).

    References
    ----------
    K. M. Passino, "Biomimicry of bacterial foraging for distributed optimization and
    control", IEEE Control Systems Magazine 22(3):52-67, 2002, doi:10.1109/MCS.2002.1004010.
    """

    name = "bfa"
    auto_iterations = False
    reference = "Passino, IEEE Control Systems Magazine 22(3):52-67, 2002"
    bounds = "leaves the box (paper)"
    bounds_note = (
        "The paper's search is unconstrained: tumbles and swims are evaluated "
        "wherever they land (clip=True clips them to the box, a deviation); "
        "dispersal re-draws in the box."
    )
    stays_in_box = False
    population = Param(int, 50, "population S (even)", low=2, aliases=("bacteria",))
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

        if self.population % 2:
            raise HyperParameterError(
                f"{self.name}: population (bacteria) must be even (half of them split), "
                f"got {self.population}"
            )

    def _jcc(self, X: np.ndarray) -> np.ndarray | float:
        if not self.swarming:
            return 0.0
        return swarming_cost(X, self.d_attract, self.w_attract, self.h_repellant,
                             self.w_repellant)

    def _decide(self, X: np.ndarray, J: np.ndarray) -> np.ndarray:
        return J + self._jcc(X)

    def search(self, space: SearchSpace, rng: np.random.Generator) -> SearchGenerator:
        S, C = self.population, self.step_size
        X = space.initial_population(S)
        J = (yield X).copy()
        event = 0
        while self.n_elim_disp is None or event < self.n_elim_disp:
            event += 1
            for _ in range(self.n_reproduction):
                health = np.zeros(S)
                T = self._decide(X, J)
                for _ in range(self.n_chemotactic):
                    health += T
                    # the step returns the deciding cost of its end, the next step's start
                    X, J, T = yield from chemotactic_step(
                        space, rng, X, J, T, C, self.n_swim, self.clip, decide=self._decide
                    )
                health += T
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
    "bfa-paper-manipulator", BacterialForaging,
    "Nasir & Tokhi 2014 section 5, manipulator: N_s=4, N_c=30, N_re=6, N_ed=6, C=0.01; "
    "S=50 and p_ed=0.25 assumed.",
    population=50, n_swim=4, n_chemotactic=30, n_reproduction=6, n_elim_disp=6, step_size=0.01,
    p_ed=0.25,
)
register_variant(
    "bfa-paper-trs", BacterialForaging,
    "Nasir & Tokhi 2014 section 5, twin rotor: N_s=4, N_c=30, N_re=4, N_ed=4, C=0.0175; "
    "S=10 and p_ed=0.25 assumed.",
    population=10, n_swim=4, n_chemotactic=30, n_reproduction=4, n_elim_disp=4, step_size=0.0175,
    p_ed=0.25,
)
