"""Tamura-Yasuda composite rotation in n dimensions, applied without per-point matrices.

``R^(n)(theta) = prod_{i=1}^{n-1} prod_{j=1}^{i} R_{n-i, n+1-j}(theta)`` (products expand
left to right).  Applied to a vector, this performs the plane rotations in lexicographic
order (1,2), (1,3), ..., (1,n), (2,3), ..., (n-1,n), with (1,2) first.  ``R_{i,j}`` is the
identity except ``[i,i] = cos, [i,j] = -sin, [j,i] = sin, [j,j] = cos``.
"""

from __future__ import annotations

import numpy as np

from ..errors import OptimiserError

__all__ = ["givens_sweep", "plane_rotation", "rotate_rows", "rotation_matrix"]


def plane_rotation(n: int, i: int, j: int, theta: float) -> np.ndarray:
    """The plane rotation ``R_{i,j}(theta)`` (1-based ``i < j``), shape (n, n).

    Parameters
    ----------
    n : int
        Dimension.
    i, j : int
        The rotated coordinate plane, 1-based, ``1 <= i < j <= n``.
    theta : float
        Angle (rad).

    Returns
    -------
    ndarray, shape (n, n)
        The rotation matrix.
    """
    r = np.eye(n)
    c, s = np.cos(theta), np.sin(theta)
    r[i - 1, i - 1] = c
    r[i - 1, j - 1] = -s
    r[j - 1, i - 1] = s
    r[j - 1, j - 1] = c
    return r


def givens_sweep(D: np.ndarray, cos, sin) -> np.ndarray:
    """Apply ``R^(n)(theta)`` to every row of ``D``: returns ``D @ R.T`` (a new array).

    Parameters
    ----------
    D : ndarray, shape (P, n)
        Rows to rotate (displacements from the spiral centre).
    cos, sin : float or ndarray of shape (P,)
        Cosine and sine of the angle; per-row arrays give each row its own angle.

    Returns
    -------
    ndarray, shape (P, n)
        Row ``i`` is ``R^(n)(theta_i) D[i]``.  ``n (n - 1) / 2`` vectorised plane updates,
        no per-row matrices.
    """
    D = np.asarray(D, dtype=float)
    if D.ndim != 2:
        raise OptimiserError(f"givens_sweep: D must have shape (P, n), got {D.shape}")
    # work on the transpose so that every coordinate is a contiguous row of length P, and
    # update in place with two scratch rows: six ufunc calls per plane, no allocation
    out = D.T.copy()
    n, P = out.shape
    c = np.asarray(cos, dtype=float)
    s = np.asarray(sin, dtype=float)
    t1 = np.empty(P)
    t2 = np.empty(P)
    for p in range(n - 1):
        a = out[p]
        for q in range(p + 1, n):
            b = out[q]
            np.multiply(s, a, out=t1)  # s a
            np.multiply(c, a, out=a)  # a <- c a - s b
            np.multiply(s, b, out=t2)
            a -= t2
            b *= c  # b <- s a_old + c b
            b += t1
    return out.T.copy()


def rotation_matrix(n: int, theta: float) -> np.ndarray:
    """The composite rotation ``R^(n)(theta)``, shape (n, n) (built once per run).

    Parameters
    ----------
    n : int
        Dimension.
    theta : float
        Angle of every plane rotation (rad).

    Returns
    -------
    ndarray, shape (n, n)
        The orthogonal matrix ``R^(n)(theta)``.
    """
    if n == 1:
        return np.eye(1)
    return givens_sweep(np.eye(n), np.cos(theta), np.sin(theta)).T


def rotate_rows(D: np.ndarray, theta) -> np.ndarray:
    """``R^(n)(theta_i) D[i]`` for every row: one GEMM for a scalar angle, else a sweep.

    Parameters
    ----------
    D : ndarray, shape (m, n)
        Rows to rotate (offsets from the spiral centre).
    theta : float or ndarray, shape (m,)
        One angle for all rows, or one per row (rad).

    Returns
    -------
    ndarray, shape (m, n)
        The rotated rows.
    """
    D = np.asarray(D, dtype=float)
    if np.ndim(theta) == 0:
        return D @ rotation_matrix(D.shape[1], float(theta)).T
    theta = np.asarray(theta, dtype=float)
    return givens_sweep(D, np.cos(theta), np.sin(theta))
