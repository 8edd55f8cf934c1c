"""Rounding bounds for the ARX routes (recursions, sums of squares, least squares).

Built on the analysis of tests/numerics.py: a sum of ``n`` products by two routes (any
order, with or without FMA, any BLAS kernel) differs by at most ``n eps sum|terms|``.

* The recursion ``y(t) = f(t) - sum_i a_i y(t - i)`` adds such an error ``delta(t)`` (an
  ``na + 1``-term sum) at every step by each route.  The difference ``d`` of two routes
  obeys the same recursion driven by the difference of their errors,
  ``A(q) d(t) = delta1(t) - delta2(t)``, so ``|d(t)| <= sum_s |h(t - s)| |delta1(s) -
  delta2(s)|`` with ``h`` the impulse response of ``1 / A(q)``: exact for the linear
  recursion, whatever its damping (a pole at radius 0.999 amplifies by up to ~1000).
* The compiled kernels (``flexid._kernels``) run the recursion in the transposed direct form
  with the state in registers, but each ``y(t)`` is still ``f(t) - a_na y(t - na) - ... -
  a_1 y(t - 1)`` summed in that order (the order of the direct form they replaced), so the
  bound above is unchanged.  ``arx_run`` computes ``f(t) = sum_j b_j reg[t, j]`` itself
  where the reference path uses a GEMM: a second ``nb``-term sum per step whose two routes
  differ by ``nb eps sum_j |b_j reg[t, j]|`` (``forced_terms`` and ``n_forced`` below),
  entering the recursion as ``delta`` does.  Thread counts and SIMD widths change which
  lanes hold a candidate, not the order of its sums.
* A sum of squares ``sum_t (target - y)^2`` moves by ``2 |e| |dy| + dy^2`` per sample, plus
  its own rounding (``K + 2`` roundings per route).
* Least squares by Householder QR or the SVD is backward stable: the solution is exact for
  data perturbed column-wise by at most ``gamma_{mn}`` (``m n u``, u = eps / 2, Higham,
  *Accuracy and Stability of Numerical Algorithms*, Thm 20.3), i.e. normwise by at most
  ``sqrt(n) m n u``.  The perturbation theorem of least squares (Higham Thm 20.1) turns
  that into ``|dx| <= kappa epsilon (2 |x| + (kappa + 1) |r| / |A|)``.  This worst-case
  bound is far above what BLAS-blocked QR does on any machine, which is the point: it
  holds on all of them.
"""

from __future__ import annotations

import numpy as np
from scipy import signal

from numerics import EPS, route_tolerance


def ar_terms(a: np.ndarray, forced: np.ndarray, state: np.ndarray, y: np.ndarray) -> np.ndarray:
    """``|f(t)| + sum_i |a_i| |y(t - i)|`` (the magnitudes each recursion step sums), (P, K).

    ``state`` is ``[y(-1), ..., y(-na)]``, shape (na,) or (P, na); ``y`` the outputs (P, K).
    """
    a, forced, y = np.atleast_2d(a), np.atleast_2d(forced), np.atleast_2d(y)
    p, na = a.shape
    k = forced.shape[1]
    state = np.broadcast_to(np.asarray(state, dtype=float), (p, na))
    terms = np.abs(forced).astype(float)
    hist = np.abs(np.concatenate([state[:, ::-1], y], axis=1))  # y(-na) .. y(K - 1)
    for i in range(1, na + 1):
        terms += np.abs(a[:, i - 1 : i]) * hist[:, na - i : na - i + k]
    return terms


def propagate(a: np.ndarray, delta: np.ndarray) -> np.ndarray:
    """``sum_s |h(t - s)| delta(s)`` per row: a per-step error bound through ``1 / A(q)``."""
    a, delta = np.atleast_2d(a), np.atleast_2d(delta)
    k = delta.shape[1]
    impulse = np.zeros(k)
    impulse[0] = 1.0
    out = np.empty_like(delta, dtype=float)
    for i in range(a.shape[0]):
        h = np.abs(signal.lfilter([1.0], np.r_[1.0, a[i]], impulse))
        out[i] = np.convolve(h, delta[i])[:k]
    return out


def ar_route_bound(a, forced, state, y, forced_terms=None, n_forced: int = 0) -> np.ndarray:
    """Bound on ``|y_route1 - y_route2|`` of the AR recursion, element-wise, shape (P, K).

    When the routes also compute ``f(t) = B(q) u(t)`` differently (a GEMM, ``lfilter``), an
    ``n_forced``-term sum of magnitudes ``forced_terms`` (P, K), that difference enters each
    step as well.
    """
    a = np.atleast_2d(np.asarray(a, dtype=float))
    delta = route_tolerance(a.shape[1] + 1) * ar_terms(a, forced, state, y)
    if forced_terms is not None:
        delta = delta + route_tolerance(n_forced) * np.atleast_2d(forced_terms)
    return propagate(a, delta)


def sse_route_bound(e: np.ndarray, dy: np.ndarray) -> np.ndarray:
    """Bound on the difference of ``sum_t e(t)^2`` by two routes whose ``e`` differ by ``dy``."""
    e, dy = np.atleast_2d(e), np.atleast_2d(dy)
    k = e.shape[1]
    return (2 * np.abs(e) * dy + dy * dy).sum(axis=1) + route_tolerance(k + 2) * (e * e).sum(
        axis=1
    )


def lstsq_error(phi: np.ndarray, x: np.ndarray, resid_norm: float = 0.0) -> float:
    """2-norm bound on one backward-stable least-squares solution minus the exact one."""
    m, n = phi.shape
    sv = np.linalg.svd(phi, compute_uv=False)
    kappa = sv[0] / sv[-1]
    epsilon = np.sqrt(n) * m * n * EPS / 2
    assert kappa * epsilon < 0.5, "the problem is too ill-conditioned for a rounding bound"
    return float(
        kappa * epsilon / (1 - kappa * epsilon)
        * (2 * np.linalg.norm(x) + (kappa + 1) * resid_norm / sv[0])
    )  # fmt: skip


def recovery_error(phi: np.ndarray, theta: np.ndarray, target_terms: np.ndarray,
                   n_terms: int) -> float:
    """2-norm bound on ``theta_ls - theta`` for noise-free data computed from ``theta``.

    Each target sample was computed by a loop summing ``n_terms`` products of magnitudes
    ``target_terms`` (per sample), so ``target - phi theta`` is rounding of at most
    ``n_terms eps target_terms`` (one route, with the margin of tests/numerics.py); least
    squares maps it through ``phi^+`` (norm ``1 / sigma_min``) and adds its own error.
    """
    rho = route_tolerance(n_terms) * np.asarray(target_terms, dtype=float)
    sigma_min = np.linalg.svd(phi, compute_uv=False)[-1]
    rho_norm = float(np.linalg.norm(rho))
    return rho_norm / sigma_min + lstsq_error(phi, theta, rho_norm)


# ------------------------------------------------------------------ rotations and spirals
def rotation_error(n: int) -> float:
    """Bound on ``|R1 d - R2 d| / |d|`` (2-norm) for two routes to the composite rotation.

    ``R^(n)(theta) d`` is ``N = n (n - 1) / 2`` plane rotations: a Givens sweep on ``d``, or
    on the identity followed by a GEMM, or a dense product of plane-rotation matrices.  Each
    plane rotation rounds its two entries within ``gamma_2 (|c a| + |s b|) <= 2 u sqrt 2 |(a,
    b)|`` and leaves the rest of the norm alone, and rotations do not amplify earlier errors:
    ``3 N eps`` for two routes; ``cos``/``sin`` within a few ulps on either route (NumPy's SIMD
    or libm) perturb each plane rotation by up to ``6 eps``: ``6 N eps``; a final dense
    matrix-vector product adds ``n sqrt(n) eps`` (n terms, ``|R| |d| <= sqrt(n) |d|``).
    """
    n_planes = n * (n - 1) // 2
    return (9 * n_planes + n * np.sqrt(n)) * EPS


def spiral_step_bound(xs, r, D, dr=0.0, dtheta=0.0, lower=None) -> np.ndarray:
    """Element-wise bound on two routes to one spiral step ``xs + r_i R(theta_i) d_i``.

    ``D`` (P, n) holds ``d_i = y_i - xs``; ``r`` is scalar or (P,).  The rotation as in
    :func:`rotation_error`; the product by ``r`` and the final addition round once each per
    route; ``dr`` and ``dtheta`` bound how far the routes' radius and angle differ
    (adaptive laws written differently), and ``|dR/dtheta| <= N``.

    ``lower``: the optimiser steps in the unit box and the objective (hence the recorded
    batches) sees ``lower + width z``.  Each recorded coordinate is then within
    ``u (|x| + |x - lower|)`` of the exact image of the optimiser's point (the product and
    the sum), those input errors move the step by at most ``(1 + r)`` times their norm, and
    the step's final addition rounds at the resolution of ``z``: ``u |x - lower|``.
    """
    D = np.atleast_2d(D)
    n = D.shape[1]
    r = np.broadcast_to(np.asarray(r, dtype=float), (D.shape[0],))[:, None]
    norm = np.linalg.norm(D, axis=1, keepdims=True)
    n_planes = n * (n - 1) // 2
    size = np.abs(xs) + r * norm  # |x'| for every coordinate of the new point
    out = EPS * size + norm * (r * (rotation_error(n) + 2 * np.sqrt(n) * EPS
                                    + n_planes * dtheta) + dr)  # fmt: skip
    if lower is not None:
        low = np.abs(np.asarray(lower, dtype=float))

        def point_error(X):
            return EPS / 2 * (2 * np.abs(X) + low)

        before = np.asarray(xs) + D
        propagated = np.linalg.norm(point_error(before), axis=1, keepdims=True)
        propagated += np.linalg.norm(point_error(np.asarray(xs)))
        out = out + EPS * (2 * size + 2 * low) + (1 + r) * propagated
    return out


# ------------------------------------------------------------------ estimated initial state
def initial_state_fit_bound(
    gram_dev: np.ndarray, fitted: np.ndarray, resid: np.ndarray, rest: np.ndarray, k: int
) -> tuple[np.ndarray, np.ndarray]:
    """Bounds on the errors and SSE of two routes that fit the free responses differently.

    Both routes solve the same normal equations in the basis ``P_m / den`` normalised to
    unit energy, whose Gram matrix is within 1.02 of the identity over the record (measured
    on lightly damped order-16 denominators up to radius 0.999).  One sums the Gram matrix
    of ``n`` computed responses; the other takes it as ``I - Q Q^T`` from the step-down
    energies, so their matrices differ by ``gram_dev`` (2-norm, per row), the
    non-orthogonality of the rounded ``P_m``.  The right-hand sides differ by as much for
    the same reason (the same responses correlated with ``e``).  To first order the fitted
    coefficients then move by ``G^-1 (dG c + dr)``, at most ``2 gram_dev |c|`` each with
    ``|G^-1| <= 1.02`` (a factor 2 of margin for the first order), so the fitted response
    (``fitted``, its 2-norm) by ``4 gram_dev |fitted|``; ``rest`` bounds the 2-norm of the
    difference of the two errors from rest (:func:`ar_route_bound`), which the fit passes
    on unchanged at most.  The SSE moves by ``2 |resid| d + d^2`` (Cauchy-Schwarz, ``resid``
    the 2-norm of the error after the fit), plus its own rounding (``k`` samples).

    Returns ``(d, dsse)``: bounds on ``|e1 - e2|`` (2-norm) and ``|sse1 - sse2|``, per row.
    """
    d = 4 * gram_dev * fitted + 2 * rest
    return d, 2 * resid * d + d * d + route_tolerance(k + 2) * resid * resid


# ------------------------------------------------------------------ numerator fit by lag sums
def _continuation_error(a, v, h, m, tol_lag):
    """Bound on the lag sums ``c(k) = sum_s h(s) v(s + k)``, ``k = -1 .. -(m - 1)``, that the
    kernel continues from ``c(0 .. na - 1)`` by the recursion of ``1/A``.

    The computed ``c`` obeys the recursion plus a rounding ``eta(k)`` per step (a sum of
    ``2 na + 2`` terms and the ``X`` terms past the window, ``m`` products each), and starts
    from lag sums off by at most ``tol_lag``: the error is the response of ``1/A`` to both,
    the start entering as ``na`` equivalent inputs of at most ``sum |a_i| tol_lag``, so at
    most ``sum_j |h(j)| (sum |a_i| tol_lag + max |eta|)``.
    """
    na, T = a.size, v.size

    def c_abs(k):
        lo, hi = max(0, -k), min(T, T - k)
        return float(np.abs(h[lo:hi] * v[lo + k : hi + k]).sum())

    def x_abs(k):
        return 0.0 if k >= 0 else float(np.abs(h[T : T - k] * v[T + k : T]).sum())

    eta = max(
        route_tolerance(2 * na + m + 2)
        * (x_abs(k) + sum(abs(a[i - 1]) * (c_abs(k + i) + x_abs(k + i)) for i in range(1, na + 1)))
        for k in range(-1, -m, -1)
    ) if m > 1 else 0.0  # fmt: skip
    gain = float(np.abs(h[: m + na]).sum())
    return gain * (float(np.abs(a).sum()) * tol_lag + eta) + tol_lag


def normal_equations_error(M: np.ndarray, E: np.ndarray, gamma: np.ndarray, target: np.ndarray,
                           c: np.ndarray, *, a: np.ndarray | None = None,
                           v: np.ndarray | None = None, h: np.ndarray | None = None,
                           n_v: int | None = None) -> float:
    """2-norm bound on ``b - b_exact`` of :func:`flexid.kernels.arx_fit_shifted`.

    The regressors are ``F = M E`` and the free response ``M gamma`` (``M`` (K, n) the delayed
    ``v`` and ``h`` over the window, see the kernel).  The route forms ``G = E^T M^T M E`` and
    ``E^T M^T (target - M gamma)`` from lag sums of ``T + 2 n`` products, end terms and the
    combinations by ``E`` (at most ``3 n`` more terms): each entry within ``(T + 3 n) eps``
    times the same sum of magnitudes (``|E|^T |M|^T |M| |E|``, ...).  Over the whole window
    with delays of ``h`` (``a``, ``v`` and ``h`` given: ``v`` over ``[0, T)``, ``h`` 16
    samples further) the lag sums of ``h`` with delays of ``v`` past it come from ``A h =
    delta`` instead, within :func:`_continuation_error`.  ``n_v`` is the number of delays
    of ``v`` in ``M`` (default the columns of ``E``; with a fitted initial state ``E`` has
    ``na`` more, the free response's coefficients).  Cholesky adds a
    backward error of ``gamma_(m+1) | |L| |L^T| |`` (Higham Thm 10.3), at most ``(m + 1) m^2
    eps`` in the 2-norm for the column-scaled matrix ``Gs`` (unit diagonal, ``|L_ij| <= 1``).
    With ``eta = ||Gs^-1||``, the perturbation of a linear system gives ``|dc| <= eta (|dr| +
    |dG| |c|) / (1 - eta |dG|)`` for the scaled solution ``c`` (``b = c / s``): the normal
    equations' ``kappa(F)^2`` (``eta ~ kappa(Fs)^2``) times the rounding of the sums, with no
    refinement to reduce it.
    """
    K = M.shape[0]
    n, m = E.shape
    s = np.linalg.norm(M @ E, axis=0)
    s[s == 0] = 1.0
    absM, absE = np.abs(M), np.abs(E)
    tol = route_tolerance(K + 3 * n)
    dGM = tol * (absM.T @ absM)
    mv = m if n_v is None else n_v
    big_l = n - mv
    if a is not None and big_l:
        na = a.size
        lag = route_tolerance(K) * max(
            float(np.abs(v[d:]) @ np.abs(h[: K - d])) for d in range(na)
        )  # the lag sums of v with delays of h that the continuation starts from
        cont = _continuation_error(a, v, h, mv, lag)
        for j in range(big_l):  # (h delayed j, v delayed k > j)
            dGM[mv + j, j + 1 : mv] += cont
            dGM[j + 1 : mv, mv + j] += cont
    dG = absE.T @ dGM @ absE / np.outer(s, s)
    dr = (tol * absE.T @ (absM.T @ np.abs(target)) + absE.T @ (dGM @ np.abs(gamma))) / s
    dG_norm = np.linalg.norm(dG) + (m + 1) * m * m * EPS
    Fs = (M @ E) / s
    eta = 1.0 / np.linalg.svd(Fs, compute_uv=False)[-1] ** 2
    assert eta * dG_norm < 0.5, "the normal equations are too ill-conditioned for a bound"
    dc = eta * (np.linalg.norm(dr) + dG_norm * np.linalg.norm(c * s)) / (1 - eta * dG_norm)
    return float(dc / s.min())


def free_cancel_bound(
    ee: np.ndarray, sse: np.ndarray, gram_dev: np.ndarray, n: int, k: int, rest: np.ndarray,
    fitted_dev: np.ndarray,
) -> np.ndarray:
    """Bound on the SSE-only shortcut of :func:`flexid.kernels.initial_state_fit`.

    Where the fit leaves at least ``FREE_CANCEL |e|^2`` the kernel returns ``|e|^2 - c.r``
    instead of summing the errors left by the fitted free response; both routes share ``e``
    and the coefficients ``c``.  In the basis normalised to unit energy (Gram matrix within
    1.02 of the identity, as in :func:`initial_state_fit_bound`), ``|e - F c|^2 = |e|^2 -
    2 c.r + c^T G c``, and the kernel's ``G`` is the true Gram matrix of the rounded basis up
    to ``gram_dev``, so the identity is off by ``gram_dev |c|^2 <= 1.02 gram_dev (|e|^2 -
    sse)``; ``c.r`` rounds within ``n`` terms of at most ``1.02 |c|^2``; the two sums of
    squares within ``(K + 2) eps`` each; ``ee`` is from another route than the kernel's
    (``rest``: the 2-norm of their difference), and the explicit route's fitted response
    rounds within ``fitted_dev`` (2-norm), moving its SSE by ``2 |resid| d + d^2``.
    """
    fit = np.maximum(ee - sse, 0.0)
    resid = np.sqrt(sse)
    norm_e = np.sqrt(ee)
    return (
        route_tolerance(k + 2) * (ee + sse)
        + (1.05 * route_tolerance(n) + 1.02 * gram_dev) * fit
        + 2 * norm_e * rest + rest * rest
        + 2 * resid * fitted_dev + fitted_dev * fitted_dev
    )
