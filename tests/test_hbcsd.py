"""Tests of the hybrid bacteria-chemotaxis spiral-dynamic algorithm.

Against the reference, every recorded spiral batch is compared with one reference step from
the batch before it (centre and adaptive laws from the recorded costs), so the tolerance is
the rounding of one step (tests/route_bounds.py), whatever the machine, and does not build
up over the run.  The reference chemotaxis moves each bacterium by ``C u`` with ``u``
normalised by another route: positions differ by at most a few eps per move, added up over
the moves (no amplification).  Cost thresholds against the sphere or random search are
modelling tolerances.
"""

from __future__ import annotations

import numpy as np
import pytest

from flexid.optimisers import create, get, minimize
from flexid.optimisers.hbcsd import adaptive_weight
from flexid.optimisers.rotation import plane_rotation, rotation_matrix
from helpers import assert_median_beats_random_search
from numerics import EPS, assert_close_to_terms
from objectives import FakeSpace, N, Recorder, box, drive, rosenbrock, shifted_problems
from route_bounds import spiral_step_bound

SHIFT, sphere, rastrigin = shifted_problems(0.5)


def dense_rotation(n, theta):
    R = np.eye(n)
    for i in range(1, n):
        for j in range(1, i + 1):
            R = R @ plane_rotation(n, n - i, n + 1 - j, theta)
    return R


def law(f, low, up, c1, c2):
    """Eq. 1 of the paper as printed: (low - up) / (1 + c1 / (c2 |f|)) + up."""
    return (low - up) / (1.0 + c1 / (c2 * abs(f))) + up


def law_error(low, up):
    """How far flexid's ``up + (low - up) g`` and :func:`law` may round apart (same ``f``):
    four roundings in ``g`` or in ``law``'s fraction, two in the final sum, per route."""
    return 6 * EPS * (abs(up) + abs(low - up))


def law_slope(f, low, up, c1, c2):
    """``|d law / d f|`` at ``f``."""
    return abs(low - up) * c1 * c2 / (c2 * np.abs(f) + c1) ** 2


def reference_spiral(batches, F0, f, r_l, r_u, c1r, c2r, theta=None, th=None):
    """Adaptive SDA, one point at a time with its own dense rotation matrix.

    One step from each of ``batches`` (the first with the known costs ``F0``, no FE), the
    centre and the laws from the costs: returns, for every batch but the last, the centre,
    the radii, the costs and the predicted next batch; and the best point and cost.
    """
    n = batches[0].shape[1]
    xs = fs = None
    steps = []
    for k, Y in enumerate(batches):
        F = np.asarray(F0 if k == 0 else f(Y), dtype=float)
        b = int(np.argmin(F))
        if fs is None or F[b] < fs:
            xs, fs = Y[b].copy(), F[b]
        if k + 1 == len(batches):
            break
        new = np.empty_like(Y)
        r = law(F, r_l, r_u, c1r, c2r)
        for i in range(Y.shape[0]):
            t = theta if theta is not None else law(F[i], *th)
            new[i] = xs + r[i] * dense_rotation(n, t) @ (Y[i] - xs)
        steps.append((xs.copy(), r, F, new))
    return steps, xs, fs


def reference_hbcsd(X, f, Nc, Ns, C, rng):
    """Phase 1 with Passino's loops, one bacterium at a time; returns personal bests."""
    X = X.copy()
    m, n = X.shape
    J = f(X)
    Pb, Jb = X.copy(), J.copy()
    rows = m
    for _ in range(Nc):
        delta = rng.uniform(-1.0, 1.0, (m, n))
        for i in range(m):
            j_last = J[i]
            u = delta[i] / np.sqrt(delta[i] @ delta[i])
            for step in range(Ns + 1):
                if step > 0:
                    if not J[i] < j_last:
                        break
                    j_last = J[i]
                X[i] = X[i] + C * u
                J[i] = f(X[i][None])[0]
                rows += 1
                if J[i] < Jb[i]:
                    Pb[i], Jb[i] = X[i].copy(), J[i]
    return Pb, Jb, rows


@pytest.mark.numerics
@pytest.mark.parametrize("mode", ["adaptive-angle", "fixed-angle"])
def test_no_chemotaxis_equals_independent_adaptive_spiral(mode):
    # costs of order 1-100 so the adaptive laws really vary between points
    rec = Recorder(lambda X: 30 * sphere(X))
    p = dict(population=7, n_chemotactic=0, k_max=15, r_lower=0.6, r_upper=0.97, c1_r=400.0,
             c2_r=1.0, theta_lower=0.4, theta_upper=1.6, c1_theta=200.0, c2_theta=0.5)
    if mode == "fixed-angle":
        p["angle"] = 0.34
    res = minimize("hbcsd", box(rec), 10**6, seed=11, params=p)
    X0 = rec.batches[0]
    steps, xs, fs = reference_spiral(
        rec.batches, 30 * sphere(X0), lambda X: 30 * sphere(X), 0.6, 0.97, 400.0, 1.0,
        theta=p.get("angle"), th=(0.4, 1.6, 200.0, 0.5),
    )
    assert len(rec.batches) == 16 and rec.rows == res.nfev == 7 * 16
    dtheta = 0.0 if mode == "fixed-angle" else law_error(0.4, 1.6)
    for (centre, r, _, want), before, got in zip(steps, rec.batches[:-1], rec.batches[1:],
                                                 strict=True):  # fmt: skip
        bound = spiral_step_bound(centre, r, before - centre, law_error(0.6, 0.97), dtheta,
                                  lower=-2.0)  # the box [-2, 2]^n seen through the unit box
        assert_close_to_terms(got, want, bound, 1.0)
    # the best of the recorded costs (the same function on the same rows): exact
    assert res.fun == fs
    np.testing.assert_array_equal(res.x, xs)
    # the radii really differ between points (the test would not see a constant law)
    r = law(30 * sphere(X0), 0.6, 0.97, 400.0, 1.0)
    th = law(30 * sphere(X0), 0.4, 1.6, 200.0, 0.5)
    assert r.max() - r.min() > 0.03 and th.max() - th.min() > 0.1


@pytest.mark.numerics
def test_chemotaxis_then_spiral_from_personal_bests():
    m, n = 6, 3
    lower, upper = -2 * np.ones(n), 2 * np.ones(n)
    X0 = np.random.default_rng(9).uniform(-2, 2, (m, n))

    def f(X):
        return 10 * ((X - 0.3) ** 2).sum(axis=1)

    opt = create("hbcsd", population=m, n_chemotactic=8, n_swim=3, step_size=0.3, k_max=5,
                 r_lower=0.7, r_upper=0.95, c1_r=3.0, c2_r=1.0, theta_lower=0.5,
                 theta_upper=1.2, c1_theta=2.0, c2_theta=1.0)
    space = FakeSpace(X0, lower, upper)
    out = [X for X, _ in drive(opt, space, f, np.random.default_rng(4))]
    Pb, Jb, rows = reference_hbcsd(X0, f, 8, 3, 0.3, np.random.default_rng(4))
    assert sum(X.shape[0] for X in out) == rows + 5 * m
    assert space.phases == ["chemotaxis"] * 8 + ["spiral"] * 5
    # chemotaxis: flexid's unit directions (np.linalg.norm) and the reference's (a dot
    # product) differ by (n + 2) eps, each move x + C u rounds once per route, and the errors
    # only add up: at most 8 (1 + 3) moves
    moves, reach = 8 * (1 + 3), np.abs(np.concatenate(out)).max()
    e_pos = moves * EPS * (0.3 * (n + 2) + reach)
    e_cost = 20 * np.abs(Pb - 0.3).sum(axis=1) * e_pos + 10 * n * e_pos**2 + (n + 3) * EPS * Jb
    # the spiral, one reference step from each batch; the first from the reference's
    # personal bests, so those errors move it too: the centre and the displacement by
    # (1 + 2 r) sqrt(n) e_pos, the laws by their slope times the cost error
    spiral = [Pb, *out[-5:]]
    steps, _, _ = reference_spiral(spiral, Jb, f, 0.7, 0.95, 3.0, 1.0, th=(0.5, 1.2, 2.0, 1.0))
    pb_centre = steps[0][0]
    for k, ((centre, r, F, want), got) in enumerate(zip(steps, out[-5:], strict=True)):
        d = spiral[k] - centre
        bound = spiral_step_bound(centre, r, d, law_error(0.7, 0.95), law_error(0.5, 1.2))
        if k == 0 or np.array_equal(centre, pb_centre):
            bound += (1 + 2 * r[:, None]) * np.sqrt(n) * e_pos
        if k == 0:
            slope = (law_slope(F, 0.7, 0.95, 3.0, 1.0)
                     + r * n * (n - 1) / 2 * law_slope(F, 0.5, 1.2, 2.0, 1.0))  # fmt: skip
            bound += np.linalg.norm(d, axis=1, keepdims=True) * (slope * e_cost)[:, None]
        assert_close_to_terms(got, want, bound, 1.0)


@pytest.mark.numerics
def test_huge_c1_equals_sda_with_upper_radius_and_angle():
    rec_h, rec_s = Recorder(sphere), Recorder(sphere)
    minimize("hbcsd", box(rec_h), 2_000, seed=5, params=dict(
        population=20, n_chemotactic=0, r_lower=0.5, r_upper=0.93, c1_r=1e300,
        theta_lower=0.1, theta_upper=0.9, c1_theta=1e300))
    minimize("sda", box(rec_s), 2_000, seed=5, params=dict(population=20, radius=0.93, angle=0.9))
    assert len(rec_h.batches) == len(rec_s.batches) == 100
    np.testing.assert_array_equal(rec_h.batches[0], rec_s.batches[0])  # shared population
    # every hbcsd batch is an SDA step (the SDA formula: one GEMM with the swept rotation)
    # from the batch before it: g ~ 1e-300 |f| is far below half an ulp of r_u and theta_u,
    # so the radius and angle round to them exactly, and only the rotation's route differs
    # (the per-row sweep of hbcsd)
    rt = rotation_matrix(N, 0.9).T
    xs = fs = None
    for before, got in zip(rec_h.batches[:-1], rec_h.batches[1:], strict=True):
        F = sphere(before)
        b = int(np.argmin(F))
        if fs is None or F[b] < fs:
            xs, fs = before[b].copy(), F[b]
        want = xs + 0.93 * ((before - xs) @ rt)
        bound = spiral_step_bound(xs, 0.93, before - xs, lower=-2.0)  # via the unit box
        assert_close_to_terms(got, want, bound, 1.0)


def test_adaptive_weight():
    F = np.array([0.0, 1.0, -3.0, np.inf, np.nan, 1e6])
    g = adaptive_weight(F, 2.0, 0.5)
    np.testing.assert_allclose(g[:3], [0.0, 0.5 / 2.5, 1.5 / 3.5])
    assert g[3] == 1.0 and g[4] == 1.0 and 0.99 < g[5] < 1.0
    # r = r_u + (r_l - r_u) g equals eq. 1 of the paper where the latter is defined
    f = np.array([0.5, 7.0, 300.0])
    r = 0.99 + (0.65 - 0.99) * adaptive_weight(f, 996.0, 0.97)
    np.testing.assert_allclose(r, law(f, 0.65, 0.99, 996.0, 0.97))
    np.testing.assert_allclose(law(1000.0, 0.65, 0.99, 996.0, 0.97), 0.822, atol=1e-3)


def test_best_non_increasing_and_phases_recorded():
    res = minimize("hbcsd", box(rastrigin, half=5.12), 10**6, seed=0,
                   params=dict(population=10, n_chemotactic=20, k_max=30))
    h = res.history
    assert np.all(np.diff(h.best) <= 0)
    assert h.phase[0] == "init"
    assert h.phase[1:21] == ["chemotaxis"] * 20 and h.phase[21:51] == ["spiral"] * 30
    assert res.nit == 50 and res.stop == "converged"
    # the spiral phase costs exactly m FE per iteration
    np.testing.assert_array_equal(np.diff(h.fe[20:51]), 10)


def test_fe_accounting_is_exact_including_a_cut_swim_batch():
    m = 50
    full = Recorder(sphere)
    minimize("hbcsd", box(full), 3_000, seed=1)
    sizes = np.array([b.shape[0] for b in full.batches])
    k = int(np.flatnonzero((sizes > 2) & (sizes < m))[0])
    cut = int(sizes[:k].sum() + sizes[k] // 2)
    for budget in [1, 50, 51, 777, cut, 2_999]:
        rec = Recorder(sphere)
        res = minimize("hbcsd", box(rec), budget, seed=1)
        assert res.nfev == rec.rows == budget
        assert res.history.fe[-1] == budget
        if budget == cut:
            assert rec.batches[-1].shape[0] == sizes[k] // 2
            np.testing.assert_array_equal(rec.batches[-1], full.batches[k][: sizes[k] // 2])
    # spiral-phase budgets (N_c = 5 then spiral until the budget)
    for budget in [1_234, 4_321]:
        rec = Recorder(sphere)
        res = minimize("hbcsd", box(rec), budget, seed=2, params=dict(n_chemotactic=5))
        assert res.nfev == rec.rows == budget and res.stop == "budget"
        assert "spiral" in res.history.phase


def test_clip_keeps_points_in_box():
    rec = Recorder(sphere)
    minimize("hbcsd", box(rec, half=0.3), 3_000, seed=0,
             params=dict(step_size=0.2, n_chemotactic=10, r_upper=1.0, clip=True))
    allx = np.concatenate(rec.batches)
    assert allx.min() >= -0.3 and allx.max() <= 0.3


def test_reaches_tolerance_on_shifted_sphere():
    # 10-D shifted sphere, box [-2, 2]^10, defaults with N_c = 20: cost < 1e-3 in 20,000 FE
    for seed in range(3):
        res = minimize("hbcsd", box(sphere), 20_000, seed=seed, params=dict(n_chemotactic=20))
        assert res.fun < 1e-3


@pytest.mark.parametrize(
    "f, half", [(rastrigin, 5.12), (rosenbrock, 2.0)], ids=["rastrigin", "rosenbrock"]
)
def test_clearly_better_than_random_search(f, half):
    assert_median_beats_random_search("hbcsd", box(f, half=half), 20_000, range(5), factor=0.8)


def test_paper_variants():
    man = create("hbcsd-paper-manipulator")
    assert (man.population, man.n_swim, man.step_size, man.n_chemotactic, man.k_max,
            man.angle, man.r_lower, man.r_upper, man.c1_r, man.c2_r) == (
        50, 4, 0.01, 500, 500, 0.34, 0.99, 1.0, 0.1, 0.3)
    trs = create("hbcsd-paper-trs")
    assert (trs.population, trs.n_swim, trs.step_size, trs.n_chemotactic, trs.k_max,
            trs.r_lower, trs.r_upper, trs.c1_r, trs.c2_r) == (
        10, 4, 0.04, 50, 150, 0.65, 0.99, 996.0, 0.97)
    assert trs.angle is None
    assert (trs.theta_lower, trs.theta_upper, trs.c1_theta, trs.c2_theta) == (
        1.03, 1.8, 110.0, 0.98)
    assert issubclass(get("hbcsd-paper-trs"), get("hbcsd"))
    res = minimize("hbcsd-paper-trs", box(sphere), 10**6, seed=0)
    assert 2_010 <= res.nfev <= 4_010 and res.nit == 200
