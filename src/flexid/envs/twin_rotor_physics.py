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
it; they are the reference route.  With :func:`outputs`, :func:`initial_state` and
:func:`input_limits`, :func:`step_states` is one of the plant's pure functions
(:class:`flexid.data.plants.PlantFunctions`, its transition).  The faster routes that compute the
same RK4 samples, and that :func:`simulate` and the environments run, are in
:mod:`flexid.envs.twin_rotor_steppers`; the tests hold them to :func:`step_states`.

References
----------
Feedback Instruments, *Twin Rotor MIMO System*, manual 33-949S: the model and the default
parameters.  The parameter table is reproduced by Pandey and Laxmi (2014, optimal control of
the TRMS by LQR) and by A. K. Agrawal (M.Tech thesis on optimal controller design for the
TRMS, NIT Rourkela, 2013), which also gives the +-2.5 V input range.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields
from typing import Any

import numpy as np

from .._validate import integer, positive_real, real
from ..errors import DataError, PlantParameterError, check_finite, plain_number
from . import sensors

__all__ = [
    "IDEAL_SENSORS",
    "OUTPUT_NAMES",
    "OUTPUT_UNITS",
    "STATE_NAMES",
    "THRUST_LAWS",
    "TwinRotorParameters",
    "clip_inputs",
    "derivatives",
    "initial_state",
    "input_limits",
    "measure",
    "modes",
    "noise_floor",
    "outputs",
    "pitch_linear_mode",
    "reference_trajectory",
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


def modes(
    params: TwinRotorParameters | None = None, inputs: Any = None
) -> tuple[np.ndarray, np.ndarray]:
    """The plant's own modes: pitch's pendulum mode linearised at an operating point.

    The operating point of constant motor voltages ``inputs``: the rotors at their steady
    states ``tau_i = k_i u_i / T_i0``, the beam at the pitch where the main rotor's moment
    balances gravity, ``Mg sin(psi) = m1(tau_1)``, at rest, yaw not turning (locked, as in
    the paper's preset, or its reaction torque balanced by the tail rotor; a turning yaw
    couples into pitch through the gyroscopic moment).  The linearisation is block
    triangular (the rotors drive pitch and yaw, nothing drives the rotors back; yaw has no
    restoring torque), so its one oscillating mode is pitch's:
    ``omega^2 = Mg cos(psi) / I1``, ``zeta = B1psi / (2 sqrt(Mg cos(psi) I1))``.  Coulomb
    friction has no linearisation at rest and is left out, as in :func:`pitch_linear_mode`.

    Parameters
    ----------
    params : TwinRotorParameters, optional
        Default the defaults.
    inputs : array_like, shape (2,), optional
        The motor voltages of the operating point [V] (a record's mean input); default 0.

    Returns
    -------
    frequency : ndarray, shape (1,) or (0,)
        Natural frequency [Hz]; none where the main rotor's moment exceeds ``Mg`` (no
        balance: the beam turns over).
    damping : ndarray, shape (1,) or (0,)
        Damping ratio [-].
    """
    p = params or TwinRotorParameters()
    u = np.zeros(2) if inputs is None else np.asarray(inputs, dtype=float).reshape(2)
    tau1 = p.k1 * u[0] / p.T10
    ratio = float(thrust(tau1, p.a1, p.b1, p.thrust_law)) / p.Mg
    if abs(ratio) >= 1.0:
        return np.zeros(0), np.zeros(0)
    stiffness = p.Mg * math.sqrt(1.0 - ratio * ratio)  # Mg cos(psi)
    w = math.sqrt(stiffness / p.I1)
    return np.array([w / (2 * math.pi)]), np.array([p.B1psi / (2 * math.sqrt(stiffness * p.I1))])


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

    The plant's pure transition (:attr:`flexid.data.plants.PlantFunctions.transition`): the
    steppers of :mod:`flexid.envs.twin_rotor_steppers` are held to it.

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


def outputs(
    x: np.ndarray, u: np.ndarray, params: TwinRotorParameters, dt: float
) -> np.ndarray:
    """The outputs of a batch of states, before the encoders: the plant's output function.

    Parameters
    ----------
    x : ndarray, shape (B, 7)
        States, columns :data:`STATE_NAMES`.
    u : ndarray, shape (B, 2)
        Motor voltages [V]; not used (no direct feed-through).
    params : TwinRotorParameters
        Not used (the outputs are states).
    dt : float
        Sample time [s]; not used.

    Returns
    -------
    ndarray, shape (B, 4)
        :data:`OUTPUT_NAMES` [rad, rad, rad/s, rad/s].
    """
    return np.asarray(x, dtype=float)[:, _OUTPUT_COLUMNS]


def initial_state(params: TwinRotorParameters, dt: float) -> np.ndarray:
    """The state at rest, where records and episodes start.

    Parameters
    ----------
    params : TwinRotorParameters
        Not used (rest is the same for every rotor).
    dt : float
        Sample time [s]; not used.

    Returns
    -------
    ndarray, shape (7,)
        Zeros, columns :data:`STATE_NAMES`.
    """
    return np.zeros(7)


def input_limits(params: TwinRotorParameters) -> tuple[np.ndarray, np.ndarray]:
    """The motor voltages' range, ``+-u_max`` for both rotors.

    Parameters
    ----------
    params : TwinRotorParameters
        Their ``u_max`` [V] is the limit.

    Returns
    -------
    low, high : ndarray, shape (2,)
        ``-u_max`` and ``u_max`` [V] for the main and tail rotor.
    """
    return np.full(2, -params.u_max), np.full(2, params.u_max)


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
        raise DataError(f"with lock_yaw the yaw rate x0[3] must be 0, got {plain_number(x[3])}")
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
