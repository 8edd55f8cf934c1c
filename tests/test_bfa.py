"""Tests of the bacterial foraging algorithm.

The reference loops normalise each tumble with a dot product, flexid with np.linalg.norm:
unit directions differ by a few eps, and since chemotaxis only adds steps ``C u`` the
positions differ by at most that per move, added up over the moves (no amplification).
Cost thresholds (0.1 on the sphere, 0.9 x random search) are modelling tolerances.
"""

from __future__ import annotations

import numpy as np
import pytest

from flexid.errors import HyperParameterError
from flexid.optimisers import create, get, minimize
from flexid.optimisers.bfa import swarming_cost, tumble_directions
from helpers import assert_median_beats_random_search
from numerics import EPS, assert_close_to_terms, route_tolerance
from objectives import FakeSpace, Recorder, box, drive, rosenbrock, shifted_problems

SHIFT, sphere, rastrigin = shifted_problems(0.5)


def reference_bfa(X, f, S, Nc, Ns, Nre, Ned, ped, C, rng, lower, upper):
    """Passino's loops, one bacterium at a time (no J_cc), cached start-of-step cost."""
    X = X.copy()
    n = X.shape[1]
    J = f(X)
    rows = S
    best = J.min()
    for ell in range(Ned):
        for _ in range(Nre):
            health = np.zeros(S)
            for _ in range(Nc):
                delta = rng.uniform(-1.0, 1.0, (S, n))
                for i in range(S):
                    health[i] += J[i]
                    j_last = J[i]
                    u = delta[i] / np.sqrt(delta[i] @ delta[i])
                    X[i] = X[i] + C * u
                    J[i] = f(X[i][None])[0]
                    rows += 1
                    best = min(best, J[i])
                    m = 0
                    while m < Ns:
                        m += 1
                        if J[i] < j_last:
                            j_last = J[i]
                            X[i] = X[i] + C * u
                            J[i] = f(X[i][None])[0]
                            rows += 1
                            best = min(best, J[i])
                        else:
                            m = Ns
            health += J
            order = np.argsort(health, kind="stable")[: S // 2]
            X = np.concatenate([X[order], X[order]])
            J = np.concatenate([J[order], J[order]])
        if ell < Ned - 1:
            mv = rng.random(S) < ped
            X[mv] = lower + (upper - lower) * rng.random((int(mv.sum()), n))
            for i in np.flatnonzero(mv):
                J[i] = f(X[i][None])[0]
                rows += 1
                best = min(best, J[i])
    return X, J, rows, best


@pytest.mark.numerics
@pytest.mark.parametrize("seed", [0, 1])
def test_matches_passino_loops(seed):
    S, n = 8, 3
    lower, upper = -2 * np.ones(n), 2 * np.ones(n)
    X0 = np.random.default_rng(100 + seed).uniform(-2, 2, (S, n))

    def f(X):
        return ((X - 0.3) ** 2).sum(axis=1)

    kw = dict(population=S, n_chemotactic=5, n_swim=3, n_reproduction=3, n_elim_disp=3,
              p_ed=0.4, step_size=0.2)
    opt = create("bfa", **kw)
    space = FakeSpace(X0, lower, upper)
    out = drive(opt, space, f, np.random.default_rng(seed))
    Xr, _, rows, best = reference_bfa(X0, f, S, 5, 3, 3, 3, 0.4, 0.2,
                                       np.random.default_rng(seed), lower, upper)
    assert sum(X.shape[0] for X, _ in out) == rows
    assert space.phases == ["chemotaxis"] * (5 * 3 * 3)
    # positions: |u| normalised by two routes ((n + 2) eps apart), x + C u rounded once per
    # route, at most N_ed N_re N_c (1 + N_s) moves per bacterium, dispersal draws identical
    last_rows = np.concatenate([X for X, _ in out])
    moves, reach = 3 * 3 * 5 * (1 + 3), np.abs(last_rows).max()
    e_pos = moves * EPS * (0.2 * (n + 2) + reach)
    # costs: |grad f| = 2 |x - 0.3| per coordinate, the same 3-term formula on both routes
    e_cost = 2 * n * (reach + 0.3) * e_pos + n * e_pos**2 + route_tolerance(n + 2) * best
    assert min(F.min() for _, F in out) == pytest.approx(best, rel=0, abs=e_cost)
    # every final reference position was evaluated by flexid's BFA at some point
    for x in Xr:
        assert np.min(np.abs(last_rows - x).max(axis=1)) <= e_pos


def test_tumble_directions_are_unit_and_passino_shaped():
    rng = np.random.default_rng(0)
    U = tumble_directions(rng, 20_000, 2)
    np.testing.assert_allclose(np.linalg.norm(U, axis=1), 1.0)  # 1e-7: far above rounding
    # normalised U[-1, 1]^2 leans to the diagonals: |cos| near 1/sqrt(2) more than isotropic
    ang = np.arctan2(U[:, 1], U[:, 0]) % (np.pi / 2)
    near_diag = np.mean(np.abs(ang - np.pi / 4) < np.pi / 16)
    assert near_diag > 0.25 + 0.03  # isotropic would give 0.25


@pytest.mark.numerics
def test_swarming_cost_matches_double_loop():
    rng = np.random.default_rng(1)
    X = rng.normal(size=(6, 3))
    want = np.zeros(6)
    terms = np.zeros(6)
    for i in range(6):
        for j in range(6):
            d2 = np.sum((X[i] - X[j]) ** 2)
            a, r = 0.1 * np.exp(-0.2 * d2), 0.1 * np.exp(-10.0 * d2)
            want[i] += -a + r
            # d2 (3 terms) enters the exponent: a relative error 4 eps of d2 scales each term
            # by 0.2 d2 or 10 d2 times that
            terms[i] += a * (1 + 0.2 * d2) + r * (1 + 10.0 * d2)
    # 12 terms a row in two orders; exp within 2 ulps on either route (NumPy's SIMD or libm)
    got = swarming_cost(X, 0.1, 0.2, 0.1, 10.0)
    assert_close_to_terms(got, want, terms, route_tolerance(12 + 4))


def test_swarming_changes_the_run_but_costs_no_fe():
    rec_off, rec_on = Recorder(sphere), Recorder(sphere)
    p = dict(population=10, n_chemotactic=10, n_reproduction=2, n_elim_disp=1, step_size=0.3)
    a = minimize("bfa", box(rec_off), 10**6, seed=2, params=p)
    # J_cc acts on distances in the unit box the driver hands the optimiser (all < sqrt(n)),
    # where a shallow attractant is nearly the same for every bacterium: use a deep one
    b = minimize("bfa", box(rec_on), 10**6, seed=2, params={**p, "swarming": True,
                                                              "d_attract": 50.0})
    assert a.nfev == rec_off.rows and b.nfev == rec_on.rows
    assert a.fun != b.fun


def test_reproduction_keeps_the_healthiest_half():
    # N_c = 1, N_s = 0: health_i = J_before + J_after of the single tumble; after
    # reproduction the next tumble starts from two copies of each of the best S/2
    S, n = 6, 2
    X0 = np.random.default_rng(5).uniform(-1, 1, (S, n))

    def f(X):
        return (X**2).sum(axis=1)

    opt = create("bfa", population=S, n_chemotactic=1, n_swim=0, n_reproduction=2,
                 n_elim_disp=1, step_size=0.5)
    rng = np.random.default_rng(0)
    out = drive(opt, FakeSpace(X0, -np.ones(n), np.ones(n)), f, rng)
    (_, J_init), (X1, J1), (X2, _) = out
    health = J_init + J1
    keep = np.argsort(health, kind="stable")[: S // 2]
    start = np.concatenate([X1[keep], X1[keep]])
    rng2 = np.random.default_rng(0)
    tumble_directions(rng2, S, n)
    U2 = tumble_directions(rng2, S, n)
    # the same function on the same draws, then x + C u on the same numbers: exact
    np.testing.assert_array_equal(X2, start + 0.5 * U2)


@pytest.mark.slow
def test_elimination_dispersal_probability():
    # N_c = N_re = 1, N_s = 0: one tumble batch of S rows per block, then a dispersal batch
    S, events, p_ed = 40, 400, 0.25
    rec = Recorder(sphere)
    res = minimize("bfa", box(rec), 10**7, seed=3, params=dict(
        population=S, n_chemotactic=1, n_swim=0, n_reproduction=1, n_elim_disp=events,
        p_ed=p_ed))
    assert res.stop == "converged"
    sizes = np.array([b.shape[0] for b in rec.batches])
    tumbles = int(np.sum(sizes == S)) - 1  # minus the initial population
    assert tumbles == events
    dispersed = rec.rows - S * (events + 1)
    trials = S * (events - 1)  # no dispersal after the last block
    mean, sd = p_ed * trials, np.sqrt(trials * p_ed * (1 - p_ed))
    assert abs(dispersed - mean) < 5 * sd
    # dispersed points are uniform in the box: their mean is near the box centre
    disp = np.concatenate([b for b in rec.batches if b.shape[0] < S])
    assert np.abs(disp.mean(axis=0)).max() < 0.1
    assert disp.min() >= -2.0 and disp.max() <= 2.0


def test_p_ed_zero_never_disperses():
    rec = Recorder(sphere)
    minimize("bfa", box(rec), 10**6, seed=3, params=dict(
        population=10, n_chemotactic=1, n_swim=0, n_reproduction=1, n_elim_disp=20, p_ed=0.0))
    assert rec.rows == 10 * 21


def test_fe_accounting_is_exact_including_a_cut_swim_batch():
    S = 50
    full = Recorder(sphere)
    minimize("bfa", box(full), 3_000, seed=1)
    sizes = np.array([b.shape[0] for b in full.batches])
    k = int(np.flatnonzero((sizes > 2) & (sizes < S))[0])  # first swim batch of >2 rows
    cut = int(sizes[:k].sum() + sizes[k] // 2)
    for budget in [1, 49, 50, 51, 777, cut, 2_999]:
        rec = Recorder(sphere)
        res = minimize("bfa", box(rec), budget, seed=1)
        assert res.nfev == rec.rows == budget
        assert res.history.fe[-1] == budget
        assert np.all(np.diff(res.history.fe) > 0)
        if budget == cut:
            last = rec.batches[-1]
            assert last.shape[0] == sizes[k] // 2
            np.testing.assert_array_equal(last, full.batches[k][: last.shape[0]])


def test_schedule_and_history_phases():
    p = dict(population=10, n_chemotactic=5, n_reproduction=2, n_elim_disp=3)
    res = minimize("bfa", box(sphere), 10**6, seed=0, params=p)
    assert res.stop == "converged"
    assert res.nit == 5 * 2 * 3
    assert res.history.phase[0] == "init"
    assert set(res.history.phase[1:]) <= {"chemotaxis", "final"}
    assert np.all(np.diff(res.history.best) <= 0)
    # chemotactic step costs S to S (N_s + 1) FE
    steps = np.diff(res.history.fe[: 1 + 5 * 2])
    assert steps.min() >= 10 and steps.max() <= 50


def test_until_budget_mode_keeps_cycling():
    p = dict(population=10, n_chemotactic=5, n_reproduction=2, n_elim_disp=None)
    res = minimize("bfa", box(sphere), 20_000, seed=0, params=p)
    assert res.nfev == 20_000 and res.stop == "budget"
    finite = minimize("bfa", box(sphere), 20_000, seed=0, params={**p, "n_elim_disp": 2})
    assert finite.nfev < 20_000 and finite.stop == "converged"


def test_clip_keeps_points_in_box():
    rec = Recorder(sphere)
    minimize("bfa", box(rec, half=0.2), 3_000, seed=0, params=dict(step_size=0.3, clip=True))
    allx = np.concatenate(rec.batches)
    assert allx.min() >= -0.2 and allx.max() <= 0.2


def test_reaches_tolerance_on_shifted_sphere():
    # 10-D shifted sphere, box [-2, 2]^10, Passino's C = 0.1 in the box's units (0.025 of a
    # side of the unit box the optimiser searches): cost < 0.1 within 20,000 FE
    for seed in range(3):
        result = minimize("bfa", box(sphere), 20_000, seed=seed, params={"step_size": 0.025})
        assert result.fun < 0.1


@pytest.mark.parametrize(
    "f, half", [(rastrigin, 5.12), (rosenbrock, 2.0)], ids=["rastrigin", "rosenbrock"]
)
def test_clearly_better_than_random_search(f, half):
    # Passino's C = 0.1 in the box's units, as a fraction of a side
    p = {"step_size": 0.1 / (2 * half)}
    assert_median_beats_random_search("bfa", box(f, half=half), 20_000, range(5), 0.9, params=p)


def test_population_must_be_even():
    # types and ranges of every hyper-parameter: test_conformance.py
    with pytest.raises(HyperParameterError, match="even"):
        create("bfa", population=7)
    with pytest.raises(HyperParameterError, match="even"):
        create("bfa", bacteria=7)  # Passino's name, an alias


def test_defaults_are_passinos():
    o = create("bfa")
    assert (o.population, o.n_chemotactic, o.n_swim, o.n_reproduction, o.n_elim_disp) == (
        50, 100, 4, 4, 2)
    assert (o.p_ed, o.step_size, o.swarming) == (0.25, 0.1, False)
    assert (o.d_attract, o.w_attract, o.h_repellant, o.w_repellant) == (0.1, 0.2, 0.1, 10.0)


def test_paper_variants():
    man = create("bfa-paper-manipulator")
    assert (man.n_swim, man.n_chemotactic, man.n_reproduction, man.n_elim_disp,
            man.step_size, man.population, man.p_ed) == (4, 30, 6, 6, 0.01, 50, 0.25)
    trs = create("bfa-paper-trs")
    assert (trs.n_swim, trs.n_chemotactic, trs.n_reproduction, trs.n_elim_disp,
            trs.step_size, trs.population, trs.p_ed) == (4, 30, 4, 4, 0.0175, 10, 0.25)
    assert issubclass(get("bfa-paper-trs"), get("bfa"))
    res = minimize("bfa-paper-trs", box(sphere), 10**6, seed=0)
    assert res.nit == 480 and 4_800 <= res.nfev <= 24_000 + 10 * 3
