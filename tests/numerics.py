"""Tolerances for one result computed by two routes, derived from rounding analysis.

A sum of ``n`` products evaluated in any order, with or without fused multiply-add, is within
``gamma_n sum|terms|`` of the exact sum, ``gamma_n = n u / (1 - n u)`` with the unit roundoff
``u = eps / 2`` (Higham, *Accuracy and Stability of Numerical Algorithms*, 2nd ed., Lemma 3.1
and eq. 3.5).  This is what BLAS kernels (blocking, vector width, FMA) and the compiled and
NumPy backends are free to change, so two routes to one dot product differ by at most
``2 gamma_n sum|terms| <= n eps sum|terms|`` (for ``n u << 1``).

A recursion over ``N`` steps of a stable map adds at most one such error per step; the map
being non-expansive (a stable, dissipative plant, in the norm of its state), earlier errors
do not grow.  So ``N n eps`` times the largest term magnitude bounds the difference of two
routes through the whole run.

Each test that compares two routes states which of these it uses and computes ``terms``
(``|C| |x|`` for an output ``C x``, for example) instead of scaling by the result itself:
an output with cancellation (the tip acceleration, whose terms are 10^6 times the output)
is only as accurate as its terms allow.
"""

from __future__ import annotations

import numpy as np

EPS = float(np.finfo(float).eps)


def route_tolerance(n_terms: int, n_steps: int = 1) -> float:
    """Bound on ``|route1 - route2| / terms`` for ``n_steps`` steps of ``n_terms``-term sums."""
    return float(n_terms) * float(n_steps) * EPS


def assert_close_to_terms(actual, desired, terms, tol: float) -> None:
    """``|actual - desired| <= tol * terms`` element-wise (``terms`` broadcasts)."""
    actual, desired = np.asarray(actual, dtype=float), np.asarray(desired, dtype=float)
    err = np.abs(actual - desired)
    bound = tol * np.asarray(terms, dtype=float)
    bad = err > bound
    if np.any(bad):
        i = np.unravel_index(int(np.argmax(err - bound)), err.shape)
        raise AssertionError(
            f"{int(bad.sum())} of {err.size} elements differ by more than {tol:.3g} x terms; "
            f"worst at {i}: |diff| {err[i]:.3g} > bound {np.broadcast_to(bound, err.shape)[i]:.3g}"
        )
