"""Gymnasium environments of the twin rotor MIMO system.

``flexid/TwinRotor-v0`` (:class:`TwinRotorEnv`) and its NumPy-batched vector version
(:class:`TwinRotorVectorEnv`, used by ``gymnasium.make_vec(...,
vectorization_mode="vector_entry_point")``).  The physics is
:mod:`flexid.envs.twin_rotor_physics`: the single environment steps with its
:class:`~flexid.envs.twin_rotor_steppers.ScalarStepper`, the vector environment with its
:class:`~flexid.envs.twin_rotor_steppers.BatchStepper`; a thin shell, as the manipulator's
environments are over :mod:`flexid.envs.beam`.
"""

from __future__ import annotations

import math
from dataclasses import fields
from typing import Any, ClassVar

import gymnasium
import numpy as np
from gymnasium import spaces

from .._validate import positive_real, real
from ..data.plants import Plant, get_plant
from ..errors import ActionError, PlantParameterError, plain_number
from . import sensors
from ._vector import BatchedVectorEnv
from .twin_rotor_physics import TwinRotorParameters
from .twin_rotor_steppers import batch_stepper, scalar_stepper

__all__ = [
    "ACTION_NAMES",
    "OBSERVATION_NAMES",
    "OBSERVATION_UNITS",
    "PLANT",
    "TwinRotorEnv",
    "TwinRotorVectorEnv",
]

_FIELDS = tuple(f.name for f in fields(TwinRotorParameters))

PLANT: Plant = get_plant("twin-rotor")
"""The registry's record of the plant: the names and units below come from it."""
OBSERVATION_NAMES: tuple[str, ...] = (*PLANT.output_names, "pitch_setpoint", "yaw_setpoint")
OBSERVATION_UNITS: tuple[str, ...] = (*PLANT.output_units, "rad", "rad")
ACTION_NAMES: tuple[str, ...] = PLANT.input_names
"""The rotors driven by the two action entries (voltages normalised by ``u_max``)."""


class _Config:
    """Validated settings shared by the single and the vector environment.

    The numbers the step uses are plain attributes (floats), read once per step.
    """

    def __init__(self, render_mode, dt, setpoint, noise_std, pitch_limit, control_weight, physics):
        if render_mode not in (None, "rgb_array"):
            raise PlantParameterError(
                f"render_mode must be None or 'rgb_array', got {render_mode!r}"
            )
        unknown = sorted(set(physics) - set(_FIELDS))
        if unknown:
            raise PlantParameterError(
                f"unknown twin-rotor parameter(s) {unknown}; physical parameters are "
                f"{', '.join(_FIELDS)}"
            )
        self.params = TwinRotorParameters(**physics)
        self.dt = positive_real(dt, "twin rotor: dt", error=PlantParameterError, unit="s")
        sp = np.asarray(setpoint, dtype=float).reshape(-1)
        if sp.shape != (2,) or not np.all(np.isfinite(sp)):
            raise PlantParameterError(
                f"setpoint must be (pitch, yaw) in rad, got {plain_number(setpoint)}"
            )
        self.setpoint = sp
        self.pitch_ref, self.yaw_ref = (float(v) for v in sp)
        noise = np.broadcast_to(np.asarray(noise_std, dtype=float), (4,)).copy()
        if not np.all(np.isfinite(noise) & (noise >= 0)):
            raise PlantParameterError(f"noise_std must be >= 0, got {plain_number(noise_std)}")
        self.noise = noise
        self.noisy = bool(np.any(noise > 0))
        self.encoder_step = self.params.encoder_step
        self.pitch_limit = positive_real(
            pitch_limit, "pitch_limit", error=PlantParameterError, unit="rad"
        )
        self.control_weight = real(
            control_weight, "control_weight", error=PlantParameterError, minimum=0
        )
        self.u_max = float(self.params.u_max)

    def spaces(self) -> tuple[spaces.Box, spaces.Box]:
        """The action and observation spaces of one environment."""
        big = np.finfo(np.float64).max
        return spaces.Box(-1.0, 1.0, (2,), np.float64), spaces.Box(-big, big, (6,), np.float64)

    def check_action(self, action: Any, batch: int | None) -> np.ndarray:
        """Voltages (V) from normalised actions, shape (2,) or (batch, 2), clipped to the box."""
        a = np.asarray(action, dtype=float)
        shape = (2,) if batch is None else (batch, 2)
        if a.shape != shape:
            raise ActionError(f"twin rotor: action must have shape {shape}, got {a.shape}")
        if not np.isfinite(a).all():
            raise ActionError(f"twin rotor: action must be finite, got {plain_number(action)}")
        u = np.maximum(a, -1.0)  # np.clip, without its Python-level dispatch
        np.minimum(u, 1.0, out=u)
        u *= self.u_max
        return u


def _in_counts(angle: float, step: float) -> float:
    """:func:`~flexid.envs.sensors.quantise` of one float, in Python (a NumPy call on two
    numbers costs more than the rest of a step); the same rounding, halves to even."""
    try:
        return round(angle / step) * step
    except (ValueError, OverflowError):  # nan and inf pass through, as they do in NumPy
        return angle


class TwinRotorEnv(gymnasium.Env):
    """Twin rotor MIMO system: regulate pitch and yaw to a set point.

    The state (``state``, shape (7,), :data:`~flexid.envs.twin_rotor_physics.STATE_NAMES`) is
    stepped by a :class:`~flexid.envs.twin_rotor_steppers.ScalarStepper`.

    Parameters
    ----------
    render_mode : {None, "rgb_array"}
        ``"rgb_array"``: :meth:`render` returns a side view (pitch) beside a top view (yaw),
        shape (400, 800, 3) uint8.
    dt : float
        Sample time [s], > 0; default 0.1.
    setpoint : (float, float)
        Pitch and yaw set points [rad]; default (0.2, 0.0).
    noise_std : float or sequence of 4 float
        Standard deviation of Gaussian measurement noise on the observed pitch [rad], yaw
        [rad], pitch rate [rad/s] and yaw rate [rad/s], >= 0; default 0.
    pitch_limit : float
        The episode terminates when ``|pitch|`` exceeds it [rad], > 0; default 1.2.
    control_weight : float
        Weight of the normalised input energy in the reward, >= 0; default 0.01.
    **physics
        Any :class:`~flexid.envs.twin_rotor_physics.TwinRotorParameters` field, e.g.
        ``lock_yaw=True``, ``Kgy=0.05``.

    Raises
    ------
    PlantParameterError
        For an invalid value or an unknown physical parameter.

    Notes
    -----
    Observation (float64, shape (6,)): {observation}: the plant's outputs, then the pitch and
    yaw set points.  Pitch and yaw are read in the encoders' steps (``encoder_counts``;
    ``encoder_counts=None`` reads them exactly).

    Action (float64, shape (2,)): {action} normalised to ``[-1, 1]`` (times ``u_max`` =
    2.5 V); finite out-of-range actions are clipped to the box (the applied voltages are in
    ``info["applied_voltage"]``), non-finite actions raise
    :class:`~flexid.errors.ActionError`.

    Reward: ``-((pitch - pitch_ref)^2 + (yaw - yaw_ref)^2 + control_weight |u / u_max|^2)``
    from the noise-free state.
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array"], "render_fps": 10}
    plant: ClassVar[Plant] = PLANT

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
        self._cfg = _Config(
            render_mode, dt, setpoint, noise_std, pitch_limit, control_weight, physics
        )
        self.render_mode = render_mode
        self.params = self._cfg.params
        self.dt = self._cfg.dt
        self.action_space, self.observation_space = self._cfg.spaces()
        self._stepper = scalar_stepper(self.params, self.dt)
        self._x: tuple[float, ...] = (0.0,) * 7

    @property
    def state(self) -> np.ndarray:
        """State (7,), :data:`STATE_NAMES` order and units (a copy); assign to set it."""
        return np.array(self._x)

    @state.setter
    def state(self, x) -> None:
        self._x = tuple(np.asarray(x, dtype=float).reshape(7).tolist())

    def _observe(self, psi: float, dpsi: float, phi: float, dphi: float) -> np.ndarray:
        cfg = self._cfg
        step = cfg.encoder_step
        if step:
            psi, phi = _in_counts(psi, step), _in_counts(phi, step)
        obs = np.array((psi, phi, dpsi, dphi, cfg.pitch_ref, cfg.yaw_ref))
        if cfg.noisy:
            obs[:4] += self.np_random.standard_normal(4) * cfg.noise
        return obs

    def reset(
        self, *, seed: int | None = None, options: dict | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        self._x = (0.0,) * 7
        return self._observe(0.0, 0.0, 0.0, 0.0), {"state": self.state}

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        cfg = self._cfg
        if type(action) is np.ndarray and action.shape == (2,) and action.dtype == np.float64:
            a1, a2 = action.tolist()  # the common case, without the array round trip
            if not (math.isfinite(a1) and math.isfinite(a2)):
                raise ActionError(f"twin rotor: action must be finite, got {plain_number(action)}")
            u_max = cfg.u_max
            u1 = (a1 if -1.0 <= a1 <= 1.0 else (1.0 if a1 > 0.0 else -1.0)) * u_max
            u2 = (a2 if -1.0 <= a2 <= 1.0 else (1.0 if a2 > 0.0 else -1.0)) * u_max
        else:
            u1, u2 = cfg.check_action(action, None).tolist()
            u_max = cfg.u_max
        x = self._x = self._stepper.step(self._x, u1, u2)
        psi, dpsi, phi, dphi = x[0], x[1], x[2], x[3]
        e1, e2 = psi - cfg.pitch_ref, phi - cfg.yaw_ref
        q1, q2 = u1 / u_max, u2 / u_max
        reward = -(e1 * e1 + e2 * e2 + cfg.control_weight * (q1 * q1 + q2 * q2))
        info = {"applied_voltage": np.array((u1, u2)), "state": np.array(x)}
        obs = self._observe(psi, dpsi, phi, dphi)
        return obs, reward, abs(psi) > cfg.pitch_limit, False, info

    def render(self) -> np.ndarray | None:
        if self.render_mode != "rgb_array":
            return None
        return _render(self._x, self._cfg.setpoint)


if TwinRotorEnv.__doc__:  # None under python -OO
    TwinRotorEnv.__doc__ = TwinRotorEnv.__doc__.replace(
        "{observation}",
        ", ".join(f"{n} ({u})" for n, u in zip(OBSERVATION_NAMES, OBSERVATION_UNITS)),
    ).replace(
        "{action}", ", ".join(f"{n} ({u})" for n, u in zip(ACTION_NAMES, PLANT.input_units))
    )


def _render(x, setpoint: np.ndarray, size: int = 400) -> np.ndarray:
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


class TwinRotorVectorEnv(BatchedVectorEnv, single_env=TwinRotorEnv, config_type=_Config):
    """``num_envs`` twin rotors stepped together (one batch stepper of the physics).

    Parameters
    ----------
    num_envs : int
        Number of sub-environments, >= 1; default 1.
    render_mode : {None, "rgb_array"}
        ``"rgb_array"``: :meth:`render` returns one :class:`TwinRotorEnv` frame per
        sub-environment, shape (num_envs, 400, 800, 3) uint8.
    max_episode_steps : int or None
        Steps after which a sub-environment is truncated, >= 1; default 600 (as the
        registration); None: never.
    **kwargs
        The keyword arguments of :class:`TwinRotorEnv` (``dt`` [s], ``setpoint`` [rad],
        ``noise_std``, ``pitch_limit`` [rad], ``control_weight`` and any physical parameter),
        with the same defaults.

    Raises
    ------
    PlantParameterError
        For an invalid argument (``num_envs`` and ``max_episode_steps`` included) or an
        unknown keyword.

    Notes
    -----
    Same spaces, reward and termination as :class:`TwinRotorEnv`.  Autoreset: Gymnasium's
    ``NEXT_STEP`` mode.  ``reset(seed=s)`` seeds sub-environment ``i`` with ``s + i``, so a
    rollout equals that of single environments seeded the same way.  ``state``
    (num_envs, 7) is a copy of the states
    (:data:`~flexid.envs.twin_rotor_physics.STATE_NAMES`); assign to set them.
    """

    def __init__(
        self,
        num_envs: int = 1,
        render_mode: str | None = None,
        *,
        max_episode_steps: int | None = 600,
        **kwargs: Any,
    ) -> None:
        super().__init__(num_envs, render_mode, max_episode_steps, kwargs)
        self._stepper = batch_stepper(self.params, self.dt, self.num_envs)
        cfg = self._cfg
        self._terms = np.empty((4, self.num_envs))
        self._refs = np.array([[cfg.pitch_ref], [cfg.yaw_ref]])
        self._input_scale = math.sqrt(cfg.control_weight) / cfg.u_max
        self._minus_ones = -np.ones(4)

    @property
    def state(self) -> np.ndarray:
        """States (num_envs, 7), :data:`STATE_NAMES` order and units (a copy)."""
        return self._stepper.state

    @state.setter
    def state(self, x) -> None:
        self._stepper.state = np.asarray(x, dtype=float).reshape(self.num_envs, 7)

    def _observe(self) -> np.ndarray:
        cfg = self._cfg
        obs = np.empty((self.num_envs, 6))
        self._stepper.outputs(obs)
        if cfg.encoder_step:
            obs[:, :2] = sensors.quantise(obs[:, :2], cfg.encoder_step)
        if cfg.noisy:
            obs[:, :4] += np.stack([r.standard_normal(4) for r in self._rngs]) * cfg.noise
        obs[:, 4:] = cfg.setpoint
        return obs

    def reset(
        self, *, seed: int | list[int] | None = None, options: dict | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        self._restart(seed)
        self._stepper.reset(np.ones(self.num_envs, dtype=bool))
        return self._observe(), {}

    def step(
        self, actions: Any
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        cfg = self._cfg
        u = cfg.check_action(actions, self.num_envs)
        done = self.prev_done
        any_done = done.any()
        if any_done:
            u[done] = 0.0
        stepper = self._stepper
        stepper.advance(u)
        self.steps += 1
        if any_done:
            stepper.reset(done)
            self.steps[done] = 0
        # reward: -(e_pitch^2 + e_yaw^2 + w |u / u_max|^2) as one sum of 4 squares per env
        terms = self._terms
        np.subtract(stepper.angles, self._refs, out=terms[:2])
        np.multiply(u.T, self._input_scale, out=terms[2:])
        terms *= terms
        reward = np.dot(self._minus_ones, terms)
        terminated = np.abs(stepper.angles[0]) > cfg.pitch_limit
        truncated = self._end_step(done, reward, terminated)
        return self._observe(), reward, terminated, truncated, {"applied_voltage": u}

    def render(self) -> np.ndarray | None:
        if self.render_mode != "rgb_array":
            return None
        return np.stack([_render(x, self._cfg.setpoint) for x in self.state])
