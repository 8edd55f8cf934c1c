"""CMA-ES with restarts (IPOP, BIPOP) and a smooth periodic box transformation.

The strategy is Hansen's (mu/mu_w, lambda)-CMA-ES with active covariance update, as in
N. Hansen, "The CMA Evolution Strategy: A Tutorial", arXiv:1604.00772 (2016), Table 1 and
equations (46)-(53).  Restarts follow A. Auger & N. Hansen, "A Restart CMA Evolution
Strategy With Increasing Population Size", IEEE CEC 2005 (IPOP: the population doubles at
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
from .cmaes import _learning_rates
from .registry import register, register_variant

__all__ = ["CMAESRestarts", "box_transform", "box_transform_inverse"]

# width of the quadratic layer at each face, as a fraction of the box side: pycma's
# min(side / 2, (1 + |bound|) / 20) is 0.03 of the side on [-5, 5]^n and 0.05 to 0.1 on
# [0, 1]^n; flexid's search space is always the unit box, so one value for both faces
LAYER = 0.05
# the largest population of the large regime, as a multiple of the default lambda: pycma's
# fmin with restarts=9 doubles nine times; later restarts keep this size (a run without an
# FE budget would otherwise grow lambda without bound)
MAX_DOUBLINGS = 9


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


@register
class CMAESRestarts(Optimiser):
    """BIPOP-CMA-ES (Hansen 2009): active CMA-ES with restarts and a smooth box transformation.

    One run of the strategy is the tutorial's active (mu/mu_w, lambda)-CMA-ES (arXiv:1604.00772,
    Table 1: all default constants, negative weights for the worse half of the population,
    ``c_m = 1``), searching R^n; each candidate is evaluated at its image under
    :func:`box_transform` (pycma's linear-quadratic periodic map into the box), so no point
    is evaluated outside the box and none is clipped.  A run ends on the first of Hansen's
    stop criteria (tutorial appendix B and the BBOB-2009 papers, pycma's defaults):

    * *TolFun*: the best costs of the last ``10 + ceil(30 n / lambda)`` generations and all
      costs of the current one lie within ``1e-11``;
    * *TolX*: ``sigma sqrt(C_ii)`` and ``sigma p_c,i`` below ``1e-12`` for all i (pycma's
      ``1e-11`` on a box of side 10, in unit-box coordinates);
    * *NoEffectAxis*: adding ``0.1 sigma sqrt(d_i) b_i`` (a principal axis, cycled) leaves the
      mean unchanged; *NoEffectCoord*: adding ``0.2 sigma sqrt(C_ii)`` leaves a coordinate of
      the mean unchanged;
    * *ConditionCov*: the condition number of ``C`` above ``1e14``;
    * *EqualFunValues*: in more than a third of the last ``10 + ceil(30 n / lambda)``
      generations the best and the k-th best cost were equal, ``k = 1 + ceil(0.1 + lambda/4)``;
    * *Stagnation*: over the last 20 % of the generations (at least ``120 + 30 n / lambda``,
      at most 20,000), the medians of the last 30 % of the best and of the median costs are
      both no better than those of the first 30 %;
    * *TolUpSigma* / *TolFacUpX*: ``sigma`` grew by ``1e20 sqrt(max eig C)``, or
      ``sigma sqrt(max C_ii)`` by ``1e3``, relative to the run's ``sigma0``;
    * *MaxIter*: ``100 + 150 (n + 3)^2 / sqrt(lambda)`` generations (pycma's ``maxiter``).

    Restarts (IPOP, Auger & Hansen 2005) draw the mean uniformly in the box with
    ``sigma = sigma0`` and twice the previous large population, up to ``2^9`` times the
    default.  With ``bipop`` (Hansen 2009), a restart is instead a *small* one whenever the
    FE spent so far in small runs (the first run counts as one, as in pycma) is below the FE
    spent in large ones: ``lambda_s = floor(lambda_def (lambda_l / (2 lambda_def))^(U_1^2))``
    with ``lambda_l`` the last large population, ``sigma = sigma0 10^(-2 U_2)``
    (``U_1, U_2`` uniform on [0, 1]), and the run is stopped once it has used half the FE of
    the large regime (pycma's ``maxiter`` of small runs).  The run goes on restarting until
    the driver's budget ends it; the last batch is cut by the driver, so the budget is shared
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
    sigma0 = Param(float, 0.3, "initial step as a fraction of the box width", low=0.0,
                   low_open=True)
    initial_points = Param(int, 50, "size of the shared initial population", low=1)
    bipop = Param(bool, True, "interleave small-population restarts (False: IPOP)")
    active = Param(bool, True, "negative weights in the covariance update (active CMA)")

    def search(self, space: SearchSpace, rng: np.random.Generator) -> SearchGenerator:
        n = space.dim
        lam_def = self.population or 4 + int(3 * np.log(n))
        X0 = space.initial_population(self.initial_points)
        F0 = yield X0
        mean = box_transform_inverse(X0[int(np.argmin(F0))])
        lam, sigma, cap = lam_def, self.sigma0, None
        fe_small = fe_large = 0
        doublings = 0
        regime = "small"  # pycma counts the first run on the small budget
        while True:
            used = yield from self._run(mean, sigma, lam, cap, rng)
            if regime == "small":
                fe_small += used
            else:
                fe_large += used
            mean = rng.random(n)
            lam_large = lam_def * 2**doublings
            if self.bipop and fe_large > 0 and fe_small < fe_large:
                regime = "small"
                u1, u2 = rng.random(2)
                lam = max(2, int(lam_def * (lam_large / (2 * lam_def)) ** (u1**2)))
                sigma = self.sigma0 * 10 ** (-2 * u2)
                cap = fe_large // 2
            else:
                regime = "large"
                doublings = min(doublings + 1, MAX_DOUBLINGS)
                lam, sigma, cap = lam_def * 2**doublings, self.sigma0, None

    def _run(
        self,
        mean: np.ndarray,
        sigma: float,
        lam: int,
        max_fe: int | None,
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
        max_fe : int or None
            FE after which the run stops (small BIPOP runs), None for no limit.
        rng : numpy.random.Generator
            The run's generator.
        """
        n = mean.size
        sigma0 = sigma
        raw, mu, mueff, mueff_neg = _weights(lam)
        cc, cs, c1, cmu, damps, chin = _learning_rates(n, mueff)
        w = np.where(raw > 0, raw / raw[raw > 0].sum(), 0.0)
        if self.active and mueff_neg > 0:
            neg_sum = -raw[raw < 0].sum()
            scale = min(1 + c1 / cmu, 1 + 2 * mueff_neg / (mueff + 2), (1 - c1 - cmu) / (n * cmu))
            w = np.where(raw < 0, scale * raw / neg_sum, w)
        w_mean = w[:mu]  # positive: c_m = 1 and the mean uses the mu best
        C = np.eye(n)
        pc, ps = np.zeros(n), np.zeros(n)
        B, D = np.eye(n), np.ones(n)
        sqrt_c, inv_sqrt_c = np.eye(n), np.eye(n)
        window = 10 + math.ceil(30 * n / lam)
        kth = min(lam, 1 + math.ceil(0.1 + lam / 4)) - 1
        stall_min = 120 + 30 * n / lam
        max_iter = 100 + 150 * (n + 3) ** 2 / np.sqrt(lam)
        best_hist: list[float] = []
        median_hist: list[float] = []
        flat: list[bool] = []
        used = 0
        g = 0
        while True:
            g += 1
            Z = rng.standard_normal((lam, n))
            # C^(1/2) = B D B' is unique (B is not), so the samples do not depend on LAPACK
            Y = Z @ sqrt_c
            G = mean + sigma * Y
            F = yield box_transform(G)
            used += lam
            order = np.argsort(F, kind="stable")
            Fs = F[order]
            Yo = Y[order]
            y_w = w_mean @ Yo[:mu]
            mean = mean + sigma * y_w
            ps = (1 - cs) * ps + np.sqrt(cs * (2 - cs) * mueff) * (inv_sqrt_c @ y_w)
            hsig = np.linalg.norm(ps) / np.sqrt(1 - (1 - cs) ** (2 * g)) / chin < 1.4 + 2 / (n + 1)
            pc = (1 - cc) * pc + hsig * np.sqrt(cc * (2 - cc) * mueff) * y_w
            w_cov = w.copy()
            if self.active:
                # negative weights rescaled by n / |C^(-1/2) y|^2 (tutorial eq. 46), so the
                # update cannot remove more than the sample's share of variance
                neg = w < 0
                norms = np.sum((Yo[neg] @ inv_sqrt_c) ** 2, axis=1)
                w_cov[neg] *= n / np.maximum(norms, 1e-300)
            C = ((1 + c1 * (1 - hsig) * cc * (2 - cc) - c1 - cmu * w.sum()) * C
                 + c1 * np.outer(pc, pc) + cmu * (Yo.T * w_cov) @ Yo)
            sigma *= np.exp((cs / damps) * (np.linalg.norm(ps) / chin - 1))
            C = (C + C.T) / 2
            evals, B = np.linalg.eigh(C)
            if not (np.all(np.isfinite(evals)) and evals.min() > 0 and np.isfinite(sigma)):
                return used
            D = np.sqrt(evals)
            sqrt_c = (B * D) @ B.T
            sqrt_c = (sqrt_c + sqrt_c.T) / 2
            inv_sqrt_c = (B / D) @ B.T
            inv_sqrt_c = (inv_sqrt_c + inv_sqrt_c.T) / 2
            best_hist.append(float(Fs[0]))
            median_hist.append(float(Fs[lam // 2]))
            flat.append(bool(Fs[0] == Fs[kth]))
            if self._should_stop(g, mean, sigma, sigma0, C, B, D, pc, Fs, best_hist,
                                 median_hist, flat, window, stall_min, max_iter):
                return used
            if max_fe is not None and used >= max_fe:
                return used

    @staticmethod
    def _should_stop(
        g: int,
        mean: np.ndarray,
        sigma: float,
        sigma0: float,
        C: np.ndarray,
        B: np.ndarray,
        D: np.ndarray,
        pc: np.ndarray,
        Fs: np.ndarray,
        best_hist: list[float],
        median_hist: list[float],
        flat: list[bool],
        window: int,
        stall_min: float,
        max_iter: float,
    ) -> str:
        """The stop criterion of the class docstring that holds after generation g, or ``""``.

        ``Fs`` (shape (lambda,)) are the generation's sorted costs; ``C``, ``B``, ``D`` the
        covariance (n, n), its eigenvectors (n, n) and the square roots of its eigenvalues
        (n,); the lists hold the best and median cost and the EqualFunValues flag of every
        generation of the run.
        """
        n = mean.size
        if g >= max_iter:
            return "MaxIter"
        recent = best_hist[-window:]
        if g >= window and max(recent) - min(recent) < 1e-11 and Fs[-1] - Fs[0] < 1e-11:
            return "TolFun"  # an infinite cost makes the range infinite: no stop
        stds = sigma * np.sqrt(np.diag(C))
        if np.all(stds < 1e-12) and np.all(np.abs(sigma * pc) < 1e-12):
            return "TolX"
        i = g % n
        if np.all(mean == mean + 0.1 * sigma * D[i] * B[:, i]):
            return "NoEffectAxis"
        if np.any(mean == mean + 0.2 * stds):
            return "NoEffectCoord"
        if D.max() ** 2 > 1e14 * D.min() ** 2:
            return "ConditionCov"
        if sum(flat[-window:]) > window / 3:
            return "EqualFunValues"
        if sigma / sigma0 > 1e20 * D.max() or stds.max() > 1e3 * sigma0:
            return "TolUpSigma"
        if g >= stall_min:
            span = int(min(max(stall_min, 0.2 * g), 20_000))
            third = max(1, int(0.3 * span))
            for hist in (best_hist, median_hist):
                last = hist[-span:]
                if np.median(last[-third:]) < np.median(last[:third]):
                    return ""  # still improving
            return "Stagnation"
        return ""


register_variant(
    "cmaes-ipop", CMAESRestarts,
    "IPOP-CMA-ES (Auger & Hansen, CEC 2005): cmaes-bipop without the small-population runs.",
    bipop=False,
)
