"""Model validation: a model on a record, its fits, residual tests, spectra and stability.

:func:`validate` runs the diagnostics of :mod:`flexid.validation.diagnostics` (fits, the correlation
tests, spectra) on a model's predictions over a record, adds its stability
(:func:`stability_report`) and returns a :class:`ValidationReport`.

Notes
-----
Initial conditions
    A predictor with an internal state (every simulation; the one-step predictor of a
    structure with a noise filter ``C`` or an ``F``) needs its state at ``t = start``; the
    rule (:data:`INITIAL_RULES`, shared with :mod:`flexid.models.polynomial`) is ``"estimate"`` (the
    state fitted by least squares to the measured output over ``t >= start``, MATLAB
    ``compare``'s default and :func:`validate`'s), ``"zero"`` (the model run from rest over
    the whole record) or ``"measured"`` (the recursion started from the measured outputs
    before ``start``).  Starting a lightly damped model from measured outputs excites a
    transient that is the mismatch between those outputs and the model's state, not the
    model's response, so ``"measured"`` can score tens of percent below ``"estimate"``; the
    report names the rule beside each fit.  The ARX one-step predictor is a finite filter of
    measured data: it has no state and no rule.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from .._json import jsonable
from .._table import LINE_WIDTH, wrapped
from .._validate import checked_keywords, positive_real
from ..data.records import IOData
from ..errors import DataError, check_finite
from ..models.families import family_of
from ..models.polynomial import INITIAL_RULES, _check_initial
from ..models.stability import stability_words
from ..models.vocabulary import CORRELATION_LAGS, VALIDATION_ALPHA, VALIDATION_GUIDE
from .diagnostics import (
    CorrelationTest,
    _p_text,
    _peak,
    billings_voon_tests,
    check_level,
    error_range,
    fit_percent,
    format_fit,
    judged,
    output_cross_tests,
    psd,
    residual_tests,
    rmse,
)
from .frequency import FrequencyAgreement, FrequencyResponseEstimate, frequency_agreement, frf
from .portmanteau import KNOWN, ParameterEffect, describe

__all__ = [
    "INITIAL_RULES",
    "StabilityReport",
    "ValidationReport",
    "between_outputs",
    "joint_tests",
    "joint_verdict",
    "residual_report",
    "stability_report",
    "validate",
]

# ============================================================================ stability
@dataclass
class StabilityReport:
    """Poles and zeros of a discrete-time model, with their continuous-time reading.

    Each pole ``z`` is mapped to ``s = log(z) / dt`` (``z = exp(s dt)``); the natural
    frequency is ``|s| / (2 pi)`` in Hz and the damping ratio ``-Re(s) / |s|``.  A pole at
    the origin has no continuous counterpart: frequency ``inf`` and damping 1.

    Attributes
    ----------
    dt : float
        Sample time in seconds.
    poles : ndarray of complex, shape (na,)
    radius : ndarray, shape (na,)
        ``|z|`` of each pole.
    damping : ndarray, shape (na,)
        Damping ratio of each pole.
    natural_frequency : ndarray, shape (na,)
        Natural frequency of each pole in Hz.
    stable : bool
        All poles strictly inside the unit circle.
    max_pole_radius : float
    zeros : list of ndarray of complex
        Zeros of each input's transfer function.
    non_minimum_phase : bool
        Some zero lies outside the unit circle.
    predictor_stable : bool or None
        Polynomial models: the one-step predictor is stable, i.e. ``C`` (minimum phase noise
        model) and every ``F`` have their roots inside the unit circle.  None when not
        recorded (an ARX model, whose one-step predictor is a finite filter and always
        stable).
    """

    dt: float
    poles: np.ndarray
    radius: np.ndarray
    damping: np.ndarray
    natural_frequency: np.ndarray
    stable: bool
    max_pole_radius: float
    zeros: list = field(default_factory=list)
    non_minimum_phase: bool = False
    predictor_stable: bool | None = None

    @property
    def max_zero_radius(self) -> float:
        """Largest ``|z|`` over all zeros (0 without zeros)."""
        radii = [np.abs(z).max() for z in self.zeros if np.size(z)]
        return float(max(radii)) if radii else 0.0

    def table(self) -> str:
        """Pole table: value, radius, damping and frequency, sorted by frequency.

        Returns
        -------
        str
            One line per pole, with a header.
        """
        order = np.argsort(self.natural_frequency, kind="stable")
        lines = [f"{'pole':>26}  {'|z|':>8}  {'damping':>8}  {'f_n [Hz]':>10}"]
        for i in order:
            z = self.poles[i]
            lines.append(
                f"{z.real:>12.6f}{z.imag:+12.6f}j  {self.radius[i]:8.5f}  "
                f"{self.damping[i]:8.4f}  {self.natural_frequency[i]:10.4g}"
            )
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe plain types (complex numbers as ``[re, im]``, inf as ``None``).

        Returns
        -------
        dict
            The fields of the report.
        """
        return {
            "dt": float(self.dt),
            "stable": bool(self.stable),
            "max_pole_radius": float(self.max_pole_radius),
            "non_minimum_phase": bool(self.non_minimum_phase),
            "max_zero_radius": self.max_zero_radius,
            "predictor_stable": self.predictor_stable,
            "poles": [[float(z.real), float(z.imag)] for z in self.poles],
            "radius": [float(v) for v in self.radius],
            "damping": jsonable(self.damping),
            "natural_frequency": jsonable(self.natural_frequency),
            "zeros": [[[float(z.real), float(z.imag)] for z in zs] for zs in self.zeros],
        }


def stability_report(poles: Any, zeros: Any = (), dt: float = 1.0) -> StabilityReport:
    """Stability and modal reading of discrete-time poles and zeros.

    Parameters
    ----------
    poles : array_like of complex, shape (na,)
        Poles in the z-plane.
    zeros : array_like of complex, or sequence of such arrays
        Zeros (one array, or one array per input).
    dt : float
        Sample time in seconds.

    Returns
    -------
    StabilityReport
    """
    dt = positive_real(dt, "sample time dt", error=DataError, unit="s")
    p = np.atleast_1d(np.asarray(poles, dtype=complex))
    check_finite(p, "poles")
    if len(zeros) and np.ndim(zeros[0]) == 0:
        zero_list = [np.asarray(zeros, dtype=complex)]
    else:
        zero_list = [np.atleast_1d(np.asarray(z, dtype=complex)) for z in zeros]
    radius = np.abs(p)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.log(np.where(radius > 0, p, 1.0)) / dt
        wn = np.abs(s)
        damping = np.where(wn > 0, -s.real / np.where(wn > 0, wn, 1.0), 1.0)
    wn = np.where(radius > 0, wn, np.inf)
    damping = np.where(radius > 0, damping, 1.0)
    max_r = float(radius.max()) if radius.size else 0.0
    nmp = any(bool(np.any(np.abs(z) > 1.0)) for z in zero_list)
    return StabilityReport(
        dt=float(dt),
        poles=p,
        radius=radius,
        damping=damping,
        natural_frequency=wn / (2.0 * np.pi),
        stable=bool(max_r < 1.0),
        max_pole_radius=max_r,
        zeros=zero_list,
        non_minimum_phase=nmp,
    )


# ============================================================================ report
#: The rule of a grey-box model's validation: its own initial state at the record's start.
GREYBOX_RULE = "model"
#: The same, with some of that state estimated (parameters ``<state>_0``).
GREYBOX_ESTIMATED_RULE = "model, estimated"


def _rule_text(initial: str, start: int) -> str:
    """An initial-condition rule in words (the measured rule says which samples it used)."""
    if initial in (GREYBOX_RULE, GREYBOX_ESTIMATED_RULE):
        run_on = f", run on through t < {start}" if start else ""
        what = "estimated initial state" if initial == GREYBOX_ESTIMATED_RULE else "initial state"
        return f"the model's {what} at t = 0{run_on}"
    text = INITIAL_RULES.get(initial, initial)
    return f"{text} before t = {start}" if initial == "measured" else text


@dataclass
class ValidationReport:
    """Everything :func:`validate` measured on one record (single output).

    Fits, RMSEs and error ranges are over the samples ``t >= start``: every sample
    (``start = 0``) under the rules ``"estimate"`` and ``"zero"``, as MATLAB ``compare``,
    from the model's first full regressor under ``"measured"``; ``initial`` states how the
    simulation's initial state was set and ``initial_one_step`` the one-step predictor's
    (:attr:`initial_rule` and :attr:`initial_rule_one_step` in words).  The correlation
    tests use the one-step residual from the model's first full regressor on, where the
    predictor uses measured data only.

    Attributes
    ----------
    n_samples : int
        Samples in the record.
    start : int
        First evaluated sample: 0, or ``model.structure.start`` under ``"measured"``.
    dt : float
        Sample time in seconds.
    initial : str
        Initial-condition rule of the simulation: ``"estimate"``, ``"zero"`` or
        ``"measured"`` (:data:`INITIAL_RULES`).
    fit_one_step, fit_simulation : float
        NRMSE fit in % of the one-step and simulation predictors.
    rmse_one_step, rmse_simulation : float
    error_range_one_step, error_range_simulation : tuple of float
        ``(min, max)`` of ``y - yhat``.
    max_lag : int
    correlation_tests : list of CorrelationTest
        ``auto e`` and one ``cross`` test per input.
    nonlinear_tests : list of CorrelationTest
        Billings-Voon tests, three per input.
    psd_frequency : ndarray, shape (F,)
        Frequencies in Hz.
    psd_measured, psd_model : ndarray, shape (F,)
        Welch PSD of the measured and simulated output over ``t >= start``.
    peak_measured, peak_model : float
        Frequency in Hz of the largest PSD peak above DC.
    stability : StabilityReport
    time, u, y, y_one_step, y_simulation : ndarray
        Signals over ``t >= start`` (``u`` is (N - start, n_u)).
    input_names : tuple of str
    output_name : str
    simulation_diverged : bool
        The free run of an unstable model overflowed (non-finite output or energy); then
        ``fit_simulation = -inf``, ``rmse_simulation = inf``, the simulation error range is
        ``(-inf, inf)`` and the model PSD is NaN.  This is reported, not raised, so that a
        comparison keeps the run.
    initial_one_step : str or None
        Initial-condition rule of the one-step predictor: ``initial`` when that predictor has
        a state, None when it is a finite filter of the measured signals (ARX under
        ``"measured"``) and no rule applies.
    output_unit : str
        The output's unit from the record (empty when the record gives none).
    frequency : FrequencyAgreement or None
        The share of the record's frequency-response estimate (over ``t >= start``) whose
        confidence band holds the model's response, where the coherence is at least
        :data:`~flexid.validation.frequency.COHERENCE_LEVEL`; None for a model without a frequency
        response (a grey-box model) or a record the estimate cannot be made from
        (:attr:`frequency_note` says why).
    frequency_estimate : FrequencyResponseEstimate or None
        That estimate (``tfestimate``) of this output.
    frequency_model : ndarray of complex, shape (F, n_u), or None
        The model's response from every input to this output at the estimate's frequencies.
    frequency_note : str
        Why there is no frequency verdict (empty when there is one).
    alpha : float
        Family-wise level of the verdict: the residual tests are judged together with
        Holm's correction (:func:`flexid.validation.diagnostics.judged`), so that a true model fails
        in at most ``alpha`` of records.
    parameters : str
        How the model's estimated parameters entered the tests' statistics, in words
        (:class:`~flexid.validation.portmanteau.ParameterEffect`).
    """

    n_samples: int
    start: int
    dt: float
    initial: str
    fit_one_step: float
    fit_simulation: float
    rmse_one_step: float
    rmse_simulation: float
    error_range_one_step: tuple[float, float]
    error_range_simulation: tuple[float, float]
    max_lag: int
    correlation_tests: list[CorrelationTest]
    nonlinear_tests: list[CorrelationTest]
    psd_frequency: np.ndarray
    psd_measured: np.ndarray
    psd_model: np.ndarray
    peak_measured: float
    peak_model: float
    stability: StabilityReport
    time: np.ndarray
    u: np.ndarray
    y: np.ndarray
    y_one_step: np.ndarray
    y_simulation: np.ndarray
    input_names: tuple = ()
    output_name: str = "y"
    simulation_diverged: bool = False
    initial_one_step: str | None = None
    output_unit: str = ""
    frequency: FrequencyAgreement | None = None
    frequency_estimate: FrequencyResponseEstimate | None = field(default=None, repr=False)
    frequency_model: np.ndarray | None = field(default=None, repr=False)
    frequency_note: str = ""
    alpha: float = VALIDATION_ALPHA
    parameters: str = KNOWN

    def __post_init__(self) -> None:
        tests = judged(self.all_tests, self.alpha)
        k = len(self.correlation_tests)
        self.correlation_tests, self.nonlinear_tests = tests[:k], tests[k:]

    def at_level(self, alpha: float) -> ValidationReport:
        """The same report judged at another family-wise level.

        Parameters
        ----------
        alpha : float
            The level, in (0, 1).

        Returns
        -------
        ValidationReport
            A copy whose tests' verdicts are at ``alpha``.
        """
        return replace(self, alpha=check_level(alpha))

    @property
    def failing(self) -> list[CorrelationTest]:
        """The tests rejected at :attr:`alpha`, most significant first."""
        return _failing(self.all_tests)

    def verdict(self) -> str:
        """The overall verdict in one line, with the level and, on a FAIL, the test that
        rejected most clearly and the others that did.

        Returns
        -------
        str
            ``"PASS at 5 % (Holm over 5 tests)"`` or ``"FAIL at 5 %: auto e (Holm p =
            2.1e-05, largest at lag +1); also cross u-e"`` (the most significant first).
        """
        return joint_verdict(self.all_tests)

    @property
    def initial_rule(self) -> str:
        """How the simulation's initial state was set, in words (from :data:`INITIAL_RULES`)."""
        return _rule_text(self.initial, self.start)

    @property
    def initial_rule_one_step(self) -> str:
        """How the one-step predictor's initial state was set, in words."""
        if self.initial_one_step is None:
            return "no initial state: a finite filter of the measured signals"
        return _rule_text(self.initial_one_step, self.start)

    @property
    def all_tests(self) -> list[CorrelationTest]:
        """Linear then nonlinear correlation tests."""
        return list(self.correlation_tests) + list(self.nonlinear_tests)

    @property
    def linear_passed(self) -> bool:
        """Autocorrelation and input cross-correlation tests all pass."""
        return all(t.passed for t in self.correlation_tests)

    @property
    def nonlinear_passed(self) -> bool:
        """All Billings-Voon tests pass."""
        return all(t.passed for t in self.nonlinear_tests)

    @property
    def passed(self) -> bool:
        """The verdict at :attr:`alpha`: no residual test (linear or Billings-Voon) rejected
        after Holm's correction over them all."""
        return self.linear_passed and self.nonlinear_passed

    def test(self, name: str) -> CorrelationTest:
        """The correlation test called ``name``.

        Parameters
        ----------
        name : str
            A test name, e.g. ``"auto e"`` or ``"cross torque-e"`` (linear or nonlinear).

        Returns
        -------
        CorrelationTest
            The test.

        Raises
        ------
        KeyError
            If no test has that name (the message lists the known ones).
        """
        for t in self.all_tests:
            if t.name == name:
                return t
        known = ", ".join(t.name for t in self.all_tests)
        raise KeyError(f"no correlation test {name!r}; known: {known}")

    @property
    def residual(self) -> np.ndarray:
        """One-step residual ``y - y_one_step`` over ``t >= start``."""
        return self.y - self.y_one_step

    def arrays(self) -> dict[str, np.ndarray]:
        """Signals and spectra for plots (all over ``t >= start``).

        Returns
        -------
        dict of str to ndarray
            ``time`` (s), ``u`` (N - start, n_u), ``y``, ``y_one_step``, ``y_simulation``,
            ``residual_one_step``, ``error_simulation`` (each (N - start,), output units),
            ``psd_frequency`` (F,) in Hz, ``psd_measured`` and ``psd_model`` (F,).
        """
        return {
            "time": self.time,
            "u": self.u,
            "y": self.y,
            "y_one_step": self.y_one_step,
            "y_simulation": self.y_simulation,
            "residual_one_step": self.y - self.y_one_step,
            "error_simulation": self.y - self.y_simulation,
            "psd_frequency": self.psd_frequency,
            "psd_measured": self.psd_measured,
            "psd_model": self.psd_model,
        }

    def correlation_panels(self, nonlinear: bool = False) -> list[tuple]:
        """The correlation functions as panels for :func:`flexid.report.plots.plot_correlations`.

        Parameters
        ----------
        nonlinear : bool, optional
            Include the Billings-Voon tests after the linear ones (default False).

        Returns
        -------
        list of tuple
            ``(title, lags, values, bound)`` per test: title ``"name: description"``,
            ``lags`` (K,) in samples, ``values`` (K,) correlation coefficients and ``bound``
            the half-width of the 95 % band.
        """
        tests = self.all_tests if nonlinear else self.correlation_tests
        return [(f"{t.name}: {t.description}", t.lags, t.values, t.bound) for t in tests]

    def summary(self) -> str:
        """A readable multi-line report for a terminal.

        Returns
        -------
        str
            Fits (each with the initial-condition rule that scored it), error RMSEs and
            ranges, each correlation test's verdict, stability and spectral peaks.
        """
        rule = self.initial_rule
        n_eval = self.n_samples - self.start
        counted = "every sample" if self.start == 0 else (
            f"t >= {self.start} ({n_eval} samples)"
        )
        lines = [
            f"Validation on {self.n_samples} samples (dt = {self.dt:g} s); fit, RMSE and errors "
            f"over {counted}",
            "",
            "Fit (NRMSE %)",
            f"  one-step prediction    {format_fit(self.fit_one_step):>9} %   "
            f"[{self.initial_rule_one_step}]",
            f"  simulation (free run)  {format_fit(self.fit_simulation):>9} %   [{rule}]"
            + ("  DIVERGED: the unstable free run overflowed" if self.simulation_diverged else ""),
            *self._unstable_fit_lines(),
            "",
            f"Errors y - yhat [{self.output_unit or 'output units'}]",
            f"  {'':22} {'RMSE':>11} {'min':>11} {'max':>11}",
        ]
        for label, r, (lo, hi) in (
            ("one-step prediction", self.rmse_one_step, self.error_range_one_step),
            ("simulation", self.rmse_simulation, self.error_range_simulation),
        ):
            lines.append(f"  {label:22} {r:11.4g} {lo:11.4g} {hi:11.4g}")
        lines += [
            "",
            f"Residual tests on the one-step residual, lags up to {self.max_lag}",
            f"  {self.parameters}",
        ]
        width = max(len(t.name) for t in self.all_tests)
        lines.append(f"  {'test':{width}}  {'Q':>8} {'dof':>4} {'p':>9} {'Holm p':>9} "
                     f"{'outside 95 %':>13}  verdict")  # fmt: skip
        for t in self.all_tests:
            if not t.applicable:
                lines.append(f"  {t.name:{width}}  {t.verdict()}")
                continue
            lines.append(f"  {t.name:{width}}  {t.statistic:8.1f} {t.dof:4d} "
                         f"{_p_text(t.p_value):>9} {_p_text(t.adjusted_p):>9} "
                         f"{f'{t.n_outside} of {t.n_lags}':>13}  {t.word}")  # fmt: skip
        # an identification's summary shows the report indented by two more characters
        lines.append(wrapped(f"{'overall':{width}}  {self.verdict()}", indent="  ",
                             hang=" " * (width + 2), width=LINE_WIDTH - 2))  # fmt: skip
        if not self.passed:
            lines.append(f"  how to read a failure: {VALIDATION_GUIDE}")
        st = self.stability
        lines += [
            "",
            "Stability",
            f"  {stability_words(st.stable, st.max_pole_radius, 5)}",
            f"  zeros: largest radius {st.max_zero_radius:.5f}, "
            f"{'non-minimum phase' if st.non_minimum_phase else 'minimum phase'}",
        ]
        if st.predictor_stable is True:
            lines.append("  one-step predictor: stable (C and every F inside the unit circle)")
        elif st.predictor_stable is False:
            lines.append("  one-step predictor: UNSTABLE (a root of C or of an F outside it)")
        lines += ["  " + row for row in st.table().splitlines()]
        lines += ["", *self._frequency_lines()]
        lines += [
            "",
            "Spectral peaks (Welch PSD, largest above DC)",
            f"  measured               {self.peak_measured:10.4g} Hz",
            f"  model (simulation)     {self.peak_model:10.4g} Hz",
        ]
        return "\n".join(lines)

    def _unstable_fit_lines(self) -> list[str]:
        """The line under the simulation fit of an unstable model: its free run grows without
        bound, so a fit from a fitted initial state holds over this record's length only."""
        st = self.stability
        if st.stable or self.simulation_diverged:
            return []
        n_eval = self.n_samples - self.start
        return [f"  ^ UNSTABLE model (pole radius {st.max_pole_radius:.4f}): its free run "
                f"diverges; fit over {n_eval} samples only"]  # fmt: skip

    @property
    def frequency_verdict(self) -> str:
        """The frequency verdict in a few characters for a table: ``"93 % of 40"`` (the share
        inside the band, of how many frequencies judged) or ``"-"`` (no verdict)."""
        agree = self.frequency
        if agree is None or int(agree.judged[0]) == 0:
            return "-"
        return f"{100 * float(agree.share[0]):.0f} % of {int(agree.judged[0])}"

    def _frequency_lines(self) -> list[str]:
        if self.frequency is None:
            return ["Frequency response", f"  no verdict: {self.frequency_note}"]
        agree, est = self.frequency, self.frequency_estimate
        head = (f"Frequency response (H1 {est.method}, {est.averages:.1f} equivalent averages, "
                f"bandwidth {est.bandwidth:.3g} Hz)")  # fmt: skip
        if int(agree.judged[0]) == 0:
            return [head, f"  no frequency with coherence >= {agree.coherence:g}: no verdict"]
        return [
            head,
            f"  inside the {100 * agree.level:.0f} % band at {self.frequency_verdict} "
            f"frequencies with coherence >= {agree.coherence:g} (a true model: about "
            f"{100 * agree.level:.0f} %)",
        ]

    def to_dict(self, arrays: bool = False) -> dict[str, Any]:
        """The report in JSON-safe plain types.

        Parameters
        ----------
        arrays : bool, optional
            Also include the signals and spectra (:meth:`arrays`, as ``"arrays"``) and each
            test's correlation function (default False).

        Returns
        -------
        dict
            The scalar results, the initial-condition rules (``initial``, ``initial_rule`` and
            the one-step predictor's ``initial_one_step``, ``initial_rule_one_step``), the
            pass flags, the tests (``CorrelationTest.to_dict``), ``stability`` and the channel
            names; non-finite simulation results are None.
        """
        out: dict[str, Any] = {
            "n_samples": int(self.n_samples),
            "start": int(self.start),
            "dt": float(self.dt),
            "initial": self.initial,
            "initial_rule": self.initial_rule,
            "initial_one_step": self.initial_one_step,
            "initial_rule_one_step": self.initial_rule_one_step,
            "fit_one_step": float(self.fit_one_step),
            "fit_simulation": jsonable(self.fit_simulation),
            "rmse_one_step": float(self.rmse_one_step),
            "rmse_simulation": jsonable(self.rmse_simulation),
            "error_range_one_step": [float(v) for v in self.error_range_one_step],
            "error_range_simulation": jsonable(self.error_range_simulation),
            "simulation_diverged": bool(self.simulation_diverged),
            "max_lag": int(self.max_lag),
            "alpha": float(self.alpha),
            "parameters": self.parameters,
            "passed": bool(self.passed),
            "linear_passed": bool(self.linear_passed),
            "nonlinear_passed": bool(self.nonlinear_passed),
            "correlation_tests": [t.to_dict(arrays) for t in self.correlation_tests],
            "nonlinear_tests": [t.to_dict(arrays) for t in self.nonlinear_tests],
            "peak_measured": float(self.peak_measured),
            "peak_model": jsonable(self.peak_model),
            "stability": self.stability.to_dict(),
            "input_names": [str(n) for n in self.input_names],
            "output_name": str(self.output_name),
            "output_unit": self.output_unit,
            "frequency": None if self.frequency is None else self.frequency.to_dict(),
            "frequency_note": self.frequency_note,
        }
        if arrays:
            out["arrays"] = jsonable(self.arrays())
        return out


def between_outputs(reports: Any) -> list[CorrelationTest]:
    """The tests between the residuals of a multi-output model's outputs
    (:func:`~flexid.validation.diagnostics.output_cross_tests`), at the reports' lags and level.

    Parameters
    ----------
    reports : sequence of ValidationReport
        One report per output, on the same record.

    Returns
    -------
    list of CorrelationTest
        One per pair of outputs.
    """
    reports = list(reports)
    residuals = np.column_stack([r.residual for r in reports])
    names = [r.output_name for r in reports]
    return output_cross_tests(residuals, reports[0].max_lag, names, alpha=reports[0].alpha)


def joint_tests(
    reports: Any, between: Any = (), alpha: float | None = None
) -> list[CorrelationTest]:
    """The residual tests of a multi-output model's outputs, judged together.

    Every output's tests and the tests between outputs' residuals
    (:func:`~flexid.validation.diagnostics.output_cross_tests`) as one battery under Holm's
    correction,
    so that a true model fails the joint verdict in at most ``alpha`` of records however many
    outputs it has.

    Parameters
    ----------
    reports : sequence of ValidationReport
        One report per output, on the same record.
    between : sequence of CorrelationTest, optional
        The tests between the outputs' residuals.
    alpha : float, optional
        Family-wise level; default the first report's.

    Returns
    -------
    list of CorrelationTest
        Copies named ``"<output>: <test>"`` (the between tests keep their names), judged;
        the joint verdict passes when every one does.
    """
    reports = list(reports)
    level = reports[0].alpha if alpha is None else alpha
    named = [replace(t, name=f"{r.output_name}: {t.name}") for r in reports for t in r.all_tests]
    return judged(named + list(between), level)


def _failing(tests: Any) -> list[CorrelationTest]:
    return sorted((t for t in tests if not t.passed), key=lambda t: t.adjusted_p)


def joint_verdict(tests: Any) -> str:
    """The joint verdict of :func:`joint_tests` in one line, as
    :meth:`ValidationReport.verdict` words one report's.

    Parameters
    ----------
    tests : sequence of CorrelationTest
        Judged tests.

    Returns
    -------
    str
        ``"PASS at 5 % (Holm over 12 tests)"`` or ``"FAIL at 5 %: <test> (...)"``.
    """
    tests = list(tests)
    level = f"{100 * tests[0].alpha:g} %"
    failing = _failing(tests)
    if not failing:
        return f"PASS at {level} (Holm over {sum(t.applicable for t in tests)} tests)"
    first, *others = failing
    names = [t.name for t in others[:3]] + ([f"{len(others) - 3} more"] if len(others) > 3 else [])
    also = f"; also {', '.join(names)}" if names else ""
    return (f"FAIL at {level}: {first.name} (Holm p {_p_text(first.adjusted_p, '= ')}, "
            f"largest at lag {first.worst_lag:+d}){also}")  # fmt: skip


# ============================================================================ entry point
def residual_report(
    y_full: np.ndarray, y1_full: np.ndarray | None, ysim_full: np.ndarray, u_full: np.ndarray,
    *, start: int, dt: float, max_lag: int, names: list[str], output_name: str, initial: str,
    initial_one_step: str | None, poles: Any, zeros: Any, predictor_stable: bool | None = None,
    test_start: int | None = None, output_unit: str = "",
    response: Callable[[np.ndarray], np.ndarray] | None = None, input_units: Any = (),
    effect: ParameterEffect | None = None,
) -> ValidationReport:
    """The validation report of a model from its outputs over a record.

    What every family's :meth:`~flexid.models.families.Family.validate` ends with: fits, error
    ranges, the correlation and Billings-Voon tests, spectra and the stability table, all
    scored over ``t >= start``.

    Parameters
    ----------
    y_full : ndarray, shape (K,)
        The measured output.
    y1_full : ndarray, shape (K,), or None
        The model's one-step prediction; None for an output-error model, whose one-step
        prediction is its simulation (a simulation that overflowed then leaves the
        correlation tests a zero residual).
    ysim_full : ndarray, shape (K,)
        The model's simulated output.
    u_full : ndarray, shape (K, n_u)
        The inputs.
    start : int
        First sample scored.
    dt : float
        Sample time (s).
    max_lag : int
        Lags of the correlation tests.
    names : list of str
        The inputs' names.
    output_name : str
        The output's name.
    initial, initial_one_step : str or None
        The initial-condition rules of the simulation and the prediction, as the report
        states them.
    poles : array_like
        The model's discrete-time poles.
    zeros : sequence of array_like
        Its zeros, one array per input.
    predictor_stable : bool, optional
        Whether its one-step predictor is stable (None: not applicable).
    test_start : int, optional
        First sample of the correlation tests' residual (default ``start``).
    output_unit : str, optional
        The output's unit.
    response : callable, optional
        ``response(frequencies) -> (F, n_u)``: the model's frequency response from every
        input to this output at frequencies in Hz, for the frequency-domain verdict (None: a
        model without one).
    input_units : sequence of str, optional
        The inputs' units (for the frequency response's).
    effect : ParameterEffect, optional
        How the model's estimated parameters enter the residual tests, with the gradient's
        rows over the tested samples (default: the parameters taken as known).

    Returns
    -------
    ValidationReport
    """
    n = y_full.size
    seg = slice(start, n)
    y, ysim, u = y_full[seg], ysim_full[seg], u_full[seg]
    with np.errstate(over="ignore", invalid="ignore"):
        diverged = not bool(np.all(np.isfinite(ysim)) and np.isfinite(np.sum(ysim * ysim)))
    if y1_full is None:
        y1 = ysim
        e = np.zeros_like(y) if diverged else y - ysim
    else:
        y1 = y1_full[seg]
        e = y - y1
    skip = 0 if test_start is None else max(test_start - start, 0)
    tests = residual_tests(e[skip:], u[skip:], max_lag, names, effect=effect)
    nonlinear = billings_voon_tests(e[skip:], u[skip:], max_lag, names, effect=effect)
    f, p_meas = psd(y, dt)
    if diverged:  # an unstable model's free run overflowed: a result to report, not an error
        p_model = np.full_like(p_meas, np.nan)
        sim_numbers = (-np.inf, np.inf, (-np.inf, np.inf))
    else:
        p_model = psd(ysim, dt)[1]
        sim_numbers = (fit_percent(y, ysim), rmse(y, ysim), error_range(y, ysim))
    one_numbers = (
        sim_numbers if y1_full is None else (fit_percent(y, y1), rmse(y, y1), error_range(y, y1))
    )
    stability = stability_report(np.asarray(poles), zeros, dt)
    stability.predictor_stable = predictor_stable
    frequency = _frequency_verdict(u, y, dt, response, names, output_name, input_units,
                                   output_unit)  # fmt: skip
    return ValidationReport(
        n_samples=n,
        start=start,
        dt=dt,
        initial=initial,
        fit_one_step=one_numbers[0],
        fit_simulation=sim_numbers[0],
        rmse_one_step=one_numbers[1],
        rmse_simulation=sim_numbers[1],
        error_range_one_step=one_numbers[2],
        error_range_simulation=sim_numbers[2],
        max_lag=max_lag,
        correlation_tests=tests,
        nonlinear_tests=nonlinear,
        psd_frequency=f,
        psd_measured=p_meas,
        psd_model=p_model,
        peak_measured=_peak(f, p_meas),
        peak_model=float("nan") if diverged else _peak(f, p_model),
        stability=stability,
        time=np.arange(start, n) * dt,
        u=u,
        y=y,
        y_one_step=y1,
        y_simulation=ysim,
        input_names=tuple(names),
        output_name=output_name,
        simulation_diverged=diverged,
        initial_one_step=initial_one_step,
        output_unit=output_unit,
        parameters=describe(effect),
        **frequency,
    )


def _frequency_verdict(
    u: np.ndarray, y: np.ndarray, dt: float, response: Callable | None, names: list[str],
    output_name: str, input_units: Any, output_unit: str,
) -> dict[str, Any]:
    """The report's frequency-domain fields: the record's estimate and the model's share
    inside its band, or why there is none."""
    if response is None:
        return {"frequency_note": "the model has no frequency response (not linear)"}
    units = {"input_units": list(input_units)} if len(input_units) else {}
    record = IOData(u, y, dt=dt, input_names=names, output_names=[output_name],
                    output_units=[output_unit], **units)  # fmt: skip
    try:
        estimate = frf(record)
    except DataError as exc:  # a short record or a constant input: no verdict, said why
        return {"frequency_note": str(exc)}
    g = np.asarray(response(estimate.frequency), dtype=complex).reshape(
        estimate.frequency.size, 1, -1)  # fmt: skip
    return {
        "frequency": frequency_agreement(estimate, g),
        "frequency_estimate": estimate,
        "frequency_model": g[:, 0, :],
    }


@checked_keywords
def validate(
    model: Any,
    data: Any,
    *,
    max_lag: int = CORRELATION_LAGS,
    initial: str = "estimate",
    split: float | int | None = None,
    dt: float | None = None,
    output: str | None = None,
    alpha: float = VALIDATION_ALPHA,
    estimated_on: Any = None,
) -> ValidationReport:
    """Validate a model on a record: fits, errors, correlation tests, PSD, stability.

    Parameters
    ----------
    model : PolynomialModel, GreyBoxModel or ARX-like
        A :class:`~flexid.models.polynomial.PolynomialModel` (ARX, ARMAX, OE, BJ), a single-output
        :class:`~flexid.models.greybox.GreyBoxModel` at its parameters' values (an output-error
        model: its one-step prediction is its simulation, run from its own initial state at
        the record's start and, with ``split``, on through the estimation part, whatever
        ``initial`` says; the report names that rule, and its poles are those of the model
        linearised at its initial state), or an
        :class:`~flexid.models.arx.ARX` or a model duck-typed to it (``structure.start``,
        ``predict(u, y)``, ``simulate(u, y_init=None)``, ``poles()``, ``zeros(input=i)``,
        optionally ``dt``; for ``initial="estimate"`` also ``to_polynomial()``, or ``a``,
        ``b`` and ``structure.na``/``nb``/``nk``).
    data : IOData or (u, y)
        Single-output record; ``u`` shape (N,) or (N, n_u), ``y`` shape (N,) or (N, 1).
    max_lag : int
        Largest lag ``L`` of the correlation tests; the evaluated part (``t >= start``)
        needs at least ``2 L + 2`` samples.
    initial : {"estimate", "zero", "measured"}
        Initial-condition rule (:data:`INITIAL_RULES`) of the simulation, and of the
        one-step predictor when it has a state (a polynomial model with ``C`` or ``F``):
        the initial state at ``t = 0`` fitted by least squares to the measured output
        (default, as MATLAB ``compare``), the model run from rest over the whole record (in
        both, every sample counts, as in MATLAB), or the recursion started from the measured
        outputs before ``start`` (counted from ``start``).  The first two run in a
        well-conditioned realisation (:mod:`flexid.models.realisation`); an ARX model runs
        its polynomial form, except :meth:`ARX.simulate <flexid.models.arx.ARX.simulate>`
        under ``"measured"``.  The correlation tests always use the one-step residual over
        ``t >= start``, where the predictor uses measured data only.
    split : float or int, optional
        Validate on the *second* part of ``data.split(split)`` only (a fraction in (0, 1) or
        a sample index); default: the whole record.
    dt : float, optional
        Sample time in seconds for a ``(u, y)`` pair; default ``model.dt``, else 1.
    output : str, optional
        For a grey-box model with several outputs, the one to validate (all are simulated
        together; the report is of this one).  Other models have one output.
    alpha : float, optional
        Family-wise level of the verdict (default :data:`~flexid.config.VALIDATION_ALPHA`,
        5 %): a true model fails in at most ``alpha`` of records.
    estimated_on : IOData, sequence of IOData or "same", optional
        The record(s) the model's parameters were estimated on: ``"same"`` when that is
        ``data``, whose residual the estimate made orthogonal to its gradient (the tests
        partial that out), or records held out from ``data``, whose estimation error adds to
        the residual (the tests add its covariance); see :mod:`flexid.validation.portmanteau`.
        Default: the parameters taken as known, as for a model not estimated from data.
        The polynomial, state-space and grey-box families account for it (a state-space or
        grey-box model of several outputs on its held-out records only); a model they cannot
        differentiate (a state-space model given by its matrices) takes its parameters as
        known, and its report says so.

    Returns
    -------
    ValidationReport
        With the rule of each fit in ``initial`` and ``initial_one_step``.

    Raises
    ------
    DataError
        NaN/inf, length mismatch, several outputs, a record too short for ``max_lag``, a
        model output that is not finite (a one-step predictor that overflowed; an
        overflowing simulation is reported as ``simulation_diverged`` instead).
    UnknownNameError
        An unknown ``initial`` rule (the message lists the valid ones); the error is also a
        DataError.
    ModelOrderError
        If the record does not reach past the model's ``start`` sample, or the model's
        input count does not match the data.
    """
    initial = _check_initial(initial)
    alpha = check_level(alpha)
    family = family_of(model, default="polynomial")
    extra = {} if estimated_on is None else {"estimated_on": estimated_on}
    report = family.validate(
        model, data, max_lag=max_lag, initial=initial, split=split, dt=dt, output=output, **extra
    )
    return report if alpha == report.alpha else report.at_level(alpha)
