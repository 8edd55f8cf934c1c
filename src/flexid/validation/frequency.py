"""Frequency-response estimates of a record, with coherence and a confidence band.

Three non-parametric estimates of ``G(f)`` from a record of ``q`` inputs and ``p`` outputs
(Ljung 1999, ch. 6; Bendat & Piersol 2010, ch. 9), each the ratio of smoothed spectra,
``H(f) = S_yu(f) S_uu(f)^-1`` (``H1``), and each smoothing an average of ``n`` (equivalent)
independent spectra:

``"tfestimate"``
    Welch's averaged periodograms (MATLAB ``tfestimate``): Hann segments, 50 % overlap, the
    mean of each segment removed; by default 8 segments (a segment of ``N / 4.5``
    samples, MATLAB's default).  ``n`` is Welch's equivalent number of independent
    segments, ``K / (1 + 2 sum_j (1 - j/K) rho_j^2)``, ``rho_j`` the overlap correlation of
    the window ``j`` segments apart (Welch 1967).
``"spa"``
    Blackman-Tukey: the record's covariances to lag ``M``, a Hann lag window, Fourier
    transformed (MATLAB ``spa``, its default ``M = min(N / 10, 30)``, 128 frequencies);
    ``n = N / sum_tau w(tau)^2`` (Ljung Table 6.1).
``"etfe"``
    The empirical transfer function ``Y(f) / U(f)`` smoothed over ``width`` DFT bins with a
    Hann window, weighted by the input's periodogram (Ljung eq. 6.46; MATLAB ``etfe``);
    ``n = 1 / sum_k w_k^2`` for weights summing to one (default ``width = 11``: ``n = 8``).

The coherence of output ``j`` is its multiple coherence with the inputs,
``gamma_j^2 = S_yu S_uu^-1 S_uy / S_yy`` (the ordinary coherence for one input), and the
noise spectrum the part the inputs do not explain, ``S_nn = (1 - gamma^2) S_yy``.  The
confidence band of each element ``H_ji`` is a circle in the complex plane (Goodman 1965;
Bendat & Piersol eq. 9.63, 9.90): with probability ``level`` the true ``G_ji`` lies within

    r^2 = F(2, 2 (n - q); level) / (n - q) * S_nn,j * [S_uu^-1]_ii

of the estimate, for Gaussian noise and independent averages; the magnitude band is
``|H| -+ r`` and the phase band ``+- arcsin(r / |H|)``.  The spectra are smoothed, so a
resonance narrower than the smoothing (:attr:`FrequencyResponseEstimate.bandwidth`) is
flattened: the band holds where the true response varies little across the bandwidth.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import ndimage, signal, stats

from .._validate import checked_keywords, integer, real
from ..data.records import IOData, load
from ..errors import DataError, UnknownNameError
from ..models.modes import model_modes

__all__ = [
    "COHERENCE_LEVEL",
    "FREQUENCY_METHODS",
    "FrequencyAgreement",
    "FrequencyResponseEstimate",
    "ModeMatch",
    "frequency_agreement",
    "frf",
    "mode_table",
    "mode_table_text",
]

FREQUENCY_METHODS = ("tfestimate", "spa", "etfe")

# The frequencies a verdict judges: those the sensors trust, where the inputs explain at least
# 90 % of an output's power (the level of the technical notes and Bendat & Piersol's rule of
# thumb for a usable estimate).
COHERENCE_LEVEL = 0.9

_WELCH_SEGMENTS = 4.5  # N / 4.5: 8 segments at 50 % overlap (MATLAB tfestimate, pwelch)
_SPA_FREQUENCIES = 128  # MATLAB spa's default grid
_ETFE_WIDTH = 11  # Hann over 11 bins: 8 equivalent averages, as the Welch default


@dataclass(frozen=True)
class FrequencyResponseEstimate:
    """A non-parametric frequency-response estimate with its coherence and band.

    Attributes
    ----------
    frequency : ndarray, shape (F,)
        Frequencies in Hz, above 0 and up to the Nyquist frequency ``1 / (2 dt)``.
    response : ndarray of complex, shape (F, ny, nu)
        ``H(f)``, output ``j`` per unit of input ``i`` at ``response[:, j, i]``.
    coherence : ndarray, shape (F, ny)
        Each output's multiple coherence with the inputs, in [0, 1].
    radius : ndarray, shape (F, ny, nu)
        Radius of each element's confidence circle at :attr:`level` (units of ``H``).
    averages : float
        The equivalent number ``n`` of independent averages of the smoothing.
    bandwidth : float
        The smoothing's equivalent bandwidth in Hz, ``n / T`` for a record of ``T`` seconds
        (the resolution: resonances closer than this merge).
    method : str
        ``"tfestimate"``, ``"spa"`` or ``"etfe"``.
    level : float
        Confidence level of :attr:`radius`.
    dt : float
        Sample time in seconds.
    input_names, output_names, input_units, output_units : tuple of str
        The record's channels.
    settings : dict
        The smoothing: ``segment`` and ``overlap`` (samples), ``lag_width`` or ``width``.
    """

    frequency: np.ndarray
    response: np.ndarray
    coherence: np.ndarray
    radius: np.ndarray
    averages: float
    bandwidth: float
    method: str
    level: float
    dt: float
    input_names: tuple[str, ...]
    output_names: tuple[str, ...]
    input_units: tuple[str, ...] = ()
    output_units: tuple[str, ...] = ()
    settings: dict = field(default_factory=dict)

    @property
    def n_inputs(self) -> int:
        """Number of inputs ``nu``."""
        return self.response.shape[2]

    @property
    def n_outputs(self) -> int:
        """Number of outputs ``ny``."""
        return self.response.shape[1]

    def magnitude_db(self) -> np.ndarray:
        """The magnitude in dB.

        Returns
        -------
        ndarray, shape (F, ny, nu)
            ``20 log10 |H|`` (``-inf`` where ``H = 0``).
        """
        with np.errstate(divide="ignore"):
            return 20.0 * np.log10(np.abs(self.response))

    def phase_deg(self) -> np.ndarray:
        """The phase in degrees.

        Returns
        -------
        ndarray, shape (F, ny, nu)
            The phase of ``H``, unwrapped along frequency.
        """
        return np.degrees(np.unwrap(np.angle(self.response), axis=0))

    def band(self) -> tuple[np.ndarray, np.ndarray]:
        """The magnitude band ``|H| -+ r`` (lower end at least 0).

        Returns
        -------
        lower, upper : ndarray, shape (F, ny, nu)
            Magnitudes in the units of ``H``.
        """
        mag = np.abs(self.response)
        return np.maximum(mag - self.radius, 0.0), mag + self.radius

    def phase_band(self) -> np.ndarray:
        """Half-width of the phase band, ``arcsin(r / |H|)`` in degrees (180 where ``r >= |H|``).

        Returns
        -------
        ndarray, shape (F, ny, nu)
        """
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = self.radius / np.abs(self.response)
        return np.where(ratio < 1.0, np.degrees(np.arcsin(np.minimum(ratio, 1.0))), 180.0)

    def inside(self, response: Any) -> np.ndarray:
        """Whether a response lies inside each element's confidence circle.

        Parameters
        ----------
        response : array_like of complex, shape (F, ny, nu)
            Another response at :attr:`frequency` (a model's, a plant's).

        Returns
        -------
        ndarray of bool, shape (F, ny, nu)
            ``|response - H| <= r``.
        """
        g = np.asarray(response, dtype=complex)
        if g.shape != self.response.shape:
            raise DataError(
                f"a response to compare needs shape {self.response.shape}, got {g.shape}"
            )
        return np.abs(g - self.response) <= self.radius

    def peaks(self, *, prominence: float = 6.0) -> np.ndarray:
        """Frequencies of the resonance peaks of the estimate that its band confirms.

        A peak is a local maximum of the response's amplitude over every input-output pair,
        ``A = sqrt(sum |H_ji|^2)``, that stands ``prominence`` dB above its contour line
        (:func:`scipy.signal.find_peaks`), and stands there beyond doubt: the peak's lower
        band edge ``A - R`` lies above the higher base's upper edge ``A + R``
        (``R = sqrt(sum r_ji^2)``), so noise in a poorly excited band makes no peak.  A
        resonance narrower than :attr:`bandwidth` is flattened by the smoothing (its
        coherence drops): it is found only with a finer resolution.

        Parameters
        ----------
        prominence : float, optional
            Least prominence in dB (default 6: twice the amplitude).

        Returns
        -------
        ndarray, shape (k,)
            Peak frequencies in Hz, increasing.
        """
        amplitude = np.sqrt(np.sum(np.abs(self.response) ** 2, axis=(1, 2)))
        spread = np.sqrt(np.sum(self.radius**2, axis=(1, 2)))
        db = 20.0 * np.log10(np.maximum(amplitude, np.finfo(float).tiny))
        found, props = signal.find_peaks(db, prominence=prominence)
        left, right = props["left_bases"], props["right_bases"]
        base = np.where(db[left] > db[right], left, right)
        sure = amplitude[found] - spread[found] > amplitude[base] + spread[base]
        return self.frequency[found[sure]]

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe form: the settings and, per frequency, the response, coherence and radius.

        Returns
        -------
        dict
        """
        return {
            "method": self.method,
            "level": self.level,
            "averages": self.averages,
            "bandwidth_hz": self.bandwidth,
            "dt": self.dt,
            "settings": dict(self.settings),
            "inputs": list(self.input_names),
            "outputs": list(self.output_names),
            "frequency_hz": self.frequency.tolist(),
            "response_real": self.response.real.tolist(),
            "response_imag": self.response.imag.tolist(),
            "coherence": self.coherence.tolist(),
            "radius": self.radius.tolist(),
        }

    def summary(self) -> str:
        """A few lines: the method, its smoothing and band, the coherence and the peaks.

        Returns
        -------
        str
        """
        lines = [
            f"frequency response ({self.method}): {self.frequency.size} frequencies, "
            f"{self.frequency[0]:.4g}..{self.frequency[-1]:.4g} Hz",
            f"  smoothing: {_settings_text(self.settings)}; {self.averages:.1f} equivalent "
            f"averages, bandwidth {self.bandwidth:.3g} Hz",
            f"  band: {100 * self.level:.0f} % confidence circle of each element",
        ]
        for j, name in enumerate(self.output_names):
            share = float(np.mean(self.coherence[:, j] >= COHERENCE_LEVEL))
            lines.append(
                f"  {name}: median coherence {np.median(self.coherence[:, j]):.3f}, "
                f"{100 * share:.0f} % of frequencies at {COHERENCE_LEVEL} or more"
            )
        peaks = self.peaks()
        lines.append(
            "  peaks [Hz]: " + (", ".join(f"{f:.4g}" for f in peaks) if peaks.size else "none")
        )
        return "\n".join(lines)


def _settings_text(settings: dict) -> str:
    return ", ".join(f"{k} {v}" for k, v in settings.items())


@dataclass(frozen=True)
class FrequencyAgreement:
    """How much of a model's frequency response lies inside a record's estimate band.

    Attributes
    ----------
    share : ndarray, shape (ny,)
        Per output, the share of the judged frequencies (over every input) at which the
        model's response lies inside the estimate's confidence circle; NaN where none is
        judged.
    judged : ndarray of int, shape (ny,)
        Per output, how many frequency-input pairs were judged: those where the output's
        coherence is at least :attr:`coherence`.
    coherence : float
        The coherence level.
    level : float
        The band's confidence level: a true model lies inside at about this share.
    method : str
        The estimate's method.
    """

    share: np.ndarray
    judged: np.ndarray
    coherence: float
    level: float
    method: str

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe form (a NaN share as None).

        Returns
        -------
        dict
        """
        return {
            "share": [None if not np.isfinite(s) else float(s) for s in self.share],
            "judged": [int(n) for n in self.judged],
            "coherence": self.coherence,
            "level": self.level,
            "method": self.method,
        }


@checked_keywords
def frequency_agreement(
    estimate: FrequencyResponseEstimate, model: Any, *, coherence: float = COHERENCE_LEVEL
) -> FrequencyAgreement:
    """The share of frequencies at which a model's response lies inside an estimate's band.

    Parameters
    ----------
    estimate : FrequencyResponseEstimate
        The record's estimate (:func:`frf`).
    model : object
        A model with ``frequency_response(frequencies) -> (F, ny, nu)`` (every linear
        flexid model), with the estimate's inputs and outputs; or that array itself.
    coherence : float, optional
        Judge only frequencies where the output's coherence is at least this (default
        :data:`COHERENCE_LEVEL`).

    Returns
    -------
    FrequencyAgreement
        A model equal to the plant lies inside at about the band's level (95 %) where the
        smoothing resolves the response; less means a mode missed, misplaced or mis-damped.
    """
    level = real(coherence, "coherence", error=DataError, minimum=0.0, maximum=1.0)
    g = model.frequency_response(estimate.frequency) if hasattr(
        model, "frequency_response") else model  # fmt: skip
    inside = estimate.inside(g)
    judged = estimate.coherence >= level  # (F, ny)
    counts = judged.sum(axis=0) * estimate.n_inputs
    hits = np.sum(inside & judged[:, :, None], axis=(0, 2))
    with np.errstate(invalid="ignore", divide="ignore"):
        share = np.where(counts > 0, hits / np.maximum(counts, 1), np.nan)
    return FrequencyAgreement(share, counts, level, estimate.level, estimate.method)


@checked_keywords
def frf(
    data: IOData | str | os.PathLike,
    method: str = "tfestimate",
    *,
    segment: int | None = None,
    overlap: float = 0.5,
    lag_width: int | None = None,
    width: int | None = None,
    resolution: float | None = None,
    frequencies: Any = None,
    level: float = 0.95,
) -> FrequencyResponseEstimate:
    """Estimate a record's frequency response with its coherence and confidence band.

    Parameters
    ----------
    data : IOData or path
        The record (``nu`` inputs, ``ny`` outputs); a path is read with
        :func:`flexid.data.load`.  Each channel's mean is removed.
    method : {"tfestimate", "spa", "etfe"}, optional
        The estimate (see the module's notes); default ``"tfestimate"`` (H1 from Welch's
        averaged cross-spectra).
    segment : int, optional
        ``"tfestimate"``: samples per segment (default ``N / 4.5``: 8 segments).
    overlap : float, optional
        ``"tfestimate"``: overlap of the segments, a fraction in [0, 1) (default 0.5).
    lag_width : int, optional
        ``"spa"``: width ``M`` of the Hann lag window in samples (default
        ``min(N / 10, 30)``, MATLAB's).
    width : int, optional
        ``"etfe"``: width of the Hann smoothing window in DFT bins, odd (default 11).
    resolution : float, optional
        The frequency resolution to aim at, in Hz, instead of ``segment``, ``lag_width`` or
        ``width``: a segment or lag window of ``1 / (resolution dt)`` samples, a smoothing
        over ``resolution N dt`` bins.
    frequencies : array_like, optional
        ``"spa"``: the frequencies in Hz (default 128, evenly to the Nyquist frequency).
    level : float, optional
        Confidence level of the band, in (0, 1) (default 0.95).

    Returns
    -------
    FrequencyResponseEstimate

    Raises
    ------
    DataError
        A constant input (nothing can be estimated from it), inputs that are linear
        combinations of each other, a segment or window longer than the record, a record too
        short for the resolution asked (fewer equivalent averages than inputs plus one),
        frequencies above the Nyquist frequency.
    UnknownNameError
        An unknown method.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy import signal
    >>> import flexid
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(8000)
    >>> y = signal.lfilter([0.0, 0.5], [1.0, -0.9], u) + 0.1 * rng.standard_normal(8000)
    >>> est = flexid.frf(flexid.IOData(u, y, dt=0.01))
    >>> est.response.shape[1:], bool(est.coherence.min() > 0.9)
    ((1, 1), True)
    """
    if method not in FREQUENCY_METHODS:
        raise UnknownNameError("frequency-response method", method, FREQUENCY_METHODS)
    if not isinstance(data, IOData):
        data = load(data)
    level = real(level, "level", error=DataError, minimum=0.0, maximum=1.0, low_open=True,
                 high_open=True)  # fmt: skip
    u, y = data.u, data.y
    n, q = u.shape
    _check_inputs(u, data.input_names)
    x = np.hstack([u, y])
    x = x - x.mean(axis=0)
    given = {k: v for k, v in (("segment", segment), ("lag_width", lag_width),
                               ("width", width)) if v is not None}  # fmt: skip
    if resolution is not None:
        if given:
            raise DataError(f"give resolution or {', '.join(given)}, not both")
        res = real(resolution, "resolution", error=DataError, minimum=0.0, low_open=True,
                   unit="Hz")  # fmt: skip
        if res > 0.5 / data.dt:
            raise DataError(
                f"a resolution of {res:g} Hz is above the Nyquist frequency {0.5 / data.dt:g} Hz"
            )
    else:
        res = None
    if method == "tfestimate":
        if res is not None:
            segment = math.ceil(1.0 / (res * data.dt))
        f, spectra, averages, settings = _welch(x, data.dt, segment, overlap)
    elif method == "spa":
        if res is not None:
            lag_width = math.ceil(1.0 / (res * data.dt))
        f, spectra, averages, settings = _blackman_tukey(x, data.dt, lag_width, frequencies)
    else:
        if res is not None:
            width = max(1, math.ceil(res * n * data.dt)) | 1
        f, spectra, averages, settings = _smoothed_etfe(x, data.dt, width)
    if averages <= q + 1:
        raise DataError(
            f"a record of {n} samples is too short for this resolution: {averages:.2f} "
            f"equivalent averages, at least {q + 1} needed with {q} input(s) (a longer "
            "record, a shorter segment or a wider smoothing)"
        )
    if method != "spa" and frequencies is not None:
        raise DataError(f"frequencies are chosen by method 'spa', not {method!r}")
    response, coherence, radius = _h1(spectra, q, averages, level, data.input_names)
    return FrequencyResponseEstimate(
        frequency=f, response=response, coherence=coherence, radius=radius,
        averages=float(averages), bandwidth=float(averages / (n * data.dt)), method=method,
        level=level, dt=data.dt, input_names=tuple(data.input_names),
        output_names=tuple(data.output_names), input_units=tuple(data.input_units),
        output_units=tuple(data.output_units), settings=settings,
    )  # fmt: skip


def _check_inputs(u: np.ndarray, names) -> None:
    for i, name in enumerate(names):
        column = u[:, i]
        if np.ptp(column) <= 1e-12 * max(1.0, float(np.max(np.abs(column)))):
            raise DataError(
                f"input {name!r} is constant: no frequency response can be estimated from it"
            )


def _h1(
    spectra: np.ndarray, q: int, averages: float, level: float, input_names
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``H = S_yu S_uu^-1``, multiple coherence and the confidence radius, per frequency.

    ``spectra`` (F, C, C) holds ``S[a, b] = E[X_a conj(X_b)]`` of the channels ``[u; y]``.
    """
    suu = spectra[:, :q, :q]
    syu = spectra[:, q:, :q]
    syy = spectra[:, q:, q:].diagonal(axis1=1, axis2=2).real  # (F, p)
    # a singular S_uu is inputs that are linear combinations of each other (at every
    # frequency) or an input with no power in a band: name the first frequency affected
    cond = np.linalg.cond(suu)
    if not np.all(np.isfinite(cond)) or cond.max() > 1e12:
        raise DataError(
            f"the inputs {list(input_names)} are (nearly) linear combinations of each other, "
            "or one has no power at some frequency: their responses cannot be told apart"
        )
    suu_inv = np.linalg.inv(suu)
    h = syu @ suu_inv  # (F, p, q)
    explained = np.einsum("fjq,fjq->fj", h, syu.conj()).real  # (S_yu S_uu^-1 S_uy)_jj
    with np.errstate(invalid="ignore", divide="ignore"):
        gamma2 = np.where(syy > 0, explained / syy, 0.0)
    gamma2 = np.clip(gamma2, 0.0, 1.0)  # a lag window's spectra may stray just outside
    noise = (1.0 - gamma2) * syy  # (F, p)
    dof = averages - q
    scale = stats.f.ppf(level, 2, 2.0 * dof) / dof
    diag = np.maximum(suu_inv.diagonal(axis1=1, axis2=2).real, 0.0)  # (F, q)
    radius = np.sqrt(scale * noise[:, :, None] * diag[:, None, :])
    return h, gamma2, radius


def _welch(
    x: np.ndarray, dt: float, segment: int | None, overlap: float
) -> tuple[np.ndarray, np.ndarray, float, dict]:
    n = x.shape[0]
    length = int(n / _WELCH_SEGMENTS) if segment is None else segment
    length = integer(length, "segment", error=DataError, minimum=8)
    if length > n:
        raise DataError(f"a segment of {length} samples is longer than the record ({n})")
    frac = real(overlap, "overlap", error=DataError, minimum=0.0, maximum=1.0, high_open=True)
    noverlap = int(frac * length)
    step = length - noverlap
    k = (n - length) // step + 1
    window = signal.get_window("hann", length)  # periodic, as scipy's welch and csd
    starts = np.arange(k) * step
    seg = np.lib.stride_tricks.sliding_window_view(x, length, axis=0)[starts]  # (K, C, L)
    seg = seg - seg.mean(axis=2, keepdims=True)
    spec = np.fft.rfft(seg * window, axis=2)  # (K, C, F)
    spectra = np.einsum("kaf,kbf->fab", spec, spec.conj()) / k
    # Welch (1967): overlapping segments are correlated by rho_j, their windows' overlap
    w2 = float(window @ window)
    rho = np.array([window[j * step:] @ window[: length - j * step] / w2
                    for j in range(1, k) if j * step < length])  # fmt: skip
    lags = np.arange(1, rho.size + 1)
    averages = k / (1.0 + 2.0 * np.sum((1.0 - lags / k) * rho**2))
    f = np.fft.rfftfreq(length, dt)
    settings = {"segment": length, "overlap": noverlap, "segments": k}
    return f[1:], spectra[1:], float(averages), settings


def _blackman_tukey(
    x: np.ndarray, dt: float, lag_width: int | None, frequencies: Any
) -> tuple[np.ndarray, np.ndarray, float, dict]:
    n, c = x.shape
    m = min(n // 10, 30) if lag_width is None else lag_width
    m = integer(m, "lag_width", error=DataError, minimum=2)
    if m >= n:
        raise DataError(f"a lag window of {m} samples is longer than the record ({n})")
    nyquist = 0.5 / dt
    if frequencies is None:
        f = nyquist * np.arange(1, _SPA_FREQUENCIES + 1) / _SPA_FREQUENCIES
    else:
        f = np.asarray(frequencies, dtype=float).reshape(-1)
        if f.size == 0 or not np.all(np.isfinite(f)) or f.min() <= 0:
            raise DataError("frequencies must be finite and above 0 Hz")
        if f.max() > nyquist * (1 + 1e-12):
            raise DataError(
                f"frequencies up to {f.max():g} Hz asked, above the Nyquist frequency "
                f"{nyquist:g} Hz"
            )
    # R_ab(tau) = (1/N) sum_t x_a(t + tau) x_b(t), by FFT, lags -M..M
    nfft = 1 << (n + m).bit_length()
    xf = np.fft.rfft(x, nfft, axis=0)
    r = np.fft.irfft(xf[:, :, None] * xf[:, None, :].conj(), nfft, axis=0) / n  # (nfft, C, C)
    lags = np.arange(-m, m + 1)
    window = 0.5 * (1.0 + np.cos(np.pi * lags / m))
    rw = r[lags] * window[:, None, None]
    kernel = np.exp(-2j * np.pi * np.outer(f * dt, lags))  # (F, 2M+1)
    spectra = (kernel @ rw.reshape(lags.size, c * c)).reshape(f.size, c, c)
    averages = n / float(window @ window)
    return f, spectra, averages, {"lag_width": m}


def _smoothed_etfe(
    x: np.ndarray, dt: float, width: int | None
) -> tuple[np.ndarray, np.ndarray, float, dict]:
    n = x.shape[0]
    w = _ETFE_WIDTH if width is None else width
    w = integer(w, "width", error=DataError, minimum=1)
    if w % 2 == 0:
        raise DataError(f"width must be an odd number of bins, got {w}")
    if w > n // 2:
        raise DataError(f"a smoothing over {w} bins is wider than the record's {n // 2} bins")
    xf = np.fft.fft(x, axis=0)
    periodogram = xf[:, :, None] * xf[:, None, :].conj() / n  # (N, C, C), two-sided
    kernel = signal.get_window("hann", w + 2, fftbins=False)[1:-1]
    kernel = kernel / kernel.sum()
    # circular smoothing: the periodogram is periodic in frequency, its negative
    # frequencies the conjugates of the positive ones
    smooth = ndimage.convolve1d(periodogram.real, kernel, axis=0, mode="wrap") + 1j * (
        ndimage.convolve1d(periodogram.imag, kernel, axis=0, mode="wrap"))  # fmt: skip
    half = n // 2
    f = np.arange(1, half + 1) / (n * dt)
    averages = 1.0 / float(kernel @ kernel)
    return f, smooth[1 : half + 1], averages, {"width": w}


# Two modes match when their frequencies differ by less than this share: closer than the
# first manipulator modes' spacing (11.8 -> 32.2 Hz) and wider than an identified mode's error
MATCH_TOLERANCE = 0.1


@dataclass(frozen=True)
class ModeMatch:
    """One row of a mode table: a model's mode, the record's peak and the plant's mode.

    Attributes
    ----------
    frequency, damping : float
        The model's mode: natural frequency [Hz] and damping ratio (NaN: a plant mode the
        model has not found).
    peak_gain : float
        The model's largest gain over its input-output pairs at the mode's damped frequency
        ``f sqrt(1 - zeta^2)``, in dB (NaN for a missed mode).
    peak : float
        The record's estimate's confirmed peak matched to it [Hz] (NaN: none).
    true_frequency, true_damping : float
        The plant's own mode matched to it (NaN: none, or the plant's modes unknown).
    """

    frequency: float
    damping: float
    peak_gain: float = math.nan
    peak: float = math.nan
    true_frequency: float = math.nan
    true_damping: float = math.nan

    @property
    def frequency_error(self) -> float:
        """``(f - f_true) / f_true`` in % (NaN without both)."""
        return 100.0 * (self.frequency - self.true_frequency) / self.true_frequency

    @property
    def damping_error(self) -> float:
        """``zeta - zeta_true`` (NaN without both)."""
        return self.damping - self.true_damping

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe form (NaN as None).

        Returns
        -------
        dict
        """
        values = {
            "frequency_hz": self.frequency, "damping": self.damping,
            "peak_gain_db": self.peak_gain, "peak_hz": self.peak,
            "true_frequency_hz": self.true_frequency, "true_damping": self.true_damping,
            "frequency_error_percent": self.frequency_error,
            "damping_error": self.damping_error,
        }  # fmt: skip
        return {k: (float(v) if math.isfinite(v) else None) for k, v in values.items()}


@checked_keywords
def mode_table(
    model: Any,
    *,
    estimate: FrequencyResponseEstimate | None = None,
    truth: tuple[Any, Any] | None = None,
    tolerance: float = MATCH_TOLERANCE,
) -> list[ModeMatch]:
    """A model's modes matched to a record's resonance peaks and to the plant's own modes.

    Each oscillating mode of the model (a pole pair with damping ratio in (0, 1),
    :func:`flexid.models.modes.modes`) gets its peak gain, the estimate's confirmed peak
    (:meth:`FrequencyResponseEstimate.peaks`) and the plant's mode nearest to it; matches
    are one to one, nearest first, within ``tolerance`` relative frequency.  The plant's
    modes below the Nyquist frequency that no model mode matches end the table as missed.

    Parameters
    ----------
    model : object
        A linear model with ``poles()``, ``dt`` and ``frequency_response(f)``.
    estimate : FrequencyResponseEstimate, optional
        The record's estimate, for its peaks.
    truth : (frequency, damping), optional
        The plant's modes (:meth:`flexid.data.plants.Plant.true_modes`), arrays in Hz and [-].
    tolerance : float, optional
        Largest relative frequency difference of a match (default 0.1).

    Returns
    -------
    list of ModeMatch
        The model's modes by frequency, then the missed plant modes.
    """
    tol = real(tolerance, "tolerance", error=DataError, minimum=0.0, low_open=True)
    found = [m for m in model_modes(model) if m.kind == "pair"
             and 0.0 < m.damping < 1.0]  # fmt: skip
    f = np.array([m.frequency for m in found])
    zeta = np.array([m.damping for m in found])
    if f.size:
        damped = f * np.sqrt(1.0 - zeta**2)
        gain = np.abs(model.frequency_response(damped)).max(axis=(1, 2))
        with np.errstate(divide="ignore"):
            gain_db = 20.0 * np.log10(gain)
    else:
        gain_db = np.zeros(0)
    peaks = estimate.peaks() if estimate is not None else np.zeros(0)
    to_peak = _match(f, peaks, tol)
    nyquist = 0.5 / model.dt
    if truth is not None:
        tf, tz = (np.asarray(v, dtype=float).reshape(-1) for v in truth)
        keep = tf < nyquist
        tf, tz = tf[keep], tz[keep]
    else:
        tf = tz = np.zeros(0)
    to_true = _match(f, tf, tol)
    rows = [
        ModeMatch(
            float(f[i]), float(zeta[i]), float(gain_db[i]),
            float(peaks[to_peak[i]]) if i in to_peak else math.nan,
            float(tf[to_true[i]]) if i in to_true else math.nan,
            float(tz[to_true[i]]) if i in to_true else math.nan,
        )
        for i in range(f.size)
    ]  # fmt: skip
    matched = set(to_true.values())
    rows += [ModeMatch(math.nan, math.nan, true_frequency=float(tf[j]),
                       true_damping=float(tz[j]))
             for j in range(tf.size) if j not in matched]  # fmt: skip
    return rows


def _match(a: np.ndarray, b: np.ndarray, tolerance: float) -> dict[int, int]:
    """One-to-one matches ``i -> j`` of frequencies ``a`` to ``b``, nearest (in log
    frequency) first, within ``tolerance`` relative difference."""
    if a.size == 0 or b.size == 0:
        return {}
    distance = np.abs(np.log(a[:, None] / b[None, :]))
    limit = math.log1p(tolerance)
    out: dict[int, int] = {}
    used: set[int] = set()
    for flat in np.argsort(distance, axis=None):
        i, j = divmod(int(flat), b.size)
        if distance[i, j] > limit:
            break
        if i not in out and j not in used:
            out[i] = j
            used.add(j)
    return out


def mode_table_text(rows: list[ModeMatch]) -> str:
    """A mode table as aligned text, a column left out where no row has a value.

    Parameters
    ----------
    rows : list of ModeMatch
        From :func:`mode_table`.

    Returns
    -------
    str
    """
    columns = [
        ("f [Hz]", lambda r: r.frequency, "{:.4g}"),
        ("damping", lambda r: r.damping, "{:.4f}"),
        ("peak gain [dB]", lambda r: r.peak_gain, "{:.1f}"),
        ("record peak [Hz]", lambda r: r.peak, "{:.4g}"),
        ("plant f [Hz]", lambda r: r.true_frequency, "{:.4g}"),
        ("f error %", lambda r: r.frequency_error, "{:+.3f}"),
        ("plant damping", lambda r: r.true_damping, "{:.4f}"),
        ("damping error", lambda r: r.damping_error, "{:+.4f}"),
    ]
    shown = [c for c in columns if any(math.isfinite(c[1](r)) for r in rows)]
    if not rows or not shown:
        return "no oscillating mode"
    table = [[name for name, _, _ in shown]]
    for r in rows:
        cells = [form.format(get(r)) if math.isfinite(get(r)) else "-" for _, get, form in shown]
        if not math.isfinite(r.frequency):
            cells[0] = "missed"
        table.append(cells)
    widths = [max(len(row[k]) for row in table) for k in range(len(shown))]
    return "\n".join("  ".join(c.rjust(w) for c, w in zip(row, widths)) for row in table)
