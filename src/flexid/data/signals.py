"""Excitation signals for identification experiments, all seeded and bounded.

Every generator returns a float64 array of shape ``(N,)`` in the unit of the plant input
(N m for the manipulator torque, V for the twin-rotor motors).  Random signals take an
explicit ``numpy.random.Generator``; the global NumPy random state is never used.

========== =================================================================================
name       definition
========== =================================================================================
prbs       maximum-length binary sequence from a linear-feedback shift register
random     random binary: +-levels drawn independently, each held ``hold`` samples
uniform    uniform random between ``low`` and ``high``, held ``hold`` samples (the paper's
           "random" input)
aprbs      amplitude-modulated PRBS: uniform random levels held random durations
multisine  sum of cosines on the record's FFT grid inside a band, Schroeder phases
chirp      swept sine, linear or logarithmic
bang_bang  +amplitude for ``width`` s, -amplitude for ``width`` s, then 0
========== =================================================================================
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from scipy import signal as sps

from .._validate import integer, positive_int, positive_real, real
from ..errors import DataError, UnknownNameError

__all__ = [
    "PRBS_TAPS",
    "SIGNALS",
    "aprbs",
    "bang_bang",
    "chirp",
    "crest_factor",
    "describe_signals",
    "make_signal",
    "multisine",
    "prbs",
    "random_binary",
    "uniform",
]

#: Feedback taps of maximum-length Fibonacci LFSRs (Xilinx XAPP052, table 3), by order.
PRBS_TAPS: dict[int, tuple[int, ...]] = {
    2: (2, 1), 3: (3, 2), 4: (4, 3), 5: (5, 3), 6: (6, 5), 7: (7, 6), 8: (8, 6, 5, 4),
    9: (9, 5), 10: (10, 7), 11: (11, 9), 12: (12, 6, 4, 1), 13: (13, 4, 3, 1),
    14: (14, 5, 3, 1), 15: (15, 14), 16: (16, 15, 13, 4), 17: (17, 14), 18: (18, 11),
    19: (19, 6, 2, 1), 20: (20, 17), 21: (21, 19), 22: (22, 21), 23: (23, 18),
    24: (24, 23, 22, 17),
}


def _count(n_samples: Any) -> int:
    return positive_int(n_samples, "n_samples", error=DataError)


def _bounds(low: Any, high: Any) -> tuple[float, float]:
    low = real(low, "signal bound low", error=DataError)
    high = real(high, "signal bound high", error=DataError)
    if low >= high:
        raise DataError(f"signal bounds need finite low < high, got low={low}, high={high}")
    return low, high


def _rng(rng: np.random.Generator | int | None) -> np.random.Generator:
    if isinstance(rng, np.random.Generator):
        return rng
    return np.random.default_rng(rng)


def _hold(values: np.ndarray, hold: int, n: int) -> np.ndarray:
    return np.repeat(values, hold)[:n]


def prbs(
    n_samples: int,
    order: int = 10,
    *,
    clock: int = 1,
    low: float = -1.0,
    high: float = 1.0,
    rng: np.random.Generator | int | None = None,
) -> np.ndarray:
    """Maximum-length pseudo-random binary sequence.

    Parameters
    ----------
    n_samples : int
        Length N.
    order : int
        Shift-register length n (2..24); the sequence has period ``(2^n - 1) * clock``.
    clock : int
        Samples each bit is held.
    low, high : float
        The two levels (input units).
    rng : Generator or int, optional
        Draws the non-zero initial register (a cyclic shift of the sequence); ``None``
        starts from all ones.

    Returns
    -------
    ndarray, shape (N,)
        Per period ``2^(n-1)`` samples at ``high`` and ``2^(n-1) - 1`` at ``low`` (times
        ``clock``).
    """
    n = _count(n_samples)
    order = integer(
        order, "PRBS order", error=DataError, minimum=min(PRBS_TAPS), maximum=max(PRBS_TAPS)
    )
    clock = positive_int(clock, "PRBS clock", error=DataError)
    low, high = _bounds(low, high)
    period = 2**order - 1
    bits_needed = -(-n // clock)
    taps = PRBS_TAPS[order]
    # Fibonacci LFSR in recurrence form: s[k] = XOR over the taps t of s[k - t]
    if rng is None:
        state = np.ones(order, dtype=np.uint8)
    else:
        g = _rng(rng)
        state = g.integers(0, 2, order).astype(np.uint8)
        if not state.any():
            state[g.integers(0, order)] = 1
    seq = np.empty(period + order, dtype=np.uint8)
    seq[:order] = state
    k = order
    step_max = min(taps)  # bits of one block never depend on each other
    while k < period:
        step = min(step_max, period - k)
        block = np.zeros(step, dtype=np.uint8)
        for t in taps:
            block ^= seq[k - t : k - t + step]
        seq[k : k + step] = block
        k += step
    bits = seq[:period]
    reps = -(-bits_needed // period)
    bits = np.tile(bits, reps)[:bits_needed]
    levels = np.where(bits == 1, high, low).astype(float)
    return _hold(levels, clock, n)


def random_binary(
    n_samples: int,
    *,
    low: float = -1.0,
    high: float = 1.0,
    hold: int = 1,
    rng: np.random.Generator | int | None = None,
) -> np.ndarray:
    """Random binary signal: ``low`` or ``high`` with equal probability, held ``hold`` samples.

    Parameters
    ----------
    n_samples : int
        Length ``N`` of the signal.
    low, high : float
        The two levels (input units).
    hold : int
        Samples each level is held.
    rng : numpy.random.Generator or int, optional
        Generator or seed.

    Returns
    -------
    ndarray, shape (N,)
        The signal.
    """
    n = _count(n_samples)
    low, high = _bounds(low, high)
    hold = positive_int(hold, "hold", error=DataError)
    bits = _rng(rng).integers(0, 2, -(-n // hold))
    return _hold(np.where(bits == 1, high, low).astype(float), hold, n)


def uniform(
    n_samples: int,
    *,
    low: float = -1.0,
    high: float = 1.0,
    hold: int = 1,
    rng: np.random.Generator | int | None = None,
) -> np.ndarray:
    """Uniform random values in ``[low, high)``, each held ``hold`` samples.

    The paper's inputs: manipulator torque uniform in +-0.3 N m every 1 ms sample; twin rotor
    main-rotor voltage uniform in +-1 V held 0.1 s.

    Parameters
    ----------
    n_samples : int
        Length ``N`` of the signal.
    low, high : float
        Range of the values (input units).
    hold : int
        Samples each value is held.
    rng : numpy.random.Generator or int, optional
        Generator or seed.

    Returns
    -------
    ndarray, shape (N,)
        The signal.
    """
    n = _count(n_samples)
    low, high = _bounds(low, high)
    hold = positive_int(hold, "hold", error=DataError)
    return _hold(_rng(rng).uniform(low, high, -(-n // hold)), hold, n)


def aprbs(
    n_samples: int,
    *,
    low: float = -1.0,
    high: float = 1.0,
    min_hold: int = 1,
    max_hold: int = 20,
    rng: np.random.Generator | int | None = None,
) -> np.ndarray:
    """Amplitude-modulated PRBS: uniform random levels held a random 1..max samples each.

    Parameters
    ----------
    n_samples : int
        Length ``N`` of the signal.
    low, high : float
        Range of the levels (input units).
    min_hold, max_hold : int
        Shortest and longest hold of a level, in samples.
    rng : numpy.random.Generator or int, optional
        Generator or seed.

    Returns
    -------
    ndarray, shape (N,)
        The signal.
    """
    n = _count(n_samples)
    low, high = _bounds(low, high)
    min_hold = positive_int(min_hold, "min_hold", error=DataError)
    max_hold = positive_int(max_hold, "max_hold", error=DataError)
    if max_hold < min_hold:
        raise DataError(f"max_hold ({max_hold}) must be >= min_hold ({min_hold})")
    g = _rng(rng)
    n_levels = n // min_hold + 1
    durations = g.integers(min_hold, max_hold + 1, n_levels)
    levels = g.uniform(low, high, n_levels)
    return np.repeat(levels, durations)[:n]


def multisine(
    n_samples: int,
    dt: float = 1.0,
    *,
    band: tuple[float, float] | None = None,
    amplitude: float = 1.0,
    n_freqs: int | None = None,
    phases: str = "schroeder",
    rng: np.random.Generator | int | None = None,
) -> np.ndarray:
    """Periodic multisine on the record's FFT grid, scaled to ``max |x| = amplitude``.

    Parameters
    ----------
    n_samples : int
    dt : float
        Sample time (s).
    band : (f_lo, f_hi), optional
        Excited band in Hz (default: from the first FFT bin to 0.4/dt).
    amplitude : float
        Peak value (input units).
    n_freqs : int, optional
        Use this many lines spread evenly over the band's FFT bins (default: every bin).
    phases : {"schroeder", "random"}
        Schroeder's low-crest phases ``phi_k = -pi k (k - 1) / K``, or uniform random phases.
    rng : Generator or int, optional
        For random phases.

    Returns
    -------
    ndarray, shape (N,)
        Power only at the chosen bins of the N-point DFT (exactly periodic over the record).
    """
    n = _count(n_samples)
    dt = positive_real(dt, "dt", error=DataError)
    amplitude = positive_real(amplitude, "amplitude", error=DataError)
    fs = 1.0 / dt
    lo, hi = band if band is not None else (fs / n, 0.4 * fs)
    lo, hi = float(lo), float(hi)
    if not (0 <= lo < hi <= fs / 2):
        raise DataError(f"multisine band must satisfy 0 <= f_lo < f_hi <= {fs / 2:g} Hz")
    bins = np.arange(1, n // 2 + (n % 2))  # strictly below Nyquist
    freqs = bins * fs / n
    bins = bins[(freqs >= lo) & (freqs <= hi)]
    if bins.size == 0:
        raise DataError(f"no FFT frequency of a {n}-sample record lies in {lo:g}-{hi:g} Hz")
    if n_freqs is not None:
        n_freqs = positive_int(n_freqs, "n_freqs", error=DataError)
        pick = np.unique(np.linspace(0, bins.size - 1, min(n_freqs, bins.size)).round())
        bins = bins[pick.astype(int)]
    k = np.arange(1, bins.size + 1)
    if phases == "schroeder":
        phi = -np.pi * k * (k - 1) / bins.size
    elif phases == "random":
        phi = _rng(rng).uniform(0, 2 * np.pi, bins.size)
    else:
        raise UnknownNameError("multisine phase rule", phases, ("schroeder", "random"))
    spectrum = np.zeros(n // 2 + 1, dtype=complex)
    spectrum[bins] = np.exp(1j * phi)
    x = np.fft.irfft(spectrum, n)
    return amplitude * x / np.abs(x).max()


def chirp(
    n_samples: int,
    dt: float = 1.0,
    *,
    f0: float = 0.1,
    f1: float | None = None,
    amplitude: float = 1.0,
    method: str = "linear",
) -> np.ndarray:
    """Swept sine from ``f0`` to ``f1`` Hz over the record (``scipy.signal.chirp``).

    Parameters
    ----------
    n_samples : int
        Length ``N`` of the signal.
    dt : float
        Sample time (s).
    f0 : float
        Start frequency (Hz).
    f1 : float, optional
        End frequency (Hz); default ``0.4 / dt``.
    amplitude : float
        Peak value (input units).
    method : str
        Sweep law of ``scipy.signal.chirp`` (``"linear"``, ``"logarithmic"``, ...).

    Returns
    -------
    ndarray, shape (N,)
        The signal.
    """
    n = _count(n_samples)
    dt = positive_real(dt, "dt", error=DataError)
    amplitude = positive_real(amplitude, "amplitude", error=DataError)
    f1 = 0.4 / dt if f1 is None else float(f1)
    f0 = float(f0)
    if method not in ("linear", "logarithmic"):
        raise UnknownNameError("chirp method", method, ("linear", "logarithmic"))
    if not (0 < f0 and 0 < f1 <= 0.5 / dt):
        raise DataError(f"chirp needs 0 < f0 and 0 < f1 <= Nyquist ({0.5 / dt:g} Hz)")
    t = np.arange(n) * dt
    t1 = max(t[-1], dt)
    return amplitude * sps.chirp(t, f0=f0, t1=t1, f1=f1, method=method, phi=-90)


def bang_bang(
    n_samples: int,
    dt: float = 1e-3,
    *,
    amplitude: float = 0.3,
    width: float = 0.3,
    start: float = 0.0,
) -> np.ndarray:
    """The classic manipulator test torque: +amplitude for ``width`` s, then -amplitude.

    Zero before ``start`` and after ``start + 2 width`` seconds.

    Parameters
    ----------
    n_samples : int
        Length ``N`` of the signal.
    dt : float
        Sample time (s).
    amplitude : float
        Height of the pulses (N m for the manipulator).
    width : float
        Duration of each pulse (s).
    start : float
        Start of the first pulse (s).

    Returns
    -------
    ndarray, shape (N,)
        The signal.
    """
    n = _count(n_samples)
    dt = positive_real(dt, "dt", error=DataError)
    amplitude = positive_real(amplitude, "amplitude", error=DataError)
    width = positive_real(width, "width", error=DataError)
    t = np.arange(n) * dt
    x = np.zeros(n)
    x[(t >= start - 1e-12) & (t < start + width - 1e-12)] = amplitude
    x[(t >= start + width - 1e-12) & (t < start + 2 * width - 1e-12)] = -amplitude
    return x


def crest_factor(x: np.ndarray) -> float:
    """Peak over RMS of a signal.

    Parameters
    ----------
    x : ndarray, shape (N,)
        The signal.

    Returns
    -------
    float
        ``max |x| / rms(x)`` (1 for a square wave, sqrt(2) for a sine).
    """
    x = np.asarray(x, dtype=float)
    return float(np.abs(x).max() / np.sqrt(np.mean(x**2)))


def _levels(options: dict[str, Any]) -> dict[str, Any]:
    """Accept ``amplitude=a`` as shorthand for ``low=-a, high=a``."""
    options = dict(options)
    if "amplitude" in options:
        a = positive_real(options.pop("amplitude"), "amplitude", error=DataError)
        options.setdefault("low", -a)
        options.setdefault("high", a)
    return options


SIGNALS: dict[str, tuple[Callable[..., np.ndarray], bool, bool, str]] = {
    # name: (function, takes dt, random, description)
    "prbs": (prbs, False, True, "maximum-length binary sequence; order, clock, low, high"),
    "random": (random_binary, False, True, "random binary; low, high, hold"),
    "uniform": (uniform, False, True, "uniform random; low, high, hold (the paper's input)"),
    "aprbs": (aprbs, False, True, "random levels, random durations; low, high, min/max_hold"),
    "multisine": (multisine, True, True, "Schroeder multisine; band, amplitude, n_freqs"),
    "chirp": (chirp, True, False, "swept sine; f0, f1, amplitude, method"),
    "bang_bang": (bang_bang, True, False, "+a for width s then -a; amplitude, width, start"),
}


def make_signal(
    name: str,
    n_samples: int,
    dt: float = 1.0,
    *,
    rng: np.random.Generator | int | None = None,
    **options: Any,
) -> np.ndarray:
    """A signal by name (see :data:`SIGNALS`), e.g. ``make_signal("prbs", 1000, order=8)``.

    ``amplitude=a`` stands for ``low=-a, high=a`` in the two-level and random signals.
    Unknown names raise :class:`~flexid.errors.UnknownNameError`; unknown options raise
    :class:`~flexid.errors.DataError`.

    Parameters
    ----------
    name : str
        Signal name, a key of :data:`SIGNALS`.
    n_samples : int
        Length ``N`` of the signal.
    dt : float
        Sample time (s), for the signals defined in seconds or hertz.
    rng : numpy.random.Generator or int, optional
        Generator or seed of the random signals.
    **options
        The signal's own options (see :func:`describe_signals`).

    Returns
    -------
    ndarray, shape (N,)
        The signal.
    """
    key = name.replace("-", "_") if name.replace("-", "_") in SIGNALS else name
    if key not in SIGNALS:
        raise UnknownNameError("signal", name, SIGNALS)
    fn, takes_dt, random, _ = SIGNALS[key]
    if key in ("prbs", "random", "uniform", "aprbs"):
        options = _levels(options)
    if random:
        options["rng"] = rng
    args = (n_samples, dt) if takes_dt else (n_samples,)
    try:
        return fn(*args, **options)
    except TypeError as exc:
        raise DataError(f"signal {name!r}: {exc}") from None


def describe_signals() -> str:
    """One line per signal: name and options.

    Returns
    -------
    str
        The lines, joined by newlines.
    """
    return "\n".join(f"{name:10s} {desc}" for name, (_, _, _, desc) in SIGNALS.items())
