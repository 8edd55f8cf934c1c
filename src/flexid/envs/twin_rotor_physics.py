"""Physics of the twin rotor MIMO system (Feedback 33-949S phenomenological model).

The phenomenological model of Feedback Instruments' Twin Rotor MIMO System manual (33-949S),
seven states ``x = [psi, psi', phi, phi', tau1, tau2, M_R]`` (pitch, pitch rate, yaw, yaw
rate, main and tail rotor states, main-rotor reaction torque on yaw)::

    I1 psi''  = M1 - Mg sin(psi) - B1psi psi' - B2psi sgn(psi') - Kgy M1 phi' cos(psi)
    I2 phi''  = M2 - B1phi phi' - B2phi sgn(phi') - M_R
    M_i       = a_i tau_i |tau_i| + b_i tau_i      (thrust_law="signed_square", default)
              = a_i tau_i^2 + b_i tau_i            (thrust_law="square", the manual's form)
    tau1'     = (k1 u1 - T10 tau1) / T11,   tau2' = (k2 u2 - T20 tau2) / T21
    M_R'      = (-M_R + kc (T0 tau1' + tau1)) / Tp

Coulomb friction ``sgn(v)`` is smoothed as ``tanh(v / coulomb_velocity)`` (default 0.05
rad/s, so the fixed-step integrator stays stable).  Inputs are the two motor voltages, clipped
to ``+-u_max`` (2.5 V).  Integration: fixed-step RK4 with ``substep`` (10 ms) substeps, input
held over each sample (default 0.1 s).  ``lock_yaw=True`` is the rig's one-degree-of-freedom
configuration (vertical channel): yaw and yaw rate stay 0 and the gyroscopic term vanishes.

Outputs, in this order: pitch (rad), yaw (rad), pitch rate (rad/s), yaw rate (rad/s), taken at
``t = k dt`` before the input of sample ``k`` acts.

Notes
-----
:func:`derivatives` is the model: the one statement of the equations, batched over a leading
axis.  :func:`step_states` (RK4 over one sample) and :func:`reference_trajectory` integrate
it; they are the reference route.  Two faster routes compute the same RK4 samples, and the
tests hold them to the reference:

:class:`ScalarStepper`
    one state in Python floats (the single environment and :func:`simulate`);
:class:`BatchStepper`
    a batch in NumPy, one row per state variable (the vector environment).

Both use the structure of the model.  The rotor states and the reaction torque
``(tau1, tau2, M_R)`` obey linear equations that pitch and yaw do not enter, so with the input
held over a sample RK4 is linear in them: their values at all ``4 n_sub`` stages of a sample
are one matrix times ``(tau1, tau2, M_R, u1, u2)`` at its start.  The matrix is built by
running the reference recursion on the unit vectors (:func:`_linear_stages`).  The thrusts at
all stages then follow in bulk (:func:`thrust`, the same function as in the model), and only
pitch, pitch rate and yaw rate are stepped stage by stage; yaw is their integral.  The routes
differ from the reference by rounding only.

When the compiled kernels run (:mod:`flexid.kernels`), :class:`CompiledScalarStepper` and
:class:`CompiledBatchStepper` take the place of both: the equations of :func:`derivatives` and
the RK4 of :func:`step_states` in C, four rotors per SIMD vector, with ``sin``, ``cos`` and
``tanh`` as inline polynomials within a few eps of the exact values (absolute error).  They too
differ from the reference by rounding only.

References
----------
Feedback Instruments, *Twin Rotor MIMO System*, manual 33-949S: the model and the default
parameters.  The parameter table is reproduced by Pandey and Laxmi (2014, optimal control of
the TRMS by LQR) and by A. K. Agrawal (M.Tech thesis on optimal controller design for the
TRMS, NIT Rourkela, 2013), which also gives the +-2.5 V input range.
"""

from __future__ import annotations

import functools
import math
from dataclasses import asdict, dataclass, fields
from itertools import islice
from typing import Any

import numpy as np
from scipy.special import expit

from .._validate import integer, positive_real, real
from ..errors import DataError, PlantParameterError, check_finite
from . import sensors

__all__ = [
    "IDEAL_SENSORS",
    "OUTPUT_NAMES",
    "OUTPUT_UNITS",
    "STATE_NAMES",
    "THRUST_LAWS",
    "BatchStepper",
    "CompiledBatchStepper",
    "CompiledScalarStepper",
    "ScalarStepper",
    "TwinRotorParameters",
    "batch_stepper",
    "clip_inputs",
    "derivatives",
    "measure",
    "noise_floor",
    "pitch_linear_mode",
    "reference_trajectory",
    "scalar_stepper",
    "simulate",
    "step_states",
    "substeps",
    "thrust",
]

OUTPUT_NAMES = ("pitch", "yaw", "pitch_rate", "yaw_rate")
OUTPUT_UNITS = ("rad", "rad", "rad/s", "rad/s")
STATE_NAMES = ("pitch", "pitch_rate", "yaw", "yaw_rate", "tau1", "tau2", "reaction_torque")
"""Columns of a state array, units rad, rad/s, rad, rad/s, model units, model units, N m."""
THRUST_LAWS = ("signed_square", "square")

IDEAL_SENSORS: dict[str, Any] = {"encoder_counts": None}
"""The measurement chain switched off: pitch and yaw read exactly."""

_OUTPUT_COLUMNS = [0, 2, 1, 3]  # outputs (pitch, yaw, pitch rate, yaw rate) from a state


_POSITIVE = ("I1", "I2", "T11", "T10", "T21", "T20", "Tp", "u_max", "coulomb_velocity",
             "substep", "Mg")  # fmt: skip
"""The parameters that must be > 0; the friction coefficients ``B*`` must be >= 0."""


@dataclass(frozen=True)
class TwinRotorParameters:
    """Parameters of the Feedback 33-949S phenomenological model; immutable and hashable.

    The defaults are the manual's values (see the module's References).  The actuators'
    dynamics are part of the model (the rotors' first-order lags ``T10``, ``T11``, ``T20``,
    ``T21``), and the angles are counted digitally, so the measurement chain is the encoders';
    nothing analog is sampled, so there is nothing to alias.  The numbers are stored as
    ``float``.

    Attributes
    ----------
    I1, I2 : float
        Moments of inertia of the beam about the pitch and the yaw axis [kg m^2], > 0.
    a1, b1 : float
        Main rotor characteristic ``M1 = a1 tau1 |tau1| + b1 tau1`` [N m per (unit of
        tau)^2, N m per unit of tau].
    a2, b2 : float
        Tail rotor characteristic, as ``a1``, ``b1``.
    Mg : float
        Gravity moment of the beam at 90 degrees of pitch [N m], > 0.
    B1psi, B2psi : float
        Viscous [N m s/rad] and Coulomb [N m] friction of the pitch axis, >= 0.
    B1phi, B2phi : float
        Viscous [N m s/rad] and Coulomb [N m] friction of the yaw axis, >= 0.
    Kgy : float
        Gyroscopic coefficient [s/rad].
    k1, k2 : float
        Static gains of the main and tail motors [unit of tau per V].
    T11, T10 : float
        Main motor lag ``k1 / (T11 s + T10)``: ``T11`` [s] and ``T10`` [-], > 0.
    T21, T20 : float
        Tail motor lag ``k2 / (T21 s + T20)``: ``T21`` [s] and ``T20`` [-], > 0.
    Tp, T0 : float
        Lag and lead time constants [s] of the reaction torque
        ``M_R = kc (T0 s + 1) / (Tp s + 1) tau1``; ``Tp`` > 0.
    kc : float
        Gain of the main rotor's reaction torque on yaw [N m per unit of tau].
    u_max : float
        Motor voltage limit [V], > 0: inputs are clipped to ``+-u_max``.
    thrust_law : {"signed_square", "square"}
        ``a tau |tau| + b tau`` (default: a negative voltage gives a negative thrust) or the
        manual's ``a tau^2 + b tau``.
    lock_yaw : bool
        The rig's one-degree-of-freedom configuration: yaw and yaw rate held at 0.
    coulomb_velocity : float
        Velocity [rad/s] that smooths ``sgn(v)`` as ``tanh(v / coulomb_velocity)``, > 0.
    substep : float
        RK4 substep [s], > 0; a sample is ``round(dt / substep)`` substeps.
    encoder_counts : int or None
        Counts per revolution of the pitch and yaw encoders, >= 1 (default 4096, a
        1,024-line encoder decoded in quadrature: an assumption for this class of rig, the
        manual's resolution was not available); None reads the angles exactly
        (:data:`IDEAL_SENSORS`).
    """

    I1: float = 6.8e-2
    I2: float = 2e-2
    a1: float = 0.0135
    b1: float = 0.0924
    a2: float = 0.02
    b2: float = 0.09
    Mg: float = 0.32
    B1psi: float = 6e-3
    B2psi: float = 1e-3
    B1phi: float = 1e-1
    B2phi: float = 1e-2
    Kgy: float = 0.05
    k1: float = 1.1
    k2: float = 0.8
    T11: float = 1.1
    T10: float = 1.0
    T21: float = 1.0
    T20: float = 1.0
    Tp: float = 2.0
    T0: float = 3.5
    kc: float = -0.2
    u_max: float = 2.5
    thrust_law: str = "signed_square"
    lock_yaw: bool = False
    coulomb_velocity: float = 0.05
    substep: float = 0.01
    encoder_counts: int | None = 4096

    def __post_init__(self) -> None:
        if self.thrust_law not in THRUST_LAWS:
            raise PlantParameterError(
                f"twin rotor: thrust_law must be one of {THRUST_LAWS}, got {self.thrust_law!r}"
            )
        if not isinstance(self.lock_yaw, (bool, np.bool_)):
            raise PlantParameterError(f"twin rotor: lock_yaw must be a bool, got {self.lock_yaw!r}")
        integer(
            self.encoder_counts, "twin rotor: encoder_counts (counts per revolution)",
            error=PlantParameterError, minimum=1, none_ok=True,
        )
        for f in fields(self):
            if f.name in ("thrust_law", "lock_yaw", "encoder_counts"):
                continue
            positive = f.name in _POSITIVE
            value = real(
                getattr(self, f.name), f"twin rotor: {f.name}", error=PlantParameterError,
                minimum=0 if positive or f.name.startswith("B") else None, low_open=positive,
            )
            object.__setattr__(self, f.name, value)

    def to_dict(self) -> dict[str, Any]:
        """The parameters as a dict, field name to value (:func:`dataclasses.asdict`).

        Returns
        -------
        dict of str to object
            One entry per field, in the order of the Attributes.
        """
        return asdict(self)

    @property
    def encoder_step(self) -> float:
        """Angle resolution ``2 pi / encoder_counts`` [rad] (0 for ideal encoders)."""
        return 0.0 if self.encoder_counts is None else 2.0 * math.pi / self.encoder_counts


def measure(y: np.ndarray, params: TwinRotorParameters | None = None) -> np.ndarray:
    """Read sampled outputs through the encoders: pitch and yaw in whole counts.

    Parameters
    ----------
    y : array_like, shape (..., 4)
        Outputs :data:`OUTPUT_NAMES` [rad, rad, rad/s, rad/s].
    params : TwinRotorParameters, optional
        Their ``encoder_counts`` sets the step; default the defaults.

    Returns
    -------
    ndarray, shape (..., 4)
        A copy of ``y`` with pitch and yaw rounded to the encoder step [rad]; the rates
        (columns 2, 3) unchanged.
    """
    p = TwinRotorParameters() if params is None else params
    y = np.array(y, dtype=float)
    if p.encoder_counts is not None:
        y[..., :2] = sensors.quantise(y[..., :2], p.encoder_step)
    return y


def noise_floor(params: TwinRotorParameters | None = None) -> np.ndarray:
    """Standard deviation of each output's own sensor noise: none for this plant.

    Parameters
    ----------
    params : TwinRotorParameters, optional
        Not used: the encoders add no noise (the interface of every plant takes them).

    Returns
    -------
    ndarray, shape (4,)
        Zeros [rad, rad, rad/s, rad/s].
    """
    return np.zeros(4)


def pitch_linear_mode(params: TwinRotorParameters | None = None) -> tuple[float, float]:
    """Natural frequency and damping ratio of pitch linearised at rest.

    Parameters
    ----------
    params : TwinRotorParameters, optional
        Default the defaults.

    Returns
    -------
    frequency : float
        ``sqrt(Mg / I1) / (2 pi)`` [Hz].
    damping : float
        ``B1psi / (2 sqrt(Mg I1))`` [-] (viscous friction only: the Coulomb term has no
        linearisation at zero speed).
    """
    p = params or TwinRotorParameters()
    wn = math.sqrt(p.Mg / p.I1)
    return wn / (2 * math.pi), p.B1psi / (2 * math.sqrt(p.Mg * p.I1))


def clip_inputs(u: Any, params: TwinRotorParameters | None = None) -> np.ndarray:
    """Motor voltages clipped to ``+-u_max`` (the documented rule for out-of-range inputs).

    Parameters
    ----------
    u : array_like
        Voltages [V], any shape.
    params : TwinRotorParameters, optional
        Their ``u_max`` is the limit; default the defaults.

    Returns
    -------
    ndarray
        The voltages [V] as floats, shape of ``u``, clipped to ``[-u_max, u_max]``.
    """
    p = params or TwinRotorParameters()
    return np.clip(np.asarray(u, dtype=float), -p.u_max, p.u_max)


def substeps(params: TwinRotorParameters, dt: float) -> tuple[int, float]:
    """Number of RK4 substeps per sample and their length.

    Parameters
    ----------
    params : TwinRotorParameters
        Their ``substep`` [s] is the target length.
    dt : float
        Sample time [s].

    Returns
    -------
    n_sub : int
        ``round(dt / substep)``, at least 1.
    h : float
        ``dt / n_sub`` [s].
    """
    n_sub = max(1, round(dt / params.substep))
    return n_sub, dt / n_sub


def thrust(tau: Any, a: Any, b: Any, law: str, out: np.ndarray | None = None) -> np.ndarray:
    """Rotor moment from the rotor state.

    ``a tau |tau| + b tau`` for ``law="signed_square"``, ``a tau^2 + b tau`` for ``"square"``,
    evaluated as ``tau (a |tau| + b)`` (``tau (a tau + b)``).

    Parameters
    ----------
    tau : array_like
        Rotor states [model units], any shape.
    a, b : float or array_like
        Quadratic [N m per (unit of tau)^2] and linear [N m per unit of tau] coefficients,
        broadcast against ``tau``.
    law : {"signed_square", "square"}
        The thrust law (:data:`THRUST_LAWS`).
    out : ndarray, optional
        An array of the result's shape: the same operations run in place, in the same order.

    Returns
    -------
    ndarray
        The moments [N m] (``out`` when given).
    """
    if out is None:
        if law == "signed_square":
            return tau * (a * np.abs(tau) + b)
        return tau * (a * tau + b)
    if law == "signed_square":
        np.abs(tau, out=out)
        out *= a
    else:
        np.multiply(a, tau, out=out)
    out += b
    out *= tau
    return out


def derivatives(x: np.ndarray, u: np.ndarray, p: TwinRotorParameters) -> np.ndarray:
    """State derivatives of a batch: the model's equations.

    Parameters
    ----------
    x : ndarray, shape (B, 7)
        States, columns :data:`STATE_NAMES`.
    u : ndarray, shape (B, 2)
        Motor voltages (V), not clipped here.
    p : TwinRotorParameters

    Returns
    -------
    ndarray, shape (B, 7)
        Time derivatives of the states (units of the state per second).
    """
    psi, dpsi, _, dphi, t1, t2, mr = x.T
    u1, u2 = u.T
    m1 = thrust(t1, p.a1, p.b1, p.thrust_law)
    m2 = thrust(t2, p.a2, p.b2, p.thrust_law)
    dt1 = (p.k1 * u1 - p.T10 * t1) / p.T11
    dt2 = (p.k2 * u2 - p.T20 * t2) / p.T21
    dmr = (-mr + p.kc * (p.T0 * dt1 + t1)) / p.Tp
    eps = p.coulomb_velocity
    ddpsi = (
        m1
        - p.Mg * np.sin(psi)
        - p.B1psi * dpsi
        - p.B2psi * np.tanh(dpsi / eps)
        - p.Kgy * m1 * dphi * np.cos(psi)
    ) / p.I1
    if p.lock_yaw:
        ddphi = np.zeros_like(psi)
        vphi = np.zeros_like(psi)
    else:
        ddphi = (m2 - p.B1phi * dphi - p.B2phi * np.tanh(dphi / eps) - mr) / p.I2
        vphi = dphi
    return np.stack([dpsi, ddpsi, vphi, ddphi, dt1, dt2, dmr], axis=1)


def _rk4(x: np.ndarray, u: np.ndarray, p: TwinRotorParameters, dt: float, stages=None):
    """RK4 over one sample; appends the four stage points of each substep to ``stages``."""
    n_sub, h = substeps(p, dt)
    for _ in range(n_sub):
        k1 = derivatives(x, u, p)
        y2 = x + 0.5 * h * k1
        k2 = derivatives(y2, u, p)
        y3 = x + 0.5 * h * k2
        k3 = derivatives(y3, u, p)
        y4 = x + h * k3
        k4 = derivatives(y4, u, p)
        if stages is not None:
            stages.extend((x, y2, y3, y4))
        x = x + (h / 6.0) * (k1 + 2 * k2 + 2 * k3 + k4)
    return x


def step_states(x: np.ndarray, u: np.ndarray, p: TwinRotorParameters, dt: float) -> np.ndarray:
    """Reference route: advance a batch of states over one sample with the inputs held.

    Parameters
    ----------
    x : ndarray, shape (B, 7)
        States at the start of the sample, columns :data:`STATE_NAMES`.
    u : ndarray, shape (B, 2)
        Motor voltages (V), already clipped.
    p : TwinRotorParameters
    dt : float
        Sample time (s); RK4 with ``round(dt / p.substep)`` substeps.

    Returns
    -------
    ndarray, shape (B, 7)
    """
    return _rk4(x, u, p, dt)


def _check_dt(dt: Any) -> float:
    """The sample time [s] as a float, checked to be finite and > 0."""
    return positive_real(dt, "twin rotor: dt", error=PlantParameterError, unit="s")


def _check_inputs(u: Any, p: TwinRotorParameters) -> np.ndarray:
    """Voltages as a clipped (N, 2) float array; shape (N,) drives the main rotor only."""
    u = np.asarray(u, dtype=float)
    if u.ndim == 1:
        u = np.column_stack([u, np.zeros_like(u)])
    if u.ndim != 2 or u.shape[1] != 2:
        raise DataError(f"u must have shape (N, 2) (main, tail rotor), got {u.shape}")
    check_finite(u, "u", DataError)
    return clip_inputs(u, p)


def _run_arguments(
    u: Any, params: TwinRotorParameters | None, dt: Any, x0: Any
) -> tuple[TwinRotorParameters, np.ndarray, float, np.ndarray]:
    """The checked arguments of a run from rest or ``x0``: ``(params, u, dt, x0)``.

    ``params`` defaults to the defaults, ``u`` becomes clipped (N, 2) voltages, ``x0`` a
    (7,) state (rest when None; with ``lock_yaw`` its yaw rate must be 0).
    """
    p = params or TwinRotorParameters()
    u = _check_inputs(u, p)
    dt = _check_dt(dt)
    x = np.zeros(7) if x0 is None else np.asarray(x0, dtype=float).reshape(-1)
    if x.shape != (7,):
        raise DataError(f"x0 must have 7 entries, got {x.size}")
    check_finite(x, "x0", DataError)
    if p.lock_yaw and x[3] != 0:
        raise DataError(f"with lock_yaw the yaw rate x0[3] must be 0, got {x[3]!r}")
    return p, u, dt, x


def reference_trajectory(
    u: Any, params: TwinRotorParameters | None = None, dt: float = 0.1, x0: Any = None
) -> np.ndarray:
    """States at the sample times by the reference route (:func:`step_states`, one by one).

    Its arguments are those of :func:`simulate`, checked the same way.

    Parameters
    ----------
    u : array_like, shape (N, 2) or (N,)
        Main and tail rotor voltages [V] held over each sample, clipped to ``+-u_max``;
        shape (N,) drives the main rotor only.
    params : TwinRotorParameters, optional
        The model; default the manual's values.
    dt : float
        Sample time [s], > 0; default 0.1.
    x0 : array_like, shape (7,), optional
        State at ``t = 0`` (default rest); with ``lock_yaw`` its yaw rate must be 0.

    Returns
    -------
    ndarray, shape (N + 1, 7)
        States at ``t = k dt``, ``k = 0 .. N``, columns :data:`STATE_NAMES`.
    """
    p, u, dt, x = _run_arguments(u, params, dt, x0)
    x = x[None, :]
    out = np.empty((u.shape[0] + 1, 7))
    out[0] = x[0]
    for k in range(u.shape[0]):
        x = step_states(x, u[k : k + 1], p, dt)
        out[k + 1] = x[0]
    return out


# ======================================================================== the faster routes
@functools.lru_cache(maxsize=32)
def _linear_stages(p: TwinRotorParameters, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """The RK4 stage values of ``(tau1, tau2, M_R)`` over one sample as linear maps.

    Returns ``stages`` (5, n_sub, 4, 3) and ``end`` (5, 3): row ``i`` is the response to the
    ``i``-th unit vector of ``(tau1, tau2, M_R, u1, u2)`` at the sample start, from the
    reference recursion itself (:func:`_rk4`).  Their rows of :func:`derivatives` are linear
    in these five numbers and independent of the other states, so the stage values of any
    start are these rows combined (up to rounding).  Read-only (shared by the cache).
    """
    n_sub, _ = substeps(p, dt)
    x = np.zeros((5, 7))
    x[[0, 1, 2], [4, 5, 6]] = 1.0
    u = np.zeros((5, 2))
    u[[3, 4], [0, 1]] = 1.0
    points: list[np.ndarray] = []
    end = _rk4(x, u, p, dt, points)[:, 4:7]
    stages = np.stack(points, axis=1)[:, :, 4:7].reshape(5, n_sub, 4, 3)
    for a in (stages, end):
        a.flags.writeable = False
    return stages, end


def _forcing_map(p: TwinRotorParameters, dt: float, scale: float):
    """Matrix and thrust coefficients that give the pitch and yaw forcing of every stage.

    With ``s = (tau1, tau2, M_R, u1, u2)`` at the sample start and ``n = n_sub``,
    ``z = s @ matrix`` has shape (12 n + 3,).  ``f = thrust(z[:8n], a, b, law)`` followed by
    ``f[1::2] -= z[8n:12n]`` holds, for each substep and each of its 4 stages, the pair
    ``scale M1 / I1`` (pitch) and ``scale (M2 - M_R) / I2`` (yaw).  ``z[12n:]`` is
    ``(tau1, tau2, M_R)`` at the end of the sample.
    """
    stages, end = _linear_stages(p, dt)
    n_sub = stages.shape[1]
    tau = stages[..., :2].reshape(5, -1)  # tau1, tau2 at each stage
    torque = scale / p.I2 * stages[..., 2].reshape(5, -1)
    matrix = np.concatenate([tau, torque, end], axis=1)
    a = np.tile([scale / p.I1 * p.a1, scale / p.I2 * p.a2], 4 * n_sub)
    b = np.tile([scale / p.I1 * p.b1, scale / p.I2 * p.b2], 4 * n_sub)
    return matrix, a, b


def _pitch_yaw_substeps(rows, psi, w, phi, v, c):
    """RK4 substeps of pitch and yaw in Python floats (the scalar route's inner loop).

    The state is ``psi``, ``w = psi' / eps``, ``phi``, ``v = phi' / eps`` (``eps`` the Coulomb
    velocity), so that the Coulomb terms are ``tanh(w)`` and ``tanh(v)``; the stage
    derivatives ``k``, ``l`` of ``w``, ``v`` are computed times ``h / 2``, so that a half-step
    stage point is one addition.  ``rows`` yields per substep, for its 4 stages, the pitch and
    yaw forcing ``(h / 2) M1 / (I1 eps)`` and ``(h / 2) (M2 - M_R) / (I2 eps)``
    (:func:`_forcing_map`); ``c`` are the constants of :class:`ScalarStepper`.
    """
    he, hfe, h6e, third, kg, mg, b1, b2, f1, f2 = c
    sin, cos, tanh = math.sin, math.cos, math.tanh
    for a1, g1, a2, g2, a3, g3, a4, g4 in rows:
        k1 = a1 * (1.0 - kg * v * cos(psi)) - mg * sin(psi) - b1 * w - b2 * tanh(w)
        l1 = g1 - f1 * v - f2 * tanh(v)
        q = psi + he * w
        w2 = w + k1
        v2 = v + l1
        k2 = a2 * (1.0 - kg * v2 * cos(q)) - mg * sin(q) - b1 * w2 - b2 * tanh(w2)
        l2 = g2 - f1 * v2 - f2 * tanh(v2)
        q = psi + he * w2
        w3 = w + k2
        v3 = v + l2
        k3 = a3 * (1.0 - kg * v3 * cos(q)) - mg * sin(q) - b1 * w3 - b2 * tanh(w3)
        l3 = g3 - f1 * v3 - f2 * tanh(v3)
        q = psi + hfe * w3
        w4 = w + 2.0 * k3
        v4 = v + 2.0 * l3
        k4 = a4 * (1.0 - kg * v4 * cos(q)) - mg * sin(q) - b1 * w4 - b2 * tanh(w4)
        l4 = g4 - f1 * v4 - f2 * tanh(v4)
        psi += h6e * (w + 2.0 * (w2 + w3) + w4)
        phi += h6e * (v + 2.0 * (v2 + v3) + v4)
        w += third * (k1 + 2.0 * (k2 + k3) + k4)
        v += third * (l1 + 2.0 * (l2 + l3) + l4)
    return psi, w, phi, v


def _pitch_substeps(rows, psi, w, phi, v, c):
    """:func:`_pitch_yaw_substeps` with the yaw locked: yaw and yaw rate (0) do not change,
    the yaw forcing is not used."""
    he, hfe, h6e, third, _, mg, b1, b2, _, _ = c
    sin, tanh = math.sin, math.tanh
    for a1, _, a2, _, a3, _, a4, _ in rows:
        k1 = a1 - mg * sin(psi) - b1 * w - b2 * tanh(w)
        q = psi + he * w
        w2 = w + k1
        k2 = a2 - mg * sin(q) - b1 * w2 - b2 * tanh(w2)
        q = psi + he * w2
        w3 = w + k2
        k3 = a3 - mg * sin(q) - b1 * w3 - b2 * tanh(w3)
        q = psi + hfe * w3
        w4 = w + 2.0 * k3
        k4 = a4 - mg * sin(q) - b1 * w4 - b2 * tanh(w4)
        psi += h6e * (w + 2.0 * (w2 + w3) + w4)
        w += third * (k1 + 2.0 * (k2 + k3) + k4)
    return psi, w, phi, v


class ScalarStepper:
    """Fast route for one twin rotor: RK4 samples in Python floats.

    Parameters
    ----------
    params : TwinRotorParameters
        The model; its constants are bound once as Python floats.
    dt : float
        Sample time [s], > 0.

    Notes
    -----
    Per sample: one small NumPy product gives the forcing of pitch and yaw at all RK4 stages
    (see the module notes), then :func:`_pitch_yaw_substeps` steps pitch, pitch rate, yaw and
    yaw rate in plain floats with the constants bound once.  Inputs are voltages, already
    clipped; with ``lock_yaw`` the yaw rate of a state must be 0.
    """

    def __init__(self, params: TwinRotorParameters, dt: float) -> None:
        p = params
        self.params = p
        self.dt = _check_dt(dt)
        self.n_sub, h = substeps(p, self.dt)
        eps = p.coulomb_velocity
        self._eps, self._inv_eps = eps, 1.0 / eps
        hh = 0.5 * h
        self._matrix, self._a, self._b = _forcing_map(p, self.dt, hh / eps)
        self._law = p.thrust_law
        self._nf = 8 * self.n_sub
        self._consts = (
            hh * eps, h * eps, h / 6.0 * eps, 1.0 / 3.0,
            p.Kgy * eps, hh * p.Mg / (p.I1 * eps), hh * p.B1psi / p.I1,
            hh * p.B2psi / (p.I1 * eps), hh * p.B1phi / p.I2, hh * p.B2phi / (p.I2 * eps),
        )  # fmt: skip
        self._substeps = _pitch_substeps if p.lock_yaw else _pitch_yaw_substeps

    def _forcing(self, s: np.ndarray) -> tuple[list[float], np.ndarray]:
        """Stage forcing and end linear states from sample starts ``s`` (..., 5).

        Returns the forcing as one flat list, 8 numbers per substep (one list: nested lists
        of a long record cost as much as the arithmetic, and keep the garbage collector
        busy), and the linear states (..., 3) at the sample ends.
        """
        z = np.dot(s, self._matrix)
        nf = self._nf
        force = thrust(z[..., :nf], self._a, self._b, self._law)
        force[..., 1::2] -= z[..., nf : nf + nf // 2]
        return force.ravel().tolist(), z[..., nf + nf // 2 :]

    def step(self, x, u1: float, u2: float) -> tuple[float, ...]:
        """State one sample later.

        Parameters
        ----------
        x : sequence of 7 float
            State, :data:`STATE_NAMES` order and units.
        u1, u2 : float
            Main and tail rotor voltages (V), held over the sample.

        Returns
        -------
        tuple of 7 float
        """
        psi, dpsi, phi, dphi, t1, t2, mr = x
        force, end = self._forcing(np.array((t1, t2, mr, u1, u2)))
        t1, t2, mr = end.tolist()
        ie = self._inv_eps
        rows = zip(*[iter(force)] * 8)
        psi, w, phi, v = self._substeps(rows, psi, dpsi * ie, phi, dphi * ie, self._consts)
        eps = self._eps
        return psi, w * eps, phi, v * eps, t1, t2, mr

    def run(self, u: np.ndarray, x0: np.ndarray) -> np.ndarray:
        """States at the sample times for a whole input record.

        Parameters
        ----------
        u : ndarray, shape (N, 2)
            Voltages (V), already clipped.
        x0 : ndarray, shape (7,)
            Initial state.

        Returns
        -------
        ndarray, shape (N + 1, 7)
            States at ``t = k dt``, ``k = 0 .. N``.
        """
        n = u.shape[0]
        out = np.empty((n + 1, 7))
        out[0] = x0
        # the linear states at every sample start first (their own recursion), then the
        # forcing of the stages chunk by chunk
        end = self._matrix[:, self._nf + self._nf // 2 :].T.tolist()
        (e10, e11, e12, e13, e14), (e20, e21, e22, e23, e24), (e30, e31, e32, e33, e34) = end
        t1, t2, mr = x0[4:].tolist()
        lin = []
        for u1, u2 in u.tolist():
            lin.append((t1, t2, mr))
            t1, t2, mr = (
                e10 * t1 + e11 * t2 + e12 * mr + e13 * u1 + e14 * u2,
                e20 * t1 + e21 * t2 + e22 * mr + e23 * u1 + e24 * u2,
                e30 * t1 + e31 * t2 + e32 * mr + e33 * u1 + e34 * u2,
            )
        lin.append((t1, t2, mr))
        out[:, 4:] = lin
        s = np.concatenate([out[:-1, 4:], u], axis=1)
        psi, dpsi, phi, dphi = x0[:4].tolist()
        ie, eps = self._inv_eps, self._eps
        w, v = dpsi * ie, dphi * ie
        advance, consts, n_sub = self._substeps, self._consts, self.n_sub
        nonlinear = []
        for start in range(0, n, _CHUNK):
            rows = zip(*[iter(self._forcing(s[start : start + _CHUNK])[0])] * 8)
            for _ in range(min(_CHUNK, n - start)):
                psi, w, phi, v = advance(islice(rows, n_sub), psi, w, phi, v, consts)
                nonlinear.append((psi, w, phi, v))
        out[1:, :4] = nonlinear
        out[1:, 1] *= eps
        out[1:, 3] *= eps
        return out


_CHUNK = 512  # samples whose stage forcing is held at once by ScalarStepper.run


class _BatchRoute:
    """What the batch routes share: ``B`` twin rotors, their state held inside.

    A route builds what pickling cannot carry (views of its arrays, a module) in
    ``_bind``, called after ``__init__`` and after unpickling; ``_UNPICKLED`` names those
    attributes, and ``_angles`` must be one of them.  ``__init__(params, dt, batch)`` keeps
    the model, the checked sample time, the batch size and the RK4 substeps.
    """

    _UNPICKLED: tuple[str, ...] = ()

    def __init__(self, params: TwinRotorParameters, dt: float, batch: int) -> None:
        self.params = params
        self.dt = _check_dt(dt)
        self.batch = int(batch)
        self.n_sub, self._h = substeps(params, self.dt)

    def _bind(self) -> None:
        raise NotImplementedError

    def __getstate__(self) -> dict[str, Any]:
        # views do not survive pickling (they come back as copies): rebuild them
        state = self.__dict__.copy()
        for key in self._UNPICKLED:
            del state[key]
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._bind()

    @property
    def angles(self) -> np.ndarray:
        """Pitch and yaw (rad), shape (2, B), a read-only view of the state."""
        return self._angles

    def reset(self, mask: np.ndarray) -> None:
        """Put the rotors where ``mask`` is true at rest.

        Parameters
        ----------
        mask : ndarray of bool, shape (B,)
            The rotors to reset; the others keep their states.
        """
        raise NotImplementedError

    def outputs(self, out: np.ndarray) -> None:
        """Write the outputs :data:`OUTPUT_NAMES` of every rotor into ``out[:, :4]``.

        Parameters
        ----------
        out : ndarray, shape (B, k), k >= 4
            Receives pitch, yaw, pitch rate and yaw rate [rad, rad, rad/s, rad/s] in its
            first four columns; the others are left alone.
        """
        raise NotImplementedError

    def advance(self, u: np.ndarray) -> None:
        """Step every rotor over one sample with its voltages held.

        Parameters
        ----------
        u : ndarray, shape (B, 2)
            Main and tail rotor voltages [V], already clipped.
        """
        raise NotImplementedError


class BatchStepper(_BatchRoute):
    """Fast route for a batch of twin rotors: RK4 samples in NumPy, the state held inside.

    Parameters
    ----------
    params : TwinRotorParameters
        The model; its constants are folded into the stage matrices once.
    dt : float
        Sample time [s], > 0.
    batch : int
        Number of twin rotors ``B``, each a column of the state rows.

    Notes
    -----
    The forcing of every stage comes in bulk as in :class:`ScalarStepper`.  Pitch, yaw and
    the two rates are rows of ``B`` values.  Per RK4 stage the nonlinear terms take four NumPy
    calls on whole rows (``sin`` of pitch and of pitch + pi/2 for the cosine, the logistic
    function of both scaled rates for the Coulomb terms, two products for the gyroscopic
    term); the derivative is linear in them, so one matrix product gives both the next stage
    point and the running RK4 sum.  The rates are held as ``W = 2 psi' / eps`` and
    ``V = 2 phi' / eps``, so that ``tanh(psi' / eps) = 2 expit(W) - 1`` needs no scaling; the
    pitch + pi/2 row is integrated with the pitch and re-derived from it at each sample.
    Every call works on ``B`` numbers, so the time per sample grows slowly with ``B`` up to a
    few hundred rotors.
    """

    # Rows of a stage block (one per substep and stage, each row B numbers): the substep's
    # start, the running RK4 sum, the stage point (5 rows each: psi, phi, W, V, psi + pi/2,
    # the outputs first), then the terms the derivative is linear in.
    _START, _SUM, _POINT = 0, 5, 10
    _SIN, _COS, _SW, _SV, _GYRO, _A, _F, _ONE = 15, 16, 17, 18, 19, 20, 21, 22
    _ROWS = 23
    _UNPICKLED = ("_y", "_angles", "_output_scale", "_plan")

    def __init__(self, params: TwinRotorParameters, dt: float, batch: int) -> None:
        super().__init__(params, dt, batch)
        p, nb, n_sub, h = params, self.batch, self.n_sub, self._h
        eps = p.coulomb_velocity
        self._half_eps = 0.5 * eps
        self._lock = bool(p.lock_yaw)
        self._law = p.thrust_law
        self._nf = 8 * n_sub
        matrix, a, b = _forcing_map(p, self.dt, 1.0)
        self._matrix = np.ascontiguousarray(matrix.T)  # one row per forcing value
        # full-size coefficients: in NumPy's inner loops a broadcast column costs twice as
        # much as an operand of the same shape
        self._a = np.repeat(a[:, None], nb, axis=1)
        self._b = np.repeat(b[:, None], nb, axis=1)
        self._s = np.zeros((5, nb))  # tau1, tau2, M_R, u1, u2 at the sample start
        self._z = np.empty((matrix.shape[1], nb))
        self._force = np.empty((self._nf, nb))
        self._blocks = np.zeros((n_sub + 1, 4, self._ROWS, nb))
        self._blocks[:, :, self._ONE] = 1.0
        self._blocks[n_sub, 0, self._POINT + 4] = 0.5 * math.pi  # at rest: psi + pi/2
        # derivative of the stage point rows from the rows POINT .. ONE of its block
        d = np.zeros((5, self._ROWS - self._POINT))
        psi, phi, w, v, shifted = range(5)
        sin, sw, sv, gyro, fa, ff, one = (
            r - self._POINT
            for r in (self._SIN, self._SW, self._SV, self._GYRO, self._A, self._F, self._ONE)
        )
        d[psi, w] = d[shifted, w] = eps / 2  # psi' = (eps / 2) W
        d[w, fa] = 2 / eps  # W' = (2 / eps) psi''; the A row is M1 / I1
        d[w, gyro] = -p.Kgy  # the gyro row is A V cos(psi)
        d[w, sin] = -2 / eps * p.Mg / p.I1
        d[w, w] = -p.B1psi / p.I1
        d[w, sw] = -4 / eps * p.B2psi / p.I1  # tanh(W / 2) = 2 expit(W) - 1
        d[w, one] = 2 / eps * p.B2psi / p.I1
        if not self._lock:
            d[phi, v] = eps / 2
            d[v, ff] = 2 / eps  # the F row is (M2 - M_R) / I2
            d[v, v] = -p.B1phi / p.I2
            d[v, sv] = -4 / eps * p.B2phi / p.I2
            d[v, one] = 2 / eps * p.B2phi / p.I2
        # per stage: [running sum; next stage point] from [start; running sum; point; terms]
        eye, zero = np.eye(5), np.zeros((5, 5))
        self._stage_matrices = []
        for c, weight in ((0.5, 1.0), (0.5, 2.0), (1.0, 2.0), (None, 1.0)):
            add = np.hstack([zero, eye, (h / 6.0) * weight * d])
            if c is None:  # the last stage completes the sum: the next substep's start
                point = add
            else:
                point = np.hstack([eye, zero, c * h * d])
            self._stage_matrices.append(np.ascontiguousarray(np.vstack([add, point])))
        self._bind()

    def _bind(self) -> None:
        """Views into the blocks: the current state and, per stage, the rows it works on.

        Built once: slicing in the loop would cost about as much as the arithmetic.
        """
        blocks, n, start, pt = self._blocks, self.n_sub, self._START, self._POINT
        self._y = blocks[n, 0, pt : pt + 5]
        self._angles = self._y[:2].view()  # pitch, yaw
        self._angles.flags.writeable = False
        self._output_scale = np.array([1.0, 1.0, self._half_eps, self._half_eps])
        self._plan = []
        for j in range(n):
            for s in range(4):
                blk = blocks[j, s]
                nxt = blocks[j, s + 1] if s < 3 else blocks[j + 1, 0]
                if s == 0:  # the substep's start, into the start rows of its 4 blocks
                    copy = (blocks[j, :, start : start + 5], blk[pt : pt + 5])
                else:
                    copy = None
                if self._lock:  # no cosine, no yaw rate, no gyroscopic term
                    terms = (blk[pt], blk[self._SIN], blk[pt + 2], blk[self._SW], None)
                else:
                    gyro = (blk[self._COS], blk[pt + 3], blk[self._GYRO], blk[self._A])
                    terms = (blk[pt : pt + 5 : 4], blk[self._SIN : self._COS + 1],
                             blk[pt + 2 : pt + 4], blk[self._SW : self._SV + 1], gyro)  # fmt: skip
                out = nxt[self._SUM : pt + 5]
                self._plan.append((copy, *terms, self._stage_matrices[s], blk, out))

    @property
    def state(self) -> np.ndarray:
        """States (B, 7), :data:`STATE_NAMES` order and units (a copy); assign to set them.

        With ``lock_yaw`` the yaw rate is held at 0.
        """
        y = self._y
        x = np.empty((self.batch, 7))
        x[:, 0] = y[0]
        x[:, 1] = y[2] * self._half_eps
        x[:, 2] = y[1]
        x[:, 3] = y[3] * self._half_eps
        x[:, 4:] = self._s[:3].T
        return x

    @state.setter
    def state(self, x: np.ndarray) -> None:
        x = np.asarray(x, dtype=float)
        y = self._y
        y[0] = x[:, 0]
        y[1] = x[:, 2]
        y[2] = x[:, 1] / self._half_eps
        y[3] = 0.0 if self._lock else x[:, 3] / self._half_eps
        y[4] = x[:, 0] + 0.5 * math.pi
        self._s[:3] = x[:, 4:].T

    def reset(self, mask: np.ndarray) -> None:
        self._y[:, mask] = 0.0
        self._y[4, mask] = 0.5 * math.pi
        self._s[:3, mask] = 0.0

    def outputs(self, out: np.ndarray) -> None:
        np.multiply(self._y[:4].T, self._output_scale, out=out[:, :4])

    def advance(self, u: np.ndarray) -> None:
        s, z, force, nf, n = self._s, self._z, self._force, self._nf, self.n_sub
        s[3:] = u.T
        np.dot(self._matrix, s, out=z)
        thrust(z[:nf], self._a, self._b, self._law, out=force)
        blocks = self._blocks
        blocks[:n, :, self._A : self._F + 1] = force.reshape(n, 4, 2, -1)
        blocks[:n, :, self._F] -= z[nf : nf + nf // 2].reshape(n, 4, -1)
        s[:3] = z[nf + nf // 2 :]
        y = self._y
        np.add(y[0], 0.5 * math.pi, out=y[4])
        first = blocks[0, 0]
        first[self._SUM : self._POINT + 5].reshape(2, 5, -1)[...] = y  # sum and point
        sin, dot, mul = np.sin, np.dot, np.multiply
        for copy, ang, trig, rate, logit, gyro, mat, blk, out in self._plan:
            if copy is not None:
                copy[0][...] = copy[1]
            sin(ang, out=trig)
            expit(rate, out=logit)
            if gyro is not None:
                cos_row, v_row, g_row, a_row = gyro
                mul(cos_row, v_row, out=g_row)
                mul(g_row, a_row, out=g_row)
            dot(mat, blk, out=out)


# ------------------------------------------------------------------------ compiled route
def _compiled():
    """The compiled kernels module when it runs and has the twin rotor stepper, else None."""
    from .. import kernels

    c = getattr(kernels, "_c", None)
    if kernels.BACKEND != "c" or not hasattr(c, "twin_rotor_run"):
        return None
    return c


#: The compiled stepper's parameter vector, in the order of ``TRS_PARAMS`` in _kernels.c.
KERNEL_PARAMETERS = ("I1", "I2", "a1", "b1", "a2", "b2", "Mg", "B1psi", "B2psi", "B1phi",
                     "B2phi", "Kgy", "k1", "k2", "T11", "T10", "T21", "T20", "Tp", "T0", "kc",
                     "coulomb_velocity")  # fmt: skip


def _kernel_params(p: TwinRotorParameters) -> np.ndarray:
    """The parameter vector of the compiled stepper (:data:`KERNEL_PARAMETERS`)."""
    return np.array([float(getattr(p, n)) for n in KERNEL_PARAMETERS])


def _kernel_arguments(p: TwinRotorParameters, dt: float) -> tuple[np.ndarray, tuple]:
    """The parameter vector and the trailing arguments ``(n_sub, h, lock_yaw, square_law)``
    of ``twin_rotor_run`` for the sample time ``dt``."""
    n_sub, h = substeps(p, dt)
    return _kernel_params(p), (n_sub, h, bool(p.lock_yaw), p.thrust_law == "square")


class CompiledScalarStepper(ScalarStepper):
    """:class:`ScalarStepper` with the samples run by the compiled RK4 of ``flexid._kernels``.

    The compiled loop evaluates the equations of :func:`derivatives` in the RK4 of
    :func:`_rk4`, with the model's constants divided out once and ``sin``, ``cos`` and
    ``tanh`` as polynomials within a few eps of the exact values (absolute error); with possible
    FMA contraction it differs from the reference route by rounding only.

    Parameters
    ----------
    params : TwinRotorParameters
        The model, handed to the compiled loop as a vector of constants.
    dt : float
        Sample time [s], > 0, as for :class:`ScalarStepper`.
    """

    def __init__(self, params: TwinRotorParameters, dt: float) -> None:
        # not ScalarStepper.__init__: the tables of the Python route are not used here
        self.params = params
        self.dt = _check_dt(dt)
        self._c = _compiled()
        self._k, self._args = _kernel_arguments(params, self.dt)
        self.n_sub = self._args[0]
        self._x = np.empty((1, 7))
        self._u = np.empty((1, 1, 2))

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        del state["_c"]  # a module does not pickle; the unpickling process finds its own
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._c = _compiled()

    def step(self, x, u1: float, u2: float) -> tuple[float, ...]:
        xb, ub = self._x, self._u
        xb[0] = x
        ub[0, 0, 0], ub[0, 0, 1] = u1, u2
        self._c.twin_rotor_run(self._k, xb, ub, None, *self._args)
        return tuple(xb[0].tolist())

    def run(self, u: np.ndarray, x0: np.ndarray) -> np.ndarray:
        n = u.shape[0]
        out = np.empty((n + 1, 7))
        out[0] = x0
        x = np.array(x0, dtype=float).reshape(1, 7)
        u3 = np.ascontiguousarray(u, dtype=float).reshape(n, 1, 2)
        self._c.twin_rotor_run(self._k, x, u3, out[1:].reshape(n, 1, 7), *self._args)
        return out


class CompiledBatchStepper(_BatchRoute):
    """:class:`BatchStepper`'s interface, the samples run by the compiled RK4.

    Parameters
    ----------
    params : TwinRotorParameters
        The model, handed to the compiled loop as a vector of constants.
    dt : float
        Sample time [s], > 0: ``round(dt / substep)`` RK4 substeps.
    batch : int
        Number of twin rotors ``B``, the rows of the state array.
    """

    _UNPICKLED = ("_c", "_angles")  # a module does not pickle: the unpickler finds its own

    def __init__(self, params: TwinRotorParameters, dt: float, batch: int) -> None:
        super().__init__(params, dt, batch)
        self._k, self._args = _kernel_arguments(params, self.dt)
        self._x = np.zeros((self.batch, 7))
        self._u = np.empty((1, self.batch, 2))
        self._bind()

    def _bind(self) -> None:
        self._c = _compiled()
        self._angles = self._x[:, 0:3:2].T  # pitch and yaw, a view
        self._angles.flags.writeable = False

    @property
    def state(self) -> np.ndarray:
        """States (B, 7) (a copy); assign to set them.  With ``lock_yaw`` the yaw rate is 0."""
        return self._x.copy()

    @state.setter
    def state(self, x: np.ndarray) -> None:
        self._x[...] = np.asarray(x, dtype=float)
        if self.params.lock_yaw:
            self._x[:, 3] = 0.0

    def reset(self, mask: np.ndarray) -> None:
        self._x[mask] = 0.0

    def outputs(self, out: np.ndarray) -> None:
        np.take(self._x, _OUTPUT_COLUMNS, axis=1, out=out[:, :4])

    def advance(self, u: np.ndarray) -> None:
        self._u[0] = u
        self._c.twin_rotor_run(self._k, self._x, self._u, None, *self._args)


def scalar_stepper(params: TwinRotorParameters, dt: float) -> ScalarStepper:
    """The fastest available route for one twin rotor.

    Parameters
    ----------
    params : TwinRotorParameters
        The model of the rotor to step.
    dt : float
        Sample time [s] of every step.

    Returns
    -------
    ScalarStepper
        A :class:`CompiledScalarStepper` when the compiled kernels run, else a
        :class:`ScalarStepper`.
    """
    if _compiled() is not None:
        return CompiledScalarStepper(params, dt)
    return ScalarStepper(params, dt)


def batch_stepper(
    params: TwinRotorParameters, dt: float, batch: int
) -> BatchStepper | CompiledBatchStepper:
    """The fastest available route for a batch of twin rotors.

    Parameters
    ----------
    params : TwinRotorParameters
        The model, shared by the whole batch.
    dt : float
        Sample time [s], the same for every rotor.
    batch : int
        Number of rotors ``B`` stepped together.

    Returns
    -------
    BatchStepper or CompiledBatchStepper
        The compiled stepper when the compiled kernels run, else the NumPy one.
    """
    if _compiled() is not None:
        return CompiledBatchStepper(params, dt, batch)
    return BatchStepper(params, dt, batch)


def simulate(
    u: Any, params: TwinRotorParameters | None = None, dt: float = 0.1, x0: Any = None
) -> np.ndarray:
    """Response of the twin rotor to sampled motor voltages (held over each sample).

    Parameters
    ----------
    u : array_like, shape (N, 2)
        Main and tail rotor voltages [V]; clipped to ``+-u_max``.  Shape (N,) drives the main
        rotor only.
    params : TwinRotorParameters, optional
        Default :class:`TwinRotorParameters` ``()``.
    dt : float
        Sample time [s], > 0; default 0.1.
    x0 : array_like, shape (7,), optional
        Initial state (default rest), columns :data:`STATE_NAMES`; with ``lock_yaw`` its yaw
        rate must be 0.

    Returns
    -------
    ndarray, shape (N, 4)
        :data:`OUTPUT_NAMES` at ``t = k dt``.

    Notes
    -----
    Computed by the compiled RK4 when the kernels run, else by :class:`ScalarStepper`;
    :func:`reference_trajectory` gives the same samples up to rounding.
    """
    p, u, dt, x = _run_arguments(u, params, dt, x0)
    return scalar_stepper(p, dt).run(u, x)[:-1, _OUTPUT_COLUMNS]
