"""Residual diagnostics: fit numbers, correlation tests and spectra, on plain arrays.

:func:`fit_percent`, :func:`rmse`, :func:`error_range`, :func:`xcorr`,
:func:`correlation_test`, :func:`residual_tests`, :func:`billings_voon_tests` and :func:`psd`
need no model; :func:`flexid.validation.validate` runs them on a model and a record.

Notes
-----
Fit
    ``fit % = 100 (1 - ||y - yhat|| / ||y - mean(y)||)`` (the NRMSE fit of MATLAB
    ``compare``): 100 for a perfect model, 0 for the constant predictor ``mean(y)``, negative
    for a model worse than that.  :func:`validate` reports it twice, always labelled: for the
    **one-step** predictor and for the **simulation** (free run) predictor, both over the
    samples ``t >= start`` (``start = model.structure.start``, the first sample with a full
    regressor), so the initial samples neither help nor hurt.
Correlation
    ``xcorr(a, b, L)[tau] = sum_t a'(t) b'(t - tau) / sqrt(sum a'^2 sum b'^2)`` for
    ``tau = -L..L``, where ``a' = a - mean(a)``, sums over the samples where both factors
    exist (biased estimator: divided by the full energy, not by ``N - |tau|``).  A positive
    lag therefore correlates ``a`` with *past* values of ``b``.
Band
    ``+-1.96 / sqrt(N)``: under the null hypothesis (white residual, independent of the
    input) each estimated correlation is approximately normal with variance ``1/N``, so about
    5 % of lags fall outside by chance.  (sysidentpy uses ``1.96/sqrt(2N-1)``, which flags
    about three times too many lags.)
Pass rule
    A test over ``m`` counted lags passes when **both**

    1. the number of lags outside the 95 % band is at most the 99 % quantile of
       ``Binomial(m, 0.05)`` (the count expected by chance, e.g. 4 of 25, 6 of 51), and
    2. no lag exceeds the simultaneous 99 % band ``z / sqrt(N)`` with the Bonferroni value
       ``z = Phi^-1(1 - 0.005 / m)`` (about 3.3 for 51 lags), so one gross violation (a large
       lag-1 autocorrelation, say) fails the test even if the other lags are quiet.

    Each rule alone rejects a valid model in at most about 1 % of records, so a single test
    wrongly fails in at most about 2 % of records, and a valid single-input
    model fails at least one of the five tests in up to about 8 % of records; see
    ``linear_passed`` and ``nonlinear_passed`` for the two groups.  A plain "no lag outside
    the 95 % band" rule, as often read off plots, fails a perfect model in most records of 25 lags
    (``1 - 0.95**25 = 72 %``).

Tests (Billings & Voon 1986; Billings & Zhu 1994), with ``e`` the one-step residual and ``u``
each input in turn; ``L = max_lag``:

============================  ========================================  ===============
name                          correlation                               counted lags
============================  ========================================  ===============
``auto e``                    ``phi_ee(tau) = corr(e(t), e(t-tau))``    ``1..L`` [#]_
``cross u-e``                 ``phi_ue(tau) = corr(e(t), u(t-tau))``    ``-L..L``
``BV e(eu)``                  ``corr(e(t), e(t-1-tau) u(t-1-tau))``     ``tau = 0..L-1``
``BV u2'-e``                  ``corr(u^2'(t-tau), e(t))``               ``-L..L``
``BV u2'-e2'``                ``corr(u^2'(t-tau), e^2'(t))``            ``-L..L``
============================  ========================================  ===============

.. [#] The autocorrelation is symmetric; lags ``-L..L`` are kept for plots, but only lags
   ``1..L`` are counted, since the negative lags repeat them and would double every count.

``u^2' = u^2 - mean(u^2)`` and ``e^2' = e^2 - mean(e^2)``; all correlations remove the
means.  With a binary input (PRBS, +-a) ``u^2`` is constant, so the two ``u^2'`` tests carry
no information; they are then marked "n/a" and count as passed.  The band is valid for any
input spectrum as long as the residual is white (the null hypothesis), since then the
variance of each estimated cross-correlation is ``1/N`` whatever the colour of ``u``.

A linear model is adequate when ``phi_ee`` is an impulse and all other functions are
zero (within the band): ``phi_ue`` at positive lags reveals un-modelled input dynamics, at
negative lags output feedback; the three Billings-Voon functions reveal un-modelled
nonlinear terms that the linear tests cannot see (a quadratic term in ``u`` or ``y`` leaves
the second-order moments ``u^2'``-``e`` nonzero, for example).

References
----------
S. A. Billings and W. S. F. Voon, "Correlation based model validity tests for non-linear
models", Int. J. Control 44(1), 235-244, 1986.
S. A. Billings and Q. M. Zhu, "Nonlinear model validation using correlation tests",
Int. J. Control 60(6), 1107-1120, 1994.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import fft as sfft
from scipy import signal, stats

from ._validate import integer, positive_int, positive_real
from .config import CORRELATION_LAGS
from .errors import DataError, check_finite

__all__ = [
    "CONFIDENCE",
    "PASS_LEVEL",
    "CorrelationTest",
    "billings_voon_tests",
    "correlation_bound",
    "correlation_test",
    "error_range",
    "fit_percent",
    "format_fit",
    "max_outside_allowed",
    "output_cross_tests",
    "psd",
    "residual_tests",
    "rmse",
    "xcorr",
]

CONFIDENCE = 0.95
"""Confidence level of the per-lag band ``z / sqrt(N)``."""

PASS_LEVEL = 0.01
"""False-rejection level of each of the two pass rules (see the module docstring)."""


# ============================================================================ input checks
def _vector(x: Any, what: str) -> np.ndarray:
    """A finite 1-D float array (a (N, 1) column is accepted)."""
    arr = np.asarray(x, dtype=float)
    if arr.ndim == 2 and arr.shape[1] == 1:
        arr = arr[:, 0]
    if arr.ndim != 1:
        raise DataError(f"{what} must be a 1-D array of samples, got shape {arr.shape}")
    if arr.size == 0:
        raise DataError(f"{what} is empty")
    check_finite(arr, what)
    return arr


def _pair(y: Any, yhat: Any, what: str = "prediction") -> tuple[np.ndarray, np.ndarray]:
    y = _vector(y, "measured output y")
    yhat = _vector(yhat, what)
    if y.shape != yhat.shape:
        raise DataError(
            f"measured output and {what} have different lengths: {y.size} and {yhat.size}"
        )
    return y, yhat


def _check_max_lag(max_lag: Any, n: int, what: str = "record") -> int:
    max_lag = positive_int(max_lag, "max_lag", error=DataError)
    if n < 2 * max_lag + 2:
        raise DataError(
            f"{what} of {n} samples is too short for max_lag={max_lag}: correlation tests "
            f"need at least 2*max_lag+2 = {2 * max_lag + 2} samples"
        )
    return max_lag


# ============================================================================ fit numbers
def fit_percent(y: Any, yhat: Any) -> float:
    """NRMSE fit in percent, ``100 (1 - ||y - yhat|| / ||y - mean(y)||)``.

    Parameters
    ----------
    y : array_like, shape (N,)
        Measured output.
    yhat : array_like, shape (N,)
        Model output (one-step prediction or simulation), same units as ``y``.

    Returns
    -------
    float
        100 for a perfect model, 0 for the mean predictor, negative when worse than that.

    Raises
    ------
    DataError
        On NaN/inf, a length mismatch or a constant ``y`` (the fit is then undefined).
    """
    y, yhat = _pair(y, yhat)
    scale = np.linalg.norm(y - y.mean())
    if scale == 0.0:
        raise DataError("fit % is undefined for a constant measured output (||y - mean|| = 0)")
    return float(100.0 * (1.0 - np.linalg.norm(y - yhat) / scale))


def format_fit(value: float | None) -> str:
    """A fit % for display: two decimals; ``"< -999"`` below -999 % (an unstable model's free
    run gives -inf or a number with a hundred digits); ``"-"`` when missing (None or NaN).

    The one fit formatter of the summaries, the comparison tables and the command line.

    Parameters
    ----------
    value : float or None
        Fit in percent.

    Returns
    -------
    str
        The formatted fit.
    """
    if value is None or math.isnan(value):
        return "-"
    return "< -999" if value < -999 else f"{value:.2f}"


def rmse(y: Any, yhat: Any) -> float:
    """Root-mean-square error ``sqrt(mean((y - yhat)^2))``, in the units of ``y``.

    Parameters
    ----------
    y, yhat : array_like, shape (N,) or (N, n_y)
        Measured and model outputs.

    Returns
    -------
    float
        The RMSE.
    """
    y, yhat = _pair(y, yhat)
    return float(np.sqrt(np.mean((y - yhat) ** 2)))


def error_range(y: Any, yhat: Any) -> tuple[float, float]:
    """Smallest and largest modelling error ``y - yhat`` (the paper's "error range").

    Parameters
    ----------
    y, yhat : array_like, shape (N,)
        Measured and model outputs.

    Returns
    -------
    tuple of float
        ``(min(y - yhat), max(y - yhat))``, in the units of ``y``.
    """
    y, yhat = _pair(y, yhat)
    err = y - yhat
    return float(err.min()), float(err.max())


# ============================================================================ correlation
def xcorr(a: Any, b: Any, max_lag: int) -> tuple[np.ndarray, np.ndarray]:
    """Normalised cross-correlation of ``a`` with ``b`` at lags ``-max_lag..max_lag``.

    ``r[tau] = sum_t a'(t) b'(t - tau) / sqrt(sum a'^2 * sum b'^2)`` with the means removed
    (``a' = a - mean(a)``) and the sum over the samples where both factors exist (biased
    estimator).  ``xcorr(a, a, L)`` is 1 at lag 0; a positive lag correlates ``a`` with past
    values of ``b``.  Computed with one real FFT, so the cost is ``O(N log N)`` whatever
    ``max_lag``.

    Parameters
    ----------
    a, b : array_like, shape (N,)
        Signals of equal length.
    max_lag : int
        Largest lag in samples, ``1 <= max_lag <= N - 1``.

    Returns
    -------
    lags : ndarray of int, shape (2 max_lag + 1,)
        ``-max_lag..max_lag``.
    r : ndarray, shape (2 max_lag + 1,)
        Correlation coefficients in [-1, 1]; all zero if either signal is constant.
    """
    a = _vector(a, "first signal")
    b = _vector(b, "second signal")
    if a.size != b.size:
        raise DataError(f"signals have different lengths: {a.size} and {b.size}")
    n = a.size
    max_lag = integer(
        max_lag, f"max_lag for {n} samples", error=DataError, minimum=0, maximum=n - 1
    )
    # the coefficients do not depend on the signals' scale: each is scaled to a peak in
    # [0.5, 1) first, so that a diverging residual (1e200, say) cannot overflow the sums to
    # inf and every coefficient to 0 (which would pass every test); by a power of two, which
    # is exact, since a rounding here would be amplified by the centring that follows
    a, b = (np.ldexp(x, -math.frexp(float(np.max(np.abs(x))))[1]) for x in (a, b))
    a = a - a.mean()
    b = b - b.mean()
    lags = np.arange(-max_lag, max_lag + 1)
    scale = math.sqrt(float(a @ a)) * math.sqrt(float(b @ b))
    if scale == 0.0:
        return lags, np.zeros(lags.size)
    nfft = sfft.next_fast_len(n + max_lag, real=True)
    c = sfft.irfft(sfft.rfft(a, nfft) * np.conj(sfft.rfft(b, nfft)), nfft)
    # c[k] = sum_t a(t) b(t - k) for k >= 0; c[nfft - k] = sum_t a(t) b(t + k)
    r = np.concatenate([c[nfft - max_lag :], c[: max_lag + 1]]) if max_lag else c[:1]
    return lags, r / scale


def correlation_bound(n: int, confidence: float = CONFIDENCE) -> float:
    """Half-width ``z / sqrt(n)`` of the band (``1.96/sqrt(n)`` at 95 %).

    Parameters
    ----------
    n : int
        Number of samples.
    confidence : float
        Two-sided confidence level, in (0, 1).

    Returns
    -------
    float
        The half-width.
    """
    z = stats.norm.ppf(0.5 + confidence / 2.0)
    return float(z / math.sqrt(n))


def max_outside_allowed(m: int, p: float = 1.0 - CONFIDENCE, level: float = PASS_LEVEL) -> int:
    """Largest number of lags outside the band that a valid model shows by chance.

    The ``1 - level`` quantile of ``Binomial(m, p)``: a white residual exceeds it in at most
    ``level`` of records (e.g. 4 of 25 lags, 6 of 51 at the defaults).

    Parameters
    ----------
    m : int
        Number of counted lags.
    p : float
        Probability of one lag outside the band (0.05 for the 95 % band).
    level : float
        Accepted rate of wrongly failed valid models.

    Returns
    -------
    int
        The allowed number of lags outside the band.
    """
    return int(stats.binom.ppf(1.0 - level, m, p))


@dataclass
class CorrelationTest:
    """One correlation test: the function, its band and the verdict.

    Attributes
    ----------
    name : str
        Short name, e.g. ``"auto e"`` or ``"cross torque-e"``.
    description : str
        The correlation in words / formula.
    lags : ndarray of int, shape (K,)
        Lags in samples (all lags, for plots).
    values : ndarray, shape (K,)
        Correlation coefficients.
    counted : ndarray of bool, shape (K,)
        Which lags the test counts (lag 0 of an autocorrelation and mirrored lags are not).
    n_samples : int
        Number of samples the correlation was estimated from.
    bound : float
        Half-width of the 95 % band, ``1.96/sqrt(n_samples)``.
    strict_bound : float
        Half-width of the simultaneous (Bonferroni) 99 % band over the counted lags.
    n_outside : int
        Counted lags outside the 95 % band.
    n_lags : int
        Number of counted lags ``m``.
    max_outside : int
        Allowed count: the 99 % quantile of ``Binomial(m, 0.05)``.
    passed : bool
        ``n_outside <= max_outside`` and no counted lag beyond ``strict_bound``.
    applicable : bool
        False when a signal of the test is constant (``u^2`` of a binary input): the
        correlation is then identically zero and says nothing; the test counts as passed.
    """

    name: str
    description: str
    lags: np.ndarray
    values: np.ndarray
    counted: np.ndarray
    n_samples: int
    bound: float
    strict_bound: float
    n_outside: int
    n_lags: int
    max_outside: int
    passed: bool
    applicable: bool = True

    @property
    def fraction_outside(self) -> float:
        """Share of counted lags outside the 95 % band."""
        return self.n_outside / self.n_lags if self.n_lags else 0.0

    @property
    def max_abs(self) -> float:
        """Largest ``|r|`` over the counted lags."""
        vals = np.abs(self.values[self.counted])
        return float(vals.max()) if vals.size else 0.0

    def verdict(self) -> str:
        """One line: ``"n of m lags outside the 95 % band (max allowed k): PASS"``.

        Returns
        -------
        str
            The verdict line.
        """
        if not self.applicable:
            return "n/a (a constant signal, e.g. u^2 of a binary input)"
        word = "PASS" if self.passed else "FAIL"
        extra = "" if self.max_abs <= self.strict_bound else "; a lag beyond the 99 % joint band"
        return (
            f"{self.n_outside} of {self.n_lags} lags outside the 95 % band "
            f"(allowed {self.max_outside}){extra}: {word}"
        )

    def to_dict(self, arrays: bool = False) -> dict[str, Any]:
        """JSON-safe plain types; the correlation arrays only when ``arrays`` is true.

        Parameters
        ----------
        arrays : bool
            Include ``lags`` and ``values``.

        Returns
        -------
        dict
            The fields of the test.
        """
        out: dict[str, Any] = {
            "name": self.name,
            "description": self.description,
            "n_samples": int(self.n_samples),
            "bound": float(self.bound),
            "strict_bound": float(self.strict_bound),
            "n_outside": int(self.n_outside),
            "n_lags": int(self.n_lags),
            "fraction_outside": float(self.fraction_outside),
            "max_outside": int(self.max_outside),
            "max_abs": self.max_abs,
            "passed": bool(self.passed),
            "applicable": bool(self.applicable),
        }
        if arrays:
            out["lags"] = [int(v) for v in self.lags]
            out["values"] = [float(v) for v in self.values]
            out["counted"] = [bool(v) for v in self.counted]
        return out


def correlation_test(
    name: str,
    lags: np.ndarray,
    values: np.ndarray,
    n_samples: int,
    counted: np.ndarray | None = None,
    description: str = "",
    applicable: bool = True,
) -> CorrelationTest:
    """Judge a correlation function against the 95 % band with the module's pass rule.

    Parameters
    ----------
    name : str
        Name of the test.
    lags, values : ndarray, shape (K,)
        Lags and correlation coefficients (e.g. from :func:`xcorr`).
    n_samples : int
        Samples used for the estimate; sets the band ``1.96/sqrt(n_samples)``.
    counted : ndarray of bool, shape (K,), optional
        Lags to count; default all.
    description : str
        Formula or words for reports.
    applicable : bool
        False marks an uninformative test (a constant signal); it then passes.

    Returns
    -------
    CorrelationTest
        The verdict with the counts, the bounds and the correlation arrays.
    """
    lags = np.asarray(lags)
    values = np.asarray(values, dtype=float)
    counted = np.ones(lags.size, dtype=bool) if counted is None else np.asarray(counted, bool)
    m = int(counted.sum())
    bound = correlation_bound(n_samples)
    z_strict = stats.norm.ppf(1.0 - PASS_LEVEL / (2.0 * max(m, 1)))
    strict = float(z_strict / math.sqrt(n_samples))
    absval = np.abs(values[counted])
    n_out = int(np.count_nonzero(absval > bound))
    allowed = max_outside_allowed(m)
    passed = (n_out <= allowed and not bool(np.any(absval > strict))) or not applicable
    return CorrelationTest(
        name=name,
        description=description,
        lags=lags,
        values=values,
        counted=counted,
        n_samples=int(n_samples),
        bound=bound,
        strict_bound=strict,
        n_outside=n_out,
        n_lags=m,
        max_outside=allowed,
        passed=bool(passed),
        applicable=bool(applicable),
    )


def _inputs_2d(u: Any, n: int) -> np.ndarray:
    arr = np.asarray(u, dtype=float)
    if arr.ndim == 1:
        arr = arr[:, None]
    if arr.ndim != 2:
        raise DataError(f"input u must have shape (N,) or (N, n_u), got {arr.shape}")
    if arr.shape[0] != n:
        raise DataError(
            f"input and residual have different lengths: u has {arr.shape[0]} samples, "
            f"the residual {n}"
        )
    check_finite(arr, "input u")
    return arr


def _input_names(names: Sequence[str] | None, n_u: int) -> list[str]:
    if names is None:
        return ["u"] if n_u == 1 else [f"u{i + 1}" for i in range(n_u)]
    names = list(names)
    if len(names) != n_u:
        raise DataError(f"{len(names)} input names given for {n_u} inputs")
    return [str(n) for n in names]


def residual_tests(
    e: Any, u: Any, max_lag: int = CORRELATION_LAGS, input_names: Sequence[str] | None = None
) -> list[CorrelationTest]:
    """Whiteness and independence tests of a residual (MATLAB ``resid``, with correct bands).

    Parameters
    ----------
    e : array_like, shape (N,)
        Residual (one-step prediction error).
    u : array_like, shape (N,) or (N, n_u)
        Inputs over the same samples.
    max_lag : int
        Largest lag ``L``; needs ``N >= 2 L + 2``.
    input_names : sequence of str, optional
        Names used in the test names (default ``u`` or ``u1, u2, ...``).

    Returns
    -------
    list of CorrelationTest
        ``auto e`` (lags ``-L..L`` stored, ``1..L`` counted) and one ``cross <input>-e``
        per input (``corr(e(t), u(t - tau))``, lags ``-L..L`` all counted).
    """
    e = _vector(e, "residual e")
    n = e.size
    max_lag = _check_max_lag(max_lag, n, "residual")
    u = _inputs_2d(u, n)
    names = _input_names(input_names, u.shape[1])
    lags, r = xcorr(e, e, max_lag)
    tests = [
        correlation_test(
            "auto e", lags, r, n, counted=lags > 0, description="phi_ee(tau) = corr(e(t), e(t-tau))"
        )
    ]
    for j, name in enumerate(names):
        lags, r = xcorr(e, u[:, j], max_lag)
        tests.append(
            correlation_test(
                f"cross {name}-e",
                lags,
                r,
                n,
                description=f"phi_ue(tau) = corr(e(t), {name}(t-tau))",
            )
        )
    return tests


def output_cross_tests(
    e: Any, max_lag: int = CORRELATION_LAGS, output_names: Sequence[str] | None = None
) -> list[CorrelationTest]:
    """Independence of the residuals of several outputs from each other (MATLAB ``resid`` of
    a multi-output model).

    A model that describes every output leaves residuals that do not predict each other:
    ``corr(e_i(t), e_j(t - tau))`` within the band at every lag but 0, where sensors whose
    noise is correlated (one acquisition card, one vibration) give a nonzero value that no
    model of the inputs can remove.

    Parameters
    ----------
    e : array_like, shape (N, ny)
        The residual of each output over the same samples, ``ny >= 2``.
    max_lag : int
        Largest lag ``L``; needs ``N >= 2 L + 2``.
    output_names : sequence of str, optional
        Names used in the test names (default ``y1, y2, ...``).

    Returns
    -------
    list of CorrelationTest
        One ``cross <i>-<j>`` per pair ``i < j`` (lags ``-L..L`` stored, every lag but 0
        counted), by the pass rule of :func:`correlation_test`.

    Raises
    ------
    DataError
        Fewer than two outputs, non-finite values or a record too short for ``max_lag``.
    """
    e = np.asarray(e, dtype=float)
    if e.ndim != 2 or e.shape[1] < 2:
        raise DataError(f"output_cross_tests needs residuals of shape (N, ny >= 2), got {e.shape}")
    n, ny = e.shape
    max_lag = _check_max_lag(max_lag, n, "residual")
    names = list(output_names) if output_names is not None else [f"y{i + 1}" for i in range(ny)]
    if len(names) != ny:
        raise DataError(f"{len(names)} output names for {ny} outputs")
    tests = []
    for i in range(ny):
        for j in range(i + 1, ny):
            lags, r = xcorr(_vector(e[:, i], names[i]), _vector(e[:, j], names[j]), max_lag)
            tests.append(correlation_test(
                f"cross {names[i]}-{names[j]}", lags, r, n, counted=lags != 0,
                description=f"corr(e_{names[i]}(t), e_{names[j]}(t-tau)), tau != 0"))  # fmt: skip
    return tests


def billings_voon_tests(
    e: Any, u: Any, max_lag: int = CORRELATION_LAGS, input_names: Sequence[str] | None = None
) -> list[CorrelationTest]:
    """Higher-order correlation tests for un-modelled nonlinear terms (Billings & Voon 1986).

    Parameters
    ----------
    e : array_like, shape (N,)
        Residual (one-step prediction error).
    u : array_like, shape (N,) or (N, n_u)
        Inputs over the same samples.
    max_lag : int
        Largest lag ``L``; needs ``N >= 2 L + 2``.
    input_names : sequence of str, optional
        Names used in the test names.

    Returns
    -------
    list of CorrelationTest
        Per input: ``BV e(eu)``, ``corr(e(t), e(t-1-tau) u(t-1-tau))`` for ``tau = 0..L-1``
        (stored at lags ``tau``); ``BV u2'-e``, ``corr(u^2'(t-tau), e(t))`` for
        ``tau = -L..L``; ``BV u2'-e2'``, ``corr(u^2'(t-tau), e^2'(t))`` for ``tau = -L..L``.
    """
    e = _vector(e, "residual e")
    n = e.size
    max_lag = _check_max_lag(max_lag, n, "residual")
    u = _inputs_2d(u, n)
    names = _input_names(input_names, u.shape[1])
    e2 = e * e
    tests = []
    for j, name in enumerate(names):
        uj = u[:, j]
        lags, r = xcorr(e, e * uj, max_lag)
        keep = lags >= 1  # corr(e(t), (e u)(t - k)) at k = 1 + tau
        tests.append(
            correlation_test(
                f"BV e({name}e)" if len(names) > 1 else "BV e(eu)",
                lags[keep] - 1,
                r[keep],
                n,
                description=f"corr(e(t), e(t-1-tau) {name}(t-1-tau)), tau = 0..{max_lag - 1}",
            )
        )
        u2 = uj * uj  # xcorr removes the mean: u^2' = u^2 - mean(u^2)
        u2_varies = bool(np.ptp(u2) > 1e-12 * max(float(np.max(np.abs(u2))), 1e-300))
        lags, r = xcorr(e, u2, max_lag)
        tests.append(
            correlation_test(
                f"BV {name}2'-e",
                lags,
                r,
                n,
                description=f"corr({name}^2'(t-tau), e(t)), tau = -{max_lag}..{max_lag}",
                applicable=u2_varies,
            )
        )
        lags, r = xcorr(e2, u2, max_lag)
        tests.append(
            correlation_test(
                f"BV {name}2'-e2'",
                lags,
                r,
                n,
                description=f"corr({name}^2'(t-tau), e^2'(t)), tau = -{max_lag}..{max_lag}",
                applicable=u2_varies,
            )
        )
    return tests


# ============================================================================ spectra
def psd(x: Any, dt: float, nperseg: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Welch power spectral density (Hann window, 50 % overlap, mean removed).

    Parameters
    ----------
    x : array_like, shape (N,)
        Signal.
    dt : float
        Sample time in seconds.
    nperseg : int, optional
        Segment length; default ``min(N, max(256, 2**floor(log2(N / 8))))`` (about eight
        segments for long records, never fewer than 256 samples of resolution).

    Returns
    -------
    f : ndarray, shape (nperseg // 2 + 1,)
        Frequencies in Hz, ``0..1/(2 dt)``.
    p : ndarray, shape (nperseg // 2 + 1,)
        One-sided PSD in ``units(x)^2 / Hz``.
    """
    x = _vector(x, "signal")
    dt = positive_real(dt, "sample time dt", error=DataError, unit="s")
    n = x.size
    if n < 4:
        raise DataError(f"a PSD needs at least 4 samples, got {n}")
    if nperseg is None:
        nperseg = min(n, max(256, 2 ** math.floor(math.log2(max(n / 8, 1)))))
    nperseg = min(integer(nperseg, "nperseg", error=DataError, minimum=4), n)
    f, p = signal.welch(x, fs=1.0 / dt, nperseg=nperseg, detrend="constant")
    return f, p


def _peak(f: np.ndarray, p: np.ndarray) -> float:
    """Frequency of the largest PSD value above DC."""
    return float(f[1:][np.argmax(p[1:])]) if f.size > 1 else float(f[0])
