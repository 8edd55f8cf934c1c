"""Tests of flexid.optimisers.hbcsd_scaled (HBCSD with phase 1 scaled to the FE budget).

The phases are instrumented, not assumed: a callback records the phase of every iteration
and the objective records every batch, so the FE spent in each phase is counted exactly
(integers).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from flexid.optimisers import available, describe, minimize
from flexid.optimisers.hbcsd import HBCSD
from flexid.optimisers.hbcsd_scaled import HBCSDScaled
from helpers import assert_defaults
from objectives import Recorder, box

D = 5
SHIFT = np.linspace(-4.0, 3.5, D)


def sphere(X):
    return np.sum((X - SHIFT) ** 2, axis=1)


def phases(name: str, budget: int, seed: int = 0) -> tuple[dict, Recorder]:
    """FE spent per phase of one run on a 5-D sphere in [-5, 5]^5.

    Each iteration's FE (the difference of the FE counts the callback sees) goes to its
    phase; the run's last, cut iteration is recorded by the driver as ``"partial"`` and
    attributed to the phase it continues (the last one seen, or ``"spiral"`` after a
    chemotactic step the share cut, since the spiral follows it).
    """
    seen: list[tuple[str, int]] = []
    rec = Recorder(sphere)
    r = minimize(name, box(rec, D, half=5.0), budget, seed=seed,
                 callback=lambda info: seen.append((info.phase, info.fe)))
    assert r.nfev == rec.rows == budget
    fe = {"init": rec.sizes[0], "chemotaxis": 0, "spiral": 0}
    last, previous = "chemotaxis", rec.sizes[0]
    for phase, count in seen:
        if phase == "partial":
            phase = last
        fe[phase] += count - previous
        previous, last = count, phase
    return fe, rec


def test_registered_beside_the_faithful_hbcsd():
    assert {"hbcsd", "hbcsd-scaled"} <= set(available())
    assert_defaults("hbcsd-scaled", HBCSDScaled, phase1_share=0.5, n_chemotactic=None,
                    k_max=None, population=50, n_swim=4, step_size=0.05, clip=False)
    assert_defaults("hbcsd", HBCSD, n_chemotactic=100, k_max=None)
    assert describe("hbcsd-scaled")["bounds"]["stays_in_box"] is False


@pytest.mark.parametrize("budget", [500, 50_000])
def test_both_phases_run_within_their_shares(budget):
    """At 500 and 50,000 FE (d = 5, m = 50): phase 1 spends at most its share
    floor((B - m) / 2) and at least one batch; phase 2 gets the rest, at least m FE."""
    fe, _ = phases("hbcsd-scaled", budget)
    share = math.floor(0.5 * (budget - 50))
    assert 50 <= fe["chemotaxis"] <= share, fe
    assert fe["spiral"] >= 50 and fe["spiral"] == budget - 50 - fe["chemotaxis"], fe
    if budget == 50_000:
        # a step costs at most m (N_s + 1) = 250 FE, so phase 1 ends within one step of it
        assert fe["chemotaxis"] > share - 250, fe


def test_the_faithful_hbcsd_never_reaches_the_spiral_at_500_fe():
    """The contrast the variant exists for: 100 chemotactic steps do not fit in 500 FE."""
    fe, _ = phases("hbcsd", 500)
    assert fe["spiral"] == 0 and fe["chemotaxis"] == 450, fe


def test_the_spiral_starts_where_phase_1_left_off():
    """After the cut step, the spiral's first batch (m points) rotates the personal bests
    about the best of them, x*: x* itself is a row of it (its offset from x* is 0), so it is
    phase 1's best point, to the rounding of mapping it to the box and back (1e-12 is
    10^3 ulps of 5)."""
    fe, rec = phases("hbcsd-scaled", 500)
    chem_end = 50 + fe["chemotaxis"]
    spent = np.cumsum(rec.sizes)
    first_spiral = int(np.flatnonzero(spent > chem_end)[0])
    assert spent[first_spiral - 1] == chem_end and rec.sizes[first_spiral] == 50
    before = np.concatenate(rec.batches[:first_spiral])
    best = before[np.argmin(sphere(before))]
    assert np.any(np.all(np.abs(rec.batches[first_spiral] - best) <= 1e-12, axis=1))


def test_without_an_fe_budget_it_runs_100_chemotactic_steps():
    seen: list[str] = []
    minimize("hbcsd-scaled", box(sphere, D, half=5.0), {"max_iter": 103}, seed=0,
             callback=lambda info: seen.append(info.phase))
    assert seen[:100] == ["chemotaxis"] * 100 and seen[100:] == ["spiral"] * 3


def test_reproducible_from_the_seed():
    a = minimize("hbcsd-scaled", box(sphere, D, half=5.0), 2000, seed=4)
    b = minimize("hbcsd-scaled", box(sphere, D, half=5.0), 2000, seed=4)
    assert a.fun == b.fun and a.nit == b.nit
    np.testing.assert_array_equal(a.x, b.x)
