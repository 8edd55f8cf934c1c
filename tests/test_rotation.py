"""Tests of the Tamura-Yasuda composite rotation (algorithms.md 1.2, 1.4, 1.6)."""

from __future__ import annotations

import numpy as np
import pytest

from flexid.optimisers.rotation import givens_sweep, plane_rotation, rotate_rows, rotation_matrix


def explicit_product(n: int, theta: float) -> np.ndarray:
    """The paper's formula, expanded left to right, with dense plane rotations."""
    R = np.eye(n)
    for i in range(1, n):
        for j in range(1, i + 1):
            R = R @ plane_rotation(n, n - i, n + 1 - j, theta)
    return R


@pytest.mark.parametrize("n", [2, 3, 5, 10, 16])
def test_orthogonal_with_unit_determinant(n):
    R = rotation_matrix(n, 0.7)
    np.testing.assert_allclose(R.T @ R, np.eye(n), atol=1e-13)
    assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-12)


def test_n3_equals_r23_r13_r12():
    th = 0.381
    expected = plane_rotation(3, 2, 3, th) @ plane_rotation(3, 1, 3, th) @ plane_rotation(
        3, 1, 2, th
    )
    np.testing.assert_allclose(rotation_matrix(3, th), expected, atol=1e-15)
    # and it is not the reversed (customhys) order
    reversed_order = plane_rotation(3, 1, 2, th) @ plane_rotation(3, 1, 3, th) @ plane_rotation(
        3, 2, 3, th
    )
    assert not np.allclose(rotation_matrix(3, th), reversed_order)


def test_n2_is_the_ordinary_rotation():
    th = 0.3
    c, s = np.cos(th), np.sin(th)
    np.testing.assert_allclose(rotation_matrix(2, th), [[c, -s], [s, c]], atol=1e-15)


@pytest.mark.parametrize("seed", range(5))
def test_sweep_matches_explicit_product(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 13))
    th = float(rng.uniform(0, 2 * np.pi))
    R = explicit_product(n, th)
    np.testing.assert_allclose(rotation_matrix(n, th), R, atol=1e-12)
    D = rng.normal(size=(7, n))
    np.testing.assert_allclose(givens_sweep(D, np.cos(th), np.sin(th)), D @ R.T, atol=1e-12)
    np.testing.assert_allclose(rotate_rows(D, th), D @ R.T, atol=1e-12)


def test_per_row_sweep_matches_one_matrix_per_row():
    rng = np.random.default_rng(3)
    P, n = 9, 6
    D = rng.normal(size=(P, n))
    th = rng.uniform(0, 2 * np.pi, P)
    expected = np.array([explicit_product(n, th[i]) @ D[i] for i in range(P)])
    np.testing.assert_allclose(givens_sweep(D, np.cos(th), np.sin(th)), expected, atol=1e-12)
    np.testing.assert_allclose(rotate_rows(D, th), expected, atol=1e-12)


def test_sweep_does_not_modify_input():
    D = np.arange(12.0).reshape(3, 4)
    D0 = D.copy()
    givens_sweep(D, 0.5, 0.2)
    np.testing.assert_array_equal(D, D0)


def test_identity_spiral_moves_nothing_and_centre_is_fixed():
    rng = np.random.default_rng(0)
    X = rng.normal(size=(5, 4))
    xs = X[2].copy()
    # r = 1, theta = 0: nothing moves
    np.testing.assert_array_equal(rotate_rows(X - xs, 0.0), X - xs)
    np.testing.assert_array_equal(rotation_matrix(4, 0.0), np.eye(4))
    np.testing.assert_allclose(xs + 1.0 * rotate_rows(X - xs, 0.0), X, rtol=0, atol=1e-15)
    # any r, theta: the centre row is a fixed point
    Y = xs + 0.9 * rotate_rows(X - xs, 1.1)
    np.testing.assert_array_equal(Y[2], xs)
    Y = xs + 0.9 * rotate_rows(X - xs, rng.uniform(0, 6, 5))
    np.testing.assert_array_equal(Y[2], xs)


def test_rotation_preserves_length():
    rng = np.random.default_rng(1)
    D = rng.normal(size=(4, 8))
    out = rotate_rows(D, rng.uniform(0, 6, 4))
    np.testing.assert_allclose(np.linalg.norm(out, axis=1), np.linalg.norm(D, axis=1))


def test_bad_shape_raises_typed_error():
    from flexid.errors import OptimiserError

    with pytest.raises(OptimiserError, match="shape"):
        givens_sweep(np.ones(3), 1.0, 0.0)
