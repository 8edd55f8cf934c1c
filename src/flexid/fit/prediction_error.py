"""The prediction-error reference of polynomial models (MATLAB ``pem``, ``oe``, ``armax``, ``bj``).

For a :class:`~flexid.models.polynomial.PolynomialStructure`
``A y = sum_j B_j/F_j u_j(t - nk_j) + C/D e``, :func:`pem` minimises the sum of squared
one-step prediction errors

    ``e(t) = D/C (A y(t) - sum_j B_j/F_j u_j(t - nk_j))``,  ``t >= structure.start``,

by Gauss-Newton/Levenberg-Marquardt (MINPACK, ``scipy.optimize.least_squares(method="lm")``)
with analytic Jacobians, from several starts, and returns the best result: what a user of
MATLAB's ``pem``/``oe``/``armax``/``bj`` runs, and the gradient reference an optimiser's result
on the same cost is compared with.  :func:`oe`, :func:`armax` and :func:`bj` take MATLAB's
orders.

Notes
-----
* **Initial conditions** (the meaning of :func:`flexid.models.polynomial.run_predictor`,
  which is the reference for one ``theta``):

  ``"zero"``
      every filter from rest at ``t = 0``: ``e`` is the cascade ``D/C (A y - sum_j w_j)``,
      ``w_j = B_j/F_j u_j(t - nk_j)``, each filter started from rest (equal, as exact
      arithmetic, to the combined predictor ``den = C F`` run from rest, ``F = prod_j F_j``);
  ``"measured"``
      the combined recursion started at ``start`` from the measured outputs, i.e. ``e(t) = 0``
      before ``start`` and ``C F e(t) = N(t)`` after, with the FIR part
      ``N = D A F y - sum_j D B_j q^-nk_j prod_(i != j) F_i u_j``;
  ``"estimate"``
      the predictor's initial state fitted by least squares: a free response of ``1/(C F)``
      over ``t >= start`` is added to the from-rest error and chosen to minimise the sum of
      squares.  Those responses are spanned by the shifts ``h(t - k)``, ``k = 0..n-1``
      (``n = structure.n_state``), of the impulse response ``h`` of ``1/(C F)``; the ``n``
      coefficients are eliminated by variable projection, ``e = (I - Pi_H) e_zero``, and the
      Jacobian is the exact (Golub-Pereyra) derivative of that projection.

* **Jacobians** (Ljung, *System Identification*, 2nd ed., sec. 10.3).  Under ``"zero"``:
  ``de/da_i = (D/C) y(t-i)``, ``de/db_ji = -(D/(C F_j)) u_j(t - nk_j - i + 1)``,
  ``de/dc_i = -(1/C) e(t-i)``, ``de/dd_i = (1/C) v(t-i)`` with ``v = A y - sum_j w_j``, and
  ``de/df_ji = (D/(C F_j)) w_j(t-i)``: the columns of one polynomial are delayed copies of one
  filtered signal, one ``lfilter`` call each.  Under ``"measured"``, differentiating
  ``C F e = 1[t >= start] N`` gives ``C F de = 1[t >= start] dN - d(C F) e``; the forcing
  columns are again delayed copies of a few FIR-filtered signals, filtered by ``1/(C F)`` in
  one call.  Each is checked against central differences in the tests.
* **Stability.**  ``A``, every ``F_j`` and ``D`` are kept stable and ``C`` minimum phase
  (every root strictly inside the unit circle, and of radius ``<= r_max``): starts with roots
  outside are mirrored to ``1/conj(r)`` as ``pem`` does (``B`` divided by the product of the
  mirrored radii of ``A`` or ``F_j`` so the magnitude response is unchanged), and a
  Levenberg-Marquardt step that leaves that set is rejected by returning a residual far
  worse than the start's (:func:`flexid.fit.reference.levenberg_marquardt`, the one run of every
  reference: LM raises its damping, and the Jacobian is only evaluated at accepted points).
* **Starts.**  Least squares ARX of orders ``(na, nb, nk)`` (or ``(max nf, nb, nk)`` for
  ``F``, one denominator per input refitted on the partial residual when the ``nf_j``
  differ); 30 Steiglitz-McBride iterations for ``F`` (per input, each on its partial
  residual); for ARMAX the joint Hannan-Rissanen regression; for a structure with ``F`` and
  a noise model (Box-Jenkins), the output-error fit of its plant ``B/F`` (this function on
  the OE structure of the same ``nb``, ``nf``, ``nk``, from its own least-squares and
  Steiglitz-McBride starts) with ``C = D = 1``, the model Box-Jenkins refines, as MATLAB's
  ``bj`` starts from an instrumental-variable plant: the one-step error of a lightly damped
  plant with a noise model has minima where the noise model absorbs what a poor plant leaves
  (on the DaISy robot arm, BJ(8,2,2,8,1) with the estimated initial state, the output-error
  start ends at an SSE about 20 times lower than the least-squares one); ``C`` and ``D`` from
  Hannan-Rissanen on the plant residual ``v`` of the others; then ``starts`` extras from
  ``numpy.random.default_rng(seed)``, alternately the first start's roots perturbed and
  uniformly drawn stable roots.  ``B`` of every start is the exact optimum of the from-rest
  error given the other polynomials (the error is linear in ``B``).  An ARX structure's error
  is linear in every parameter, so it gets no extras (every start converges to least
  squares).
* **The cap.**  A cap is a safeguard, not a target: when the best point has a root within
  ``1e-6`` of ``r_max < 1``, LM continues from it with the cap lifted to
  ``1 - (1 - r_max)/100`` and then to the unit circle itself (roots strictly inside), and the
  better stable point is kept.  A best point still on the cap is continued with its roots
  on the cap held at their radii (:func:`flexid.fit.reference.along_the_cap`) and restarted with
  them pulled in (:func:`flexid.fit.reference.restarts_on_the_cap`): plain LM stops on the cap
  short of the minimum along it, 2.5 % above it on the DaISy robot arm's OE(8,8,1) (first
  two thirds, measured-output rule), and a lower basin may lie behind it (the dryer's
  OE(6,6,3), mean removed, first two thirds, estimated initial state: 3.684 on the cap,
  3.665 along it, 3.470 pulled in).
  A minimum on the cap, where the SSE still falls towards it, is the estimate
  (``cap_reason`` of the result says so).  The result reports whether its final point still sits on
  the cap in force (``on_cap`` of the result) and whether it is a first-order local minimum
  (``local_minimum``).
* **Convergence.**  On a large-residual (misspecified) fit Gauss-Newton converges only
  linearly, and MINPACK's ``ftol`` test may stop it with the relative gradient still above
  :data:`OPTIMALITY_THRESHOLD` although the SSE has settled to ~1e-11; an interior final
  point that fails the gradient test gets one more run with the tolerances ``tol * 1e-5``
  (``"polish"`` in the result's ``runs``).
* **Budget.**  By default each run has MINPACK's ``100 * n_params`` residual evaluations.
  A run they stop within ``1.1`` times the best SSE of all the starts continues from where it
  stopped, a budget at a time while its SSE still falls (by more than ``1e-9`` relative), up
  to ten budgets in all (``"<kind>, continued"`` in the result's ``runs``).  Slow valleys
  are common in over-parametrised structures (a pole pair nearly cancelled by a zero pair
  moves along an almost flat direction): on the simulated twin rotor's pitch, OE(5,5,1) from
  least squares needs about 3,000 evaluations to reach its minimum, and a budget of 1,000
  left it 16 % above it, 3 % above the best start.  Runs far above the best (the manipulator's
  OE(16,16,1) with the estimated initial state: wandering starts at 500 times the best SSE)
  are not continued, so they cost one budget, not ten; and a run still above 100 times the
  best SSE of the runs before it after ``10 * n_params`` evaluations is abandoned at its best
  point (there, three of the four wandering starts: the fit of OE(16,16,1) to seed 1 of the
  manipulator's paper preset takes 4,250 residual evaluations instead of 12,900).  A run from
  a random or perturbed start is also abandoned when the fall of its SSE over its last
  ``10 * n_params`` evaluations, repeated over the rest of its budget, would not bring it down
  to ``1.1`` times the best of the runs before it (where it would be continued; a run within
  that may be crawling towards a better minimum: on the dryer, OE(8,8,3) from a random start
  at 1.01 times the best reaches 0.81 times it in 1,700 more evaluations).  On the CD player
  arm's first output (two inputs, 1,365 samples), OE([8,8],[8,8],[1,1]) spent 6,400 of its
  7,200 evaluations on two such crawls ending 40 % above the best, and OE([3,3],[3,3],[1,1])
  29,000 of 33,000 on continued runs that gained 1 %.  The structured starts are never
  abandoned for crawling: the slow valley of the twin rotor's OE(5,5,1) gains 0.5 % in its
  first 1,000 continued evaluations and 15 % in the next 900.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
from scipy import linalg, signal

from .._validate import checked_keywords, integer, real
from ..costs.polynomial import orthogonal_numerators
from ..errors import ConfigError, DataError
from ..models.arx import _io_arrays
from ..models.polynomial import PolynomialModel, PolynomialStructure, _check_initial, _poly_mul
from ..models.polynomial import structure as _named_structure
from ..models.stability import (
    mirror_inside,
    perturbed_poles,
    pole_radius_batched,
    pull_inside,
    random_poles,
    within_radius,
)
from ..models.vocabulary import REFERENCE_STARTS
from .output_error import _SM_ITERATIONS
from .reference import (
    CAP_TOLERANCE,
    CHUNKS,
    OPTIMALITY_THRESHOLD,
    PROMISING,
    PULLED_TO,
    ReferenceResult,
    ReferenceRun,
    along_the_cap,
    cap_reason,
    levenberg_marquardt,
    optimality,
    restarts_on_the_cap,
)

__all__ = [
    "OPTIMALITY_THRESHOLD",
    "PEMResult",
    "PEMRun",
    "armax",
    "bj",
    "oe",
    "pem",
    "prediction_errors",
    "prediction_jacobian",
]

# the random and perturbed starts, which explore: a run of theirs that crawls too slowly to
# reach the best of the others is abandoned (the structured starts keep whole budgets: a slow
# valley can speed up, as on the twin rotor's OE(5,5,1) below)
_EXTRA_KINDS = ("perturbed", "random")
# The continuation run of a final point that fails the gradient test uses tol times this
# factor, not below the floor (MINPACK refuses tolerances under machine epsilon).
_POLISH_FACTOR = 1e-5
_POLISH_FLOOR = 1e-15


#: The result of :func:`pem` (the one reference result type; its keys below).
PEMResult = ReferenceResult
#: One run of :func:`pem`.
PEMRun = ReferenceRun


# =================================================================================== helpers
def _fir(b: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``b(q) x`` from rest, shape of ``x`` (axis 0)."""
    if not np.any(b):
        return np.zeros_like(x, dtype=float)
    return signal.lfilter(b, [1.0], x, axis=0)


def _iir(b: np.ndarray, a: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``b(q)/a(q) x`` from rest along axis 0 (``a`` monic)."""
    if not np.any(b):
        return np.zeros_like(x, dtype=float)
    return signal.lfilter(b, a, x, axis=0)


def _lagged(g: np.ndarray, lo: int, hi: int, start: int) -> np.ndarray:
    """Columns ``g(t - lag)``, ``lag = lo..hi``, rows ``t = start..N-1``: shape (K, hi-lo+1).

    Every lag is at most ``start`` (the structure's first counted sample reaches back no
    further), so no sample before ``t = 0`` is needed.
    """
    n = g.size
    if hi < lo:
        return np.zeros((n - start, 0))
    windows = np.lib.stride_tricks.sliding_window_view(g[start - hi : n - lo], hi - lo + 1)
    return windows[:, ::-1].copy()


def _delayed(x: np.ndarray, lo: int, hi: int) -> np.ndarray:
    """Columns ``x(t - lag)``, ``lag = lo..hi``, for every ``t >= 0`` (zero before 0)."""
    return _lagged(np.concatenate([np.zeros(hi), x]), lo, hi, hi)


def _lstsq(phi: np.ndarray, target: np.ndarray) -> np.ndarray | None:
    if phi.shape[1] == 0:
        return np.zeros(0)
    try:
        sol = linalg.lstsq(phi, target)[0]
    except (linalg.LinAlgError, ValueError):
        return None
    return sol if np.isfinite(sol).all() else None


# =================================================================================== problem
class _Problem:
    """Prediction errors and analytic Jacobians of one structure on one record."""

    def __init__(self, s: PolynomialStructure, u: np.ndarray, y: np.ndarray, initial: str):
        self.s = s
        self.u = u
        self.y = y
        self.initial = initial
        self.start = s.start
        self.N = y.size
        self.K = self.N - self.start
        self.m = s.n_inputs
        self.sl = s.slices()
        self.n = s.n_params
        self.energy = float(y[self.start :] @ y[self.start :])
        self.nfev = 0
        self.njev = 0
        # (slice, order) of every polynomial whose roots are constrained
        self.rooted = [(self.sl["a"], s.na), (self.sl["c"], s.nc), (self.sl["d"], s.nd)]
        self.rooted += [(sl, nf) for sl, nf in zip(self.sl["f"], s.nf)]
        self.rooted = [(sl, k) for sl, k in self.rooted if k]

    # ------------------------------------------------------------------ polynomials
    def parts(self, theta: np.ndarray):
        """Monic ``a, c, d``, delayed ``b_j`` and monic ``f_j`` of ``theta``."""
        one = np.ones(1)
        sl = self.sl
        a = np.concatenate([one, theta[sl["a"]]])
        c = np.concatenate([one, theta[sl["c"]]])
        d = np.concatenate([one, theta[sl["d"]]])
        # an input without B coefficients and delay keeps a zero numerator (not an empty one)
        b = [
            np.concatenate([np.zeros(max(nk, 1 - (s.stop - s.start))), theta[s]])
            for nk, s in zip(self.s.nk, sl["b"])
        ]
        f = [np.concatenate([one, theta[s]]) for s in sl["f"]]
        return a, b, c, d, f

    def admissible(self, theta: np.ndarray, r_max: float) -> bool:
        """Every constrained polynomial strictly stable with root radii ``<= r_max``."""
        return all(within_radius(theta[sl], r_max) for sl, _ in self.rooted)

    def max_radius(self, theta: np.ndarray) -> float:
        radii = [float(pole_radius_batched(theta[sl][None, :])[0]) for sl, _ in self.rooted]
        return max(radii, default=0.0)

    def predictor_ok(self, theta: np.ndarray) -> bool:
        """``C`` and every ``F_j`` strictly stable: the predictor filters by ``1/(C F)``."""
        parts = [self.sl["c"], *self.sl["f"]]
        return all(within_radius(theta[sl], 1.0) for sl in parts)

    # ------------------------------------------------------------------ errors
    def errors(self, theta: np.ndarray, jac: bool) -> tuple[np.ndarray, np.ndarray | None]:
        if self.initial == "zero":
            return self._zero(theta, jac)
        if self.initial == "measured":
            return self._measured(theta, jac)
        return self._estimate(theta, jac)

    def _zero(self, theta: np.ndarray, jac: bool):
        s, st, u, y = self.s, self.start, self.u, self.y
        a, b, c, d, f = self.parts(theta)
        w = [_iir(b[j], f[j], u[:, j]) for j in range(self.m)]
        v = _fir(a, y) - np.sum(w, axis=0)
        e_full = _iir(d, c, v)
        if not jac:
            return e_full[st:], None
        cols = []
        if s.na:
            cols.append(_lagged(_iir(d, c, y), 1, s.na, st))
        # the b and f columns of input j share the filter D/(C F_j): one call for both
        g_uw = [
            _iir(d, np.convolve(c, f[j]), np.stack([u[:, j], w[j]], axis=1)) for j in range(self.m)
        ]
        for j, (nb, nk) in enumerate(zip(s.nb, s.nk)):
            cols.append(-_lagged(g_uw[j][:, 0], nk, nk + nb - 1, st))
        if s.nc or s.nd:
            g_ev = _iir(np.ones(1), c, np.stack([e_full, v], axis=1))
            cols.append(-_lagged(g_ev[:, 0], 1, s.nc, st))
            cols.append(_lagged(g_ev[:, 1], 1, s.nd, st))
        for j, nf in enumerate(s.nf):
            cols.append(_lagged(g_uw[j][:, 1], 1, nf, st))
        return e_full[st:], np.hstack(cols)

    def _measured(self, theta: np.ndarray, jac: bool):
        s, st, u, y, m = self.s, self.start, self.u, self.y, self.m
        a, b, c, d, f = self.parts(theta)
        f_all = _poly_mul(*f)
        den = np.convolve(c, f_all)

        def f_without(*skip: int) -> np.ndarray:
            return _poly_mul(*[f[i] for i in range(m) if i not in skip])

        # B_j q^-nk_j prod_(i != j) F_i u_j, the plant part of F v
        bu = [_fir(np.convolve(b[j], f_without(j)), u[:, j]) for j in range(m)]
        fv = _fir(np.convolve(a, f_all), y) - np.sum(bu, axis=0)
        forcing = _fir(d, fv)
        e = signal.lfilter([1.0], den, forcing[st:])
        if not jac:
            return e, None
        e_full = np.concatenate([np.zeros(st), e])
        cols = []
        if s.na:
            cols.append(_lagged(_fir(np.convolve(d, f_all), y), 1, s.na, st))
        for j, (nb, nk) in enumerate(zip(s.nb, s.nk)):
            g = _fir(np.convolve(d, f_without(j)), u[:, j])
            cols.append(-_lagged(g, nk, nk + nb - 1, st))
        if s.nc:
            cols.append(-_lagged(_fir(f_all, e_full), 1, s.nc, st))
        if s.nd:
            cols.append(_lagged(fv, 1, s.nd, st))
        for j, nf in enumerate(s.nf):
            if not nf:
                continue
            g = _fir(_poly_mul(d, a, f_without(j)), y)
            for i in range(m):
                if i != j:
                    g -= _fir(_poly_mul(d, b[i], f_without(i, j)), u[:, i])
            g -= _fir(np.convolve(c, f_without(j)), e_full)
            cols.append(_lagged(g, 1, nf, st))
        return e, signal.lfilter([1.0], den, np.hstack(cols), axis=0)

    def _estimate(self, theta: np.ndarray, jac: bool):
        r, jr = self._zero(theta, jac)
        n, K = self.s.n_state, self.K
        if n == 0:
            return r, jr
        _, _, c, _, f = self.parts(theta)
        den = np.convolve(c, _poly_mul(*f))
        impulse = np.zeros(K)
        impulse[0] = 1.0
        # The free responses from t = start are the responses of N(q)/den to an impulse at
        # start, deg N < n.  The shifts q^-k/den span them but are numerically dependent for
        # lightly damped orders (condition numbers above 1e16 at order 16), so the projection
        # uses the orthogonal numerators' basis (nearly orthogonal) and its QR.
        T = orthogonal_numerators(den[None, :], n)[0]
        # P_m/den on an impulse is 1/den driven by the coefficients of P_m: one call for all
        drive = np.zeros((K, n + 1))
        drive[:n, :n] = T.T
        drive[0, n] = 1.0  # and the impulse response h of 1/den, for the Jacobian
        responses = signal.lfilter([1.0], den, drive, axis=0)
        q, _ = np.linalg.qr(responses[:, :n])
        w = q @ (q.T @ r)  # the fitted free response
        e = r - w
        if not jac:
            return e, None
        # Golub & Pereyra with the shift basis H(theta) = [q^-k/den impulse]:
        # d e = P_perp (dr - dH x) - (H^+)' dH' e, with H x = w, so that
        # dH x / d p_i = -q^-i (1/p) w for a coefficient p_i of a factor p of den (C or F_j)
        g_all = jr.copy()
        shifts = _delayed(responses[:, n], 0, n - 1)
        r_h = q.T @ shifts  # H = Q R_H on the counted samples
        second = np.zeros((K, self.n))
        moving = [(self.sl["c"], c), *zip(self.sl["f"], f)]
        for sl, p in moving:
            order = p.size - 1
            if not order:
                continue
            g_all[:, sl] += _delayed(signal.lfilter([1.0], p, w), 1, order)
            # (dH_i' e)_k = -sum_t phi(t - i - k) e(t), phi the impulse response of 1/(den p)
            phi = signal.lfilter([1.0], np.convolve(den, p), impulse)
            top = order + n - 1
            padded = np.concatenate([e, np.zeros(top)])
            ahead = np.lib.stride_tricks.sliding_window_view(padded, top + 1)
            corr = phi @ ahead  # corr[lag] = sum_t phi(t) e(t + lag)
            idx = np.arange(n)[:, None] + np.arange(1, order + 1)[None, :]
            v = corr[idx]  # (n, order): -(dH_i' e)_k
            try:
                with np.errstate(all="ignore"):
                    z = np.linalg.solve(r_h.T, v)
            except np.linalg.LinAlgError:  # R_H singular in rounding: drop the term
                z = None
            if z is not None and np.isfinite(z).all():
                second[:, sl] = q @ z  # -(H^+)' dH' e  (H^+' = Q R_H^-T)
            # else the term is dropped (Kaufman's variant): J' e, the gradient, is unchanged,
            # since the term lies in span(H), orthogonal to e
        proj = g_all - q @ (q.T @ g_all)
        return e, proj + second

    # ------------------------------------------------------------------ linear pieces
    def refit_b(self, theta: np.ndarray) -> np.ndarray:
        """``theta`` with ``B`` the least-squares optimum of the from-rest error given the
        other polynomials (``e = D A/C y - sum_j B_j D/(C F_j) u_j`` is linear in ``B``)."""
        return _with_b(self, theta, *self.b_system(theta))

    def b_system(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The regressors (K, sum nb) and target (K,) of ``B`` in :meth:`refit_b`."""
        s, st = self.s, self.start
        a, _, c, d, f = self.parts(theta)
        target = _iir(np.convolve(d, a), c, self.y)[st:]
        cols = []
        for j, (nb, nk) in enumerate(zip(s.nb, s.nk)):
            g = _iir(d, np.convolve(c, f[j]), self.u[:, j])
            cols.append(_lagged(g, nk, nk + nb - 1, st))
        return np.hstack(cols), target

    def plant_residual(self, theta: np.ndarray) -> np.ndarray:
        """``v = A y - sum_j B_j/F_j u_j`` over ``t >= start`` (from rest)."""
        a, b, _, _, f = self.parts(theta)
        w = [_iir(b[j], f[j], self.u[:, j]) for j in range(self.m)]
        return (_fir(a, self.y) - np.sum(w, axis=0))[self.start :]


def _with_b(prob: Any, theta: np.ndarray, phi: np.ndarray, target: np.ndarray) -> np.ndarray:
    """``theta`` with ``B`` the least-squares solution of ``phi b = target`` (unchanged when
    that breaks down)."""
    sol = _lstsq(phi, target)
    out = theta.copy()
    if sol is not None:
        i = 0
        for sl in prob.sl["b"]:
            k = sl.stop - sl.start
            out[sl] = sol[i : i + k]
            i += k
    return out


class _Problems:
    """Prediction errors and Jacobians of one structure on several records (experiments):
    each record's errors, under its own initial state, one after another."""

    def __init__(self, s: PolynomialStructure, records: list, initial: str):
        self.each = [_Problem(s, u, y, initial) for u, y in records]
        first = self.each[0]
        self.s, self.initial, self.start, self.m = s, initial, first.start, first.m
        self.sl, self.n, self.rooted = first.sl, first.n, first.rooted
        self.K = sum(p.K for p in self.each)
        self.energy = sum(p.energy for p in self.each)
        self.nfev = 0
        self.njev = 0
        # the constraints and polynomials depend on theta only
        self.parts, self.admissible = first.parts, first.admissible
        self.max_radius, self.predictor_ok = first.max_radius, first.predictor_ok

    def errors(self, theta: np.ndarray, jac: bool) -> tuple[np.ndarray, np.ndarray | None]:
        found = [p.errors(theta, jac) for p in self.each]
        e = np.concatenate([f[0] for f in found])
        return e, (np.vstack([f[1] for f in found]) if jac else None)

    def refit_b(self, theta: np.ndarray) -> np.ndarray:
        systems = [p.b_system(theta) for p in self.each]
        phi = np.vstack([sys[0] for sys in systems])
        return _with_b(self, theta, phi, np.concatenate([sys[1] for sys in systems]))


# =================================================================================== starts
def _mirror_all(prob: _Problem, theta: np.ndarray) -> np.ndarray:
    """Roots outside the circle mirrored to ``1/conj(r)``: ``A`` with every ``B`` and each
    ``F_j`` with its ``B_j`` gain-corrected (output_error's rule), ``C`` and ``D`` alone."""
    sl = prob.sl
    out = theta.copy()
    na = prob.s.na
    if na:
        b_all = np.concatenate([out[s] for s in sl["b"]])
        new = mirror_inside(np.concatenate([out[sl["a"]], b_all]), na)
        out[sl["a"]] = new[:na]
        i = na
        for s in sl["b"]:
            k = s.stop - s.start
            out[s] = new[i : i + k]
            i += k
    for s_f, s_b, nf in zip(sl["f"], sl["b"], prob.s.nf):
        if nf:
            new = mirror_inside(np.concatenate([out[s_f], out[s_b]]), nf)
            out[s_f], out[s_b] = new[:nf], new[nf:]
    for key in ("c", "d"):
        if out[sl[key]].size:
            out[sl[key]] = mirror_inside(out[sl[key]], out[sl[key]].size)
    return out


def _makewithin_radius(prob: _Problem, theta: np.ndarray, r_max: float) -> np.ndarray:
    """Mirror, then pull roots above ``r_max`` in to it (``B`` refitted if any moved)."""
    out = _mirror_all(prob, theta)
    moved = False
    for sl, _ in prob.rooted:
        if not within_radius(out[sl], r_max):
            out[sl] = pull_inside(out[sl], r_max)
            moved = True
    return prob.refit_b(out) if moved else out


def _arx_fit(prob: _Problem, y: np.ndarray, u: np.ndarray, na: int, nb, nk):
    """Least-squares ``y = -sum a_i y(t-i) + sum_j B_j u_j(t - nk_j) + e`` over ``t >= start``:
    ``a`` (na,) and a list of ``b_j``, or None when the fit breaks down."""
    st = prob.start
    cols = [-_lagged(y, 1, na, st)]
    cols += [_lagged(u[:, j], k, k + n - 1, st) for j, (n, k) in enumerate(zip(nb, nk))]
    sol = _lstsq(np.hstack(cols), y[st:])
    if sol is None:
        return None
    bs, i = [], na
    for n in nb:
        bs.append(sol[i : i + n])
        i += n
    return sol[:na], bs


def _hannan_rissanen(v: np.ndarray, nc: int, nd: int) -> tuple[np.ndarray, np.ndarray]:
    """``c`` (nc,), ``d`` (nd,) of ``D v = C e`` by Hannan-Rissanen (roots mirrored inside).

    A long AR model of ``v`` (order ``max(20, 3 (nc + nd))``, at most a quarter of the
    record) gives an innovation estimate ``e_hat``; ``v(t) = -sum d_i v(t-i) + sum c_i
    e_hat(t-i) + e(t)`` is then linear least squares (Hannan & Rissanen, Biometrika 69, 1982).
    """
    k = v.size
    m = max(1, min(max(20, 3 * (nc + nd)), k // 4))
    lag_v = _delayed(v, 1, m)
    a_long = _lstsq(lag_v[m:], -v[m:])
    if a_long is None:
        return np.zeros(nc), np.zeros(nd)
    e_hat = v + lag_v @ a_long
    e_hat[:m] = 0.0
    phi = np.hstack([-_delayed(v, 1, nd), _delayed(e_hat, 1, nc)])
    k0 = m + max(nc, nd)
    par = _lstsq(phi[k0:], v[k0:])
    if par is None:
        return np.zeros(nc), np.zeros(nd)
    d = mirror_inside(par[:nd], nd) if nd else np.zeros(0)
    c = mirror_inside(par[nd:], nc) if nc else np.zeros(0)
    return c, d


def _with_noise_model(prob: _Problem, theta: np.ndarray, r_max: float) -> np.ndarray:
    """``theta`` (admissible) with ``C``, ``D`` from Hannan-Rissanen on its plant residual
    and ``B`` refitted given them."""
    s = prob.s
    theta = _makewithin_radius(prob, theta, r_max)
    if s.nc or s.nd:
        c, d = _hannan_rissanen(prob.plant_residual(theta), s.nc, s.nd)
        theta = theta.copy()
        theta[prob.sl["c"]], theta[prob.sl["d"]] = c, d
    return _makewithin_radius(prob, prob.refit_b(theta), r_max)


def _steiglitz_mcbride(prob: _Problem, theta: np.ndarray, iterations: int) -> np.ndarray | None:
    """Steiglitz-McBride for the ``F_j``, per input on its partial residual (backfitting).

    For each input: ``y_j = y - sum_(l != j) B_l/F_l u_l``; ``u_j`` and ``y_j`` filtered by
    the current ``1/F_j``; ARX ``(nf_j, nb_j, nk_j)`` refitted by least squares (Steiglitz &
    McBride, IEEE TAC 10(4), 1965; Ljung sec. 10.4).  With one input this is
    :func:`flexid.fit.output_error._steiglitz_mcbride`.  ``None`` if it breaks down.
    """
    s, u, y = prob.s, prob.u, prob.y
    f = prob.parts(theta)[4]
    b = [theta[sl].copy() for sl in prob.sl["b"]]

    def sim(j: int) -> np.ndarray:
        return _iir(np.concatenate([np.zeros(s.nk[j]), b[j]]), f[j], u[:, j])

    for _ in range(iterations):
        for j in range(prob.m):
            y_j = y - sum((sim(i) for i in range(prob.m) if i != j), np.zeros_like(y))
            uf = signal.lfilter([1.0], f[j], u[:, j : j + 1], axis=0)
            fit = _arx_fit(
                prob, signal.lfilter([1.0], f[j], y_j), uf, s.nf[j], [s.nb[j]], [s.nk[j]]
            )
            if fit is None:
                return None
            new = mirror_inside(np.concatenate([fit[0], fit[1][0]]), s.nf[j])
            if not np.isfinite(new).all():
                return None
            f[j] = np.concatenate([[1.0], new[: s.nf[j]]])
            b[j] = new[s.nf[j] :]
    out = theta.copy()
    for j in range(prob.m):
        out[prob.sl["f"][j]] = f[j][1:]
        out[prob.sl["b"][j]] = b[j]
    return out


def _armax_hannan_rissanen(prob: _Problem) -> np.ndarray | None:
    """ARMAX ``A y = B u + C e`` jointly by Hannan-Rissanen: ``e_hat`` from a long ARX fit,
    then ``y = -sum a_i y(t-i) + B u + sum c_i e_hat(t-i) + e`` by least squares."""
    s, u, y, st = prob.s, prob.u, prob.y, prob.start
    m = max(1, min(max(20, 3 * (s.na + s.nc)), prob.K // (4 * (1 + prob.m))))
    cols = [-_delayed(y, 1, m)] + [
        _delayed(u[:, j], s.nk[j], s.nk[j] + m - 1) for j in range(prob.m)
    ]
    phi = np.hstack(cols)
    k0 = max(st, m + max(s.nk))
    par = _lstsq(phi[k0:], y[k0:])
    if par is None:
        return None
    e_hat = y - phi @ par
    e_hat[:k0] = 0.0
    cols = [-_delayed(y, 1, s.na)]
    cols += [_delayed(u[:, j], k, k + n - 1) for j, (n, k) in enumerate(zip(s.nb, s.nk))]
    cols.append(_delayed(e_hat, 1, s.nc))
    k1 = k0 + s.nc
    par = _lstsq(np.hstack(cols)[k1:], y[k1:])
    if par is None:
        return None
    theta = np.zeros(prob.n)
    theta[prob.sl["a"]] = par[: s.na]
    i = s.na
    for sl in prob.sl["b"]:
        k = sl.stop - sl.start
        theta[sl] = par[i : i + k]
        i += k
    theta[prob.sl["c"]] = par[i:]
    return theta


def _plant_starts(prob: _Problem) -> list[tuple[str, np.ndarray]]:
    """Least squares, Steiglitz-McBride and (ARMAX) Hannan-Rissanen plant starts."""
    s = prob.s
    out: list[tuple[str, np.ndarray]] = []
    theta = np.zeros(prob.n)
    if s.na or not any(s.nf):
        fit = _arx_fit(prob, prob.y, prob.u, s.na, s.nb, s.nk)
        if fit is not None:
            theta[prob.sl["a"]] = fit[0]
            for sl, bj in zip(prob.sl["b"], fit[1]):
                theta[sl] = bj
            out.append(("least-squares", theta))
    else:
        top = max(s.nf)
        fit = _arx_fit(prob, prob.y, prob.u, top, s.nb, s.nk)
        if fit is not None:
            a = mirror_inside(fit[0], top) if top else fit[0]
            for j, nf in enumerate(s.nf):
                theta[prob.sl["b"][j]] = fit[1][j]
                theta[prob.sl["f"][j]] = a[:nf] if nf == top else 0.0
            if any(nf not in (0, top) for nf in s.nf):
                # one pass of per-input least squares on the partial residuals of the
                # common-denominator fit gives each F_j its own order
                one_pass = _steiglitz_mcbride(prob, _mirror_all(prob, theta), 1)
                theta = one_pass if one_pass is not None else theta
            out.append(("least-squares", theta))
            sm = _steiglitz_mcbride(prob, _makewithin_radius(prob, theta, 1.0), _SM_ITERATIONS)
            if sm is not None:
                out.append(("steiglitz-mcbride", sm))
    if s.na and s.nc and not s.nd and not any(s.nf):
        hr = _armax_hannan_rissanen(prob)
        if hr is not None:
            out.append(("hannan-rissanen", hr))
    return out


def _output_error_plant(
    prob: _Problem, s: PolynomialStructure, data: Any, initial: str, tol: float
) -> np.ndarray:
    """``theta`` with ``B`` and the ``F_j`` of the output-error fit of ``s``'s plant on
    ``data`` (a ``(u, y)`` pair or a list of them)."""
    plant = PolynomialStructure.oe(s.nb, s.nf, s.nk)
    fit = pem(data, plant, initial=initial, starts=0, tol=tol)
    prob.nfev += fit.nfev  # the reference's cost counts every evaluation it made
    prob.njev += fit.njev
    sl = plant.slices()
    theta = np.zeros(prob.n)
    for j in range(len(s.nb)):
        theta[prob.sl["b"][j]] = fit.theta[sl["b"][j]]
        theta[prob.sl["f"][j]] = fit.theta[sl["f"][j]]
    return theta


def _extra_start(
    prob: _Problem, base: np.ndarray, rng: np.random.Generator, perturbed: bool, r_max: float
) -> np.ndarray:
    """``base`` with every constrained polynomial's roots perturbed (or drawn afresh), ``B``
    refitted; drawn roots get ``C``, ``D`` from Hannan-Rissanen."""
    theta = base.copy()
    noise = (prob.sl["c"], prob.sl["d"])
    for sl, order in prob.rooted:
        if perturbed:
            theta[sl] = perturbed_poles(theta[sl], rng)
        elif sl not in noise:
            theta[sl] = random_poles(order, rng)
        else:
            theta[sl] = 0.0
    if perturbed:
        return _makewithin_radius(prob, prob.refit_b(theta), r_max)
    return _with_noise_model(prob, prob.refit_b(theta), r_max)


# =================================================================================== solver
def _run_lm(
    prob: _Problem,
    theta0: np.ndarray,
    kind: str,
    max_nfev: int | None,
    tol: float,
    r_max: float,
    chunks: int = 1,
    target: float = np.inf,
    crawl: bool = False,
) -> ReferenceRun:
    """Levenberg-Marquardt from an admissible start within the cap ``r_max``, counted on ``prob``.

    ``target``, ``chunks`` and ``crawl`` as in :func:`flexid.fit.reference.levenberg_marquardt`.
    """
    run = levenberg_marquardt(
        lambda x: prob.errors(x, False)[0],
        lambda x: prob.errors(x, True)[1],
        theta0,
        kind,
        admissible=lambda x: prob.admissible(x, r_max),
        energy=prob.energy,
        max_nfev=max_nfev,
        tol=tol,
        chunks=chunks,
        target=target,
        crawl=crawl,
    )
    prob.nfev += run.nfev
    prob.njev += run.njev
    return run


def _lifted_caps(r_max: float) -> list[float]:
    """The caps tried, in turn, while the best point sits on the current one."""
    if r_max >= 1.0:
        return []
    return [1.0 - (1.0 - r_max) / 100.0, 1.0]


# =================================================================================== checks
def _check_structure(structure: Any) -> PolynomialStructure:
    from ..models.arx import ARXStructure

    if isinstance(structure, ARXStructure):
        return PolynomialStructure.arx(structure.na, structure.nb, structure.nk)
    if not isinstance(structure, PolynomialStructure):
        raise ConfigError(
            "structure must be a PolynomialStructure (flexid.structure(...)) or an "
            f"ARXStructure, got {type(structure).__name__}"
        )
    return structure


def _signals(s: PolynomialStructure, u: Any, y: Any) -> tuple[np.ndarray, np.ndarray]:
    u, y = _io_arrays(u, y)
    if u.shape[1] != s.n_inputs:
        raise DataError(f"u has {u.shape[1]} column(s) but {s!r} has {s.n_inputs} input(s)")
    s.check_samples(y.size)
    return u, y


def _data(data: Any, s: PolynomialStructure) -> tuple[np.ndarray, np.ndarray, float]:
    from ..data.records import IOData

    if isinstance(data, IOData):
        u, y = _signals(s, data, None)
        return u, y, float(data.dt)
    if isinstance(data, tuple) and len(data) == 2:
        u, y = _signals(s, *data)
        return u, y, 1.0
    raise DataError(
        f"data must be an IOData, a (u, y) tuple or a list of them, got {type(data).__name__}"
    )


def _records(data: Any, s: PolynomialStructure) -> tuple[list, float]:
    """The ``(u, y)`` arrays of one record or of a list of them, and the sample time."""
    if not isinstance(data, list):
        u, y, dt = _data(data, s)
        return [(u, y)], dt
    if not data:
        raise DataError("data is an empty list of records")
    found = [_data(d, s) for d in data]
    return [(u, y) for u, y, _ in found], found[0][2]


def _theta(theta: Any, s: PolynomialStructure, what: str) -> np.ndarray:
    arr = np.array(theta, dtype=float).reshape(-1) if np.ndim(theta) <= 1 else None
    if arr is None or arr.shape != (s.n_params,):
        raise DataError(f"{what} must have shape ({s.n_params},) for {s!r}")
    if not np.isfinite(arr).all():
        raise DataError(f"{what} has non-finite values")
    return arr


def _problem(structure: Any, theta: Any, u: Any, y: Any, initial: Any):
    s = _check_structure(structure)
    initial = _check_initial(initial)
    theta = _theta(theta, s, "theta")
    u, y = _signals(s, u, y)
    prob = _Problem(s, u, y, initial)
    if not prob.predictor_ok(theta):
        raise DataError(
            "theta's predictor is unstable (a root of C or of an F_j on or outside the unit "
            "circle): the prediction errors filter by 1/(C F)"
        )
    return prob, theta


# =================================================================================== public
def prediction_errors(
    structure: PolynomialStructure, theta: Any, u: Any, y: Any, initial: str
) -> np.ndarray:
    """One-step prediction errors ``e = D/C (A y - sum_j B_j/F_j u_j(t - nk_j))``.

    The reference route (``scipy.signal.lfilter``), under an initial-condition rule (see the
    module docstring); equal to ``y - yhat`` of :func:`flexid.models.polynomial.run_predictor` with
    ``model.predictor_polynomials(1)`` over ``t >= structure.start``.

    Parameters
    ----------
    structure : PolynomialStructure
    theta : array_like, shape (n_params,)
        Parameters in ``structure.param_names`` order; ``C`` and every ``F_j`` stable.
    u : array_like, shape (N,) or (N, n_u), or IOData
        Inputs (input units); an IOData carries ``y`` too (then ``y`` is None).
    y : array_like, shape (N,), or None
        Measured output (output units).
    initial : {"estimate", "zero", "measured"}
        Initial-condition rule.

    Returns
    -------
    ndarray, shape (K,)
        ``e(t)``, ``t = start .. N-1`` (output units), ``K = N - structure.start``.

    Raises
    ------
    ConfigError
        For an unknown ``initial`` or a ``structure`` that is not one.
    DataError
        For bad signals, a wrongly shaped or non-finite ``theta``, or an unstable predictor.
    ModelOrderError
        When the record is too short for the structure.
    """
    prob, theta = _problem(structure, theta, u, y, initial)
    return prob.errors(theta, False)[0]


def prediction_jacobian(
    structure: PolynomialStructure, theta: Any, u: Any, y: Any, initial: str
) -> tuple[np.ndarray, np.ndarray]:
    """Prediction errors and their analytic Jacobian with respect to ``theta``.

    Parameters
    ----------
    structure : PolynomialStructure
    theta : array_like, shape (n_params,)
        Parameters; ``C`` and every ``F_j`` stable.
    u : array_like, shape (N,) or (N, n_u), or IOData
        Inputs.
    y : array_like, shape (N,), or None
        Measured output (None when ``u`` is an IOData).
    initial : {"estimate", "zero", "measured"}
        Initial-condition rule.

    Returns
    -------
    e : ndarray, shape (K,)
        :func:`prediction_errors` (output units).
    J : ndarray, shape (K, n_params)
        ``d e / d theta`` (output units per parameter unit): the filtered-signal formulas of
        the module docstring; under ``"estimate"`` the exact derivative of the projected
        error (the initial state re-fitted at every ``theta``).

    Raises
    ------
    ConfigError
        For an unknown ``initial`` or a ``structure`` that is not one.
    DataError
        For bad signals, a wrongly shaped or non-finite ``theta``, or an unstable predictor.
    ModelOrderError
        When the record is too short for the structure.
    """
    prob, theta = _problem(structure, theta, u, y, initial)
    return prob.errors(theta, True)


@checked_keywords
def pem(
    data: Any,
    structure: PolynomialStructure,
    *,
    initial: str = "estimate",
    starts: int = REFERENCE_STARTS,
    seed: int | np.random.Generator = 0,
    r_max: float = 1.0,
    max_nfev: int | None = None,
    tol: float = 1e-10,
    x0: Any = None,
) -> PEMResult:
    """Prediction-error estimate of a polynomial model: the best stable Levenberg-Marquardt fit.

    Minimises the sum of squared one-step prediction errors of ``structure`` over
    ``t >= structure.start`` (see the module docstring for the rules, Jacobians, starts and
    stability handling).

    Parameters
    ----------
    data : IOData, tuple of (u, y), or list of them
        Single-output record: ``u`` shape (N,) or (N, n_u), ``y`` shape (N,); an IOData's
        ``dt`` (s) goes to the model (1.0 for a tuple).  A list: several records of one
        system (experiments), whose errors are minimised together, each record under its
        own initial state; the starts are fitted on the records joined end to end.
    structure : PolynomialStructure
        From :func:`flexid.models.polynomial.structure` (an
        :class:`~flexid.models.arx.ARXStructure` is accepted too).
    initial : {"estimate", "zero", "measured"}, optional
        Initial-condition rule of the prediction errors (default ``"estimate"``, MATLAB's).
    starts : int, optional
        Number of random/perturbed starts besides least squares, Steiglitz-McBride and
        Hannan-Rissanen (>= 0; ignored for ARX, whose error is linear in ``theta``).
    seed : int or numpy.random.Generator, optional
        Seed of ``numpy.random.default_rng`` for those starts.
    r_max : float, optional
        Largest root radius of ``A``, the ``F_j``, ``D`` and ``C`` at an accepted step, in
        (0, 1]; 1 keeps them strictly inside the circle.  Lifted when the best point sits on
        it (module docstring).
    max_nfev : int, optional
        Residual-evaluation budget of each run, a hard one.  Default: MINPACK's
        ``100 * n_params`` at a time, continued while the SSE still falls, up to ten times
        that (module docstring, "Budget").
    tol : float, optional
        ``ftol``, ``xtol`` and ``gtol`` of each run, in (0, 1).
    x0 : array_like, shape (n_params,), optional
        One more start (mirrored, capped when needed).

    Returns
    -------
    ReferenceResult
        ``x`` (the coefficients, ``structure.param_names`` order; also ``theta``), ``fun``
        (the SSE over ``t >= structure.start`` under ``initial``; also ``sse``), ``status``,
        ``std`` and the other keys of :class:`~flexid.fit.reference.ReferenceResult`, and:

        ``model`` : PolynomialModel
            The estimate, with ``param_std = std`` and ``noise_variance = sigma^2 =
            SSE / (K - n_params)``.
        ``K`` : int
            Number of error samples, ``N - structure.start``.
        ``initial`` : str
            The initial-condition rule of the errors.
        ``on_cap`` : bool
            A root of ``A``, an ``F_j``, ``D`` or ``C`` within 1e-6 of ``r_cap``.
        ``r_cap`` : float
            The root-radius cap in force at the end: ``r_max``, or a lifted one (up to 1)
            when the best point sat on ``r_max``.
        ``max_radius`` : float
            Largest root radius of ``A``, the ``F_j``, ``D`` and ``C``.
        ``cap_reason`` : str
            Why the estimate ends on the cap (module notes, "The cap"), ``""`` off it.
        ``stable``, ``predictor_stable`` : bool
            ``model.is_stable`` and ``model.predictor_stable``.
        ``cost`` : float
            An optimiser's cost at ``x`` when the reference ran for one
            (:meth:`flexid.fit.estimation.PolynomialEstimationProblem.output_error_reference`),
            NaN otherwise.

        ``local_minimum`` is ``optimality < OPTIMALITY_THRESHOLD`` (1e-6) and not
        ``on_cap``; ``nfev`` and ``njev`` include the output-error fit that gives a
        Box-Jenkins structure its ``"output-error"`` start.

    Raises
    ------
    ConfigError
        For an unknown ``initial``, a ``structure`` that is not one, or a bad ``starts``,
        ``seed``, ``r_max``, ``max_nfev`` or ``tol``.
    DataError
        For bad data or a bad ``x0``.
    ModelOrderError
        When the record is too short for the structure.
    """
    t_begin = time.perf_counter()
    s = _check_structure(structure)
    initial = _check_initial(initial)
    starts, seed, r_max, max_nfev, tol = _check_pem_options(starts, seed, r_max, max_nfev, tol)
    records, dt = _records(data, s)
    x0 = None if x0 is None else _theta(x0, s, "x0")
    rng = np.random.default_rng(seed)
    prob, first = _pem_problems(s, records, initial)
    start_list = _starts(first, records if len(records) > 1 else records[0], initial, tol,
                         starts, rng, r_max, x0)  # fmt: skip
    if first is not prob:
        prob.nfev, prob.njev = first.nfev, first.njev
    runs: list[ReferenceRun] = []
    for kind, th in start_list:
        floor = min((r.sse for r in runs), default=np.inf)
        extra = kind in _EXTRA_KINDS
        runs.append(_run_lm(prob, th, kind, max_nfev, tol, r_max, target=floor, crawl=extra))
    if max_nfev is None:  # a budget the caller gives is a hard one
        _continue_promising(prob, runs, tol, r_max)
    best = int(np.argmin([r.sse for r in runs]))
    message = f"best of {len(start_list)} start(s): {runs[best].kind} ({runs[best].message})"
    best, cap, note = _off_the_cap(prob, runs, best, r_max, max_nfev, tol)
    best, note_along = _along_the_cap(prob, runs, best, cap, max_nfev, tol)
    note += note_along
    e, jac = prob.errors(runs[best].theta, True)
    best, note_polish, e, jac = _polish(prob, runs, best, cap, max_nfev, tol, e, jac)
    message += note + note_polish
    theta = runs[best].theta
    max_radius = prob.max_radius(theta)
    on_cap = bool(prob.rooted) and max_radius >= cap - CAP_TOLERANCE
    why = cap_reason(cap) if on_cap and note_along else ""
    result = ReferenceResult.at(
        runs, best, e, jac, on_cap=on_cap, nfev=prob.nfev, njev=prob.njev,
        message=message + (f"; ends on the cap: {why}" if why else ""),
        t_begin=t_begin, K=prob.K, initial=initial, r_cap=cap, max_radius=max_radius,
        cost=float("nan"), cap_reason=why,
    )
    model = PolynomialModel(s, result.x, dt=dt, param_std=result.std,
                            noise_variance=result.noise_variance)  # fmt: skip
    result.update(model=model, stable=model.is_stable, predictor_stable=model.predictor_stable)
    return result


def _check_pem_options(
    starts: Any, seed: Any, r_max: Any, max_nfev: Any, tol: Any
) -> tuple[int, int | np.random.Generator, float, int | None, float]:
    """``starts``, ``seed``, ``r_max``, ``max_nfev`` and ``tol`` of :func:`pem`, checked."""
    starts = integer(starts, "starts", error=ConfigError, minimum=0)
    if not isinstance(seed, np.random.Generator):
        seed = integer(seed, "seed", error=ConfigError, minimum=0)
    r_max = real(r_max, "r_max", error=ConfigError, minimum=0, maximum=1, low_open=True)
    max_nfev = integer(max_nfev, "max_nfev", error=ConfigError, minimum=1, none_ok=True)
    tol = real(tol, "tol", error=ConfigError, minimum=0, maximum=1, low_open=True, high_open=True)
    return starts, seed, r_max, max_nfev, tol


def _pem_problems(
    s: PolynomialStructure, records: list[tuple[np.ndarray, np.ndarray]], initial: str
) -> tuple[_Problem | _Problems, _Problem]:
    """The problem :func:`pem` minimises and the one its starts are fitted on (the same one
    for a single record)."""
    if len(records) == 1:
        prob = first = _Problem(s, *records[0], initial)
    else:
        # the starts are fitted on the records joined end to end: the junctions perturb a
        # start, not the minimum Levenberg-Marquardt then finds on the records apart
        prob = _Problems(s, records, initial)
        first = _Problem(s, np.vstack([r[0] for r in records]),
                         np.concatenate([r[1] for r in records]), initial)  # fmt: skip
    return prob, first


def _continue_promising(
    prob: _Problem | _Problems, runs: list[ReferenceRun], tol: float, r_max: float
) -> None:
    """Append to ``runs`` the continuation of each promising run that ran out of budget."""
    floor = min(r.sse for r in runs)
    # the most promising first, so that each later one must catch up with it
    for run in sorted(runs, key=lambda r: r.sse):
        if run.out_of_budget and run.sse <= PROMISING * floor:
            target = min(r.sse for r in runs if r is not run)
            kind = f"{run.kind}, continued"
            runs.append(
                _run_lm(
                    prob, run.theta, kind, None, tol, r_max, CHUNKS - 1, target=target,
                    crawl=run.kind in _EXTRA_KINDS,
                )
            )


def _starts(
    prob: _Problem, data: Any, initial: str, tol: float, starts: int,
    rng: np.random.Generator, r_max: float, x0: np.ndarray | None,
) -> list[tuple[str, np.ndarray]]:
    """``(kind, theta)`` of every start of :func:`pem`, each admissible (module notes)."""
    s = prob.s
    start_list = [(k, _with_noise_model(prob, th, r_max)) for k, th in _plant_starts(prob)]
    if any(s.nf) and (s.nc or s.nd) and not s.na:
        # the output-error model itself (C = D = 1), which the noise model then refines
        oe_plant = _output_error_plant(prob, s, data, initial, tol)
        start_list.append(("output-error", _makewithin_radius(prob, oe_plant, r_max)))
    if not start_list:  # every linear fit broke down (rank-deficient data): start from B only
        start_list = [("least-squares", _makewithin_radius(prob, np.zeros(prob.n), r_max))]
    if s.kind != "arx" and prob.rooted:
        base = start_list[0][1]
        for i in range(starts):
            perturbed = i % 2 == 0
            start_list.append(
                (
                    "perturbed" if perturbed else "random",
                    _extra_start(prob, base, rng, perturbed, r_max),
                )
            )
    if x0 is not None:
        start_list.append(("x0", _makewithin_radius(prob, x0, r_max)))
    return start_list


def _off_the_cap(
    prob: _Problem, runs: list[ReferenceRun], best: int, r_max: float, max_nfev: int | None,
    tol: float,
) -> tuple[int, float, str]:
    """Continue the best run with lifted pole-radius caps while it ends on the cap.

    Returns the best run's index, the cap it ended under, and the note for the message; the
    new runs are appended to ``runs``.
    """
    message = ""
    cap = r_max
    for lifted in _lifted_caps(r_max):
        if prob.max_radius(runs[best].theta) < cap - CAP_TOLERANCE:
            break
        run = _run_lm(prob, runs[best].theta, f"cap r_max={lifted:g}", max_nfev, tol, lifted)
        runs.append(run)
        message += f"; on the cap {cap:g}, continued with the cap {lifted:g}"
        cap = lifted
        if run.sse < runs[best].sse:
            best = len(runs) - 1
            message += f" (SSE {run.sse0:.6g} -> {run.sse:.6g})"
    return best, cap, message


def _along_the_cap(
    prob: _Problem, runs: list[ReferenceRun], best: int, cap: float, max_nfev: int | None,
    tol: float,
) -> tuple[int, str]:
    """Restarts of a best run that ends on the cap
    (:func:`flexid.fit.reference.restarts_on_the_cap`).

    Along the cap (:func:`flexid.fit.reference.along_the_cap`) and LM from the point with the
    roots above each radius of :data:`PULLED_TO` pulled in to it (``B`` refitted).  Returns
    the best run's index and the note for the message; the runs are appended to ``runs``.
    """
    if not prob.rooted or prob.max_radius(runs[best].theta) < cap - CAP_TOLERANCE:
        return best, ""
    chunks = CHUNKS if max_nfev is None else 1

    def along(theta: np.ndarray) -> ReferenceRun | None:
        return along_the_cap(
            lambda x: prob.errors(x, False)[0], lambda x: prob.errors(x, True)[1], theta,
            [sl for sl, _ in prob.rooted], cap, within=within_radius, energy=prob.energy,
            max_nfev=max_nfev, tol=tol, counter=prob,
        )

    def pulled(theta: np.ndarray) -> list[ReferenceRun]:
        out = []
        for radius in PULLED_TO:
            th = theta.copy()
            for sl, _ in prob.rooted:
                if not within_radius(th[sl], radius):
                    th[sl] = pull_inside(th[sl], radius)
            th = prob.refit_b(th)
            if prob.admissible(th, cap):
                out.append(_run_lm(prob, th, f"pulled in to {radius:g}", max_nfev, tol, cap,
                                   chunks))  # fmt: skip
        return out

    won, new, note = restarts_on_the_cap(
        runs[best], on_cap=lambda x: prob.max_radius(x) >= cap - CAP_TOLERANCE, along=along,
        pulled=pulled, admissible=lambda x: prob.admissible(x, cap), cap=cap,
    )
    runs += new
    return next((i for i, r in enumerate(runs) if r is won), best), note


def _polish(
    prob: _Problem, runs: list[ReferenceRun], best: int, cap: float, max_nfev: int | None,
    tol: float, e: np.ndarray, jac: np.ndarray,
) -> tuple[int, str, np.ndarray, np.ndarray]:
    """One more run with tighter tolerances when the best one stopped short of first-order
    optimality inside the cap.

    ``e`` and ``jac`` are the best run's errors and Jacobian; returned are the best run's
    index, the note for the message, and its errors and Jacobian.
    """
    if (
        optimality(e, jac) < OPTIMALITY_THRESHOLD
        or prob.max_radius(runs[best].theta) >= cap - CAP_TOLERANCE
    ):
        return best, "", e, jac
    # Gauss-Newton converges only linearly on a large-residual (misspecified) fit, and
    # MINPACK's ftol test can stop it while the gradient is still well above the threshold
    polish_tol = max(tol * _POLISH_FACTOR, _POLISH_FLOOR)
    run = _run_lm(prob, runs[best].theta.copy(), "polish", max_nfev, polish_tol, cap)
    runs.append(run)
    if run.sse <= runs[best].sse:
        e, jac = prob.errors(run.theta.copy(), True)
        return len(runs) - 1, f"; polished with tol {polish_tol:g}", e, jac
    return best, "", e, jac


def _pem_options() -> set[str]:
    """The keyword options of :func:`pem` that :func:`oe`, :func:`armax` and :func:`bj` pass on."""
    import inspect

    return set(inspect.signature(pem).parameters) - {"data", "structure"}


@checked_keywords(also=_pem_options)
def oe(data: Any, nb: Any, nf: Any, nk: Any = 1, **options: Any) -> PEMResult:
    """Output-error model ``y = sum_j B_j/F_j u_j(t - nk_j) + e`` (MATLAB ``oe(data, [nb nf nk])``).

    Parameters
    ----------
    data : IOData or tuple of (u, y)
        See :func:`pem`.
    nb, nf, nk : int or sequence of int
        Per input: number of ``B`` coefficients, order of ``F``, delay (samples).
    **options
        Keywords of :func:`pem` (``initial``, ``starts``, ``seed``, ``r_max``, ...).

    Returns
    -------
    PEMResult
    """
    return pem(data, _named_structure("oe", nb=nb, nf=nf, nk=nk), **options)


@checked_keywords(also=_pem_options)
def armax(data: Any, na: int, nb: Any, nc: int, nk: Any = 1, **options: Any) -> PEMResult:
    """ARMAX model ``A y = sum_j B_j u_j(t - nk_j) + C e`` (MATLAB ``armax(data, [na nb nc nk])``).

    Parameters
    ----------
    data : IOData or tuple of (u, y)
        See :func:`pem`.
    na, nc : int
        Orders of ``A`` and ``C``.
    nb, nk : int or sequence of int
        Per input: number of ``B`` coefficients and delay (samples).
    **options
        Keywords of :func:`pem`.

    Returns
    -------
    PEMResult
    """
    return pem(data, _named_structure("armax", na=na, nb=nb, nc=nc, nk=nk), **options)


@checked_keywords(also=_pem_options)
def bj(data: Any, nb: Any, nc: int, nd: int, nf: Any, nk: Any = 1, **options: Any) -> PEMResult:
    """Box-Jenkins model ``y = sum_j B_j/F_j u_j(t - nk_j) + C/D e``
    (MATLAB ``bj(data, [nb nc nd nf nk])``).

    Parameters
    ----------
    data : IOData or tuple of (u, y)
        See :func:`pem`.
    nb, nf, nk : int or sequence of int
        Per input: number of ``B`` coefficients, order of ``F``, delay (samples).
    nc, nd : int
        Orders of ``C`` and ``D``.
    **options
        Keywords of :func:`pem`.

    Returns
    -------
    PEMResult
    """
    return pem(data, _named_structure("bj", nb=nb, nc=nc, nd=nd, nf=nf, nk=nk), **options)
