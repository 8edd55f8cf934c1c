"""Modes of a discrete-time model: natural frequency and damping ratio of each pole.

A flexible structure is described by its modes, a natural frequency and a damping ratio
each.  A discrete pole ``z`` maps to the continuous ``s = log(z) / dt`` (exact for the free
response); its natural frequency is ``|s| / (2 pi)`` Hz and its damping ratio
``-Re(s) / |s|`` (MATLAB ``damp``, Ljung sec. 4.3).  A conjugate pair is one mode; a real
pole is one (an overdamped or first-order one).  Two kinds have no continuous equivalent of
their own, and say so: a pole on the negative real axis (``log`` of a negative number, its
frequency the Nyquist frequency's neighbourhood) and a pole at the origin (a pure delay).
A pole at ``z = 1`` is an integrator (a rigid-body mode has two).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import DataError

__all__ = ["Mode", "model_modes", "modes"]

# A pole's imaginary part below this (relative to its magnitude, at least 1) is a real pole:
# the conjugate pairs np.linalg.eig and np.roots return are exact mirror images, and the
# rounding of a real eigenvalue's imaginary part is of order eps times its magnitude.
_REAL_TOLERANCE = 1e-9


@dataclass(frozen=True)
class Mode:
    """One mode of a discrete-time model.

    Attributes
    ----------
    frequency : float
        Natural frequency ``|s| / (2 pi)`` in Hz (``s = log(z) / dt``); ``inf`` for a pole at
        the origin.
    damping : float
        Damping ratio ``-Re(s) / |s|``: in (0, 1) for a stable oscillating mode, 1 or more
        for a real positive pole inside the circle, negative for an unstable one; NaN for an
        integrator (``s = 0``).
    pole : complex
        The discrete pole (of a pair, the member with positive imaginary part).
    kind : {"pair", "real", "integrator", "negative real", "delay"}
        ``"negative real"`` and ``"delay"`` (``z = 0``) have no continuous equivalent of
        their own: their frequency and damping are those of ``log(z) / dt`` as MATLAB
        ``damp`` reports them.
    """

    frequency: float
    damping: float
    pole: complex
    kind: str

    @property
    def period(self) -> float:
        """``1 / frequency`` in seconds (``inf`` for an integrator)."""
        return math.inf if self.frequency == 0 else 1.0 / self.frequency

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe form: frequency (Hz), damping, the pole's real and imaginary parts, kind.

        Returns
        -------
        dict
        """
        return {
            "frequency_hz": float(self.frequency),
            "damping": float(self.damping),
            "pole": [float(self.pole.real), float(self.pole.imag)],
            "kind": self.kind,
        }


def modes(poles: Any, dt: float) -> list[Mode]:
    """The modes of a set of discrete poles, by increasing natural frequency.

    Parameters
    ----------
    poles : array_like of complex, shape (n,)
        The poles (eigenvalues of ``A``, roots of a denominator); complex ones in conjugate
        pairs.
    dt : float
        Sample time in seconds, > 0.

    Returns
    -------
    list of Mode
        One per conjugate pair and one per real pole.

    Raises
    ------
    DataError
        For a non-finite pole, a complex pole without its conjugate, or a bad ``dt``.

    Examples
    --------
    >>> import numpy as np
    >>> s = 2 * np.pi * 5.0 * (-0.02 + 1j * np.sqrt(1 - 0.02**2))  # 5 Hz, 2 % damping
    >>> z = np.exp(s * 0.01)
    >>> m = modes([z, np.conj(z)], dt=0.01)[0]
    >>> round(m.frequency, 9), round(m.damping, 9), m.kind
    (5.0, 0.02, 'pair')
    """
    dt = float(dt)
    if not (math.isfinite(dt) and dt > 0):
        raise DataError(f"modes: dt must be a positive number of seconds, got {dt}")
    p = np.asarray(poles, dtype=complex).reshape(-1)
    if not np.isfinite(p).all():
        raise DataError("modes: the poles must be finite")
    scale = np.maximum(np.abs(p), 1.0)
    real = np.abs(p.imag) <= _REAL_TOLERANCE * scale
    upper, lower = p[~real & (p.imag > 0)], p[~real & (p.imag < 0)]
    if upper.size != lower.size or not np.allclose(
        np.sort_complex(upper), np.sort_complex(np.conj(lower)), rtol=1e-7, atol=1e-12
    ):
        raise DataError("modes: every complex pole needs its conjugate (a real model's poles)")
    out = [_mode(complex(z), dt, "pair") for z in upper]
    for z in p[real].real:
        kind = "real"
        if z == 0.0:
            kind = "delay"
        elif z < 0.0:
            kind = "negative real"
        elif abs(z - 1.0) <= _REAL_TOLERANCE:
            kind = "integrator"
        out.append(_mode(complex(z, 0.0), dt, kind))
    return sorted(out, key=lambda m: (m.frequency, m.kind))


def model_modes(model: Any) -> list[Mode]:
    """The modes of a model: its own list where it keeps one (a modal state-space model lists
    each mode once, however many inputs its realisation repeats it for), else those of its
    poles.

    Parameters
    ----------
    model : object
        A model with ``modes()``, or with ``poles()`` and ``dt`` (s).

    Returns
    -------
    list of Mode
        By increasing natural frequency.
    """
    if hasattr(model, "modes"):
        return list(model.modes())
    return modes(model.poles(), model.dt)


def _mode(z: complex, dt: float, kind: str) -> Mode:
    if kind == "delay":
        return Mode(math.inf, 1.0, z, kind)
    if kind == "integrator":
        return Mode(0.0, math.nan, z, kind)
    s = complex(np.log(z)) / dt
    w = abs(s)
    return Mode(w / (2.0 * math.pi), -s.real / w, z, kind)
