"""flexid's CMA-ES run against pycma from the same state, generation by generation.

Run: ``PYTHONPATH=src .venv/bin/python benchmarks/cmaes_vs_pycma_trace.py`` (BBOB f10 and
f12, d = 20, about a minute) or ``--fid 18 --dim 5 --lam 17 --gens 600`` (a large population,
where pycma's cap on the coordinates' standard deviations acts).  Needs ``ioh`` and ``cma``.
It was written to find why ``cmaes-bipop`` converged more slowly than pycma on the
ill-conditioned BBOB functions (docs/measurements/cmaes-bbob.md has the numbers).

Three comparisons:

1. The constants: lambda, mu, mu_eff, the weights (negative ones included), c_c, c_sigma,
   c_1, c_mu, d_sigma of flexid's ``cmaes`` / ``cmaes-bipop`` next to pycma's
   (``es.sp``, ``es.adapt_sigma``) for the dimension (and ``--lam``) given.
2. Lock-step: one run of ``cmaes-bipop``'s strategy (``CMAESRestarts._run``, no restarts)
   and one ``cma.CMAEvolutionStrategy`` (bounds [-5, 5], ``BoundTransform``) from the same
   mean and sigma; every generation pycma samples, and flexid is fed *the same candidate
   points* (its standard normal draws are solved for from pycma's genotypes and flexid's
   own mean, sigma and C), so both rank the same costs and only their updates differ.  With
   ``--layer pycma`` (the default) flexid's box transformation uses the layer width of
   pycma's on [-5, 5] (0.025 of the side, flexid's ``LAYER`` too), so the evaluated points
   are identical too; ``--layer flexid`` keeps ``LAYER``.  Printed every ``--every``
   generations: sigma (box-side units), the condition number of C, the relative difference
   of the two covariances ``sigma^2 diag(s) C diag(s)`` (``s``: the coordinate scaling of
   pycma's ``maxstd``) and of the means, ||p_sigma||, and the best cost; then the first
   generations after which sigma or the covariance differ by more than 1e-8 and 1e-3.
   flexid's stop criteria stay on (pycma's are off), so a stop of flexid ends the trace.
3. Free runs (``--seeds N``): each strategy on its own random numbers from uniform starts
   in [-4, 4]^d, the FE it takes to reach 1e-8 (one run, no restarts, at most 3,000 d FE).
"""

from __future__ import annotations

import argparse
import sys
import warnings

import numpy as np

from flexid.optimisers import cmaes_restarts as cr
from flexid.optimisers.cmaes import _learning_rates
from flexid.optimisers.cmaes_restarts import CMAESRestarts, _active_weights, _weights

HALF = 5.0


def _problem(fid: int, dim: int, instance: int = 1):
    import ioh

    p = ioh.get_problem(fid, instance, dim, ioh.ProblemClass.BBOB)
    return p, float(p.optimum.y)


def constants(dim: int, lam: int | None = None) -> None:
    """Print flexid's and pycma's default constants for ``dim`` (and ``lam``)."""
    import cma

    opts = {"verbose": -9, "bounds": [-HALF, HALF]}
    if lam is not None:
        opts["popsize"] = lam
    es = cma.CMAEvolutionStrategy(dim * [0.0], 3.0, opts)
    lam = es.sp.popsize
    w_p = np.asarray(es.sp.weights)
    _, mu, mueff, _ = _weights(lam)
    cc, cs, c1, cmu, damps, _ = _learning_rates(dim, mueff, lam)
    w_f = _active_weights(lam, dim, c1, cmu)
    print(f"d = {dim}, lambda = {lam}")
    rows = [
        ("mu", es.sp.weights.mu, mu),
        ("mueff", es.sp.weights.mueff, mueff),
        ("cc", es.sp.cc, cc),
        ("cs", es.adapt_sigma.cs, cs),
        ("c1", es.sp.c1, c1),
        ("cmu", es.sp.cmu, cmu),
        ("damps", es.adapt_sigma.damps, damps),
        ("sum w", w_p.sum(), np.nan if w_f is None else w_f.sum()),
    ]
    print(f"  {'':6} {'pycma':>14} {'flexid':>14} {'rel diff':>9}")
    for name, p, f in rows:
        print(f"  {name:6} {p:14.8g} {f:14.8g} {abs(f - p) / abs(p):9.2e}")
    print("  weights pycma ", np.array2string(w_p, precision=4, max_line_width=200))
    if w_f is not None:
        print("  weights flexid", np.array2string(w_f, precision=4, max_line_width=200))


class _Feed:
    """A stand-in for ``numpy.random.Generator`` that makes flexid sample given points.

    Its ``standard_normal`` is called by ``CMAESRestarts._run`` after the update of the
    previous generation; it reads the run's mean, sigma and ``C^(1/2)`` from the caller's
    frame, keeps them (the state to compare) and returns the draws ``Z`` for which the run's
    candidates ``mean + sigma Z C^(1/2)`` are the points ``G`` (unit-box coordinates).
    """

    def __init__(self) -> None:
        self.G: np.ndarray | None = None
        self.state: dict = {}

    def standard_normal(self, shape) -> np.ndarray:
        loc = sys._getframe(1).f_locals
        self.state = {k: np.copy(loc[k]) for k in ("mean", "sigma", "C", "ps", "pc", "sv")}
        G, self.G = self.G, None
        assert G is not None and G.shape == tuple(shape)
        Y = (G - loc["mean"]) / (loc["sigma"] * loc["sv"])
        return np.linalg.solve(loc["sqrt_c"], Y.T).T

    def random(self, *a):
        raise AssertionError("a single run draws no uniforms")


def lockstep(
    fid: int, dim: int, gens: int, every: int, layer: str, seed: int = 1, lam: int | None = None
) -> int:
    """Run pycma and flexid's run from the same state on the same candidates (see module).

    Returns the first generation after which sigma or sigma^2 C differ by more than 1e-8
    (relative), 0 if none does.
    """
    import cma

    problem, f_opt = _problem(fid, dim)
    x0 = np.random.default_rng(seed).uniform(-4, 4, dim)
    es = cma.CMAEvolutionStrategy(
        x0,
        0.3 * 2 * HALF,
        {
            "bounds": [-HALF, HALF],
            "verbose": -9,
            "seed": seed,
            "tolfun": 0,
            "tolx": 0,
            "tolfunhist": 0,
            "tolflatfitness": 1e9,
            "tolstagnation": 0,
            "maxiter": 10**9,
            "tolconditioncov": 0,
            "tolupsigma": 0,
            "tolxstagnation": False,
            **({} if lam is None else {"popsize": lam}),
        },
    )
    # pycma starts from C = diag(1 + 5e-6 i) (against equal eigenvalues); flexid from I
    es.sm.C, es.sm.B, es.sm.D = np.eye(dim), np.eye(dim), np.ones(dim)
    es.sm._inverse_root_C = None
    transform = cr.box_transform.__defaults__
    if layer == "pycma":
        tf = es.boundary_handler.bounds_tf
        tf.initialize(dim)
        cr.box_transform.__defaults__ = (float(tf._al[0]) / (2 * HALF),)
    feed = _Feed()
    # flexid's stop criteria are on (pycma's are off): a stop of flexid ends the trace
    gen = CMAESRestarts()._run(
        (x0 + HALF) / (2 * HALF),
        0.3,
        es.sp.popsize,
        10**9,
        int(100 + 100 * dim**1.5 / es.sp.popsize),
        feed,
    )
    print(
        f"\nlock-step f{fid} d={dim} lambda={es.sp.popsize}, layer {layer} "
        "(sigma in box-side units; d(.) relative differences; C here is the covariance "
        "sigma^2 diag(s) C diag(s) with pycma's coordinate scaling s)"
    )
    print(
        f"{'g':>5} {'sigma pycma':>12} {'flexid':>10} {'cond(C) pycma':>13} {'flexid':>9} "
        f"{'d(s2 C)':>8} {'d(mean)':>8} {'|ps| pycma':>10} {'flexid':>7} {'f - fopt':>9}"
    )
    first = jump = 0
    F, prev = None, {}
    try:
        for g in range(1, gens + 1):
            X = np.asarray(es.ask())
            feed.G = (np.array([es.sent_solutions[x]["geno"] for x in X]) + HALF) / (2 * HALF)
            try:
                Xf = next(gen) if F is None else gen.send(F)
            except StopIteration:
                print(f"flexid's run stopped after generation {g - 1} (a stop criterion)")
                break
            if g > 1:
                compare = feed.state  # flexid after generation g - 1, pycma's is in `prev`
                s_f, sv = float(compare["sigma"]), compare["sv"]
                C_f = compare["C"] * s_f**2 * np.outer(sv, sv)
                dC = np.linalg.norm(C_f - prev["C"]) / np.linalg.norm(prev["C"])
                dm = np.linalg.norm(compare["mean"] - prev["mean"]) / prev["sigma"]
                ds = abs(s_f / prev["sigma"] - 1)
                if not first and (ds > 1e-8 or dC > 1e-8):
                    first = g - 1
                if not jump and dC > 1e-3:
                    jump = g - 1
                if (g - 1) % every == 0 or g - 1 in (1, first, jump):
                    print(
                        f"{g - 1:5d} {prev['sigma']:12.4e} {s_f:10.4e} {prev['cond']:13.3e} "
                        f"{np.linalg.cond(compare['C']):9.3e} {dC:8.1e} {dm:8.1e} "
                        f"{prev['ps']:10.3f} {np.linalg.norm(compare['ps']):7.3f} "
                        f"{prev['best'] - f_opt:9.2e}"
                    )
                if prev["best"] - f_opt < 1e-8:
                    break
            if layer == "pycma":
                dx = np.max(np.abs(Xf * 2 * HALF - HALF - X))
                assert dx < 1e-9 * HALF, f"evaluated points differ by {dx:g}"
            F = np.asarray(problem(X), dtype=float)
            es.tell(list(X), list(F))
            sv_p = es.sigma_vec.scaling * np.ones(dim)
            prev = {
                "sigma": es.sigma / (2 * HALF),
                "C": es.sm.C * (es.sigma / (2 * HALF)) ** 2 * np.outer(sv_p, sv_p),
                "mean": (es.mean + HALF) / (2 * HALF),
                "cond": np.linalg.cond(es.sm.C),
                "ps": float(np.linalg.norm(es.adapt_sigma.ps)),
                "best": float(es.best.f),
            }
    finally:
        cr.box_transform.__defaults__ = transform
    print(
        f"first generation after which sigma or sigma^2 C differ by > 1e-8: {first or 'none'}"
        f", by > 1e-3: {jump or 'none'}"
        f"; stopped at g = {g - 1}, f - f_opt = {prev['best'] - f_opt:.2e}, "
        f"{es.countevals} FE"
    )
    return first


def free_runs(fid: int, dim: int, seeds: int) -> None:
    """FE to 1e-8 of one run (no restarts) of each, from uniform starts, own random numbers."""
    import cma

    problem, f_opt = _problem(fid, dim)
    budget = 3000 * dim
    out = {"pycma": [], "flexid": []}
    for seed in range(1, seeds + 1):
        x0 = np.random.default_rng(seed).uniform(-4, 4, dim)
        es = cma.CMAEvolutionStrategy(
            x0,
            3.0,
            {
                "bounds": [-HALF, HALF],
                "verbose": -9,
                "seed": seed,
                "maxfevals": budget,
                "ftarget": f_opt + 1e-8,
            },
        )
        while not es.stop():
            X = es.ask()
            es.tell(X, list(np.asarray(problem(np.asarray(X)), dtype=float)))
        out["pycma"].append(es.countevals if es.best.f - f_opt < 1e-8 else np.inf)
        lam = es.sp.popsize
        gen = CMAESRestarts()._run(
            (x0 + HALF) / (2 * HALF),
            0.3,
            lam,
            100 + (150 * (dim + 3) ** 2) // lam**0.5,
            int(100 + 100 * dim**1.5 / lam),
            np.random.default_rng(seed),
        )
        X, fe, best = next(gen), 0, np.inf
        while fe < budget:
            F = np.asarray(problem(X * 2 * HALF - HALF), dtype=float)
            fe += len(F)
            best = min(best, F.min())
            if best - f_opt < 1e-8:
                break
            try:
                X = gen.send(F)
            except StopIteration:
                break
        out["flexid"].append(fe if best - f_opt < 1e-8 else np.inf)
    for k, v in out.items():
        print(f"free runs f{fid} d={dim} {k:6}: FE to 1e-8 {v} median {np.median(v):.0f}")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fid", type=int, default=None, help="BBOB id (default 10 and 12)")
    parser.add_argument("--dim", type=int, default=20)
    parser.add_argument("--gens", type=int, default=1500)
    parser.add_argument("--every", type=int, default=100)
    parser.add_argument("--layer", choices=("pycma", "flexid"), default="pycma")
    parser.add_argument("--seeds", type=int, default=0, help="free runs per strategy")
    parser.add_argument("--lam", type=int, default=None, help="lambda (default pycma's)")
    args = parser.parse_args(argv)
    warnings.simplefilter("ignore")
    constants(args.dim, args.lam)
    for fid in [args.fid] if args.fid else [10, 12]:
        lockstep(fid, args.dim, args.gens, args.every, args.layer, lam=args.lam)
        if args.seeds:
            free_runs(fid, args.dim, args.seeds)


if __name__ == "__main__":
    main()
