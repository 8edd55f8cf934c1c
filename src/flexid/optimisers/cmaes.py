"""CMA-ES, the covariance matrix adaptation evolution strategy (Hansen)."""

from __future__ import annotations

import math

import numpy as np

from ._params import Optimiser, Param, SearchGenerator
from ._problem import SearchSpace
from .registry import register

__all__ = ["CMAES"]


def _learning_rates(
    n: int, mueff: float, lam: int | None = None
) -> tuple[float, float, float, float, float, float]:
    """The default learning rates of CMA-ES, as pycma 4 computes them.

    Hansen's tutorial (arXiv:1604.00772v2, 2023, table 1) for ``c_c``, ``c_1`` and ``c_mu``
    (with its ``1/4`` offset in ``c_mu``); pycma's ``CMAAdaptSigmaCSA`` for the step size,
    which differs from the tutorial: ``c_sigma = (mu_eff + 2) / (n + mu_eff + 3)`` (at most
    1/2; the tutorial has ``+ 5``) and ``d_sigma = 1 + 2 max(0, a sqrt((mu_eff - 1) / (n +
    1)) - 1) + c_sigma`` with ``a = max(1, 3 (1 - 2^(-n/9)))`` (the tutorial has ``a = 1``;
    the two differ only for large ``mu_eff``, i.e. the large populations of IPOP); and
    ``c_1`` times ``min(1, lambda / 6)``.

    Parameters
    ----------
    n : int
        Dimension.
    mueff : float
        Variance-effective selection mass of the positive weights.
    lam : int or None
        Population size (only ``lambda < 6`` lowers ``c_1``); None means at least 6.

    Returns
    -------
    cc, cs, c1, cmu, damps, chin : float
        Rates of the rank-one path, the step-size path, the rank-one and rank-mu updates,
        the step-size damping, and ``E||N(0, I)|| = sqrt(2) Gamma((n + 1)/2) / Gamma(n/2)``.
    """
    cc = (4 + mueff / n) / (n + 4 + 2 * mueff / n)
    cs = min(0.5, (mueff + 2) / (n + mueff + 3))
    c1 = min(1.0, (lam if lam is not None else 6) / 6) * 2 / ((n + 1.3) ** 2 + mueff)
    cmu = min(1 - c1, 2 * (0.25 + mueff - 2 + 1 / mueff) / ((n + 2) ** 2 + mueff))
    a = max(1.0, 3 * (1 - 0.5 ** (n / 9)))
    damps = 1 + 2 * max(0.0, a * np.sqrt((mueff - 1) / (n + 1)) - 1) + cs
    # E||N(0, I)|| exactly, as pycma's sigma update uses it (its table of Mh.chiN; the
    # tutorial's series sqrt(n) (1 - 1/(4n) + 1/(21 n^2)) is 4e-5 high at n = 20)
    chin = math.sqrt(2) * math.exp(math.lgamma((n + 1) / 2) - math.lgamma(n / 2))
    return cc, cs, c1, cmu, damps, chin


def _hsig(ps: np.ndarray, cs: float, g: int) -> bool:
    """pycma's stall of the rank-one path: ``|p_sigma|^2 / (1 - (1 - c_sigma)^(2g)) / n <
    2 + 4 / (n + 1)`` after generation ``g`` (the tutorial's test of ``|p_sigma|`` against
    ``(1.4 + 2 / (n + 1)) E|N(0, I)|`` has a threshold within 3 % of it: 43.6 against 43.8
    for ``|p_sigma|^2`` at n = 20, 13.6 against 13.3 at n = 5)."""
    n = ps.size
    return bool(np.sum(ps**2) / (1 - (1 - cs) ** (2 * g)) / n < 2 + 4 / (n + 1))


def _sigma_factor(ps: np.ndarray, cs: float, damps: float, chin: float) -> float:
    """The CSA step-size change ``exp((c_sigma / d_sigma) (|p_sigma| / E|N(0, I)| - 1))``,
    its exponent clipped to [-1, 1] as pycma does."""
    return float(np.exp(np.clip((cs / damps) * (np.linalg.norm(ps) / chin - 1), -1.0, 1.0)))


@register
class CMAES(Optimiser):
    """(mu/mu_w, lambda)-CMA-ES with rank-one and rank-mu updates (Hansen's tutorial, 2016).

    Plain numpy implementation of the tutorial's algorithm (arXiv:1604.00772, Table 1 and
    Fig. 7): positive recombination weights ``w_i ∝ ln(mu + 1/2) - ln i`` (sum 1),
    ``mu = lambda // 2``, cumulation paths ``p_sigma`` and ``p_c`` with the ``h_sigma``
    stall, rank-one (``c1``) and rank-mu (``c_mu``) covariance updates and cumulative
    step-size adaptation (``c_sigma``, ``d_sigma``), all with pycma 4's default constants
    (the tutorial's of 2023 except for the step size and ``h_sigma``, see
    ``_learning_rates``; the sigma change per generation is at most a factor ``e``, as in
    pycma).  ``C`` is symmetrised and eigendecomposed every generation (cheap for the
    n <= 30 of ARX problems).

    Parameters
    ----------
    population : int or None
        ``lambda`` (FE per generation); None means ``4 + floor(3 ln n)``.
    sigma0 : float
        Initial step size as a fraction of the box width (default 0.3); the search runs in
        coordinates normalised to ``[0, 1]^n``, so the initial distribution is isotropic
        relative to the box.
    initial_points : int
        Size of the shared initial population evaluated as the first batch (default 50).
        It differs from ``population`` (lambda, the size of every later generation), the
        name every flexid optimiser gives its population size.
    penalty : float
        Weight of the boundary penalty used for ranking (default 1; 0 disables it).

    Notes
    -----
    Initial mean: the best point of the shared initial population (so CMA-ES starts from
    the same evaluated points as every other optimiser for a seed; ``space.x0`` is not
    used).  Bounds: a sample outside the box is evaluated at its projection onto the box
    (no FE outside the box) and, for ranking only, its cost gets a penalty ``penalty *
    median|f| * ||x - clip(x)||^2`` (normalised coordinates); the update uses the
    unclipped sample.  Costs of +inf (NaN/inf from the objective) rank last.  One
    generation is one iteration (``lambda`` FE).
    """

    name = "cmaes"
    reference = "Hansen & Ostermeier, Evol. Comput. 9(2):159-195, 2001; Hansen, arXiv:1604.00772"
    bounds = "clip + penalty"
    bounds_note = (
        "A sample outside the box is evaluated at its projection onto the box "
        "and ranked with a penalty on its distance to it; the update uses the "
        "unclipped sample."
    )
    stays_in_box = True
    population = Param(int, None, "lambda (None: 4 + floor(3 ln n))", low=2, none_ok=True)
    sigma0 = Param(
        float, 0.3, "initial step as a fraction of the box width", low=0.0, low_open=True
    )
    initial_points = Param(int, 50, "size of the shared initial population", low=1)
    penalty = Param(float, 1.0, "boundary penalty weight", low=0.0)

    def search(self, space: SearchSpace, rng: np.random.Generator) -> SearchGenerator:
        n = space.dim
        lo, width = space.lower, space.upper - space.lower
        lam = self.population or 4 + int(3 * np.log(n))
        mu = lam // 2
        w = np.log(mu + 0.5) - np.log(np.arange(1, mu + 1))
        w /= w.sum()
        mueff = 1.0 / np.sum(w**2)
        cc, cs, c1, cmu, damps, chin = _learning_rates(n, mueff, lam)

        X0 = space.initial_population(self.initial_points)
        F0 = yield X0
        mean = (X0[int(np.argmin(F0))] - lo) / width
        sigma = self.sigma0
        C = np.eye(n)
        pc = np.zeros(n)
        ps = np.zeros(n)
        B, D = np.eye(n), np.ones(n)
        sqrt_c = np.eye(n)
        g = 0
        while True:
            g += 1
            Z = rng.standard_normal((lam, n))
            # C^(1/2) = B D B' is unique, unlike B (LAPACK picks the signs and, for repeated
            # eigenvalues, the basis of eigenvectors), so the samples do not depend on the LAPACK
            # build; the distribution is the same as that of B D z.
            Y = Z @ sqrt_c
            Xn = mean + sigma * Y
            Xc = np.clip(Xn, 0.0, 1.0)
            F = yield lo + Xc * width
            dist = np.sum((Xn - Xc) ** 2, axis=1)
            finite = np.isfinite(F)
            scale = np.median(np.abs(F[finite])) if finite.any() else 1.0
            rank_cost = np.where(finite, F + self.penalty * max(scale, 1e-300) * dist, np.inf)
            order = np.argsort(rank_cost, kind="stable")[:mu]
            y_w = w @ Y[order]
            mean = mean + sigma * y_w
            c_inv_sqrt_y = B @ ((B.T @ y_w) / D)
            ps = (1 - cs) * ps + np.sqrt(cs * (2 - cs) * mueff) * c_inv_sqrt_y
            hsig = _hsig(ps, cs, g)
            pc = (1 - cc) * pc + hsig * np.sqrt(cc * (2 - cc) * mueff) * y_w
            Yo = Y[order]
            C = (
                (1 - c1 - cmu) * C
                + c1 * (np.outer(pc, pc) + (1 - hsig) * cc * (2 - cc) * C)
                + cmu * (Yo.T * w) @ Yo
            )
            sigma *= _sigma_factor(ps, cs, damps, chin)
            sigma = min(sigma, 1e3)
            C = (C + C.T) / 2
            evals, B = np.linalg.eigh(C)
            D = np.sqrt(np.maximum(evals, 1e-300))
            sqrt_c = (B * D) @ B.T
            sqrt_c = (sqrt_c + sqrt_c.T) / 2
