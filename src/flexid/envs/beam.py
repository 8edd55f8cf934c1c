"""Physics of the single-link flexible manipulator (Sheffield rig).

A uniform Euler-Bernoulli beam is clamped to a motor hub that rotates in the horizontal
plane; the hub torque is the input.  The beam is discretised in space by the
finite-difference method of lines: degrees of freedom
``q = [theta, y_1, ..., y_n]`` (hub angle and total transverse displacements of the ``n``
nodes, ``y_0 = 0`` at the pivot), lumped masses, symmetric ``M`` and ``K``,

    M q'' + C q' + K q = B tau,

with modal damping ``C = M Phi diag(2 zeta_k omega_k) Phi^T M`` (rigid mode undamped) plus
an optional hub viscous friction ``c_h`` on ``C[theta, theta]``.  The state space model
``x = [q; q']`` is discretised exactly for a piecewise-constant (zero-order-hold) torque with
the augmented matrix exponential ``expm([[A, B], [0, 0]] dt)``.

Outputs, in this order (:data:`OUTPUT_NAMES`, :data:`OUTPUT_UNITS`):

``hub_angle``          theta [rad]
``hub_velocity``       theta' [rad/s]
``tip_deflection``     end-point residual deflection w(l) = y_n - l theta [m]
``tip_acceleration``   total end-point acceleration y_n'' [m/s^2]

Everything here is a pure function of a frozen :class:`BeamParameters`; the discretised
model is cached per ``(params, dt)``.  The exact modal frequencies of the continuous
hub-beam (:func:`exact_frequencies`) are the validation reference for the finite-difference
model (:func:`natural_frequencies`).

The plant's pure functions (:class:`flexid.data.plants.PlantFunctions`) are :func:`step_states`
(the exact discretisation of one sample, :class:`Stepper`'s step), :func:`outputs` and
:func:`initial_state`; the environments step the same :class:`Stepper`.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import threading
from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.optimize
import scipy.signal

from flexid._validate import integer, positive_int, real
from flexid.errors import PlantParameterError, check_finite, plain_number

from . import sensors

__all__ = [
    "DAMPING_LAWS",
    "IDEAL_SENSORS",
    "OUTPUT_NAMES",
    "OUTPUT_UNITS",
    "BeamModel",
    "BeamParameters",
    "Stepper",
    "continuous_model",
    "discrete_model",
    "exact_frequencies",
    "fd_matrices",
    "initial_state",
    "measure",
    "measured_model",
    "modes",
    "natural_frequencies",
    "node_positions",
    "noise_floor",
    "outputs",
    "simulate",
    "step_states",
]

OUTPUT_NAMES: tuple[str, ...] = ("hub_angle", "hub_velocity", "tip_deflection", "tip_acceleration")
"""Names of the four plant outputs, in column order."""
OUTPUT_UNITS: tuple[str, ...] = ("rad", "rad/s", "m", "m/s^2")
"""SI units of the four plant outputs, in column order."""

DAMPING_LAWS = ("constant", "stiffness")
"""How the damping ratios of the modes beyond ``damping_ratios`` are set."""

IDEAL_SENSORS: dict[str, object] = {
    "damping_law": "constant",
    "actuator_bandwidth": None,
    "accelerometer_bandwidth": None,
    "anti_alias_fraction": None,
    "encoder_counts": None,
    "tachometer_noise": 0.0,
}
"""The chain switched off: torque applied as commanded, every output read ideally, and the
higher modes damped like the last listed one (``BeamParameters(**IDEAL_SENSORS)``)."""


def _number(name: str, value, unit: str, *, strict: bool) -> float:
    """A beam parameter: a finite real number, > 0 if ``strict`` else >= 0."""
    return real(
        value, f"beam parameter {name!r}", error=PlantParameterError, minimum=0, low_open=strict,
        unit=unit,
    )


@dataclass(frozen=True)
class BeamParameters:
    """Physical parameters of the hub-beam system (SI units); immutable and hashable.

    Defaults are the Sheffield rig values of the HBCSD paper.

    Parameters
    ----------
    length : float
        Beam length l [m], > 0.  Default 0.96.
    width : float
        Beam width b [m], > 0.  Default 19.008e-3.
    thickness : float
        Beam thickness h [m], > 0.  Default 3.2004e-3.
    youngs_modulus : float
        Young's modulus E [Pa], > 0.  Default 71e9 (aluminium).
    density : float
        Volumetric density [kg/m^3], > 0.  Default 2710.
    hub_inertia : float
        Hub inertia I_h [kg m^2], > 0.  Default 5.86e-4.
    payload_mass : float
        Tip payload mass M_p [kg], >= 0.  Default 0.
    payload_inertia : float
        Rotary inertia J_p of the tip payload about its centre [kg m^2], >= 0.  Default 0.
        Lumped on the slope of the last section (an energy-consistent approximation).
    damping_ratios : tuple of float
        Modal damping ratios of the flexible modes 1, 2, 3, ...; modes beyond the tuple use
        its last value.  Each in [0, 1).  Default (0.026, 0.038, 0.04).  The rigid-body mode
        is undamped.
    hub_viscous_friction : float
        Hub viscous friction c_h [N m s/rad], >= 0.  Default 0.
    hub_coulomb_friction : float
        Hub Coulomb friction torque tau_c [N m], >= 0.  Default 0.  When non-zero the plant is
        nonlinear: the smoothed friction torque ``-tau_c tanh(theta' / coulomb_velocity)`` is
        updated on sub-steps short enough for stability (:class:`Stepper`), and
        :func:`simulate` steps sample by sample (still batched over runs).
    coulomb_velocity : float
        Smoothing velocity of the Coulomb friction [rad/s], > 0.  Default 0.05.
    n_sections : int
        Number of finite-difference sections n, in [4, 400].  Default 40 (< 1 % frequency
        error on the first three modes needs n >= 30).
    damping_law : {"stiffness", "constant"}
        Damping of the modes beyond ``damping_ratios``.  ``"stiffness"`` (default):
        ``zeta_k = zeta_last omega_k / omega_last``, the stiffness-proportional (Rayleigh
        ``beta K``) law of material and joint damping, which grows with frequency, so that
        the beam's higher modes die out as a real beam's do.  ``"constant"``: the last
        listed ratio for every higher mode (lightly damped modes up to the Nyquist
        frequency).  The frequencies do not depend on it.
    actuator_bandwidth : float or None
        -3 dB bandwidth [Hz] of the drive amplifier's current loop, a first-order lag from
        the commanded to the applied torque.  Default 500 Hz, a current loop of a PWM
        amplifier on a small DC servo motor (hundreds of Hz to a few kHz); None: ideal.
    accelerometer_bandwidth : float or None
        Natural frequency [Hz] of the tip accelerometer, a damped (zeta = 0.707)
        second-order sensor.  Default 1000 Hz (a capacitive or piezo-resistive sensor of a
        few grams); None: ideal.
    anti_alias_fraction : float or None
        Cutoff of the anti-aliasing filter on the analog channels (hub velocity, tip
        deflection and acceleration) as a fraction of the sampling rate ``1/dt``, in
        (0, 0.5).  Default 0.2 (200 Hz at 1 kHz: above the 0-100 Hz band of the first three
        modes, well below Nyquist); None: no filter.  The filter acts on the continuous
        signal, before the sampler.
    anti_alias_order : int
        Order of the Butterworth anti-aliasing filter, in [1, 8].  Default 4.
    encoder_counts : int or None
        Counts per revolution of the hub encoder: the hub angle is read in steps of
        ``2 pi / encoder_counts``.  Default 2048 (the rig's encoder, 2,048 pulses per
        revolution); None: ideal.
    tachometer_noise : float
        Standard deviation [rad/s] of the tachometer's white noise (ripple and brush
        noise) on the hub velocity, >= 0.  Default 0.005.

    Notes
    -----
    ``BeamParameters(**IDEAL_SENSORS)`` switches the measurement and actuation chain off:
    the data are then those of the beam alone, as before the chain existed.
    """

    length: float = 0.96
    width: float = 19.008e-3
    thickness: float = 3.2004e-3
    youngs_modulus: float = 71e9
    density: float = 2710.0
    hub_inertia: float = 5.86e-4
    payload_mass: float = 0.0
    payload_inertia: float = 0.0
    damping_ratios: tuple[float, ...] = (0.026, 0.038, 0.04)
    hub_viscous_friction: float = 0.0
    hub_coulomb_friction: float = 0.0
    coulomb_velocity: float = 0.05
    n_sections: int = 40
    damping_law: str = "stiffness"
    actuator_bandwidth: float | None = 500.0
    accelerometer_bandwidth: float | None = 1000.0
    anti_alias_fraction: float | None = 0.2
    anti_alias_order: int = 4
    encoder_counts: int | None = 2048
    tachometer_noise: float = 0.005

    def __post_init__(self) -> None:
        strict = {
            "length": "m",
            "width": "m",
            "thickness": "m",
            "youngs_modulus": "Pa",
            "density": "kg/m^3",
            "hub_inertia": "kg m^2",
            "coulomb_velocity": "rad/s",
        }
        loose = {
            "payload_mass": "kg",
            "payload_inertia": "kg m^2",
            "hub_viscous_friction": "N m s/rad",
            "hub_coulomb_friction": "N m",
        }
        for name, unit in strict.items():
            object.__setattr__(self, name, _number(name, getattr(self, name), unit, strict=True))
        for name, unit in loose.items():
            object.__setattr__(self, name, _number(name, getattr(self, name), unit, strict=False))
        ratios = self.damping_ratios
        if np.isscalar(ratios):
            ratios = (ratios,)
        try:
            ratios = tuple(float(z) for z in ratios)
        except (TypeError, ValueError):
            raise PlantParameterError(
                "beam parameter 'damping_ratios' must be a sequence of numbers in [0, 1), "
                f"got {self.damping_ratios!r}"
            ) from None
        if not ratios or not all(math.isfinite(z) and 0.0 <= z < 1.0 for z in ratios):
            raise PlantParameterError(
                "beam parameter 'damping_ratios' must be a non-empty sequence of values in "
                f"[0, 1), got {self.damping_ratios!r}"
            )
        object.__setattr__(self, "damping_ratios", ratios)
        n = integer(
            self.n_sections, "beam parameter 'n_sections'", error=PlantParameterError,
            minimum=4, maximum=400,
        )
        object.__setattr__(self, "n_sections", n)
        self._check_chain()

    def _check_chain(self) -> None:
        if self.damping_law not in DAMPING_LAWS:
            raise PlantParameterError(
                f"beam parameter 'damping_law' must be one of {DAMPING_LAWS}, "
                f"got {self.damping_law!r}"
            )
        for name in ("actuator_bandwidth", "accelerometer_bandwidth"):
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, _number(name, value, "Hz", strict=True))
        frac = self.anti_alias_fraction
        if frac is not None:
            frac = _number("anti_alias_fraction", frac, "of the sampling rate", strict=True)
            if frac >= 0.5:
                raise PlantParameterError(
                    "beam parameter 'anti_alias_fraction' must be below 0.5 (the Nyquist "
                    f"frequency), got {plain_number(frac)}"
                )
            object.__setattr__(self, "anti_alias_fraction", frac)
        order = integer(
            self.anti_alias_order, "beam parameter 'anti_alias_order'",
            error=PlantParameterError, minimum=1, maximum=8,
        )
        object.__setattr__(self, "anti_alias_order", order)
        counts = integer(
            self.encoder_counts, "beam parameter 'encoder_counts' (counts per revolution)",
            error=PlantParameterError, minimum=1, none_ok=True,
        )
        object.__setattr__(self, "encoder_counts", counts)
        object.__setattr__(
            self,
            "tachometer_noise",
            _number("tachometer_noise", self.tachometer_noise, "rad/s", strict=False),
        )

    @property
    def ideal_sensors(self) -> bool:
        """True when the measurement and actuation chain is off (:data:`IDEAL_SENSORS`)."""
        return all(getattr(self, k) == v for k, v in IDEAL_SENSORS.items())

    @property
    def encoder_step(self) -> float:
        """Hub-angle resolution ``2 pi / encoder_counts`` [rad] (0 for an ideal encoder)."""
        return 0.0 if self.encoder_counts is None else 2.0 * math.pi / self.encoder_counts

    # ---- derived properties -------------------------------------------------------------
    @property
    def area(self) -> float:
        """Cross-section area A = b h [m^2]."""
        return self.width * self.thickness

    @property
    def second_moment(self) -> float:
        """Second moment of area I = b h^3 / 12 [m^4]."""
        return self.width * self.thickness**3 / 12.0

    @property
    def flexural_rigidity(self) -> float:
        """Flexural rigidity EI [N m^2]."""
        return self.youngs_modulus * self.second_moment

    @property
    def mass_per_length(self) -> float:
        """Mass per unit length rho A [kg/m]."""
        return self.density * self.area

    @property
    def beam_mass(self) -> float:
        """Beam mass rho A l [kg]."""
        return self.mass_per_length * self.length

    @property
    def beam_inertia(self) -> float:
        """Beam inertia about the hub axis I_b = rho A l^3 / 3 [kg m^2]."""
        return self.mass_per_length * self.length**3 / 3.0

    @property
    def total_inertia(self) -> float:
        """Rigid-body inertia J = I_h + I_b + M_p l^2 + J_p [kg m^2]."""
        return (
            self.hub_inertia
            + self.beam_inertia
            + self.payload_mass * self.length**2
            + self.payload_inertia
        )

    @property
    def is_linear(self) -> bool:
        """True when there is no Coulomb friction (the plant is then LTI)."""
        return self.hub_coulomb_friction == 0.0

    def replace(self, **changes) -> BeamParameters:
        """A copy with some parameters changed.

        Parameters
        ----------
        **changes
            New values of fields (SI units, as in the class), validated as in the
            constructor.

        Returns
        -------
        BeamParameters
            The new parameters.

        Raises
        ------
        PlantParameterError
            If a new value is invalid.
        TypeError
            For a name that is not a field.
        """
        return dataclasses.replace(self, **changes)

    def damping_ratio(self, mode: int, omega: np.ndarray | None = None) -> float:
        """Damping ratio of one flexible mode.

        Parameters
        ----------
        mode : int
            Flexible mode number, 1-based (the rigid-body mode is not counted).
        omega : ndarray, shape (n_sections + 1,), optional
            Undamped modal frequencies [rad/s], rigid mode first, when the caller has them;
            the ``"stiffness"`` law needs them beyond ``damping_ratios`` (computed here
            when omitted).

        Returns
        -------
        float
            The ratio ``zeta``: listed in ``damping_ratios``, else by ``damping_law``.
        """
        listed = len(self.damping_ratios)
        if mode <= listed or self.damping_law == "constant":
            return self.damping_ratios[min(mode, listed) - 1]
        if omega is None:
            omega = _modes(self)[0]
        return self.damping_ratios[-1] * float(omega[mode] / omega[listed])


def _params(params: BeamParameters | None) -> BeamParameters:
    if params is None:
        return _DEFAULT
    if not isinstance(params, BeamParameters):
        raise PlantParameterError(
            f"params must be a BeamParameters instance or None, got {type(params).__name__}"
        )
    return params


def _check_dt(dt: float) -> float:
    return real(
        dt, "sample time 'dt'", error=PlantParameterError, minimum=0, maximum=0.1, low_open=True,
        unit="s",
    )


# ---- exact continuous solution ----------------------------------------------------------
def _char_det(lam, mu_h: float, mu_p: float, mu_j: float):
    """Characteristic determinant of the hub-beam at lambda = beta l (scaled, sign-preserving).

    Mode shape Y = c1 sin + c2 cos + c3 sinh + c4 cosh of (beta x); rows are the boundary
    conditions Y(0) = 0, hub torque balance, tip moment, tip shear.  The hyperbolic columns
    are divided by cosh(lambda) (a positive factor: same roots, bounded entries).  ``lam``
    may be a scalar or an array (evaluated elementwise).
    """
    lam = np.asarray(lam, dtype=float)
    s, c = np.sin(lam), np.cos(lam)
    th = np.tanh(lam)
    ech = np.exp(-lam) * 2.0 / (1.0 + np.exp(-2.0 * lam))  # 1 / cosh, overflow-free
    zero, one = np.zeros_like(lam), np.ones_like(lam)
    l3 = lam**3
    f0 = [zero, one, zero, ech]
    d1_0 = [one, zero, ech, zero]
    d2_0 = [zero, -one, zero, ech]
    fl = [s, c, th, one]
    d1_l = [c, -s, one, th]
    d2_l = [-s, -c, th, one]
    d3_l = [-c, s, one, th]
    rows = [
        f0,
        [mu_h * l3 * a + b for a, b in zip(d1_0, d2_0)],
        [-mu_j * l3 * a + b for a, b in zip(d1_l, d2_l)],
        [mu_p * lam * a + b for a, b in zip(fl, d3_l)],
    ]
    m = np.moveaxis(np.array(rows), (0, 1), (-2, -1))  # (..., 4, 4)
    return np.linalg.det(m)


def _char_det_scalar(lam: float, mu_h: float, mu_p: float, mu_j: float) -> float:
    return float(_char_det(lam, mu_h, mu_p, mu_j))


def exact_frequencies(params: BeamParameters | None = None, n_modes: int = 3) -> np.ndarray:
    """Exact natural frequencies of the continuous hub-beam (Euler-Bernoulli).

    Roots ``lambda = beta l`` of the 4 x 4 characteristic determinant of the boundary
    conditions (pinned at the hub with hub inertia, free end with payload mass and rotary
    inertia), bracketed by sign changes on a grid of step
    0.005 and refined with Brent's method; ``f = lambda^2 sqrt(EI / (rho A l^4)) / (2 pi)``.
    The rigid-body mode (0 Hz) is not returned.  Damping and friction are ignored.

    Parameters
    ----------
    params : BeamParameters, optional
        Plant parameters (default: :class:`BeamParameters` defaults).
    n_modes : int
        Number of flexible modes, >= 1.

    Returns
    -------
    ndarray, shape (n_modes,)
        Frequencies [Hz], ascending.
    """
    p = _params(params)
    n_modes = positive_int(n_modes, "n_modes", error=PlantParameterError)
    rho_a, ell = p.mass_per_length, p.length
    mu_h = p.hub_inertia / (rho_a * ell**3)
    mu_p = p.payload_mass / (rho_a * ell)
    mu_j = p.payload_inertia / (rho_a * ell**3)
    roots: list[float] = []
    step, lo = 0.005, 1e-2
    while len(roots) < n_modes:  # one root per ~pi interval: usually a single pass
        grid = lo + step * np.arange(int((n_modes + 2) * math.pi / step) + 1)
        values = _char_det(grid, mu_h, mu_p, mu_j)
        for i in np.flatnonzero(values[:-1] * values[1:] <= 0.0):
            if values[i] == 0.0:
                roots.append(float(grid[i]))
            elif values[i + 1] != 0.0:
                root = scipy.optimize.brentq(
                    _char_det_scalar, grid[i], grid[i + 1], args=(mu_h, mu_p, mu_j), xtol=1e-13
                )
                roots.append(root)
        lo = grid[-1]
        if lo > 1e3:  # pragma: no cover - defensive
            raise PlantParameterError("exact_frequencies: root bracketing failed")
    lam = np.array(roots[:n_modes])
    return lam**2 * math.sqrt(p.flexural_rigidity / (rho_a * ell**4)) / (2.0 * math.pi)


# ---- finite-difference model ------------------------------------------------------------
def node_positions(params: BeamParameters | None = None) -> np.ndarray:
    """Positions of the finite-difference nodes along the beam.

    Parameters
    ----------
    params : BeamParameters, optional
        The beam (default: the rig's :class:`BeamParameters`).

    Returns
    -------
    ndarray, shape (n + 1,)
        ``x_i = i l / n`` [m] for the nodes ``i = 0..n`` (``n = n_sections``), hub first.
    """
    p = _params(params)
    return np.linspace(0.0, p.length, p.n_sections + 1)


@functools.lru_cache(maxsize=64)
def _fd_matrices(p: BeamParameters) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    n = p.n_sections
    dx = p.length / n
    ei, rho_a = p.flexural_rigidity, p.mass_per_length
    nd = n + 1  # DOFs: theta, y_1..y_n
    m = np.zeros((nd, nd))
    m[0, 0] = p.hub_inertia
    m[np.arange(1, n), np.arange(1, n)] = rho_a * dx
    m[n, n] = rho_a * dx / 2.0 + p.payload_mass
    if p.payload_inertia > 0.0:  # J_p on the slope (y_n - y_{n-1}) / dx of the last section
        jp = p.payload_inertia / dx**2
        m[np.ix_([n - 1, n], [n - 1, n])] += jp * np.array([[1.0, -1.0], [-1.0, 1.0]])
    k = np.zeros((nd, nd))
    k[0, 0] = 2.0 * ei / dx
    k[0, 1] = -2.0 * ei / dx**2
    g = ei / dx**3
    stencil = (1.0, -4.0, 6.0, -4.0, 1.0)
    for i in range(1, n):  # interior node rows (multiplied by dx: symmetric K)
        for off, c in zip(range(-2, 3), stencil):
            j = i + off
            if j == -1:  # ghost from the hub slope: y_{-1} = y_1 - 2 dx theta
                k[i, 1] += g * c
                k[i, 0] += -2.0 * dx * g * c
            elif j == 0:  # pinned at the pivot
                continue
            elif j == n + 1:  # ghost from y''(l) = 0: y_{n+1} = 2 y_n - y_{n-1}
                k[i, n] += 2.0 * g * c
                k[i, n - 1] -= g * c
            else:
                k[i, j] += g * c
    k[n, n - 2] += g  # free end: shear condition with the tip mass folded into node n
    k[n, n - 1] += -2.0 * g
    k[n, n] += g
    b = np.zeros(nd)
    b[0] = 1.0
    for a in (m, k, b):
        a.setflags(write=False)
    return m, k, b


def fd_matrices(params: BeamParameters | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mass, stiffness and input matrices of the finite-difference model.

    Parameters
    ----------
    params : BeamParameters, optional
        Plant parameters.

    Returns
    -------
    M : ndarray, shape (n + 1, n + 1)
        Mass matrix (symmetric positive definite) for ``q = [theta, y_1, ..., y_n]``
        [kg m^2 on theta, kg on the nodes].
    K : ndarray, shape (n + 1, n + 1)
        Stiffness matrix (symmetric positive semi-definite, one rigid-body null vector).
    B : ndarray, shape (n + 1,)
        Torque input vector (``e_theta``).
    """
    m, k, b = _fd_matrices(_params(params))
    return m.copy(), k.copy(), b.copy()


@functools.lru_cache(maxsize=64)
def _modes(p: BeamParameters) -> tuple[np.ndarray, np.ndarray]:
    m, k, _ = _fd_matrices(p)
    w2, phi = scipy.linalg.eigh(k, m)
    w2 = np.clip(w2, 0.0, None)
    return np.sqrt(w2), phi


def natural_frequencies(params: BeamParameters | None = None, n_modes: int = 3) -> np.ndarray:
    """Undamped natural frequencies of the finite-difference model.

    From the generalised eigenproblem ``K phi = omega^2 M phi``; the rigid-body mode (0 Hz)
    is skipped.

    Parameters
    ----------
    params : BeamParameters, optional
        The beam (default: the rig's :class:`BeamParameters`).
    n_modes : int, optional
        Number of flexible modes, in ``[1, n_sections]`` (default 3).

    Returns
    -------
    ndarray, shape (n_modes,)
        Frequencies [Hz] in increasing order.

    Raises
    ------
    PlantParameterError
        If ``n_modes`` is out of range.
    """
    p = _params(params)
    n_modes = integer(
        n_modes, "n_modes (at most n_sections)", error=PlantParameterError, minimum=1,
        maximum=p.n_sections,
    )
    omega, _ = _modes(p)
    return omega[1 : 1 + n_modes] / (2.0 * math.pi)


def modes(params: BeamParameters | None = None, inputs=None) -> tuple[np.ndarray, np.ndarray]:
    """The plant's own modes: natural frequency and damping ratio of each flexible mode.

    The complex eigenvalue pairs ``s`` of :func:`continuous_model`'s ``A`` (the beam on its
    hub, modal damping and hub viscous friction included, the measurement chain left out):
    ``f = |s| / (2 pi)``, ``zeta = -Re(s) / |s|``.  The rigid-body mode (at 0 Hz) and
    overdamped modes (real eigenvalues) are left out.

    Parameters
    ----------
    params : BeamParameters, optional
        The beam (default: the rig's :class:`BeamParameters`).
    inputs : array_like, optional
        The operating point's input; the beam is linear, its modes do not depend on it.

    Returns
    -------
    frequency : ndarray, shape (k,)
        Natural frequencies [Hz], increasing.
    damping : ndarray, shape (k,)
        Their damping ratios [-].
    """
    p = _params(params)
    s = np.linalg.eigvals(_continuous(p)[0])
    # the rigid body's double eigenvalue at 0 comes out of eigvals split by rounding, as a
    # pair some 1e-5 of the first flexible frequency: a mode is at least 1e-3 of that one
    first = _modes(p)[0][1]
    s = s[(s.imag > 0) & (np.abs(s) > 1e-3 * first)]
    w = np.abs(s)
    order = np.argsort(w)
    return w[order] / (2.0 * math.pi), -s.real[order] / w[order]


@functools.lru_cache(maxsize=64)
def _continuous(p: BeamParameters) -> tuple[np.ndarray, ...]:
    m, k, b = _fd_matrices(p)
    nd = m.shape[0]
    omega, phi = _modes(p)
    zeta = np.array([0.0] + [p.damping_ratio(i, omega) for i in range(1, nd)])
    mphi = m @ phi
    c = (mphi * (2.0 * zeta * omega)) @ mphi.T
    c[0, 0] += p.hub_viscous_friction
    minv_k = np.linalg.solve(m, k)
    minv_c = np.linalg.solve(m, c)
    minv_b = np.linalg.solve(m, b)
    a = np.zeros((2 * nd, 2 * nd))
    a[:nd, nd:] = np.eye(nd)
    a[nd:, :nd] = -minv_k
    a[nd:, nd:] = -minv_c
    bc = np.concatenate([np.zeros(nd), minv_b])[:, None]
    n = p.n_sections
    cy = np.zeros((4, 2 * nd))
    cy[0, 0] = 1.0
    cy[1, nd] = 1.0
    cy[2, n] = 1.0
    cy[2, 0] = -p.length
    cy[3] = a[nd + n]
    dy = np.zeros((4, 1))
    dy[3, 0] = bc[nd + n, 0]
    for arr in (a, bc, cy, dy):
        arr.setflags(write=False)
    return a, bc, cy, dy


def _sensor_filters(p: BeamParameters, dt: float) -> list:
    """Filter of each output channel (OUTPUT_NAMES order); the encoder has none."""
    aa = None
    if p.anti_alias_fraction is not None:
        aa = sensors.butterworth(p.anti_alias_order, p.anti_alias_fraction / dt)
    acc = aa
    if p.accelerometer_bandwidth is not None:
        acc = sensors.second_order_lowpass(p.accelerometer_bandwidth)
        if aa is not None:
            acc = sensors.series(acc, aa)
    return [None, aa, aa, acc]


def _measured(p: BeamParameters, dt: float) -> tuple[np.ndarray, ...]:
    """The beam with its chain: inputs [commanded torque, torque at the hub] when there is an
    actuator, [torque] when there is not."""
    a, b, c, d = _continuous(p)
    if p.actuator_bandwidth is not None:
        al, bl, cl, dl = sensors.first_order_lag(p.actuator_bandwidth)
        n = a.shape[0]
        a_act = np.zeros((n + 1, n + 1))
        a_act[:n, :n] = a
        a_act[:n, n:] = b @ cl
        a_act[n:, n:] = al
        b_act = np.zeros((n + 1, 2))
        b_act[:n, :1] = b @ dl
        b_act[:n, 1:] = b
        b_act[n:, :1] = bl
        a, b, c, d = a_act, b_act, np.hstack([c, d @ cl]), np.hstack([d @ dl, d])
    filters = _sensor_filters(p, dt)
    if any(f is not None for f in filters):
        a, b, c, d = sensors.filter_outputs((a, b, c, d), filters)
    return a, b, c, d


def measured_model(
    params: BeamParameters | None = None, dt: float = 1e-3
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Continuous-time model of the beam seen through its chain, for sampling at ``dt``.

    The actuator lag in front of the beam, and behind it the accelerometer and the
    anti-aliasing filter of the analog channels (the filter's cutoff depends on ``dt``).
    The state is ``[q; q'; actuator; filters]``.  With ideal sensors this is
    :func:`continuous_model`.

    Parameters
    ----------
    params : BeamParameters, optional
        The beam and its chain (default: the rig's :class:`BeamParameters`).
    dt : float, optional
        Sample time [s] the model will be sampled at (default 1e-3).

    Returns
    -------
    A : ndarray, shape (n_x, n_x)
    B : ndarray, shape (n_x, 1)
        From the commanded torque [N m].
    C : ndarray, shape (4, n_x)
    D : ndarray, shape (4, 1)
    """
    p = _params(params)
    a, b, c, d = _measured(p, _check_dt(dt))
    return a.copy(), b[:, :1].copy(), c.copy(), d[:, :1].copy()


def measure(y: np.ndarray, params: BeamParameters | None = None) -> np.ndarray:
    """Read sampled outputs through the digital sensors: the encoder's steps.

    The hub angle (column 0) is rounded to multiples of :attr:`BeamParameters.encoder_step`;
    the other columns are returned unchanged (their chain is in :func:`measured_model`, the
    tachometer's noise in :func:`noise_floor`).

    Parameters
    ----------
    y : ndarray, shape (..., 4)
        Sampled outputs in :data:`OUTPUT_NAMES` order and :data:`OUTPUT_UNITS`.
    params : BeamParameters, optional
        The beam (default: the rig's :class:`BeamParameters`).

    Returns
    -------
    ndarray, shape (..., 4)
        The measured outputs (a copy; ``y`` itself is not changed).
    """
    p = _params(params)
    y = np.array(y, dtype=float)
    if p.encoder_counts is not None:
        y[..., 0] = sensors.quantise(y[..., 0], p.encoder_step)
    return y


def noise_floor(params: BeamParameters | None = None) -> np.ndarray:
    """Standard deviation of each output's own sensor noise.

    Parameters
    ----------
    params : BeamParameters, optional
        The beam (default: the rig's :class:`BeamParameters`).

    Returns
    -------
    ndarray, shape (4,)
        In :data:`OUTPUT_UNITS`: only the hub velocity has one (``tachometer_noise``
        [rad/s]); the others are 0.
    """
    p = _params(params)
    return np.array([0.0, p.tachometer_noise, 0.0, 0.0])


def continuous_model(
    params: BeamParameters | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Continuous-time state space ``x' = A x + B tau``, ``y = C x + D tau``.

    The state is ``x = [q; q']`` with ``q = [theta, y_1, ..., y_n]`` (rad, m; rad/s, m/s).
    Coulomb friction (if any) is not included, nor is the measurement and actuation chain
    (see :func:`measured_model`).

    Parameters
    ----------
    params : BeamParameters, optional
        The beam (default: the rig's :class:`BeamParameters`).

    Returns
    -------
    A : ndarray, shape (2 n + 2, 2 n + 2)
    B : ndarray, shape (2 n + 2, 1)
    C : ndarray, shape (4, 2 n + 2)
        Rows in :data:`OUTPUT_NAMES` order.
    D : ndarray, shape (4, 1)
    """
    return tuple(x.copy() for x in _continuous(_params(params)))  # type: ignore[return-value]


class BeamModel:
    """Exact zero-order-hold discretisation of the beam model at one sample time.

    Obtain it from :func:`discrete_model` (cached).  The matrices are read-only.

    Parameters
    ----------
    params : BeamParameters
        The beam and its measurement and actuation chain.
    dt : float
        Sample time [s], > 0 (not checked here; :func:`discrete_model` checks it).

    Attributes
    ----------
    params : BeamParameters
    dt : float
        Sample time [s].
    A, B, C, D : ndarray
        ``x[k+1] = A x[k] + B tau[k]``, ``y[k] = C x[k] + D tau[k]`` for the commanded
        torque ``tau``; shapes (n_x, n_x), (n_x, 1), (4, n_x), (4, 1).
    B_hub, D_hub : ndarray
        The same for a torque acting at the hub itself (friction), bypassing the actuator;
        equal to ``B`` and ``D`` when the actuator is ideal.
    n_states : int
        ``2 (n_sections + 1)`` beam states ``[q; q']`` first, then the actuator's state and
        the sensor filters' states (see :func:`measured_model`).
    """

    def __init__(self, params: BeamParameters, dt: float):
        self.params = params
        self.dt = dt
        ac, bc, cy, dy = _measured(params, dt)
        nx = ac.shape[0]
        nu = bc.shape[1]
        aug = np.zeros((nx + nu, nx + nu))
        aug[:nx, :nx] = ac
        aug[:nx, nx:] = bc
        e = scipy.linalg.expm(aug * dt)
        self.A = e[:nx, :nx].copy()
        self.B = e[:nx, nx : nx + 1].copy()
        self.B_hub = e[:nx, nx + nu - 1 :].copy()
        self.C = np.array(cy)
        self.D = dy[:, :1].copy()
        self.D_hub = dy[:, nu - 1 :].copy()
        self.n_states = nx
        for arr in (self.A, self.B, self.B_hub, self.C, self.D, self.D_hub):
            arr.setflags(write=False)
        self._reset_markov()

    def __getstate__(self) -> dict:
        # the lock cannot be pickled, and the impulse-response cache is left behind (it can
        # be large, and the copy recomputes the same values on demand)
        state = self.__dict__.copy()
        for key in ("_markov", "_markov_len", "_chunk", "_chunk_step_t", "_markov_lock"):
            del state[key]
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._reset_markov()

    def _reset_markov(self) -> None:
        # Rows 0.._markov_len-1 of _markov are final; _chunk holds the states of the last
        # computed chunk, from which the next one is computed (see markov_parameters).  The
        # lock keeps a model shared between threads consistent.
        self._markov = np.empty((1, 4))
        self._markov[0] = self.D[:, 0]
        self._markov_len = 1
        self._chunk: np.ndarray | None = None
        self._chunk_step_t: np.ndarray | None = None
        self._markov_lock = threading.Lock()

    def state_powers(self, x0: np.ndarray, n: int) -> np.ndarray:
        """Return ``A^k x0`` for k = 0..n-1 by repeated doubling (no per-sample loop).

        Parameters
        ----------
        x0 : ndarray, shape (n_x,) or (B, n_x)
        n : int

        Returns
        -------
        ndarray, shape (n, n_x) or (n, B, n_x)
        """
        x0 = np.asarray(x0, dtype=float)
        out = np.empty((n, *x0.shape))
        if n == 0:
            return out
        out[0] = x0
        filled = 1
        power = np.asarray(self.A)  # A^filled
        while filled < n:
            take = min(filled, n - filled)
            out[filled : filled + take] = out[:take] @ power.T
            filled += take
            if filled < n:  # only reached after a full doubling (take == previous filled)
                power = power @ power
        return out

    def projected_powers(self, x0: np.ndarray, n: int, proj: np.ndarray) -> np.ndarray:
        """Return ``proj A^k x0`` for k = 0..n-1 in memory-bounded blocks.

        Parameters
        ----------
        x0 : ndarray, shape (n_x,) or (B, n_x)
        n : int
        proj : ndarray, shape (p, n_x)

        Returns
        -------
        ndarray, shape (n, p) or (n, B, p)
        """
        x0 = np.asarray(x0, dtype=float)
        out = np.empty((n, *x0.shape[:-1], proj.shape[0]))
        if n == 0:
            return out
        block = max(1, min(n, _BLOCK_ELEMENTS // x0.size))
        current = self.state_powers(x0, block)  # A^k x0, k < block
        step = np.linalg.matrix_power(np.asarray(self.A), block).T if block < n else None
        start = 0
        while start < n:
            take = min(block, n - start)
            out[start : start + take] = current[:take] @ proj.T
            start += take
            if start < n:
                current = current @ step
        return out

    def markov_parameters(self, n: int) -> np.ndarray:
        """Impulse response ``h[0] = D``, ``h[k] = C A^(k-1) B`` (k >= 1), shape (n, 4).

        The result is cached and extended on demand, and every entry is computed by one fixed
        route whatever ``n`` and whatever was asked before, so the returned values are
        bit-identical across calls, call orders and processes (on one machine and library
        set).  ``h[1 + j]`` for ``j`` in chunk ``c``, ``[c L, (c + 1) L)`` with
        ``L = _MARKOV_CHUNK``, is ``C X_c[j - c L]``, where ``X_0 = [A^i B]`` (i < L) by
        doubling and ``X_(c+1) = X_c (A^L)^T``: every product has the same shapes for every
        chunk, since a BLAS product's rounding can depend on its shapes.

        Parameters
        ----------
        n : int
            Number of samples, >= 0.

        Returns
        -------
        ndarray, shape (n, 4)
            Read-only.
        """
        with self._markov_lock:
            if self._markov_len < n:
                self._extend_markov(n)
            h = self._markov[:n]
        h.setflags(write=False)
        return h

    def _extend_markov(self, n: int) -> None:
        """Compute the chunks of the impulse response up to sample ``n`` (caller holds lock)."""
        size = _MARKOV_CHUNK
        have = (self._markov_len - 1) // size
        need = -(-(n - 1) // size)
        rows = 1 + need * size
        if rows > self._markov.shape[0]:
            # room for twice the chunks held so far: a record growing a chunk at a time does
            # not copy the cache each time (the extra rows are filled only when asked for)
            capacity = 1 + max(need, 2 * have) * size
            grown = np.empty((capacity, 4))
            grown[: self._markov_len] = self._markov[: self._markov_len]
            self._markov = grown
        c_t = np.asarray(self.C).T
        for chunk in range(have, need):
            if chunk == 0:
                states, step = self._first_chunk(size)
                self._chunk_step_t = np.ascontiguousarray(step.T)
            else:
                states = self._chunk @ self._chunk_step_t
            self._chunk = states
            self._markov[1 + chunk * size : 1 + (chunk + 1) * size] = states @ c_t
        self._markov_len = rows

    def _first_chunk(self, size: int) -> tuple[np.ndarray, np.ndarray]:
        """``A^i B`` for i < ``size`` (a power of two) by doubling, and ``A^size``."""
        out = np.empty((size, self.n_states))
        out[0] = self.B[:, 0]
        power = np.asarray(self.A)  # A^filled
        filled = 1
        while filled < size:
            out[filled : 2 * filled] = out[:filled] @ power.T
            power = power @ power
            filled *= 2
        return out, power


_MARKOV_CHUNK = 512  # impulse-response samples per chunk: a power of two (BeamModel._first_chunk)
_BLOCK_ELEMENTS = 1 << 21  # states held at once by BeamModel.projected_powers (16 MB)


@functools.lru_cache(maxsize=32)
def _discrete(p: BeamParameters, dt: float) -> BeamModel:
    return BeamModel(p, dt)


def discrete_model(params: BeamParameters | None = None, dt: float = 1e-3) -> BeamModel:
    """Exact ZOH discretisation of the linear beam model, cached per ``(params, dt)``.

    Parameters
    ----------
    params : BeamParameters, optional
    dt : float
        Sample time [s], in (0, 0.1].

    Returns
    -------
    BeamModel
    """
    return _discrete(_params(params), _check_dt(dt))


def _as_state(x0, model: BeamModel, batch: int | None) -> np.ndarray | None:
    if x0 is None:
        return None
    x0 = np.asarray(x0, dtype=float)
    nx = model.n_states
    ok_shapes = [(nx,)] + ([(batch, nx)] if batch is not None else [])
    if x0.shape not in ok_shapes:
        raise PlantParameterError(
            f"initial state x0 must have shape {' or '.join(map(str, ok_shapes))} "
            f"([q; q'] with q = [theta, y_1..y_n]), got {x0.shape}"
        )
    check_finite(x0, "initial state x0", PlantParameterError)
    return x0


def simulate(
    torque,
    params: BeamParameters | None = None,
    dt: float = 1e-3,
    x0=None,
) -> np.ndarray:
    """Simulate the flexible manipulator for a sampled (zero-order-hold) hub torque.

    Parameters
    ----------
    torque : array_like, shape (N,) or (B, N)
        Hub torque [N m], held constant over each sample interval; a 2-D array is a batch of
        ``B`` independent runs.
    params : BeamParameters, optional
        Plant parameters (default rig).
    dt : float
        Sample time [s], default 1 ms.
    x0 : array_like, shape (n_x,) or (B, n_x), optional
        Initial state ``[q; q']`` (default: at rest, zero); see :func:`continuous_model`.

    Returns
    -------
    ndarray, shape (N, 4) or (B, N, 4)
        Outputs sampled at the start of each interval, ``y[k] = C x[k] + D tau[k]``, columns
        :data:`OUTPUT_NAMES` (rad, rad/s, m, m/s^2).

    Raises
    ------
    PlantParameterError
        Bad shapes, non-finite torque or state, bad ``dt`` or ``params``.

    Notes
    -----
    Linear plant (no Coulomb friction): exact, computed as the FFT convolution of the torque
    with the cached impulse response of the ZOH model, plus the free response of ``x0``
    (powers of A by repeated doubling); no per-sample Python loop.  With Coulomb friction the
    plant is stepped sample by sample with :class:`Stepper` (vectorised over the batch).
    """
    p = _params(params)
    dt = _check_dt(dt)
    try:
        u = np.asarray(torque, dtype=float)
    except (TypeError, ValueError):
        raise PlantParameterError(
            "torque must be a numeric array of shape (N,) or (B, N)"
        ) from None
    if u.ndim not in (1, 2) or u.shape[-1] == 0:
        raise PlantParameterError(
            f"torque must have shape (N,) or (B, N) with N >= 1, got {u.shape}"
        )
    check_finite(u, "torque", PlantParameterError)
    single = u.ndim == 1
    u2 = u[None, :] if single else u
    nb, n = u2.shape
    model = discrete_model(p, dt)
    x_init = _as_state(x0, model, None if single else nb)
    if p.is_linear:
        h = model.markov_parameters(n)  # (n, 4)
        if n == 1:
            y = u2[:, :, None] * h[None, :, :]
        else:
            y = scipy.signal.fftconvolve(u2[:, :, None], h[None, :, :], axes=1)[:, :n, :]
        if x_init is not None:
            free = model.projected_powers(x_init, n, model.C)  # (n, 4) or (n, B, 4)
            y = y + (free[None] if free.ndim == 2 else np.swapaxes(free, 0, 1))
    else:
        y = _simulate_coulomb(u2, p, model, x_init)
    return y[0] if single else y


class Stepper:
    """Advance beam states by one sample, linear or with smoothed hub Coulomb friction.

    Used by :func:`simulate` (nonlinear case) and by the Gymnasium environments, so that both
    step the plant the same way.

    Parameters
    ----------
    params : BeamParameters, optional
    dt : float
        Sample time [s].

    Notes
    -----
    With Coulomb friction the sample is split into ``n_substeps`` equal sub-intervals; over
    each the input torque minus the friction torque ``tau_c tanh(theta' / v_s)`` (evaluated at
    the start of the sub-interval) is held and propagated exactly.  ``n_substeps`` is the
    smallest integer with ``dt / n_substeps <= I_h v_s / tau_c``, half the stability limit of
    this explicit friction update on the hub inertia.
    """

    def __init__(self, params: BeamParameters | None = None, dt: float = 1e-3):
        p = _params(params)
        self.params = p
        self.dt = _check_dt(dt)
        self.model = discrete_model(p, self.dt)
        if p.is_linear:
            self.n_substeps = 1
        else:
            limit = p.hub_inertia * p.coulomb_velocity / p.hub_coulomb_friction
            self.n_substeps = max(1, math.ceil(self.dt / limit - 1e-9))
        sub = self.model if self.n_substeps == 1 else discrete_model(p, self.dt / self.n_substeps)
        self._a_t = np.array(sub.A.T)
        self._b = np.array(sub.B[:, 0])
        self._b_hub = np.array(sub.B_hub[:, 0])
        self._c_t = np.array(self.model.C.T)
        self._d = np.array(self.model.D[:, 0])
        self._d_hub = np.array(self.model.D_hub[:, 0])
        self._has_d = bool(np.any(self._d != 0.0) or np.any(self._d_hub != 0.0))
        # friction bypasses the actuator, so it needs its own input columns when there is one
        self._split = p.actuator_bandwidth is not None
        self._vel = p.n_sections + 1  # index of theta' in the state

    @property
    def n_states(self) -> int:
        """Number of states n_x."""
        return self.model.n_states

    def friction(self, x: np.ndarray) -> np.ndarray:
        """Hub Coulomb friction torque opposing the motion.

        Parameters
        ----------
        x : ndarray, shape (..., n_x)
            States.

        Returns
        -------
        ndarray, shape (...)
            ``tau_c tanh(theta' / coulomb_velocity)`` [N m] (zeros for a linear plant).
        """
        p = self.params
        if p.is_linear:
            return np.zeros(x.shape[:-1])
        return p.hub_coulomb_friction * np.tanh(x[..., self._vel] / p.coulomb_velocity)

    def outputs(self, x: np.ndarray, tau=0.0) -> np.ndarray:
        """Outputs ``C x + D (tau - friction)`` of states.

        Parameters
        ----------
        x : ndarray, shape (..., n_x)
            States.
        tau : float or ndarray, shape (...), optional
            Commanded torque [N m] at the same samples (default 0); it matters only when
            the output has a direct feed-through (the tip acceleration).

        Returns
        -------
        ndarray, shape (..., 4)
            Outputs in :data:`OUTPUT_NAMES` order and :data:`OUTPUT_UNITS`, before the
            encoder's steps (:func:`measure`).
        """
        y = x @ self._c_t
        if self._has_d:
            if self._split:
                tau = np.asarray(tau, dtype=float)
                y = y + np.multiply.outer(tau, self._d)
                return y - np.multiply.outer(self.friction(x), self._d_hub)
            net = np.asarray(tau, dtype=float) - self.friction(x)
            y = y + np.multiply.outer(net, self._d)
        return y

    def step(self, x: np.ndarray, tau) -> np.ndarray:
        """State(s) one sample later for torque(s) ``tau`` held over the sample.

        Parameters
        ----------
        x : ndarray, shape (n_x,) or (B, n_x)
        tau : float or ndarray, shape () or (B,)
            Hub torque [N m].

        Returns
        -------
        ndarray, same shape as ``x``
        """
        if self.n_substeps == 1 and self.params.is_linear:
            if np.ndim(tau) == 0:
                return x @ self._a_t + float(tau) * self._b
            return x @ self._a_t + np.multiply.outer(tau, self._b)
        tau = np.asarray(tau, dtype=float)
        for _ in range(self.n_substeps):
            if self._split:
                x = (
                    x @ self._a_t
                    + np.multiply.outer(tau, self._b)
                    - np.multiply.outer(self.friction(x), self._b_hub)
                )
            else:
                x = x @ self._a_t + np.multiply.outer(tau - self.friction(x), self._b)
        return x


def _simulate_coulomb(u: np.ndarray, p: BeamParameters, model: BeamModel, x0) -> np.ndarray:
    nb, n = u.shape
    nx = model.n_states
    stepper = Stepper(p, model.dt)
    x = np.zeros((nb, nx)) if x0 is None else np.broadcast_to(x0, (nb, nx)).copy()
    y = np.empty((nb, n, 4))
    for k in range(n):
        y[:, k] = stepper.outputs(x, u[:, k])
        x = stepper.step(x, u[:, k])
    return y


@functools.lru_cache(maxsize=32)
def _stepper(p: BeamParameters, dt: float) -> Stepper:
    return Stepper(p, dt)


def step_states(
    x: np.ndarray, u: np.ndarray, params: BeamParameters, dt: float
) -> np.ndarray:
    """States one sample later, the commanded torque held: the plant's pure transition.

    The exact zero-order-hold discretisation of :class:`Stepper` (with Coulomb friction, its
    substeps), the model cached per ``(params, dt)``.

    Parameters
    ----------
    x : ndarray, shape (B, n_x)
        States ``[q; q'; chain]`` (:class:`BeamModel`'s ``n_states``; rad, m, rad/s, m/s and
        the chain's own states).
    u : ndarray, shape (B, 1)
        Commanded hub torque [N m] held over the sample.
    params : BeamParameters
        The beam and its chain.
    dt : float
        Sample time [s], in (0, 0.1].

    Returns
    -------
    ndarray, shape (B, n_x)
        The states at the end of the sample.
    """
    stepper = _stepper(_params(params), _check_dt(dt))
    return stepper.step(np.asarray(x, dtype=float), np.asarray(u, dtype=float)[:, 0])


def outputs(x: np.ndarray, u: np.ndarray, params: BeamParameters, dt: float) -> np.ndarray:
    """The outputs of a batch of states, before the digital sensors: ``C x + D (u - friction)``.

    Parameters
    ----------
    x : ndarray, shape (B, n_x)
        States, as for :func:`step_states`.
    u : ndarray, shape (B, 1)
        Commanded hub torque [N m] acting at those states (the tip acceleration feels it
        directly).
    params : BeamParameters
        The beam and its chain.
    dt : float
        Sample time [s] (the anti-aliasing filter's cutoff depends on it).

    Returns
    -------
    ndarray, shape (B, 4)
        :data:`OUTPUT_NAMES` in :data:`OUTPUT_UNITS`, before the encoder's steps
        (:func:`measure`).
    """
    stepper = _stepper(_params(params), _check_dt(dt))
    return stepper.outputs(np.asarray(x, dtype=float), np.asarray(u, dtype=float)[:, 0])


def initial_state(params: BeamParameters, dt: float) -> np.ndarray:
    """The state at rest, where records and episodes start.

    Parameters
    ----------
    params : BeamParameters
        The beam and its chain (they set the number of states).
    dt : float
        Sample time [s].

    Returns
    -------
    ndarray, shape (n_x,)
        Zeros.
    """
    return np.zeros(discrete_model(params, dt).n_states)


_DEFAULT = BeamParameters()
