"""CMA-ES with restarts (IPOP, BIPOP) and a smooth periodic box transformation.

The strategy is Hansen's (mu/mu_w, lambda)-CMA-ES with active covariance update, as in
N. Hansen, "The CMA Evolution Strategy: A Tutorial", arXiv:1604.00772 (2016, 2023), Table 1
and equations (46)-(53), with pycma 4's default constants and stop criteria.  Restarts
follow A. Auger & N. Hansen, "A Restart CMA Evolution Strategy With Increasing Population
Size", IEEE CEC 2005 (IPOP: the population doubles at
each restart), and N. Hansen, "Benchmarking a BI-Population CMA-ES on the BBOB-2009
Function Testbed", GECCO 2009 workshop (BIPOP: large-population runs interleaved with
small-population runs of random lambda and sigma, each regime getting the same budget).

Bounds are handled as pycma's ``BoundTransform`` does (``cma.transformations.
BoxConstraintsLinQuadTransformation``): the strategy runs unconstrained in R^n and every
candidate is mapped into the box by a periodic transformation that is the identity inside
the box, except in a thin layer at each face where it is quadratic, and mirrors outside.
It was chosen over clipping with a penalty (flexid's ``cmaes``) because the map is
continuous and differentiable: the cost seen by the strategy has no plateau outside the box,
so the mean cannot slide onto a face and stall there while sigma collapses, an optimum on or
near a face is still a smooth optimum of the transformed problem, and every evaluated point
lies in the box without a penalty weight to tune.
"""

from __future__ import annotations

import math
from collections.abc import Generator

import numpy as np

from ._params import Optimiser, Param, SearchGenerator
from ._problem import SearchSpace
from .cmaes import _hsig, _learning_rates, _sigma_factor
from .registry import register, register_variant

__all__ = ["CMAESRestarts", "box_transform", "box_transform_inverse"]

# width of the quadratic layer at each face, as a fraction of the box side: pycma's
# min(side / 2, max(1, |bound|) / 20), 0.025 of the side on every box [-b, b]^n with b >= 1
# (BBOB's [-5, 5]^n among them; 0.05 on [0, 1]^n).  flexid's search space is the unit box
# (the optimiser does not see the problem's bounds), so one value: pycma's on such boxes.
# (It was 0.05 before; on BBOB f11 at d = 20, instance 1, seeds 1-12, cmaes-bipop with
# 20,000 FE reached 1e-8 in 9 runs with 0.05 and in 11 with 0.025.)
LAYER = 0.025
# the largest population of the large regime, as a multiple of the default lambda: pycma's
# fmin with restarts=9 doubles nine times; later restarts keep this size (a run without an
# FE budget would otherwise grow lambda without bound)
MAX_DOUBLINGS = 9
# the largest standard deviation of a coordinate, as a fraction of the box side (pycma's
# maxstd_boundrange): a coordinate whose sigma sv_i sqrt(C_ii) exceeds it is scaled down
MAX_STD = 1 / 3


def box_transform(G: np.ndarray, a: float = LAYER) -> np.ndarray:
    """Map points of R^n into the unit box (pycma's ``BoxConstraintsLinQuadTransformation``).

    Each coordinate is first shifted by the period ``2 (1 + 2a)`` into
    ``[-1/2 - 2a, 3/2 + 2a)`` and mirrored at ``-a`` and ``1 + a`` into ``[-a, 1 + a]``; then
    it is the identity on ``[a, 1 - a]`` and quadratic on the layers ``[-a, a]`` (onto
    ``[0, a]``) and ``[1 - a, 1 + a]`` (onto ``[1 - a, 1]``), with matching values and slopes.

    Parameters
    ----------
    G : ndarray, shape (P, n) or (n,)
        Points of the strategy's unconstrained space (unit-box coordinates).
    a : float
        Width of the quadratic layer at each face, in (0, 1/2].

    Returns
    -------
    ndarray, shape of ``G``
        The points in ``[0, 1]^n``.
    """
    start, period = -0.5 - 2 * a, 2 * (1 + 2 * a)
    # shift only what lies outside one period, so points in the box are not rounded
    far = (G < start) | (G >= start + period)
    x = np.where(far, start + np.mod(G - start, period), G)
    x = np.where(x > 1 + a, 2 * (1 + a) - x, x)
    x = np.where(x < -a, -2 * a - x, x)
    upper = np.where(x > 1 - a, 1 - (x - 1 - a) ** 2 / (4 * a), x)
    x = np.where(x < a, (x + a) ** 2 / (4 * a), upper)
    return np.clip(x, 0.0, 1.0)  # the quadratic pieces round to within one ulp of [0, 1]


def box_transform_inverse(X: np.ndarray, a: float = LAYER) -> np.ndarray:
    """The point of ``[-a, 1 + a]^n`` that :func:`box_transform` maps to ``X``.

    Parameters
    ----------
    X : ndarray, shape (P, n) or (n,)
        Points of the unit box.
    a : float
        Width of the quadratic layer, as in :func:`box_transform`.

    Returns
    -------
    ndarray, shape of ``X``
        Pre-images in the invertible domain (the identity on ``[a, 1 - a]``).
    """
    X = np.clip(X, 0.0, 1.0)
    return np.where(
        X < a, -a + 2 * np.sqrt(a * X), np.where(X > 1 - a, 1 + a - 2 * np.sqrt(a * (1 - X)), X)
    )


def _weights(lam: int) -> tuple[np.ndarray, int, float, float]:
    """Recombination weights of the tutorial's Table 1 before the negative ones are scaled.

    Returns the raw weights ``w'_i = ln((lambda + 1) / 2) - ln i`` (shape (lambda,)), ``mu``,
    ``mu_eff`` and ``mu_eff^-``.
    """
    raw = np.log((lam + 1) / 2) - np.log(np.arange(1, lam + 1))
    mu = lam // 2
    pos, neg = raw[raw > 0], raw[raw < 0]
    mueff = pos.sum() ** 2 / np.sum(pos**2)
    mueff_neg = neg.sum() ** 2 / np.sum(neg**2) if neg.size else 0.0
    return raw, mu, float(mueff), float(mueff_neg)


def _active_weights(lam: int, n: int, c1: float, cmu: float, active: bool = True) -> np.ndarray:
    """The recombination weights of the covariance update, shape (lambda,), best first.

    The positive ones are ``w'_i`` of :func:`_weights` over their sum; the negative ones
    (active CMA, zero without it) are ``w'_i`` scaled so that their sum is ``-min(1 + c_1 /
    c_mu, 1 + 2 mu_eff^- / (mu_eff + 2), (1 - c_1 - c_mu) / (n c_mu))`` (the tutorial's
    eq. 53, pycma's ``RecombinationWeights.finalize_negative_weights``).
    """
    raw, _, mueff, mueff_neg = _weights(lam)
    w = np.where(raw > 0, raw / raw[raw > 0].sum(), 0.0)
    if active and mueff_neg > 0:
        scale = min(1 + c1 / cmu, 1 + 2 * mueff_neg / (mueff + 2), (1 - c1 - cmu) / (n * cmu))
        w = np.where(raw < 0, scale * raw / -raw[raw < 0].sum(), w)
    return w


@register
class CMAESRestarts(Optimiser):
    """BIPOP-CMA-ES (Hansen 2009): active CMA-ES with restarts and a smooth box transformation.

    One run of the strategy is pycma 4's active (mu/mu_w, lambda)-CMA-ES: the tutorial's
    algorithm (arXiv:1604.00772, Table 1: negative weights for the worse half of the
    population, ``c_m = 1``) with pycma's default constants, ``h_sigma`` and sigma update
    (see ``cmaes._learning_rates``) and its cap on the coordinates' standard deviations
    (``maxstd``, 1/3 of the side: a coordinate scaling ``s``, a step being ``sigma s y`` with
    ``y ~ N(0, C)``); it searches R^n and each candidate is evaluated at its image under
    :func:`box_transform` (pycma's linear-quadratic periodic map into the box), so no point
    is evaluated outside the box and none is clipped.  A lock-step run against pycma from the
    same state on the same samples agrees to 1e-8 in sigma and the covariance over 1,500
    generations (``benchmarks/cmaes_vs_pycma_trace.py``).  A run ends on the first of
    pycma's default stop criteria (thresholds on x are pycma's on a box of side 10, divided
    by 10; ``sd_i = sigma s_i sqrt(C_ii)``):

    * *tolfun*: the costs of the generation and the best costs of the last
      ``floor(10 + 30 n / lambda)`` generations lie within ``1e-11``; *tolfunhist*: those
      best costs (at least 10) within ``1e-12``;
    * *tolx*: ``sd_i`` and ``sigma s_i p_c,i`` below ``1e-12`` for all i;
    * *tolxstagnation*: the mean moved by less than ``1e-10 max(1, t / T)^(1/2)`` within the
      last ``t > T = 20 + g / 10`` generations;
    * *noeffectaxis*: adding ``0.1 sigma sqrt(d_i) s b_i`` (a principal axis, cycled) leaves
      the mean unchanged; *noeffectcoord*: adding ``0.2 sd_i`` leaves a coordinate of the
      mean unchanged;
    * *tolconditioncov*: the condition number of ``C`` above ``1e14``;
    * *tolflatfitness*: in two generations in a row the best cost is not below the cost of
      rank ``floor(0.75 lambda)``;
    * *tolstagnation*: with ``S = floor(100 + 100 n^1.5 / p_0)``, after ``n (5 + 100 /
      lambda)`` generations and ``S / 2`` generations without a new best, the medians of the
      best and of the median costs (recorded every 5th generation) over the last ``l = max(S
      / 10, records / 10)`` records are no better than over the ``l`` before;
    * *tolupsigma* / *tolfacupx*: ``sigma / sqrt(max eig C)`` above ``1e20 sigma0``, or
      ``max sd_i`` above ``1e3 sigma0``;
    * *maxiter*: ``100 + floor(150 (n + 3)^2 / sqrt(p_0))`` generations.

    ``p_0`` is pycma's population size before rounding, ``population`` or ``4 + 3 ln n``
    (``lambda_def = floor(p_0)``); ``S`` and *maxiter* are computed once from it and kept for
    every restart, as pycma's ``fmin`` does.  Restarts (IPOP, Auger & Hansen 2005) draw the
    mean uniformly in the box with ``sigma = sigma0`` and, at the k-th large restart,
    ``lambda = floor(2^k p_0)``, k up to 9.  With ``bipop`` (Hansen 2009), a restart is
    instead a *small* one whenever the FE spent so far in small runs (the first run counts
    as one, as in pycma) is below the FE spent in large ones: ``lambda_s = floor(p_0
    (2^k)^(U_1^2))`` after k large restarts (pycma's rule; up to the last large lambda),
    ``sigma = sigma0 10^(-2 U_2)`` (``U_1, U_2`` uniform on [0, 1]), and the run is stopped
    after ``min(maxiter, FE_large / (2 lambda_s))`` generations (half the FE of the large
    regime, pycma's ``maxiter`` of small runs).  The run goes on restarting until the
    driver's budget ends it; the last batch is cut by the driver, so the budget is shared
    between the restarts exactly.

    Parameters
    ----------
    population : int or None
        Default ``lambda`` (FE per generation of the first run); None means
        ``4 + floor(3 ln n)``.
    sigma0 : float
        Initial step size as a fraction of the box side (default 0.3, for a start uniform in
        the box).
    initial_points : int
        Size of the shared initial population evaluated as the first batch (default 50).
    bipop : bool
        Interleave small-population runs (BIPOP, default True); False gives IPOP.
    active : bool
        Use the negative weights of active CMA in the covariance update (default True, as
        pycma's ``CMA_active``).

    Notes
    -----
    The first run starts at the best point of the shared initial population (the one every
    flexid optimiser evaluates first for a seed), mapped back through the transformation,
    so a run depends only on the seed: all randomness comes from the run's generator.
    Every generation is one batch (``lambda`` FE) and one iteration.  Costs of +inf rank
    last.
    """

    name = "cmaes-bipop"
    reference = (
        "Hansen, arXiv:1604.00772 (tutorial); Auger & Hansen, CEC 2005 (IPOP); "
        "Hansen, GECCO BBOB workshop 2009 (BIPOP)"
    )
    bounds = "periodic transform"
    bounds_note = (
        "Candidates are mapped into the box by pycma's linear-quadratic "
        "periodic transformation (the identity inside, away from the faces), "
        "so every point evaluated is in the box."
    )
    stays_in_box = True
    population = Param(int, None, "default lambda (None: 4 + floor(3 ln n))", low=2, none_ok=True)
    sigma0 = Param(
        float, 0.3, "initial step as a fraction of the box width", low=0.0, low_open=True
    )
    initial_points = Param(int, 50, "size of the shared initial population", low=1)
    bipop = Param(bool, True, "interleave small-population restarts (False: IPOP)")
    active = Param(bool, True, "negative weights in the covariance update (active CMA)")

    def search(self, space: SearchSpace, rng: np.random.Generator) -> SearchGenerator:
        n = space.dim
        # pycma's popsize option before rounding: the restarts' lambdas are its multiples
        # rounded down (int(2^k (4 + 3 ln n)), not 2^k int(4 + 3 ln n))
        popsize0 = float(self.population or 4 + 3 * math.log(n))
        lam_def = int(popsize0)
        X0 = space.initial_population(self.initial_points)
        F0 = yield X0
        mean = box_transform_inverse(X0[int(np.argmin(F0))])
        # pycma's fmin evaluates maxiter and tolstagnation once, for the first run's popsize,
        # and keeps them for every restart
        max_iter = 100 + math.floor(150 * (n + 3) ** 2 / math.sqrt(popsize0))
        stagnation = int(100 + 100 * n**1.5 / popsize0)
        lam, sigma, iters = lam_def, self.sigma0, max_iter
        fe_small = fe_large = 0
        doublings = 0
        regime = "small"  # pycma counts the first run on the small budget
        while True:
            used = yield from self._run(mean, sigma, lam, iters, stagnation, rng)
            if regime == "small":
                fe_small += used
            else:
                fe_large += used
            mean = rng.random(n)
            if self.bipop and fe_large > 0 and fe_small < fe_large:
                regime = "small"
                u1, u2 = rng.random(2)
                # pycma: popsize0 * 2^(large runs so far)^(U^2), i.e. up to the last large lambda
                lam = max(2, int(popsize0 * (2**doublings) ** (u1**2)))
                sigma = self.sigma0 * 10 ** (-2 * u2)
                iters = min(max_iter, 0.5 * fe_large / lam)
            else:
                regime = "large"
                doublings = min(doublings + 1, MAX_DOUBLINGS)
                lam, sigma, iters = int(popsize0 * 2**doublings), self.sigma0, max_iter

    def _run(
        self,
        mean: np.ndarray,
        sigma: float,
        lam: int,
        max_iter: float,
        stagnation: int,
        rng: np.random.Generator,
    ) -> Generator[np.ndarray, np.ndarray, int]:
        """One CMA-ES run from ``mean`` until a stop criterion; returns the FE it used.

        Parameters
        ----------
        mean : ndarray, shape (n,)
            Start mean in the strategy's unconstrained coordinates.
        sigma : float
            Initial step size (unit-box coordinates).
        lam : int
            Population size lambda.
        max_iter : float
            Generations after which the run stops (pycma's ``maxiter``).
        stagnation : int
            pycma's ``tolstagnation`` (generations).
        rng : numpy.random.Generator
            The run's generator.
        """
        n = mean.size
        _, mu, mueff, _ = _weights(lam)
        cc, cs, c1, cmu, damps, chin = _learning_rates(n, mueff, lam)
        w = _active_weights(lam, n, c1, cmu, self.active)
        w_mean = w[:mu]  # positive: c_m = 1 and the mean uses the mu best
        C = np.eye(n)
        pc, ps = np.zeros(n), np.zeros(n)
        B, D = np.eye(n), np.ones(n)
        sqrt_c, inv_sqrt_c = np.eye(n), np.eye(n)
        # coordinate scaling (pycma's sigma_vec): a step is sigma * sv * y with y ~ N(0, C)
        sv = np.ones(n)
        stop = _Stop(n, lam, sigma, max_iter, stagnation, mean)
        used = 0
        g = 0
        while True:
            g += 1
            Z = rng.standard_normal((lam, n))
            # C^(1/2) = B D B' is unique (B is not), so the samples do not depend on LAPACK
            Y = Z @ sqrt_c
            G = mean + sigma * sv * Y
            F = yield box_transform(G)
            used += lam
            order = np.argsort(F, kind="stable")
            Fs = F[order]
            Yo = Y[order]
            y_w = w_mean @ Yo[:mu]
            mean = mean + sigma * sv * y_w
            ps = (1 - cs) * ps + np.sqrt(cs * (2 - cs) * mueff) * (inv_sqrt_c @ y_w)
            hsig = _hsig(ps, cs, g)
            pc = (1 - cc) * pc + hsig * np.sqrt(cc * (2 - cc) * mueff) * y_w
            w_cov = w.copy()
            if self.active:
                # negative weights rescaled by n / |C^(-1/2) y|^2 (tutorial eq. 46), so the
                # update cannot remove more than the sample's share of variance
                neg = w < 0
                norms = np.sum((Yo[neg] @ inv_sqrt_c) ** 2, axis=1)
                w_cov[neg] *= n / np.maximum(norms, 1e-300)
            C = (
                (1 + c1 * (1 - hsig) * cc * (2 - cc) - c1 - cmu * w.sum()) * C
                + c1 * np.outer(pc, pc)
                + cmu * (Yo.T * w_cov) @ Yo
            )
            sigma *= _sigma_factor(ps, cs, damps, chin)
            C = (C + C.T) / 2
            evals, B = np.linalg.eigh(C)
            if not (np.all(np.isfinite(evals)) and evals.min() > 0 and np.isfinite(sigma)):
                return used
            D = np.sqrt(evals)
            sqrt_c = (B * D) @ B.T
            sqrt_c = (sqrt_c + sqrt_c.T) / 2
            inv_sqrt_c = (B / D) @ B.T
            inv_sqrt_c = (inv_sqrt_c + inv_sqrt_c.T) / 2
            # pycma's maxstd: no coordinate's standard deviation above MAX_STD of the side
            # (its threshold is exp(1e-4) higher in the first two generations)
            stds = sigma * sv * np.sqrt(np.diag(C))
            wide = stds > MAX_STD * (np.exp(1e-4) if g <= 2 else 1.0)
            sv[wide] *= MAX_STD / stds[wide]
            if stop.update(g, used, mean, sigma, C, B, D, pc, Fs, sv):
                return used


class _Stop:
    """pycma's (4.x) stop criteria of one run, checked after every generation.

    Thresholds in unit-box coordinates are pycma's on a box of side 10 (BBOB's [-5, 5]^n)
    divided by 10.  :meth:`update` returns the name of the criterion that holds, or ``""``.

    Parameters
    ----------
    n, lam : int
        Dimension and population size.
    sigma0 : float
        The run's initial step size.
    max_iter : float
        ``maxiter``.
    stagnation : int
        ``tolstagnation`` (generations).
    mean : ndarray, shape (n,)
        The initial mean (for ``tolxstagnation``).
    """

    TOLFUN = 1e-11
    TOLFUNHIST = 1e-12
    TOLX = 1e-12  # pycma's 1e-11 on a side of 10
    TOLXSTAG = 1e-10  # pycma's tolxstagnation [1e-9, 20, 0.1], delta on a side of 10
    TOLUPSIGMA = 1e20
    TOLFACUPX = 1e3
    TOLCONDITIONCOV = 1e14

    def __init__(
        self, n: int, lam: int, sigma0: float, max_iter: float, stagnation: int, mean: np.ndarray
    ) -> None:
        self.n, self.lam, self.sigma0 = n, lam, sigma0
        self.max_iter, self.stagnation = max_iter, stagnation
        self.hist_len = int(10 + 30 * n / lam)  # pycma's fit.hist
        self.hist: list[float] = []  # best of each generation, newest last
        self.histbest: list[float] = []  # every 5th generation, newest last, at most 2e4
        self.histmedian: list[float] = []
        self.best, self.best_fe = np.inf, 0
        self.flat = 0
        self.x_ref, self.g_ref = np.array(mean, dtype=float), 0

    def update(
        self,
        g: int,
        used: int,
        mean: np.ndarray,
        sigma: float,
        C: np.ndarray,
        B: np.ndarray,
        D: np.ndarray,
        pc: np.ndarray,
        Fs: np.ndarray,
        sv: np.ndarray,
    ) -> str:
        """Record generation ``g`` (``used`` FE so far, sorted costs ``Fs``) and test.

        ``C``, ``B``, ``D`` are the covariance (n, n), its eigenvectors (n, n) and the square
        roots of its eigenvalues (n,), ascending; ``mean``, ``sigma``, ``pc`` and the
        coordinate scaling ``sv`` (n,) the state after the update (a step is ``sigma sv y``
        with ``y ~ N(0, C)``).
        """
        threshold = self._record(g, used, mean, Fs)
        if g >= self.max_iter:
            return "maxiter"
        stds = sigma * sv * np.sqrt(np.diag(C))
        return (self._spread_stop(g, used, stds, sigma, sv, pc, Fs, threshold)
                or self._effect_stop(g, mean, stds, sigma, D, B, sv, Fs))  # fmt: skip

    def _record(self, g: int, used: int, mean: np.ndarray, Fs: np.ndarray) -> float:
        """The histories of generation ``g``; the mean's reference point of tolxstagnation
        moved where the mean moved more than delta; that test's generation threshold."""
        lam = self.lam
        if Fs[0] < self.best:
            self.best, self.best_fe = float(Fs[0]), used
        self.hist.append(float(Fs[0]))
        if len(self.hist) > self.hist_len:
            del self.hist[0]
        if g % 5 == 0:
            i = lam // 2
            self.histbest.append(float(Fs[0]))
            self.histmedian.append(float(Fs[i] if lam % 2 else (Fs[i - 1] + Fs[i]) / 2))
            if len(self.histbest) > 20_000:
                del self.histbest[0], self.histmedian[0]
        # tolxstagnation: the mean moved less than delta over time_threshold generations
        threshold = 20 + 0.1 * g
        delta = self.TOLXSTAG * max(1.0, (g - self.g_ref) / threshold) ** 0.5
        if np.linalg.norm(self.x_ref - mean) > delta:
            self.x_ref, self.g_ref = np.array(mean, dtype=float), g
        return threshold

    def _spread_stop(
        self, g: int, used: int, stds: np.ndarray, sigma: float, sv: np.ndarray,
        pc: np.ndarray, Fs: np.ndarray, threshold: float,
    ) -> str:
        """The tests on the search's spread and the costs' progress, in pycma's order."""
        if np.any(stds > self.sigma0 * self.TOLFACUPX):
            return "tolfacupx"
        if np.all(stds < self.TOLX) and np.all(np.abs(sigma * sv * pc) < self.TOLX):
            return "tolx"
        hist_range = max(self.hist) - min(self.hist)
        if Fs[-1] - Fs[0] < self.TOLFUN and hist_range < self.TOLFUN:
            return "tolfun"  # an infinite cost makes the range infinite: no stop
        if len(self.hist) > 9 and hist_range < self.TOLFUNHIST:
            return "tolfunhist"
        if self._stagnated(g, used):
            return "tolstagnation"
        if g - self.g_ref > threshold:
            return "tolxstagnation"
        return ""

    def _effect_stop(
        self, g: int, mean: np.ndarray, stds: np.ndarray, sigma: float, D: np.ndarray,
        B: np.ndarray, sv: np.ndarray, Fs: np.ndarray,
    ) -> str:
        """The tests on the step's effect, the covariance's condition and flat costs."""
        if sigma / D.max() > self.sigma0 * self.TOLUPSIGMA:
            return "tolupsigma"
        if np.any(mean == mean + 0.2 * stds):
            return "noeffectcoord"
        i = g % self.n
        if np.all(mean == mean + 0.1 * sigma * D[i] * sv * B[:, i]):
            return "noeffectaxis"
        if D[-1] > self.TOLCONDITIONCOV**0.5 * D[0]:
            return "tolconditioncov"
        self.flat = self.flat + 1 if not Fs[0] < Fs[int(0.75 * self.lam)] else 0
        if self.flat > 1:
            return "tolflatfitness"
        return ""

    def _stagnated(self, g: int, used: int) -> bool:
        """pycma's ``tolstagnation``: the medians of the best and of the median costs over
        the last ``l`` recorded generations are no better than over the ``l`` before."""
        stag = self.stagnation
        rec = len(self.histbest)
        ell = max(stag / 5 / 2, rec / 10)
        if not (
            stag
            and ell <= g
            and g > self.n * (5 + 100 / self.lam)
            and (used - self.best_fe) / self.lam > stag / 2
        ):
            return False
        ell = int(ell)
        if not (rec > 100 and 2 * ell < rec):
            return False
        for h in (self.histmedian, self.histbest):
            recent, before = h[rec - ell :], h[rec - 2 * ell : rec - ell]
            if np.median(recent) < np.median(before):
                return False
        return True


register_variant(
    "cmaes-ipop",
    CMAESRestarts,
    "IPOP-CMA-ES (Auger & Hansen, CEC 2005): cmaes-bipop without the small-population runs.",
    bipop=False,
)
