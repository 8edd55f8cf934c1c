"""Tests of flexid.models.stability: the vectorised Schur-Cohn test against np.roots.

Decisions are compared exactly, so the tests keep only polynomials whose decision rounding
cannot change: a root is kept away from the unit circle by more than rounding of the
coefficients can move it (np.poly, np.roots' backward error, the recursion: a few eps each).
They carry the ``numerics`` mark: the compiled kernel (FMA or not), the NumPy reference and
LAPACK's eigenvalues all decide them.
"""

from __future__ import annotations

import numpy as np
import pytest

from flexid.models.stability import is_stable, max_pole_radius, reflection_coefficients
from numerics import EPS


def _random_roots(rng, n, near_circle):
    pairs = n // 2
    r = rng.uniform(0.2, 1.4, pairs)
    ang = rng.uniform(0.0, np.pi, pairs)
    z = r * np.exp(1j * ang)
    roots = np.concatenate([z, z.conj(), rng.uniform(-1.3, 1.3, n - 2 * pairs)])
    if near_circle:
        # move the largest root to within 1e-6..1e-4 of the unit circle, either side
        scale = 1.0 + rng.choice([-1.0, 1.0]) * 10 ** rng.uniform(-6.0, -4.0)
        roots = roots / np.abs(roots).max() * scale
    return roots


def decided_by_coefficients(full: np.ndarray, roots: np.ndarray) -> bool:
    """True unless rounding of the coefficients could move the root nearest the unit circle
    across it: relative coefficient errors of 4 n eps (np.poly's rounding, the backward
    error of np.roots and of the recursion) move a simple root ``z`` by at most
    ``4 n eps sum_j |a_j| |z|^(n-j) / |A'(z)|`` (first order); keep a factor 2 margin."""
    n = full.size - 1
    z = roots[np.argmin(np.abs(np.abs(roots) - 1.0))]
    slope = abs(np.polyval(np.polyder(full), z))
    sensitivity = 4 * n * EPS * np.polyval(np.abs(full), abs(z)) / slope if slope else np.inf
    return 2 * sensitivity < abs(abs(z) - 1.0)


@pytest.mark.numerics
def test_agrees_with_np_roots_on_10000_polynomials_including_near_unit_circle():
    rng = np.random.default_rng(2026)
    coeffs, truth = [], []
    for n in range(1, 17):
        for k in range(700):
            roots = _random_roots(rng, n, near_circle=k % 2 == 0)
            a = np.poly(roots).real[1:]
            full = np.concatenate([[1.0], a])
            found = np.roots(full)
            if not decided_by_coefficients(full, found):  # rounding could decide these
                continue
            coeffs.append(a)
            truth.append(np.abs(found).max() < 1.0)
    assert len(coeffs) >= 10_000
    assert sum(truth) > 2000 and len(truth) - sum(truth) > 2000
    by_order: dict[int, list] = {}
    for a, t in zip(coeffs, truth):
        by_order.setdefault(a.size, []).append((a, t))
    for rows in by_order.values():
        A = np.array([a for a, _ in rows])
        expected = np.array([t for _, t in rows])
        np.testing.assert_array_equal(is_stable(A), expected)


@pytest.mark.numerics
def test_roots_within_1e_6_of_the_circle_both_sides():
    for n in (2, 5, 8, 16):
        for eps in (1e-6, 1e-7):
            ang = np.linspace(0.3, 2.8, n // 2)
            inside = np.poly(np.r_[(1 - eps) * np.exp(1j * ang), (1 - eps) * np.exp(-1j * ang)])
            outside = np.poly(np.r_[(1 + eps) * np.exp(1j * ang), (1 + eps) * np.exp(-1j * ang)])
            for full in (inside.real, outside.real):  # the decision is not rounding's
                assert decided_by_coefficients(full, np.roots(full))
            assert is_stable(inside.real[1:])[0]
            assert not is_stable(outside.real[1:])[0]


def test_edge_cases():
    assert is_stable(np.zeros((3, 0))).tolist() == [True, True, True]
    assert is_stable([0.5]).tolist() == [True]
    assert is_stable([-1.0]).tolist() == [False]  # pole exactly on the unit circle
    assert is_stable([0.0, 1.0]).tolist() == [False]  # z^2 + 1: poles at +-j
    assert is_stable([[np.nan, 0.1], [np.inf, 0.0], [0.1, 0.2]]).tolist() == [False, False, True]
    big = np.full((2, 8), 1e200)
    assert not is_stable(big).any()


def test_reflection_coefficients_and_radius():
    a = np.poly([0.5, -0.25]).real[1:]
    k = reflection_coefficients(a)
    assert k.shape == (1, 2)
    assert np.all(np.abs(k) < 1)
    np.testing.assert_allclose(max_pole_radius(a), [0.5])
    assert max_pole_radius(np.zeros((1, 0))).tolist() == [0.0]


def test_shape_errors():
    with pytest.raises(ValueError):
        is_stable(np.zeros((2, 2, 2)))
