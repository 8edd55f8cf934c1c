"""A prediction-error fit of a SISO Box-Jenkins model (MATLAB ``bj``), for the benchmarks.

The model is

    y(t) = B(q)/F(q) u(t - nk) + C(q)/D(q) e(t)

with ``B = b_0 + b_1 q^-1 + ... + b_{nb-1} q^-(nb-1)`` (``nb`` taps) and ``F``, ``C``, ``D``
monic (``F = 1 + f_1 q^-1 + ... + f_nf q^-nf``, the same for ``C`` and ``D``).  The output-error
model is the special case ``nc = nd = 0``.

:func:`box_jenkins` minimises the sum of squared one-step prediction errors

    e(t) = D/C (y(t) - B/F u(t - nk))

over ``t >= start = max(nf, nb + nk - 1, nc, nd)``, every filter run from zero initial state
at ``t = 0`` (the paper presets start from rest, so zero state is the plant's own), by
Levenberg-Marquardt (``scipy.optimize.least_squares(method="lm")``) with the analytic Jacobian

* ``de/db_j = -D/(C F) u(t - nk - j)``,
* ``de/df_i = D/(C F) w(t - i)`` with ``w = B/F u``,
* ``de/dc_i = -1/C e(t - i)``,
* ``de/dd_i = 1/C v(t - i)`` with ``v = y - w``,

each a delayed copy of one filtered signal (four ``lfilter`` calls per Jacobian).

Starts: ``B/F`` from flexid's output-error reference (:func:`flexid.output_error.output_error`
on a simulation-predictor :class:`~flexid.objective.ARXCost`, zero initial state), then ``C/D``
from the output-error residual ``v`` by Hannan-Rissanen (a long AR fit of ``v`` gives an
innovation estimate ``e_hat``; ``D v = C e_hat`` is then linear least squares), then the joint
fit.  ``F`` and ``C`` are kept stable (the predictor filters by ``1/F`` and ``1/C``): a start
with roots outside the unit circle has them mirrored to ``1/conj(r)`` as MATLAB's ``pem``
does (``B`` divided by the product of the mirrored radii of ``F`` so ``|B/F|`` is unchanged;
``C/D`` keeps its spectral shape up to the variance), and a Levenberg-Marquardt step that
leaves the stable region is rejected (the residual function returns a vector far worse than
the start's, so MINPACK raises its damping), as in :mod:`flexid.output_error`.  ``D`` is free
(it is a numerator of the predictor).

Run ``python benchmarks/_box_jenkins.py`` for :func:`selfcheck`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import scipy.signal
from scipy.optimize import least_squares

from flexid.arx import ARXStructure
from flexid.objective import ARXCost
from flexid.output_error import _mirror as _mirror_theta
from flexid.output_error import output_error
from flexid.stability import is_stable
from flexid.validation import residual_tests

__all__ = ["BoxJenkins", "box_jenkins", "selfcheck"]

# A rejected (unstable) step returns residuals whose sum of squares is this factor times the
# start's plus the output energy: far above anything reachable from a stable start.
_REJECT_FACTOR = 1e6


# ===================================================================================== model
@dataclass
class BoxJenkins:
    """A fitted Box-Jenkins model ``y = B/F u(t - nk) + C/D e``.

    Attributes
    ----------
    b : ndarray, shape (nb,)
        ``b_0 .. b_{nb-1}`` (output units per input unit).
    f, c, d : ndarray, shape (nf + 1,), (nc + 1,), (nd + 1,)
        Monic polynomials in ``q^-1``, leading 1 included; ``f`` and ``c`` stable.
    nk : int
        Input delay in samples.
    dt : float
        Sample time in s.
    sigma2 : float
        Innovation variance ``SSE / (K - n_params)`` on the estimation record.
    param_std : ndarray, shape (n_params,)
        Asymptotic standard deviations ``sqrt(diag(sigma2 (J'J)^-1))`` in ``theta`` order
        ``[b, f_1.., c_1.., d_1..]``.
    sse : float
        Sum of squared prediction errors at the optimum (estimation record, ``t >= start``).
    sse_oe_start : float
        The same sum at the joint fit's start (output-error ``B/F`` and the ARMA ``C/D``).
    nfev : int
        Residual evaluations of the joint fit.
    wall_time : float
        Seconds for the whole fit (output-error starts included).
    message : str
        The joint fit's stopping message.
    """

    b: np.ndarray
    f: np.ndarray
    c: np.ndarray
    d: np.ndarray
    nk: int
    dt: float
    sigma2: float
    param_std: np.ndarray
    sse: float
    sse_oe_start: float
    nfev: int
    wall_time: float
    message: str

    @property
    def theta(self) -> np.ndarray:
        """``[b, f_1.., c_1.., d_1..]``, shape (n_params,)."""
        return np.concatenate([self.b, self.f[1:], self.c[1:], self.d[1:]])

    @property
    def start(self) -> int:
        """First sample of the estimation sum, ``max(nf, nb + nk - 1, nc, nd)``."""
        return _start(self.b.size, self.f.size - 1, self.c.size - 1, self.d.size - 1, self.nk)

    @property
    def num(self) -> np.ndarray:
        """``B`` with the delay, ``[0]*nk + b``, in powers of ``q^-1``."""
        return np.concatenate([np.zeros(self.nk), self.b])

    def simulate(self, u: np.ndarray, u_past: np.ndarray | None = None) -> np.ndarray:
        """Free-run output ``B/F u(t - nk)``.

        Parameters
        ----------
        u : ndarray, shape (N,)
            Input.
        u_past : ndarray, shape (M,), optional
            Input before ``u`` (e.g. the estimation record): the filter starts from rest
            ``M`` samples earlier, so the state at the first sample of ``u`` is the one the
            known past input left.  Default: rest at the first sample of ``u``.

        Returns
        -------
        ndarray, shape (N,)
            Simulated output (output units).
        """
        u_all, m = _with_past(u, u_past)
        return scipy.signal.lfilter(self.num, self.f, u_all)[m:]

    def predict(
        self,
        u: np.ndarray,
        y: np.ndarray,
        u_past: np.ndarray | None = None,
        y_past: np.ndarray | None = None,
    ) -> np.ndarray:
        """One-step prediction ``yhat = y - D/C (y - B/F u)``.

        Parameters
        ----------
        u, y : ndarray, shape (N,)
            Input and measured output.
        u_past, y_past : ndarray, shape (M,), optional
            The record before ``u``/``y`` (both or neither): every filter starts from rest
            ``M`` samples earlier.  Default: rest at the first sample.

        Returns
        -------
        ndarray, shape (N,)
            ``yhat(t)`` uses ``y`` up to ``t - 1`` and ``u`` up to ``t - nk`` only.
        """
        u_all, m = _with_past(u, u_past)
        y_all, m_y = _with_past(y, y_past)
        if m != m_y:
            raise ValueError("u_past and y_past must have the same length")
        w = scipy.signal.lfilter(self.num, self.f, u_all)
        e = scipy.signal.lfilter(self.d, self.c, y_all - w)
        return (y_all - e)[m:]


def _with_past(x: np.ndarray, past: np.ndarray | None) -> tuple[np.ndarray, int]:
    x = np.asarray(x, dtype=float).reshape(-1)
    if past is None:
        return x, 0
    past = np.asarray(past, dtype=float).reshape(-1)
    return np.concatenate([past, x]), past.size


def _start(nb: int, nf: int, nc: int, nd: int, nk: int) -> int:
    return max(nf, nb + nk - 1, nc, nd)


# ===================================================================================== pieces
def _split(theta: np.ndarray, nb: int, nf: int, nc: int) -> tuple[np.ndarray, ...]:
    """``b`` and the monic ``f``, ``c``, ``d`` of ``theta = [b, f.., c.., d..]``."""
    one = np.ones(1)
    b = theta[:nb]
    f = np.concatenate([one, theta[nb : nb + nf]])
    c = np.concatenate([one, theta[nb + nf : nb + nf + nc]])
    d = np.concatenate([one, theta[nb + nf + nc :]])
    return b, f, c, d


def _stable(poly: np.ndarray) -> bool:
    """All roots of the monic ``poly`` (in ``q^-1``, leading 1 included) inside the circle."""
    return bool(is_stable(poly[1:])[0])


def _mirror(poly: np.ndarray, num: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Monic ``poly`` with roots outside the circle mirrored, and ``num`` rescaled so that
    ``|num / poly|`` is unchanged (flexid's output-error start rule, as MATLAB's ``pem``)."""
    num = np.zeros(0) if num is None else num
    na = poly.size - 1
    theta = _mirror_theta(np.concatenate([poly[1:], num]), na)
    return np.concatenate([[1.0], theta[:na]]), theta[na:]


def _shifted(x: np.ndarray, lags: np.ndarray) -> np.ndarray:
    """Columns ``x(t - lag)`` (zero before ``t = 0``), shape (N, len(lags))."""
    n = x.size
    out = np.zeros((n, lags.size))
    for j, lag in enumerate(lags):  # a few dozen columns, each one array copy
        out[lag:, j] = x[: n - lag]
    return out


class _PEM:
    """Prediction errors and their Jacobian for one record and one set of orders."""

    def __init__(
        self, u: np.ndarray, y: np.ndarray, nb: int, nf: int, nc: int, nd: int, nk: int
    ) -> None:
        self.u, self.y = u, y
        self.nb, self.nf, self.nc, self.nd, self.nk = nb, nf, nc, nd, nk
        self.start = _start(nb, nf, nc, nd, nk)
        self.nfev = 0

    def signals(self, theta: np.ndarray) -> tuple[np.ndarray, ...]:
        """``e``, ``w = B/F u`` and ``v = y - w`` over the whole record, zero initial state."""
        b, f, c, d = _split(theta, self.nb, self.nf, self.nc)
        w = scipy.signal.lfilter(np.concatenate([np.zeros(self.nk), b]), f, self.u)
        v = self.y - w
        e = scipy.signal.lfilter(d, c, v)
        return e, w, v

    def residuals(self, theta: np.ndarray) -> np.ndarray:
        self.nfev += 1
        return self.signals(theta)[0][self.start :]

    def jacobian(self, theta: np.ndarray) -> np.ndarray:
        """``d e(t) / d theta`` for ``t >= start``, shape (K, n_params)."""
        _, f, c, d = _split(theta, self.nb, self.nf, self.nc)
        e, w, v = self.signals(theta)
        cf = np.convolve(c, f)
        g_u = scipy.signal.lfilter(d, cf, self.u)
        g_w = scipy.signal.lfilter(d, cf, w)
        g_e = scipy.signal.lfilter([1.0], c, e)
        g_v = scipy.signal.lfilter([1.0], c, v)
        cols = [
            -_shifted(g_u, self.nk + np.arange(self.nb)),
            _shifted(g_w, 1 + np.arange(self.nf)),
            -_shifted(g_e, 1 + np.arange(self.nc)),
            _shifted(g_v, 1 + np.arange(self.nd)),
        ]
        return np.hstack(cols)[self.start :]


def _arma_start(v: np.ndarray, nc: int, nd: int, start: int) -> tuple[np.ndarray, np.ndarray]:
    """Hannan-Rissanen estimate of ``D v = C e``: monic ``c`` (stable) and ``d``.

    A long AR model ``A_m v = e`` (order ``m = max(20, 3 (nc + nd))``, least squares) gives
    an innovation estimate ``e_hat = A_m v``; then ``v(t) = -sum d_i v(t-i) + sum c_i
    e_hat(t-i) + e(t)`` is linear in ``(c, d)``.  Roots of ``c`` outside the circle are
    mirrored.
    """
    if nc == 0 and nd == 0:
        return np.ones(1), np.ones(1)
    v = v[start:]
    m = max(20, 3 * (nc + nd))
    lag_v = _shifted(v, 1 + np.arange(m))
    a_long = np.linalg.lstsq(lag_v[m:], -v[m:], rcond=None)[0]
    e_hat = v + lag_v @ a_long
    e_hat[:m] = 0.0
    phi = np.hstack([-_shifted(v, 1 + np.arange(nd)), _shifted(e_hat, 1 + np.arange(nc))])
    k0 = m + max(nc, nd)
    par = np.linalg.lstsq(phi[k0:], v[k0:], rcond=None)[0]
    d = np.concatenate([[1.0], par[:nd]])
    c, _ = _mirror(np.concatenate([[1.0], par[nd:]]))
    return c, d


# ===================================================================================== fit
def box_jenkins(
    u: np.ndarray,
    y: np.ndarray,
    nb: int,
    nf: int,
    nc: int = 0,
    nd: int = 0,
    nk: int = 1,
    *,
    dt: float = 1.0,
    oe_starts: int = 4,
    seed: int = 0,
    tol: float = 1e-10,
    max_nfev: int | None = None,
) -> BoxJenkins:
    """Prediction-error fit of ``y = B/F u(t - nk) + C/D e`` (see the module docstring).

    Parameters
    ----------
    u, y : ndarray, shape (N,)
        Estimation record, input and output; zero initial state at ``t = 0``.
    nb : int
        Number of ``b`` taps (>= 1).
    nf, nc, nd : int
        Orders of the monic ``F``, ``C``, ``D`` (``nc = nd = 0``: output error).
    nk : int
        Input delay in samples.
    dt : float
        Sample time in s (stored on the model).
    oe_starts : int
        ``starts`` of the output-error reference that initialises ``B/F``.
    seed : int
        Seed of its random starts.
    tol : float
        ``ftol``, ``xtol`` and ``gtol`` of the joint Levenberg-Marquardt fit.
    max_nfev : int, optional
        Residual-evaluation budget of the joint fit (default MINPACK's ``100 * n_params``).

    Returns
    -------
    BoxJenkins
        With ``f`` and ``c`` stable.
    """
    t0 = time.perf_counter()
    u = np.asarray(u, dtype=float).reshape(-1)
    y = np.asarray(y, dtype=float).reshape(-1)
    # output-error start (B/F), zero initial state as in the joint fit
    cost = ARXCost(
        ARXStructure(nf, nb, nk), (u, y), predictor="simulation", metric="sse", initial="zero"
    )
    oe = output_error(cost, starts=oe_starts, seed=seed)
    f, b = _mirror(np.concatenate([[1.0], oe.theta[:nf]]), oe.theta[nf:])
    pem = _PEM(u, y, nb, nf, nc, nd, nk)
    theta_oe = np.concatenate([b, f[1:], np.zeros(nc + nd)])
    _, _, v = pem.signals(theta_oe)
    c, d = _arma_start(v, nc, nd, pem.start)
    theta0 = np.concatenate([b, f[1:], c[1:], d[1:]])

    r0 = pem.residuals(theta0)
    sse0 = float(r0 @ r0)
    bad = np.full(r0.size, np.sqrt((_REJECT_FACTOR * (sse0 + float(y @ y)) + 1.0) / r0.size))

    def fun(theta: np.ndarray) -> np.ndarray:
        _, f_, c_, _ = _split(theta, nb, nf, nc)
        if not (np.isfinite(theta).all() and _stable(f_) and _stable(c_)):
            return bad
        return pem.residuals(theta)

    sol = least_squares(
        fun,
        theta0,
        jac=pem.jacobian,
        method="lm",
        x_scale="jac",
        ftol=tol,
        xtol=tol,
        gtol=tol,
        max_nfev=max_nfev,
    )
    theta = np.asarray(sol.x, dtype=float)
    r = fun(theta)
    sse = float(r @ r)
    if not sse <= sse0:  # defensive: MINPACK returns its best accepted point
        theta, r, sse = theta0, r0, sse0
    jac = pem.jacobian(theta)
    k, n = jac.shape
    sigma2 = sse / max(k - n, 1)
    _, s, vt = np.linalg.svd(jac, full_matrices=False)
    cov = (vt.T / np.maximum(s, s[0] * 1e-12) ** 2) @ vt * sigma2
    b, f, c, d = _split(theta, nb, nf, nc)
    return BoxJenkins(
        b=b.copy(),
        f=f,
        c=c,
        d=d,
        nk=nk,
        dt=float(dt),
        sigma2=sigma2,
        param_std=np.sqrt(np.diag(cov)),
        sse=sse,
        sse_oe_start=sse0,
        nfev=pem.nfev,
        wall_time=time.perf_counter() - t0,
        message=str(sol.message),
    )


# ===================================================================================== check
def selfcheck(seed: int = 1, n: int = 4000) -> None:
    """Fit a known Box-Jenkins system and check the recovery; an ARX fit must fail.

    The system: ``F = 1 - 1.5 q^-1 + 0.7 q^-2`` (poles at radius 0.84), ``B = 1 + 0.5 q^-1``,
    ``nk = 1``, ``C = 1 + 0.5 q^-1``, ``D = 1 - 0.9 q^-1``, white Gaussian input (unit
    variance) and innovation (standard deviation 0.5), ``n`` samples.

    Tolerance: the estimate is asymptotically normal about the true ``theta`` with the
    covariance ``sigma^2 (J'J)^-1`` of the Jacobian at the optimum, whose standard deviations
    are of order ``1/sqrt(N)``; each coefficient must lie within 4 of them (a false failure
    has probability ~6e-5 per coefficient, ~4e-4 for the six), and each standard deviation
    must be below ``3/sqrt(N)`` so the tolerance is not vacuous.  Then the held-out
    prediction errors (the last quarter, the filters warmed up on the first three quarters)
    must pass both correlation tests, and least-squares ARX(2,2,1) on the same data must
    fail the autocorrelation test.

    Raises
    ------
    AssertionError
        When a check fails.
    """
    rng = np.random.default_rng(seed)
    b0, f0 = np.array([1.0, 0.5]), np.array([1.0, -1.5, 0.7])
    c0, d0 = np.array([1.0, 0.5]), np.array([1.0, -0.9])
    u = rng.standard_normal(n)
    e = 0.5 * rng.standard_normal(n)
    y = scipy.signal.lfilter([0.0, *b0], f0, u) + scipy.signal.lfilter(c0, d0, e)
    m = 3 * n // 4
    model = box_jenkins(u[:m], y[:m], nb=2, nf=2, nc=1, nd=1, nk=1)
    true = np.concatenate([b0, f0[1:], c0[1:], d0[1:]])
    err = np.abs(model.theta - true)
    print(f"true      {np.round(true, 4)}")
    print(f"estimate  {np.round(model.theta, 4)}")
    print(f"std       {np.round(model.param_std, 4)}  (1/sqrt(N) = {1 / np.sqrt(m):.4f})")
    print(f"|err|/std {np.round(err / model.param_std, 2)}; sigma {np.sqrt(model.sigma2):.4f}")
    assert np.all(model.param_std < 3.0 / np.sqrt(m)), "standard deviations not O(1/sqrt(N))"
    assert np.all(err <= 4.0 * model.param_std), "a coefficient outside 4 standard deviations"

    yhat = model.predict(u[m:], y[m:], u_past=u[:m], y_past=y[:m])
    tests = residual_tests(y[m:] - yhat, u[m:])
    print("BJ  held out: " + "; ".join(f"{t.name} {t.verdict()}" for t in tests))
    assert all(t.passed for t in tests), "the BJ residual fails a correlation test"

    arx = ARXStructure(2, 2, 1).least_squares(u[:m], y[:m])
    e_arx = y[m:] - arx.predict(u[m:], y[m:])
    arx_tests = residual_tests(e_arx[arx.structure.start :], u[m + arx.structure.start :])
    print("ARX held out: " + "; ".join(f"{t.name} {t.verdict()}" for t in arx_tests))
    assert not arx_tests[0].passed, "ARX passes the autocorrelation test: the check is blind"
    print(f"selfcheck passed ({model.wall_time:.2f} s, {model.nfev} residual evaluations)")


if __name__ == "__main__":
    selfcheck()
