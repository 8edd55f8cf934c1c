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
    5 % of lags fall outside by chance.  The plots draw it and each test counts the lags
    outside it, as information: a count is not a verdict (25 lags of a perfect model all
    stay inside in only ``0.95**25 = 28 %`` of records).
Verdict
    Each test is a portmanteau test over its counted lags (:mod:`flexid.validation.portmanteau`): a
    statistic ``Q``, about ``chi^2(m)`` for a valid model whatever the input's colour, and a
    p-value, with the estimated parameters' effect on the distribution accounted for when
    the report knows which record the model was estimated on.  A report judges its battery
    at the family-wise level ``alpha`` (default
    :data:`~flexid.config.VALIDATION_ALPHA`, 5 %) with Holm's correction: it rejects a
    true model in at most ``alpha`` of records, and each test's adjusted p-value says how
    far it is from the verdict.  The measured rates (size and power) are in the guide's
    validation page.

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
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from scipy import fft as sfft
from scipy import signal, stats

from .._validate import integer, level, positive_int, positive_real
from ..errors import DataError, FlexidError, check_finite
from ..models.vocabulary import CORRELATION_LAGS, VALIDATION_ALPHA
from .portmanteau import KNOWN, ParameterEffect, _unit, describe, holm, portmanteau

__all__ = [
    "CONFIDENCE",
    "CorrelationTest",
    "billings_voon_tests",
    "check_level",
    "correlation_bound",
    "error_range",
    "fit_percent",
    "format_fit",
    "judged",
    "output_cross_tests",
    "psd",
    "residual_tests",
    "rmse",
    "xcorr",
]

CONFIDENCE = 0.95
"""Confidence level of the per-lag band ``z / sqrt(N)`` drawn on the correlation plots."""


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
    # scaled by powers of two first: a diverging residual cannot overflow the sums to inf and
    # every coefficient to 0 (which would pass every test)
    a, b = _unit(a), _unit(b)
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


@dataclass
class CorrelationTest:
    """One residual test: the correlation function, its statistic, p-value and verdict.

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
        Half-width of the 95 % band of one lag, ``1.96/sqrt(n_samples)`` (for plots and the
        count of lags outside it, which is information, not the verdict).
    n_outside : int
        Counted lags outside the 95 % band.
    n_lags : int
        Number of counted lags ``m``.
    statistic : float
        The portmanteau statistic ``Q`` (:mod:`flexid.validation.portmanteau`), about ``chi^2(dof)``
        for a valid model.
    dof : int
        Its degrees of freedom.
    p_value : float
        The test's own p-value.
    adjusted_p : float
        Its p-value after Holm's correction over the battery it was judged in (the report's
        tests); the test's own when judged alone.
    alpha : float
        The family-wise level of the verdict.
    applicable : bool
        False when the test says nothing: a signal of it is constant (``u^2`` of a binary
        input, whose correlation is identically zero), or ``u^2`` of a two-level input, an
        affine function of ``u`` that repeats the input cross-correlation test; it then
        passes and does not count in the battery.
    parameters : str
        How the estimated parameters entered the statistic, in words.
    """

    name: str
    description: str
    lags: np.ndarray
    values: np.ndarray
    counted: np.ndarray
    n_samples: int
    bound: float
    n_outside: int
    n_lags: int
    statistic: float
    dof: int
    p_value: float
    adjusted_p: float = float("nan")
    alpha: float = VALIDATION_ALPHA
    applicable: bool = True
    parameters: str = KNOWN

    def __post_init__(self) -> None:
        if math.isnan(self.adjusted_p):
            self.adjusted_p = self.p_value

    @property
    def passed(self) -> bool:
        """Not rejected at ``alpha``: the adjusted p-value is at least ``alpha`` (or the test
        does not apply)."""
        return (not self.applicable) or self.adjusted_p >= self.alpha

    @property
    def fraction_outside(self) -> float:
        """Share of counted lags outside the 95 % band."""
        return self.n_outside / self.n_lags if self.n_lags else 0.0

    @property
    def max_abs(self) -> float:
        """Largest ``|r|`` over the counted lags."""
        vals = np.abs(self.values[self.counted])
        return float(vals.max()) if vals.size else 0.0

    @property
    def worst_lag(self) -> int:
        """The counted lag of the largest ``|r|`` (0 when none is counted)."""
        vals = np.where(self.counted, np.abs(self.values), -1.0)
        return int(self.lags[int(np.argmax(vals))]) if np.any(self.counted) else 0

    def verdict(self) -> str:
        """One line: ``"Q = 31.2 (25 dof), p = 0.18, Holm 0.90; 2/25 lags outside 95 %: PASS"``.

        Returns
        -------
        str
            The verdict line.
        """
        if not self.applicable:
            return "n/a (u^2 of a two-level input: constant, or repeating the linear test)"
        held = "" if self.adjusted_p == self.p_value else f", Holm {_p_text(self.adjusted_p)}"
        return (
            f"Q = {self.statistic:.1f} ({self.dof} dof), p = {_p_text(self.p_value)}{held}; "
            f"{self.n_outside}/{self.n_lags} lags outside 95 %: {self.word}"
        )

    @property
    def word(self) -> str:
        """``"PASS"``, ``"FAIL (lag +7)"`` (the counted lag of the largest correlation) or
        ``"n/a"``."""
        if not self.applicable:
            return "n/a"
        return "PASS" if self.passed else f"FAIL (lag {self.worst_lag:+d})"

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
            "n_outside": int(self.n_outside),
            "n_lags": int(self.n_lags),
            "fraction_outside": float(self.fraction_outside),
            "max_abs": self.max_abs,
            "statistic": float(self.statistic),
            "dof": int(self.dof),
            "p_value": float(self.p_value),
            "adjusted_p": float(self.adjusted_p),
            "alpha": float(self.alpha),
            "parameters": self.parameters,
            "passed": bool(self.passed),
            "applicable": bool(self.applicable),
        }
        if arrays:
            out["lags"] = [int(v) for v in self.lags]
            out["values"] = [float(v) for v in self.values]
            out["counted"] = [bool(v) for v in self.counted]
        return out


def _p_text(p: float, equals: str = "") -> str:
    """A p-value for a line of text: three significant digits (after ``equals``), ``"< 1e-16"``
    below that (double precision's resolution of ``1 - F``)."""
    return "< 1e-16" if p < 1e-16 else f"{equals}{p:.3g}"


def _test(
    name: str, description: str, e: np.ndarray, x: np.ndarray, max_lag: int, counted: Any,
    *, shift: int = 0, effect: ParameterEffect | None = None, applicable: bool = True,
    alpha: float = VALIDATION_ALPHA,
) -> CorrelationTest:
    """One test of ``corr(e(t), x(t - shift - tau))``: the correlation for plots (lags
    ``tau`` at which ``counted(tau)`` is true are counted) and the portmanteau statistic over
    the counted lags."""
    lags, r = xcorr(e, x, max_lag)
    if shift:  # lags from ``shift`` on, renumbered from 0
        lags, r = lags[lags >= shift] - shift, r[lags >= shift]
    counted = np.asarray(counted(lags), dtype=bool)
    n = e.size
    bound = correlation_bound(n)
    n_out = int(np.count_nonzero(np.abs(r[counted]) > bound))
    stat = portmanteau(e, x, lags[counted] + shift, effect)
    return CorrelationTest(
        name=name, description=description, lags=lags, values=r, counted=counted,
        n_samples=int(n), bound=bound, n_outside=n_out, n_lags=int(counted.sum()),
        statistic=stat.statistic, dof=stat.dof, p_value=stat.p_value, alpha=alpha,
        applicable=bool(applicable and stat.dof > 0),
        parameters=describe(effect),
    )  # fmt: skip


def _every(lags: np.ndarray) -> np.ndarray:
    return np.ones(lags.size, dtype=bool)


def judged(
    tests: Sequence[CorrelationTest], alpha: float = VALIDATION_ALPHA
) -> list[CorrelationTest]:
    """A battery of tests judged together at the family-wise level ``alpha``.

    Holm's correction (:func:`flexid.validation.portmanteau.holm`) over the applicable tests: the
    battery rejects a valid model in at most ``alpha`` of records, whatever the tests'
    dependence.

    Parameters
    ----------
    tests : sequence of CorrelationTest
        The tests, each with its own p-value.
    alpha : float
        Family-wise level, in (0, 1).

    Returns
    -------
    list of CorrelationTest
        Copies with ``adjusted_p`` and ``alpha`` set (an inapplicable test keeps its own
        p-value and passes).
    """
    alpha = check_level(alpha)
    live = [i for i, t in enumerate(tests) if t.applicable]
    adjusted = dict(zip(live, holm([tests[i].p_value for i in live]), strict=True))
    return [
        replace(t, adjusted_p=float(adjusted.get(i, t.p_value)), alpha=alpha)
        for i, t in enumerate(tests)
    ]


def check_level(alpha: Any, error: type[FlexidError] = DataError) -> float:
    """A family-wise level, checked: a number in (0, 1).

    Parameters
    ----------
    alpha : object
        The level given.
    error : type of FlexidError
        The exception raised otherwise.

    Returns
    -------
    float
        The level.
    """
    return level(alpha, "alpha (the validation level)", error=error)


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


def _residual_and_inputs(
    e: Any, u: Any, max_lag: Any, input_names: Sequence[str] | None
) -> tuple[np.ndarray, np.ndarray, int, list[str]]:
    """The checked arguments of the tests of a residual against the inputs: the residual
    (N,), the inputs (N, n_u), the largest lag and the input names."""
    e = _vector(e, "residual e")
    max_lag = _check_max_lag(max_lag, e.size, "residual")
    u = _inputs_2d(u, e.size)
    return e, u, max_lag, _input_names(input_names, u.shape[1])


def residual_tests(
    e: Any, u: Any, max_lag: int = CORRELATION_LAGS, input_names: Sequence[str] | None = None,
    *, effect: ParameterEffect | None = None, alpha: float = VALIDATION_ALPHA,
) -> list[CorrelationTest]:
    """Whiteness and independence tests of a residual (MATLAB ``resid``, as portmanteau tests).

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
    effect : ParameterEffect, optional
        How the model's estimated parameters enter the statistics
        (:mod:`flexid.validation.portmanteau`); default: taken as known.
    alpha : float, optional
        Level of each test's own verdict (a report judges its battery with Holm's
        correction instead).

    Returns
    -------
    list of CorrelationTest
        ``auto e`` (lags ``-L..L`` stored, ``1..L`` tested) and one ``cross <input>-e`` per
        input (``corr(e(t), u(t - tau))``, lags ``-L..L`` all tested).
    """
    e, u, max_lag, names = _residual_and_inputs(e, u, max_lag, input_names)
    tests = [
        _test("auto e", "phi_ee(tau) = corr(e(t), e(t-tau))", e, e, max_lag,
              lambda lags: lags > 0, effect=effect, alpha=alpha)
    ]  # fmt: skip
    for j, name in enumerate(names):
        tests.append(_test(
            f"cross {name}-e", f"phi_ue(tau) = corr(e(t), {name}(t-tau))", e, u[:, j], max_lag,
            _every, effect=effect, alpha=alpha))  # fmt: skip
    return tests


def output_cross_tests(
    e: Any, max_lag: int = CORRELATION_LAGS, output_names: Sequence[str] | None = None,
    *, alpha: float = VALIDATION_ALPHA,
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
    alpha : float, optional
        Level of each test's own verdict.

    Returns
    -------
    list of CorrelationTest
        One ``cross <i>-<j>`` per pair ``i < j`` (lags ``-L..L`` stored, every lag but 0
        tested).

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
            tests.append(_test(
                f"cross {names[i]}-{names[j]}",
                f"corr(e_{names[i]}(t), e_{names[j]}(t-tau)), tau != 0",
                _vector(e[:, i], names[i]), _vector(e[:, j], names[j]), max_lag,
                lambda lags: lags != 0, alpha=alpha))  # fmt: skip
    return tests


def billings_voon_tests(
    e: Any, u: Any, max_lag: int = CORRELATION_LAGS, input_names: Sequence[str] | None = None,
    *, effect: ParameterEffect | None = None, alpha: float = VALIDATION_ALPHA,
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
    effect : ParameterEffect, optional
        How the estimated parameters enter the statistics of the two tests linear in ``e``
        (the estimate moves ``e^2`` only to second order).
    alpha : float, optional
        Level of each test's own verdict.

    Returns
    -------
    list of CorrelationTest
        Per input: ``BV e(eu)``, ``corr(e(t), e(t-1-tau) u(t-1-tau))`` for ``tau = 0..L-1``
        (stored at lags ``tau``); ``BV u2'-e``, ``corr(u^2'(t-tau), e(t))`` for
        ``tau = -L..L``; ``BV u2'-e2'``, ``corr(u^2'(t-tau), e^2'(t))`` for ``tau = -L..L``.
    """
    e, u, max_lag, names = _residual_and_inputs(e, u, max_lag, input_names)
    e2 = e * e
    tests = []
    for j, name in enumerate(names):
        uj = u[:, j]
        tests.append(_test(
            f"BV e({name}e)" if len(names) > 1 else "BV e(eu)",
            f"corr(e(t), e(t-1-tau) {name}(t-1-tau)), tau = 0..{max_lag - 1}",
            e, e * uj, max_lag, _every, shift=1, effect=effect, alpha=alpha))  # fmt: skip
        u2 = uj * uj  # the tests remove the mean: u^2' = u^2 - mean(u^2)
        u2_varies = bool(np.ptp(u2) > 1e-12 * max(float(np.max(np.abs(u2))), 1e-300))
        # an input of two levels a, b (a PRBS with an offset) has u^2 = (a + b) u - a b, an
        # affine function of u: corr(u^2', e) then repeats the input cross-correlation test
        levels = np.unique(uj).size
        tests.append(_test(
            f"BV {name}2'-e", f"corr({name}^2'(t-tau), e(t)), tau = -{max_lag}..{max_lag}",
            e, u2, max_lag, _every, effect=effect, applicable=u2_varies and levels > 2,
            alpha=alpha))  # fmt: skip
        tests.append(_test(
            f"BV {name}2'-e2'", f"corr({name}^2'(t-tau), e^2'(t)), tau = -{max_lag}..{max_lag}",
            e2, u2, max_lag, _every, applicable=u2_varies, alpha=alpha))  # fmt: skip
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
