"""Scale-freedom: an optimiser's run does not depend on the units of the box.

Every optimiser searches the unit box and the driver maps its points to the problem's box,
so a run on ``f(x)`` over a box and on ``f(x / s)`` over the box scaled by ``s`` visit the
same normalised points.  The objective is integer-valued (a staircase of Rosenbrock), so
every decision compares exact integers and rounding of the affine map (``eps`` of the
values) cannot change a decision; the normalised points then agree to that rounding.
"""

from __future__ import annotations

import numpy as np
import pytest

from flexid.optimisers import Problem, available, minimize

LOWER, UPPER = np.array([-2.0, -1.0, 0.0, -3.0]), np.array([2.0, 3.0, 1.0, -1.0])
SCALE = 1e3


def staircase(X: np.ndarray) -> np.ndarray:
    Z = X - 0.5 * (LOWER + UPPER) + 1.0
    f = np.sum(100.0 * (Z[:, 1:] - Z[:, :-1] ** 2) ** 2 + (1.0 - Z[:, :-1]) ** 2, axis=1)
    return np.floor(8.0 * f)


def _visited(name: str, scale: float) -> np.ndarray:
    seen: list[np.ndarray] = []

    def f(X):
        seen.append((X - scale * LOWER) / (scale * (UPPER - LOWER)))
        return staircase(X / scale)

    minimize(name, Problem(f, scale * LOWER, scale * UPPER), 600, seed=3)
    return np.concatenate(seen)


@pytest.mark.numerics
@pytest.mark.parametrize("name", sorted(available()))
def test_same_normalised_points_on_a_scaled_box(name):
    a, b = _visited(name, 1.0), _visited(name, SCALE)
    assert a.shape == b.shape and a.shape[0] == 600
    # the affine maps to and from each box round at a few eps of the values in [0, 1]
    np.testing.assert_allclose(a, b, rtol=0, atol=16 * np.finfo(float).eps)
