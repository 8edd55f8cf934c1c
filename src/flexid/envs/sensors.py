"""The measurement and actuation chain between a simulated plant and its sampled record.

A laboratory never sees a plant's states directly: the command passes through a drive
amplifier, analog signals through their sensors and an anti-aliasing filter before the
sampler, angles through an encoder that counts whole steps.  These are the linear blocks
and the quantiser the plants compose with their physics.  Every block is a continuous-time
state space ``(A, B, C, D)`` so that a linear plant and its chain can be discretised
exactly together, which is the chain simulated at the plant's internal rate: the filter
acts on the continuous signal before the sampler, so what lies above the Nyquist frequency
is attenuated before it can alias.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.signal

from flexid._validate import integer, positive_real
from flexid.errors import PlantParameterError

__all__ = [
    "StateSpace",
    "butterworth",
    "filter_outputs",
    "first_order_lag",
    "quantise",
    "second_order_lowpass",
    "series",
    "total_noise",
]

StateSpace = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]
"""Continuous-time ``(A, B, C, D)`` with shapes (n, n), (n, m), (p, n), (p, m)."""


def _corner(name: str, hz: float) -> float:
    return 2.0 * math.pi * positive_real(hz, name, error=PlantParameterError, unit="Hz")


def first_order_lag(bandwidth: float) -> StateSpace:
    """Unit-gain first-order lag ``w / (s + w)`` with ``w = 2 pi bandwidth``.

    A drive amplifier's current loop: the torque follows the command with this lag.

    Parameters
    ----------
    bandwidth : float
        -3 dB frequency [Hz], > 0.

    Returns
    -------
    StateSpace
        ``(A, B, C, D)`` with one state, shapes (1, 1) each.

    Raises
    ------
    PlantParameterError
        If ``bandwidth`` is not a positive finite number.
    """
    w = _corner("actuator bandwidth", bandwidth)
    return (np.array([[-w]]), np.array([[w]]), np.array([[1.0]]), np.zeros((1, 1)))


def second_order_lowpass(bandwidth: float, zeta: float = math.sqrt(0.5)) -> StateSpace:
    """Unit-gain second-order low-pass ``w^2 / (s^2 + 2 zeta w s + w^2)``.

    With ``zeta = 1/sqrt(2)`` (default) the -3 dB frequency is ``bandwidth``: the response of
    a damped (capacitive or piezo-resistive) accelerometer below its mounted resonance.

    Parameters
    ----------
    bandwidth : float
        Natural frequency [Hz], > 0.
    zeta : float
        Damping ratio, > 0 (not checked).

    Returns
    -------
    StateSpace
        ``(A, B, C, D)`` with two states (position, rate), shapes (2, 2), (2, 1), (1, 2),
        (1, 1).

    Raises
    ------
    PlantParameterError
        If ``bandwidth`` is not a positive finite number.
    """
    w = _corner("sensor bandwidth", bandwidth)
    a = np.array([[0.0, 1.0], [-w * w, -2.0 * zeta * w]])
    return (a, np.array([[0.0], [w * w]]), np.array([[1.0, 0.0]]), np.zeros((1, 1)))


def butterworth(order: int, cutoff: float) -> StateSpace:
    """Analog Butterworth low-pass of ``order`` with its -3 dB point at ``cutoff`` [Hz].

    Realised as a cascade of first- and second-order sections (real state space, no
    polynomial of high degree), unit gain at DC.

    Parameters
    ----------
    order : int
        Filter order, in [1, 8].
    cutoff : float
        -3 dB frequency [Hz], > 0.

    Returns
    -------
    StateSpace
        ``(A, B, C, D)`` with ``order`` states, single input and output.

    Raises
    ------
    PlantParameterError
        If ``order`` or ``cutoff`` is out of range.
    """
    order = integer(
        order, "anti-alias filter order", error=PlantParameterError, minimum=1, maximum=8
    )
    w = _corner("anti-alias cutoff", cutoff)
    _, poles, _ = scipy.signal.buttap(order)
    sections: list[StateSpace] = []
    for p in poles:
        if p.imag > 1e-12:
            zeta = -p.real / abs(p)  # |p| = 1 for the normalised prototype
            sections.append(second_order_lowpass(w / (2.0 * math.pi), zeta))
        elif abs(p.imag) <= 1e-12:
            sections.append(first_order_lag(w / (2.0 * math.pi)))
    system = sections[0]
    for section in sections[1:]:
        system = series(system, section)
    return system


def series(first: StateSpace, second: StateSpace) -> StateSpace:
    """Two systems in series: ``second`` driven by the output of ``first``.

    Parameters
    ----------
    first : StateSpace
        The first system, ``n1`` states, ``m`` inputs, ``p1`` outputs.
    second : StateSpace
        The second system, ``n2`` states, ``p1`` inputs, ``p`` outputs.

    Returns
    -------
    StateSpace
        ``(A, B, C, D)`` from the inputs of ``first`` to the outputs of ``second``; the
        state is ``[x_first; x_second]`` (``n1 + n2`` states).
    """
    a1, b1, c1, d1 = first
    a2, b2, c2, d2 = second
    n1, n2 = a1.shape[0], a2.shape[0]
    a = np.zeros((n1 + n2, n1 + n2))
    a[:n1, :n1] = a1
    a[n1:, :n1] = b2 @ c1
    a[n1:, n1:] = a2
    b = np.vstack([b1, b2 @ d1])
    c = np.hstack([d2 @ c1, c2])
    return a, b, c, d2 @ d1


def total_noise(std: np.ndarray, floor: np.ndarray) -> np.ndarray:
    """Standard deviation of added noise and a sensor's own noise, independent.

    Added in quadrature; where the floor is 0 the result is ``std`` itself, bit for bit.

    Parameters
    ----------
    std : ndarray, shape (p,)
        Standard deviation of the added measurement noise per output (output units).
    floor : ndarray, shape (p,)
        Standard deviation of each sensor's own noise (output units, >= 0).

    Returns
    -------
    ndarray, shape (p,)
        ``sqrt(std^2 + floor^2)`` where ``floor > 0``, else ``std``.
    """
    return np.where(floor > 0, np.hypot(std, floor), std)


def quantise(x: np.ndarray, step: float) -> np.ndarray:
    """Round to the nearest multiple of ``step`` (an encoder's count times its resolution).

    Mid-tread: zero stays zero, and the error is within ``+-step/2``.

    Parameters
    ----------
    x : array_like
        Values to quantise (any shape, e.g. angles in rad).
    step : float
        Resolution, > 0, in the units of ``x``.

    Returns
    -------
    ndarray
        ``round(x / step) * step``, same shape as ``x`` (halves round to even).
    """
    return np.round(np.asarray(x, dtype=float) / step) * step


def filter_outputs(system: StateSpace, filters: list[StateSpace | None]) -> StateSpace:
    """Pass output ``i`` of ``system`` through ``filters[i]`` (``None``: unfiltered).

    The state is ``[x_system; x_filter_0; x_filter_1; ...]`` (filters in output order), so the
    system's own states keep their indices.

    Parameters
    ----------
    system : StateSpace
        The system, ``n`` states, ``m`` inputs, ``p`` outputs.
    filters : list of StateSpace or None
        One entry per output (``p``): a single-input, single-output filter, or None.

    Returns
    -------
    StateSpace
        ``(A, B, C, D)`` with ``m`` inputs, ``p`` outputs and ``n`` plus the filters'
        states.
    """
    a, b, c, d = system
    n_sys = a.shape[0]
    used = [(i, f) for i, f in enumerate(filters) if f is not None]
    n = n_sys + sum(f[0].shape[0] for _, f in used)
    a_new = np.zeros((n, n))
    a_new[:n_sys, :n_sys] = a
    b_new = np.zeros((n, b.shape[1]))
    b_new[:n_sys] = b
    c_new = np.zeros((c.shape[0], n))
    c_new[:, :n_sys] = c
    d_new = d.copy()
    pos = n_sys
    for i, (af, bf, cf, df) in used:
        k = af.shape[0]
        a_new[pos : pos + k, :n_sys] = bf @ c[i : i + 1]
        a_new[pos : pos + k, pos : pos + k] = af
        b_new[pos : pos + k] = bf @ d[i : i + 1]
        c_new[i, :n_sys] = (df @ c[i : i + 1])[0]
        c_new[i, pos : pos + k] = cf[0]
        d_new[i] = (df @ d[i : i + 1])[0]
        pos += k
    return a_new, b_new, c_new, d_new
