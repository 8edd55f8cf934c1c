"""flexid's CMA-ES against pycma (``cma`` 4.x), the reference implementation.

The constants are compared to 1e-12 relative (they are the same formulas; the difference is
rounding).  The update is compared in lock-step: pycma samples, flexid's run is made to
sample the same points (its standard normal draws are solved for from them), both see the
same costs, and after every generation sigma and the covariance ``sigma^2 diag(s) C diag(s)``
must agree to 1e-9 relative and the paths (of norm about sqrt(n)) to 1e-8.  The only
difference in arithmetic is pycma's ``+ 1e-9`` in the Mahalanobis norm of the vectors with
negative weights (2e-10 relative at n = 8), and the 40 generations let rounding grow by a
few orders at most.  Before the constants were pycma's (c_sigma with ``+ 5``, c_mu without
the 1/4 offset, d_sigma without pycma's factor for large mu_eff, the tutorial's h_sigma and
E||N(0, I)|| series, no cap on the coordinates' standard deviations), the constants differed
by up to 60 % (d_sigma at lambda = 120, n = 20) and sigma after the first generation by
1e-3.
"""

from __future__ import annotations

import math
import sys
import warnings

import numpy as np
import pytest

from flexid.optimisers.cmaes import _learning_rates
from flexid.optimisers.cmaes_restarts import CMAESRestarts, _active_weights, _weights

cma = pytest.importorskip("cma")


def _pycma(n: int, lam: int | None, x0=None, sigma0: float = 1.0, **opts):
    options = {"verbose": -9, "seed": 1, **opts}
    if lam is not None:
        options["popsize"] = lam
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return cma.CMAEvolutionStrategy(np.zeros(n) if x0 is None else x0, sigma0, options)


@pytest.mark.parametrize("n", [2, 3, 5, 10, 20, 40])
@pytest.mark.parametrize("lam_factor", [None, 2, 10])
def test_default_constants_equal_pycmas(n, lam_factor):
    lam_def = 4 + int(3 * np.log(n))
    lam = None if lam_factor is None else lam_factor * lam_def
    es = _pycma(n, lam)
    lam = es.sp.popsize
    assert lam == (lam_def if lam_factor is None else lam_factor * lam_def)
    _, mu, mueff, _ = _weights(lam)
    cc, cs, c1, cmu, damps, chin = _learning_rates(n, mueff, lam)
    sm = es.sm.parameters(mueff=es.sp.weights.mueff, lam=lam)  # the c1, cmu of the update
    assert mu == es.sp.weights.mu
    for mine, ref in [
        (mueff, es.sp.weights.mueff),
        (cc, es.sp.cc),
        (c1, sm["c1"]),
        (cmu, sm["cmu"]),
        (cs, es.adapt_sigma.cs),
        (damps, es.adapt_sigma.damps),
        (chin, cma.utilities.math.Mh.chiN(n)),
    ]:
        assert mine == pytest.approx(ref, rel=1e-12, abs=0)
    w = _active_weights(lam, n, c1, cmu)
    np.testing.assert_allclose(w, np.asarray(es.sp.weights), rtol=1e-12, atol=1e-15)
    assert w.sum() == pytest.approx(sum(es.sp.weights), rel=1e-12)
    assert np.all(_active_weights(lam, n, c1, cmu, active=False)[mu:] == 0)


class _Feed:
    """Makes ``CMAESRestarts._run`` sample the points ``G`` (see the module docstring)."""

    def __init__(self) -> None:
        self.G = None
        self.state: dict = {}

    def standard_normal(self, shape):
        loc = sys._getframe(1).f_locals  # the run's state after the previous update
        self.state = {k: np.copy(loc[k]) for k in ("mean", "sigma", "C", "ps", "pc", "sv")}
        G, self.G = self.G, None
        assert G.shape == tuple(shape)
        Y = (G - loc["mean"]) / (loc["sigma"] * loc["sv"])
        return np.linalg.solve(loc["sqrt_c"], Y.T).T


def test_forty_generations_in_lock_step_with_pycma():
    """An ellipsoid of condition 1e4 at n = 8 (lambda 10, 5 negative weights), the mean in
    the middle of the unit box and sigma 0.01, so no sample reaches the transformation's
    layers (the map is the identity); pycma runs without bounds."""
    n = 8
    scale = 10.0 ** (2 * np.arange(n) / (n - 1))
    centre = 0.5 + 0.01 * np.linspace(-1, 1, n)

    def f(X):
        return np.sum((scale * (X - centre)) ** 2, axis=1)

    x0 = np.full(n, 0.5)
    es = _pycma(n, None, x0, 0.01, tolfun=0, tolx=0, tolfunhist=0, tolflatfitness=1e9)
    es.sm.C, es.sm.B, es.sm.D = np.eye(n), np.eye(n), np.ones(n)  # pycma perturbs C0 by 5e-6
    es.sm._inverse_root_C = None
    lam = es.sp.popsize
    feed = _Feed()
    run = CMAESRestarts()._run(x0.copy(), 0.01, lam, 10**6, 10**6, feed)
    F, ref = None, {}
    for g in range(1, 42):
        X = np.asarray(es.ask())
        feed.G = X
        Xf = next(run) if F is None else run.send(F)
        np.testing.assert_array_equal(Xf, np.clip(Xf, 0.05, 0.95))  # inside the layers
        if g > 1:
            s = feed.state
            assert float(s["sigma"]) == pytest.approx(ref["sigma"], rel=1e-9, abs=0), g
            C = s["C"] * float(s["sigma"]) ** 2 * np.outer(s["sv"], s["sv"])
            assert np.linalg.norm(C - ref["C"]) <= 1e-9 * np.linalg.norm(ref["C"]), g
            np.testing.assert_allclose(s["mean"], ref["mean"], rtol=0, atol=1e-13)
            np.testing.assert_allclose(s["ps"], ref["ps"], rtol=0, atol=1e-8)
            np.testing.assert_allclose(s["pc"], ref["pc"], rtol=0, atol=1e-8)
        np.testing.assert_allclose(Xf, X, rtol=0, atol=1e-13)
        F = f(X)
        es.tell(list(X), list(F))
        sv = es.sigma_vec.scaling * np.ones(n)
        ref = {
            "sigma": es.sigma,
            "C": es.sm.C * es.sigma**2 * np.outer(sv, sv),
            "mean": es.mean.copy(),
            "ps": es.adapt_sigma.ps.copy(),
            "pc": es.pc.copy(),
        }
    assert ref["sigma"] < 0.01 * math.exp(-0.5)  # the run has moved: sigma decreased


def test_lock_step_through_the_box_transformation_and_the_std_cap():
    """pycma on BBOB's box [-5, 5]^5 (its layer is then 0.025 of the side, flexid's) with
    lambda 17 from sigma 3 (0.3 of the side): samples reach the layers and beyond, and sigma
    grows in the first generation so that pycma's maxstd (1/3 of the side) scales coordinates
    down.  flexid runs in the unit box, ``u = (x + 5) / 10``.  20 generations, to 1e-8 (2e-8
    for |p_sigma| ~ 2): pycma's ``+ 1e-9`` in the norm is 2e-9 / |z| of each of the eight
    negative weights per generation, and it accumulates (measured: 2e-9 in sigma and C, 6e-9
    in p_sigma after 20 generations)."""
    n, half = 5, 5.0
    centre = np.array([0.2, 0.9, 0.5, 0.985, 0.35])  # unit box; one coordinate in a layer

    def f(U):
        return np.sum((10.0 ** np.arange(n) / 100) * (U - centre) ** 2, axis=1)

    u0 = np.array([0.5, 0.6, 0.4, 0.7, 0.5])
    es = _pycma(
        n,
        17,
        2 * half * u0 - half,
        0.3 * 2 * half,
        bounds=[-half, half],
        tolfun=0,
        tolx=0,
        tolfunhist=0,
        tolflatfitness=1e9,
    )
    es.sm.C, es.sm.B, es.sm.D = np.eye(n), np.eye(n), np.ones(n)
    es.sm._inverse_root_C = None
    feed = _Feed()
    run = CMAESRestarts()._run(u0.copy(), 0.3, 17, 10**6, 10**6, feed)
    F, ref, capped, outside = None, {}, 0, 0
    for g in range(1, 22):
        X = np.asarray(es.ask())
        G = (np.array([es.sent_solutions[x]["geno"] for x in X]) + half) / (2 * half)
        outside += int(np.sum((G < 0) | (G > 1)))
        feed.G = G
        Uf = next(run) if F is None else run.send(F)
        U = (X + half) / (2 * half)
        np.testing.assert_allclose(Uf, U, rtol=0, atol=1e-13)  # the same transformation
        if g > 1:
            s = feed.state
            capped += bool(np.any(s["sv"] != 1))
            assert float(s["sigma"]) == pytest.approx(ref["sigma"], rel=1e-8, abs=0), g
            np.testing.assert_allclose(s["sv"], ref["sv"], rtol=1e-8, atol=0)
            C = s["C"] * float(s["sigma"]) ** 2 * np.outer(s["sv"], s["sv"])
            assert np.linalg.norm(C - ref["C"]) <= 1e-8 * np.linalg.norm(ref["C"]), g
            np.testing.assert_allclose(s["mean"], ref["mean"], rtol=0, atol=1e-12)
            np.testing.assert_allclose(s["ps"], ref["ps"], rtol=0, atol=2e-8)
        F = f(U)
        es.tell(list(X), list(F))
        sv = es.sigma_vec.scaling * np.ones(n)
        sigma = es.sigma / (2 * half)
        ref = {
            "sigma": sigma,
            "sv": sv,
            "C": es.sm.C * sigma**2 * np.outer(sv, sv),
            "mean": (es.mean + half) / (2 * half),
            "ps": es.adapt_sigma.ps.copy(),
        }
    assert capped >= 10 and outside >= 50  # both mechanisms were exercised
