"""Tests of the Tamura-Yasuda composite rotation.

The Givens sweep and the explicit product of plane-rotation matrices are two routes to one
rotation: they agree within ``rotation_error`` of tests/route_bounds.py (``N = n (n-1) / 2``
plane rotations, a few eps each), and those tests carry the ``numerics`` mark.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import linalg

from flexid.optimisers.rotation import givens_sweep, plane_rotation, rotate_rows, rotation_matrix
from numerics import EPS, assert_close_to_terms
from route_bounds import rotation_error


def explicit_product(n: int, theta: float) -> np.ndarray:
    """The paper's formula, expanded left to right, with dense plane rotations."""
    R = np.eye(n)
    for i in range(1, n):
        for j in range(1, i + 1):
            R = R @ plane_rotation(n, n - i, n + 1 - j, theta)
    return R


@pytest.mark.numerics
@pytest.mark.parametrize("n", [2, 3, 5, 10, 16])
def test_orthogonal_with_unit_determinant(n):
    R = rotation_matrix(n, 0.7)
    # each column of R is within rotation_error(n) of a column of the exact R (unit length):
    # R^T R within twice that, plus the GEMM's n-term sums
    tol = 2 * rotation_error(n) + n * EPS
    np.testing.assert_allclose(R.T @ R, np.eye(n), rtol=0, atol=tol)
    # det(R + E) - 1 ~ trace(R^T E) <= n sqrt(n) max_j |E e_j|; the LU of np.linalg.det
    # (partial pivoting) is exact for R + F, |F| <= gamma_3n |L| |U|, and the cofactors of a
    # rotation are its entries (<= 1): n^2 gamma_3n max(|L| |U|)
    _, lower, upper = linalg.lu(R)
    growth = (np.abs(lower) @ np.abs(upper)).max()
    tol_det = n * np.sqrt(n) * rotation_error(n) + n * n * 3 * n * EPS / 2 * growth
    assert np.linalg.det(R) == pytest.approx(1.0, rel=0, abs=tol_det)


@pytest.mark.numerics
def test_n3_equals_r23_r13_r12():
    th = 0.381
    expected = plane_rotation(3, 2, 3, th) @ plane_rotation(3, 1, 3, th) @ plane_rotation(
        3, 1, 2, th
    )
    # sweep against GEMMs of plane rotations; the orders differ by O(1), not by rounding
    np.testing.assert_allclose(rotation_matrix(3, th), expected, rtol=0, atol=rotation_error(3))
    # and it is not the reversed (customhys) order
    reversed_order = plane_rotation(3, 1, 2, th) @ plane_rotation(3, 1, 3, th) @ plane_rotation(
        3, 2, 3, th
    )
    assert not np.allclose(rotation_matrix(3, th), reversed_order)


def test_n2_is_the_ordinary_rotation():
    th = 0.3
    c, s = np.cos(th), np.sin(th)
    # one plane rotation of the identity: products with 1 and 0, sums with 0, the same cos
    # and sin of the same float: exact on any machine
    np.testing.assert_array_equal(rotation_matrix(2, th), [[c, -s], [s, c]])


@pytest.mark.numerics
@pytest.mark.parametrize("seed", range(5))
def test_sweep_matches_explicit_product(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 13))
    th = float(rng.uniform(0, 2 * np.pi))
    R = explicit_product(n, th)
    np.testing.assert_allclose(rotation_matrix(n, th), R, rtol=0, atol=rotation_error(n))
    D = rng.normal(size=(7, n))
    # per row: within rotation_error(n) |d| (tests/route_bounds.py)
    norms = np.linalg.norm(D, axis=1, keepdims=True)
    assert_close_to_terms(givens_sweep(D, np.cos(th), np.sin(th)), D @ R.T, norms,
                          rotation_error(n))  # fmt: skip
    assert_close_to_terms(rotate_rows(D, th), D @ R.T, norms, rotation_error(n))


@pytest.mark.numerics
def test_per_row_sweep_matches_one_matrix_per_row():
    rng = np.random.default_rng(3)
    P, n = 9, 6
    D = rng.normal(size=(P, n))
    th = rng.uniform(0, 2 * np.pi, P)
    expected = np.array([explicit_product(n, th[i]) @ D[i] for i in range(P)])
    norms = np.linalg.norm(D, axis=1, keepdims=True)
    got = givens_sweep(D, np.cos(th), np.sin(th))
    assert_close_to_terms(got, expected, norms, rotation_error(n))
    assert_close_to_terms(rotate_rows(D, th), expected, norms, rotation_error(n))


def test_sweep_does_not_modify_input():
    D = np.arange(12.0).reshape(3, 4)
    D0 = D.copy()
    givens_sweep(D, 0.5, 0.2)
    np.testing.assert_array_equal(D, D0)


def test_identity_spiral_moves_nothing_and_centre_is_fixed():
    rng = np.random.default_rng(0)
    X = rng.normal(size=(5, 4))
    xs = X[2].copy()
    # r = 1, theta = 0: nothing moves.  cos 0 = 1 and sin 0 = 0 exactly, so the rotation and
    # the GEMM with the identity multiply by 1 and 0 and add zeros: exact on any machine
    np.testing.assert_array_equal(rotate_rows(X - xs, 0.0), X - xs)
    np.testing.assert_array_equal(rotation_matrix(4, 0.0), np.eye(4))
    # (x - xs) + xs rounds twice: within u |x - xs| + u |x| of x
    assert_close_to_terms(xs + 1.0 * rotate_rows(X - xs, 0.0), X, np.abs(X - xs) + np.abs(X),
                          EPS / 2 * (1 + EPS))  # fmt: skip
    # any r, theta: the centre row is a fixed point (a zero row rotates to zeros exactly)
    Y = xs + 0.9 * rotate_rows(X - xs, 1.1)
    np.testing.assert_array_equal(Y[2], xs)
    Y = xs + 0.9 * rotate_rows(X - xs, rng.uniform(0, 6, 5))
    np.testing.assert_array_equal(Y[2], xs)


def test_rotation_preserves_length():
    rng = np.random.default_rng(1)
    D = rng.normal(size=(4, 8))
    out = rotate_rows(D, rng.uniform(0, 6, 4))
    # rtol 1e-7 (the default) is far above the rounding, rotation_error(8) ~ 6e-14
    np.testing.assert_allclose(np.linalg.norm(out, axis=1), np.linalg.norm(D, axis=1))


def test_bad_shape_raises_typed_error():
    from flexid.errors import OptimiserError

    with pytest.raises(OptimiserError, match="shape"):
        givens_sweep(np.ones(3), 1.0, 0.0)
