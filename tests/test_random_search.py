"""Tests of flexid.optimisers.random_search (what every optimiser must do: test_conformance.py)."""

from __future__ import annotations

import numpy as np

from flexid.optimisers import Problem, minimize


def test_first_batch_is_shared_population_then_uniform_draws():
    seen = []

    def f(X):
        seen.append(X.copy())
        return (X**2).sum(axis=1)

    p = Problem(f, [-1, 0], [1, 3])
    r = minimize("random-search", p, budget=130, seed=5, params={"population": 50})
    assert [len(X) for X in seen] == [50, 50, 30]  # last batch truncated
    assert r.nfev == 130 and r.nit == 2
    ss = np.random.SeedSequence(5).spawn(2)
    np.testing.assert_array_equal(seen[0], p.initial_population(50, ss[0]))
    rng = np.random.default_rng(ss[1])
    expect = np.array([-1, 0]) + np.array([2, 3]) * rng.random((50, 2))
    np.testing.assert_array_equal(seen[1], expect)
    X = np.concatenate(seen)
    assert X.min(axis=0)[0] >= -1 and X.max(axis=0)[1] <= 3
    # the result is exactly the best sampled point
    F = (X**2).sum(axis=1)
    assert r.fun == F.min()
    np.testing.assert_array_equal(r.x, X[np.argmin(F)])
