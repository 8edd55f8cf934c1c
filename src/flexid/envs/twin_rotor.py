"""Twin rotor MIMO system: physics (Feedback 33-949S phenomenological model) and environments.

Model A of ``plants.md`` section 2.1, seven states ``x = [psi, psi', phi, phi', tau1, tau2,
M_R]`` (pitch, pitch rate, yaw, yaw rate, main and tail rotor states, main-rotor reaction
torque on yaw)::

    I1 psi''  = M1 - Mg sin(psi) - B1psi psi' - B2psi sgn(psi') - Kgy M1 phi' cos(psi)
    I2 phi''  = M2 - B1phi phi' - B2phi sgn(phi') - M_R
    M_i       = a_i tau_i |tau_i| + b_i tau_i      (thrust_law="signed_square", default)
              = a_i tau_i^2 + b_i tau_i            (thrust_law="square", the manual's form)
    tau1'     = (k1 u1 - T10 tau1) / T11,   tau2' = (k2 u2 - T20 tau2) / T21
    M_R'      = (-M_R + kc (T0 tau1' + tau1)) / Tp

Coulomb friction ``sgn(v)`` is smoothed as ``tanh(v / coulomb_velocity)`` (default 0.05
rad/s, so the fixed-step integrator stays stable).  Inputs are the two motor voltages, clipped
to ``+-u_max`` (2.5 V).  Integration: fixed-step RK4 with 10 ms substeps, input held over each
sample (default 0.1 s).  ``lock_yaw=True`` is the rig's one-degree-of-freedom configuration
(vertical channel): yaw and yaw rate stay 0 and the gyroscopic term vanishes.

Outputs, in this order: pitch (rad), yaw (rad), pitch rate (rad/s), yaw rate (rad/s), taken at
``t = k dt`` before the input of sample ``k`` acts.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields, replace
from typing import Any, ClassVar

import gymnasium
import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from gymnasium.vector.utils import batch_space

from ..errors import ActionError, DataError, PlantParameterError, check_finite

__all__ = [
    "INPUT_NAMES",
    "INPUT_UNITS",
    "OUTPUT_NAMES",
    "OUTPUT_UNITS",
    "TwinRotorEnv",
    "TwinRotorParameters",
    "TwinRotorVectorEnv",
    "clip_inputs",
    "derivatives",
    "pitch_linear_mode",
    "simulate",
    "step_states",
]

INPUT_NAMES = ("main_rotor", "tail_rotor")
INPUT_UNITS = ("V", "V")
OUTPUT_NAMES = ("pitch", "yaw", "pitch_rate", "yaw_rate")
OUTPUT_UNITS = ("rad", "rad", "rad/s", "rad/s")
THRUST_LAWS = ("signed_square", "square")


@dataclass(frozen=True)
class TwinRotorParameters:
    """Parameters of the Feedback 33-949S phenomenological model (``plants.md`` 2.1).

    Inertias in kg m^2, moments in N m, friction in N m s/rad (viscous) and N m (Coulomb),
    time constants in s; ``u_max`` in V; ``substep`` in s.
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

    def __post_init__(self) -> None:
        positive = ("I1", "I2", "T11", "T10", "T21", "T20", "Tp", "u_max", "coulomb_velocity",
                    "substep", "Mg")
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name == "thrust_law":
                if value not in THRUST_LAWS:
                    raise PlantParameterError(
                        f"twin rotor: thrust_law must be one of {THRUST_LAWS}, got {value!r}"
                    )
                continue
            if f.name == "lock_yaw":
                if not isinstance(value, (bool, np.bool_)):
                    raise PlantParameterError(f"twin rotor: lock_yaw must be a bool, got {value!r}")
                continue
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(
                value
            ):
                raise PlantParameterError(
                    f"twin rotor: {f.name} must be a finite number, got {value!r}"
                )
            if f.name in positive and value <= 0:
                raise PlantParameterError(f"twin rotor: {f.name} must be > 0, got {value!r}")
            if f.name.startswith("B") and value < 0:
                raise PlantParameterError(f"twin rotor: {f.name} must be >= 0, got {value!r}")

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def pitch_linear_mode(params: TwinRotorParameters | None = None) -> tuple[float, float]:
    """Natural frequency (Hz) and damping ratio of pitch linearised at rest.

    ``omega_n = sqrt(Mg / I1)``, ``zeta = B1psi / (2 sqrt(Mg I1))`` (viscous friction only:
    the Coulomb term has no linearisation at zero speed).
    """
    p = params or TwinRotorParameters()
    wn = math.sqrt(p.Mg / p.I1)
    return wn / (2 * math.pi), p.B1psi / (2 * math.sqrt(p.Mg * p.I1))


def clip_inputs(u: Any, params: TwinRotorParameters | None = None) -> np.ndarray:
    """Motor voltages clipped to ``+-u_max`` (the documented rule for out-of-range inputs)."""
    p = params or TwinRotorParameters()
    return np.clip(np.asarray(u, dtype=float), -p.u_max, p.u_max)


def derivatives(x: np.ndarray, u: np.ndarray, p: TwinRotorParameters) -> np.ndarray:
    """State derivatives for a batch: ``x`` (B, 7), ``u`` (B, 2) -> (B, 7)."""
    psi, dpsi, _, dphi, t1, t2, mr = x.T
    u1, u2 = u.T
    if p.thrust_law == "signed_square":
        m1 = p.a1 * t1 * np.abs(t1) + p.b1 * t1
        m2 = p.a2 * t2 * np.abs(t2) + p.b2 * t2
    else:
        m1 = p.a1 * t1 * t1 + p.b1 * t1
        m2 = p.a2 * t2 * t2 + p.b2 * t2
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


def step_states(x: np.ndarray, u: np.ndarray, p: TwinRotorParameters, dt: float) -> np.ndarray:
    """Advance a batch of states (B, 7) over one sample ``dt`` with inputs (B, 2) held."""
    n_sub = max(1, round(dt / p.substep))
    h = dt / n_sub
    for _ in range(n_sub):
        k1 = derivatives(x, u, p)
        k2 = derivatives(x + 0.5 * h * k1, u, p)
        k3 = derivatives(x + 0.5 * h * k2, u, p)
        k4 = derivatives(x + h * k3, u, p)
        x = x + (h / 6.0) * (k1 + 2 * k2 + 2 * k3 + k4)
    return x


def _simulate_scalar(u: np.ndarray, p: TwinRotorParameters, dt: float, x0: np.ndarray):
    """Scalar-Python RK4, unrolled (fast for one trajectory: no array overhead per substep)."""
    n = u.shape[0]
    out = np.empty((n, 4))
    n_sub = max(1, round(dt / p.substep))
    h = dt / n_sub
    h2, h6 = 0.5 * h, h / 6.0
    I1, I2, a1, b1, a2, b2 = p.I1, p.I2, p.a1, p.b1, p.a2, p.b2
    Mg, B1s, B2s, B1f, B2f, Kgy = p.Mg, p.B1psi, p.B2psi, p.B1phi, p.B2phi, p.Kgy
    inv_eps = 1.0 / p.coulomb_velocity
    signed = p.thrust_law == "signed_square"
    lock = p.lock_yaw
    r1, r2 = p.T10 / p.T11, p.T20 / p.T21
    kc, T0, Tp = p.kc, p.T0, p.Tp
    sin, cos, tanh = math.sin, math.cos, math.tanh

    def m1(t: float) -> float:
        return a1 * t * (abs(t) if signed else t) + b1 * t

    def m2(t: float) -> float:
        return a2 * t * (abs(t) if signed else t) + b2 * t

    psi, dpsi, phi, dphi, t1, t2, mr = (float(v) for v in x0)
    u1s = u[:, 0].tolist()
    u2s = u[:, 1].tolist()
    for k in range(n):
        out[k, 0] = psi
        out[k, 1] = phi
        out[k, 2] = dpsi
        out[k, 3] = dphi
        c1 = p.k1 * u1s[k] / p.T11
        c2 = p.k2 * u2s[k] / p.T21
        for _ in range(n_sub):
            if lock:
                # stage 1
                e1 = c1 - r1 * t1
                a_1 = (m1(t1) - Mg * sin(psi) - B1s * dpsi - B2s * tanh(dpsi * inv_eps)) / I1
                # stage 2
                q, w, t = psi + h2 * dpsi, dpsi + h2 * a_1, t1 + h2 * e1
                e2 = c1 - r1 * t
                a_2 = (m1(t) - Mg * sin(q) - B1s * w - B2s * tanh(w * inv_eps)) / I1
                v2 = w
                # stage 3
                q, w, t = psi + h2 * v2, dpsi + h2 * a_2, t1 + h2 * e2
                e3 = c1 - r1 * t
                a_3 = (m1(t) - Mg * sin(q) - B1s * w - B2s * tanh(w * inv_eps)) / I1
                v3 = w
                # stage 4
                q, w, t = psi + h * v3, dpsi + h * a_3, t1 + h * e3
                e4 = c1 - r1 * t
                a_4 = (m1(t) - Mg * sin(q) - B1s * w - B2s * tanh(w * inv_eps)) / I1
                v4 = w
                psi += h6 * (dpsi + 2 * v2 + 2 * v3 + v4)
                dpsi += h6 * (a_1 + 2 * a_2 + 2 * a_3 + a_4)
                t1 += h6 * (e1 + 2 * e2 + 2 * e3 + e4)
                # tail rotor and reaction torque do not act on a locked yaw axis; keep them
                # consistent anyway (linear, same RK4)
                f1 = c2 - r2 * t2
                f2 = c2 - r2 * (t2 + h2 * f1)
                f3 = c2 - r2 * (t2 + h2 * f2)
                f4 = c2 - r2 * (t2 + h * f3)
                t2 += h6 * (f1 + 2 * f2 + 2 * f3 + f4)
                g1 = (-mr + kc * (T0 * e1 + t1)) / Tp
                mr += h * g1  # not an output and not fed back when locked
                continue
            x = (psi, dpsi, phi, dphi, t1, t2, mr)
            acc = [0.0] * 7
            prev = (0.0,) * 7
            for stage, (f, wgt) in enumerate(((0.0, 1.0), (h2, 2.0), (h2, 2.0), (h, 1.0))):
                if stage == 0:
                    ypsi, ydpsi, ydphi, yt1, yt2, ymr = psi, dpsi, dphi, t1, t2, mr
                else:
                    ypsi = psi + f * prev[0]
                    ydpsi = dpsi + f * prev[1]
                    ydphi = dphi + f * prev[3]
                    yt1 = t1 + f * prev[4]
                    yt2 = t2 + f * prev[5]
                    ymr = mr + f * prev[6]
                mm1 = m1(yt1)
                d_t1 = c1 - r1 * yt1
                d_t2 = c2 - r2 * yt2
                d_mr = (-ymr + kc * (T0 * d_t1 + yt1)) / Tp
                dd = (
                    mm1 - Mg * sin(ypsi) - B1s * ydpsi - B2s * tanh(ydpsi * inv_eps)
                    - Kgy * mm1 * ydphi * cos(ypsi)
                ) / I1
                ddf = (m2(yt2) - B1f * ydphi - B2f * tanh(ydphi * inv_eps) - ymr) / I2
                prev = (ydpsi, dd, ydphi, ddf, d_t1, d_t2, d_mr)
                for i in range(7):
                    acc[i] += wgt * prev[i]
            psi, dpsi, phi, dphi, t1, t2, mr = (x[i] + h6 * acc[i] for i in range(7))
    return out


def simulate(
    u: Any,
    params: TwinRotorParameters | None = None,
    dt: float = 0.1,
    x0: Any = None,
) -> np.ndarray:
    """Response of the twin rotor to sampled motor voltages (held over each sample).

    Parameters
    ----------
    u : array_like, shape (N, 2)
        Main and tail rotor voltages (V); clipped to ``+-u_max``.  Shape (N,) drives the main
        rotor only.
    params : TwinRotorParameters, optional
    dt : float
        Sample time (s), default 0.1.
    x0 : array_like, shape (7,), optional
        Initial state (default rest).

    Returns
    -------
    ndarray, shape (N, 4)
        :data:`OUTPUT_NAMES` at ``t = k dt``.
    """
    p = params or TwinRotorParameters()
    u = np.asarray(u, dtype=float)
    if u.ndim == 1:
        u = np.column_stack([u, np.zeros_like(u)])
    if u.ndim != 2 or u.shape[1] != 2:
        raise DataError(f"u must have shape (N, 2) (main, tail rotor), got {u.shape}")
    check_finite(u, "u", DataError)
    if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0):
        raise PlantParameterError(f"twin rotor: dt must be > 0 seconds, got {dt!r}")
    x = np.zeros(7) if x0 is None else np.asarray(x0, dtype=float).reshape(-1)
    if x.shape != (7,):
        raise DataError(f"x0 must have 7 entries, got {x.size}")
    return _simulate_scalar(clip_inputs(u, p), p, float(dt), x)


# ================================================================================ environments
_FIELDS = tuple(f.name for f in fields(TwinRotorParameters))


class _Config:
    """Validated settings shared by the single and the vector environment."""

    def __init__(self, dt, setpoint, noise_std, pitch_limit, control_weight, physics):
        unknown = sorted(set(physics) - set(_FIELDS))
        if unknown:
            raise PlantParameterError(
                f"unknown twin-rotor parameter(s) {unknown}; physical parameters are "
                f"{', '.join(_FIELDS)}"
            )
        self.params = TwinRotorParameters(**physics)
        if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0):
            raise PlantParameterError(f"twin rotor: dt must be > 0 seconds, got {dt!r}")
        self.dt = float(dt)
        sp = np.asarray(setpoint, dtype=float).reshape(-1)
        if sp.shape != (2,) or not np.all(np.isfinite(sp)):
            raise PlantParameterError(f"setpoint must be (pitch, yaw) in rad, got {setpoint!r}")
        self.setpoint = sp
        noise = np.broadcast_to(np.asarray(noise_std, dtype=float), (4,)).copy()
        if not np.all(np.isfinite(noise) & (noise >= 0)):
            raise PlantParameterError(f"noise_std must be >= 0, got {noise_std!r}")
        self.noise = noise
        if not (math.isfinite(pitch_limit) and pitch_limit > 0):
            raise PlantParameterError(f"pitch_limit must be > 0 rad, got {pitch_limit!r}")
        self.pitch_limit = float(pitch_limit)
        if not (math.isfinite(control_weight) and control_weight >= 0):
            raise PlantParameterError(f"control_weight must be >= 0, got {control_weight!r}")
        self.control_weight = float(control_weight)
        big = np.finfo(np.float64).max
        self.action_space = spaces.Box(-1.0, 1.0, (2,), np.float64)
        self.observation_space = spaces.Box(-big, big, (6,), np.float64)

    def check_action(self, action: Any, batch: int | None) -> np.ndarray:
        a = np.asarray(action, dtype=float)
        shape = (2,) if batch is None else (batch, 2)
        if a.shape != shape:
            raise ActionError(f"twin rotor: action must have shape {shape}, got {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ActionError(f"twin rotor: action must be finite, got {action!r}")
        return np.clip(a, -1.0, 1.0) * self.params.u_max

    def observe(self, x: np.ndarray, rngs) -> np.ndarray:
        x = np.atleast_2d(x)
        y = np.stack([x[:, 0], x[:, 2], x[:, 1], x[:, 3]], axis=1)
        if np.any(self.noise > 0):
            y = y + np.stack([r.standard_normal(4) for r in rngs]) * self.noise
        sp = np.broadcast_to(self.setpoint, (x.shape[0], 2))
        return np.concatenate([y, sp], axis=1)

    def reward(self, x: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        x = np.atleast_2d(x)
        u = np.atleast_2d(u)
        err = (x[:, 0] - self.setpoint[0]) ** 2 + (x[:, 2] - self.setpoint[1]) ** 2
        r = -(err + self.control_weight * np.sum((u / self.params.u_max) ** 2, axis=1))
        return r, np.abs(x[:, 0]) > self.pitch_limit


_DOC = """
    Parameters
    ----------
    render_mode : {None, "rgb_array"}
    dt : float
        Sample time (s), default 0.1.
    setpoint : (float, float)
        Pitch and yaw set point (rad), default (0.2, 0.0).
    noise_std : float or sequence of 4
        Gaussian measurement noise on the observed outputs (rad, rad/s), default 0.
    pitch_limit : float
        The episode terminates when ``|pitch|`` exceeds it (rad), default 1.2.
    control_weight : float
        Weight of the normalised input energy in the reward, default 0.01.
    **physics
        Any :class:`TwinRotorParameters` field, e.g. ``lock_yaw=True``, ``Kgy=0.05``.

    Observation (float64, shape (6,)): pitch, yaw (rad), pitch rate, yaw rate (rad/s), then the
    pitch and yaw set points.  Action (float64, shape (2,)): main and tail rotor voltages
    normalised to ``[-1, 1]`` (times ``u_max`` = 2.5 V); finite out-of-range actions are
    clipped to the box (the applied voltages are in ``info["applied_voltage"]``), non-finite
    actions raise
    :class:`~flexid.errors.ActionError`.  Reward: ``-((pitch - pitch_ref)^2 + (yaw -
    yaw_ref)^2 + control_weight |u / u_max|^2)`` from the noise-free state.
"""


class TwinRotorEnv(gymnasium.Env):
    """Twin rotor MIMO system: regulate pitch and yaw to a set point."""

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array"], "render_fps": 10}

    def __init__(
        self,
        render_mode: str | None = None,
        *,
        dt: float = 0.1,
        setpoint=(0.2, 0.0),
        noise_std=0.0,
        pitch_limit: float = 1.2,
        control_weight: float = 0.01,
        **physics: Any,
    ) -> None:
        if render_mode not in (None, "rgb_array"):
            raise PlantParameterError(
                f"render_mode must be None or 'rgb_array', got {render_mode!r}"
            )
        self.render_mode = render_mode
        self._cfg = _Config(dt, setpoint, noise_std, pitch_limit, control_weight, physics)
        self.params = self._cfg.params
        self.dt = self._cfg.dt
        self.action_space = self._cfg.action_space
        self.observation_space = self._cfg.observation_space
        self.state = np.zeros(7)

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        self.state = np.zeros(7)
        if self.params.lock_yaw:
            self.state[2:4] = 0.0
        obs = self._cfg.observe(self.state, [self.np_random])[0]
        return obs, {"state": self.state.copy()}

    def step(self, action):
        u = self._cfg.check_action(action, None)
        self.state = step_states(self.state[None, :], u[None, :], self.params, self.dt)[0]
        reward, terminated = self._cfg.reward(self.state, u)
        obs = self._cfg.observe(self.state, [self.np_random])[0]
        info = {"applied_voltage": u, "state": self.state.copy()}
        return obs, float(reward[0]), bool(terminated[0]), False, info

    def render(self):
        if self.render_mode != "rgb_array":
            return None
        return _render(self.state, self._cfg.setpoint)


TwinRotorEnv.__doc__ = (TwinRotorEnv.__doc__ or "") + "\n" + _DOC


def _render(x: np.ndarray, setpoint: np.ndarray, size: int = 400) -> np.ndarray:
    """Side view (pitch) on the left, top view (yaw) on the right."""
    from ._render import Canvas

    canvas = Canvas(2 * size, size, (250, 250, 250))
    half = size / 2
    for k, angle, ref in ((0, x[0], setpoint[0]), (1, x[2], setpoint[1])):
        cx, cy = half + k * size, half
        r = 0.4 * size
        canvas.line(cx + r * math.cos(ref), cy - r * math.sin(ref),
                    cx - r * math.cos(ref), cy + r * math.sin(ref), (180, 180, 180), 2)
        ex, ey = r * math.cos(angle), r * math.sin(angle)
        canvas.line(cx - ex, cy + ey, cx + ex, cy - ey, (30, 60, 160), 6)
        canvas.circle(cx + ex, cy - ey, 0.06 * size, (200, 40, 40))  # main / tail rotor
        canvas.circle(cx - ex, cy + ey, 0.04 * size, (60, 160, 60))
        canvas.circle(cx, cy, 0.02 * size, (0, 0, 0))
    return canvas.frame()


class TwinRotorVectorEnv(gymnasium.vector.VectorEnv):
    """``num_envs`` twin rotors stepped together (one batched RK4).

    Same keyword arguments, spaces, reward and termination as :class:`TwinRotorEnv`, plus
    ``num_envs`` and ``max_episode_steps`` (default 600).  Autoreset: Gymnasium's
    ``NEXT_STEP`` mode.  ``reset(seed=s)`` seeds sub-environment ``i`` with ``s + i``, so a
    rollout equals that of single environments seeded the same way.
    """

    metadata: ClassVar[dict[str, Any]] = {
        "render_modes": ["rgb_array"],
        "render_fps": 10,
        "autoreset_mode": gymnasium.vector.AutoresetMode.NEXT_STEP,
    }

    def __init__(
        self,
        num_envs: int = 1,
        render_mode: str | None = None,
        *,
        max_episode_steps: int | None = 600,
        dt: float = 0.1,
        setpoint=(0.2, 0.0),
        noise_std=0.0,
        pitch_limit: float = 1.2,
        control_weight: float = 0.01,
        **physics: Any,
    ) -> None:
        if (
            isinstance(num_envs, bool)
            or not isinstance(num_envs, (int, np.integer))
            or num_envs < 1
        ):
            raise PlantParameterError(f"num_envs must be an integer >= 1, got {num_envs!r}")
        self._cfg = _Config(dt, setpoint, noise_std, pitch_limit, control_weight, physics)
        self.num_envs = int(num_envs)
        self.max_episode_steps = max_episode_steps
        self.params = self._cfg.params
        self.dt = self._cfg.dt
        self.render_mode = render_mode
        self.single_action_space = self._cfg.action_space
        self.single_observation_space = self._cfg.observation_space
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.state = np.zeros((self.num_envs, 7))
        self.steps = np.zeros(self.num_envs, dtype=np.int64)
        self.prev_done = np.zeros(self.num_envs, dtype=bool)
        self._rngs = [seeding.np_random(None)[0] for _ in range(self.num_envs)]

    def reset(self, *, seed: int | list[int] | None = None, options: dict | None = None):
        if seed is not None:
            seeds = (
                [int(seed) + i for i in range(self.num_envs)]
                if isinstance(seed, (int, np.integer))
                else list(seed)
            )
            if len(seeds) != self.num_envs:
                raise PlantParameterError(f"reset needs {self.num_envs} seeds, got {len(seeds)}")
            self._rngs = [seeding.np_random(s)[0] for s in seeds]
        self.state[:] = 0.0
        self.steps[:] = 0
        self.prev_done[:] = False
        return self._cfg.observe(self.state, self._rngs), {}

    def step(self, actions):
        u = self._cfg.check_action(actions, self.num_envs)
        done = self.prev_done
        u = np.where(done[:, None], 0.0, u)
        self.state = step_states(self.state, u, self.params, self.dt)
        self.steps += 1
        self.state[done] = 0.0
        self.steps[done] = 0
        reward, terminated = self._cfg.reward(self.state, u)
        truncated = (
            self.steps >= self.max_episode_steps
            if self.max_episode_steps is not None
            else np.zeros(self.num_envs, dtype=bool)
        )
        reward[done] = 0.0
        terminated[done] = False
        truncated[done] = False
        self.prev_done = terminated | truncated
        obs = self._cfg.observe(self.state, self._rngs)
        return obs, reward, terminated, truncated, {"applied_voltage": u}

    def render(self):
        if self.render_mode != "rgb_array":
            return None
        return np.stack([_render(x, self._cfg.setpoint) for x in self.state])


def _replace(params: TwinRotorParameters, **changes: Any) -> TwinRotorParameters:
    return replace(params, **changes)
