"""Gymnasium environments for the single-link flexible manipulator.

``flexid/FlexibleManipulator-v0`` (:class:`FlexibleManipulatorEnv`) and its NumPy-batched
vector version (:class:`FlexibleManipulatorVectorEnv`, used by
``gymnasium.make_vec(..., vectorization_mode="vector_entry_point")``).  The physics is
:mod:`flexid.envs.beam`: a finite-difference Euler-Bernoulli beam on a motor hub, discretised
exactly for a zero-order-hold torque.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, ClassVar

import gymnasium
import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding

from flexid._validate import real
from flexid.data.plants import Plant, get_plant
from flexid.envs import beam, sensors
from flexid.envs._render import Canvas
from flexid.envs._vector import BatchedVectorEnv
from flexid.errors import ActionError, PlantParameterError, plain_number

__all__ = ["OBSERVATION_NAMES", "PLANT", "FlexibleManipulatorEnv", "FlexibleManipulatorVectorEnv"]

PLANT: Plant = get_plant("manipulator")
"""The registry's record of the plant (names and units of its input and outputs)."""
OBSERVATION_NAMES: tuple[str, ...] = (*PLANT.output_names, "target_angle")
"""Names of the observation entries, in order."""

_BEAM_FIELDS = tuple(f.name for f in dataclasses.fields(beam.BeamParameters))
_BIG = float(np.finfo(np.float64).max)
_NOISE_CHUNK = 64  # steps of measurement noise drawn at once per environment


def _real(name: str, value, lo: float, hi: float, *, lo_open: bool = False) -> float:
    return real(
        value, repr(name), error=PlantParameterError, minimum=lo, maximum=hi, low_open=lo_open
    )


class _Config:
    """Validated options shared by the single and the vector environment."""

    def __init__(
        self,
        dt: float,
        tau_max: float,
        noise_std,
        target_angle: float,
        target_range: float | None,
        angle_limit: float,
        angle_weight: float,
        tip_weight: float,
        torque_weight: float,
        render_mode: str | None,
        physics: dict[str, Any],
    ):
        unknown = set(physics) - set(_BEAM_FIELDS)
        if unknown:
            raise PlantParameterError(
                f"unknown manipulator parameter(s) {sorted(unknown)}; physical parameters are "
                f"{', '.join(_BEAM_FIELDS)}"
            )
        self.params = beam.BeamParameters(**physics)
        self.dt = _real("dt", dt, 0.0, 0.1, lo_open=True)
        self.tau_max = _real("tau_max", tau_max, 0.0, 1e3, lo_open=True)
        std = np.asarray(noise_std, dtype=float) if noise_std is not None else np.zeros(4)
        if std.shape == ():
            std = np.full(4, float(std))
        if std.shape != (4,) or not np.all(np.isfinite(std)) or np.any(std < 0):
            raise PlantParameterError(
                "'noise_std' must be a non-negative number or 4 non-negative numbers (std of "
                f"{', '.join(beam.OUTPUT_NAMES)} in {', '.join(beam.OUTPUT_UNITS)}), "
                f"got {plain_number(noise_std)}"
            )
        self.noise_std = sensors.total_noise(std, beam.noise_floor(self.params))
        self.noisy = bool(np.any(self.noise_std > 0))
        self.encoder_step = self.params.encoder_step
        self.angle_limit = _real("angle_limit", angle_limit, 0.0, 1e3, lo_open=True)
        self.target_angle = _real(
            "target_angle", target_angle, -self.angle_limit, self.angle_limit
        )
        if target_range is None:
            target_range = min(1.0, self.angle_limit)
        self.target_range = _real("target_range", target_range, 0.0, self.angle_limit)
        self.angle_weight = _real("angle_weight", angle_weight, 0.0, 1e12)
        self.tip_weight = _real("tip_weight", tip_weight, 0.0, 1e12)
        self.torque_weight = _real("torque_weight", torque_weight, 0.0, 1e12)
        if render_mode is not None and render_mode not in FlexibleManipulatorEnv.metadata[
            "render_modes"
        ]:
            raise PlantParameterError(
                f"render_mode must be None or one of "
                f"{FlexibleManipulatorEnv.metadata['render_modes']}, got {render_mode!r}"
            )
        self.render_mode = render_mode
        self.stepper = beam.Stepper(self.params, self.dt)
        self.n_states = self.stepper.n_states

    def spaces(self) -> tuple[spaces.Box, spaces.Box]:
        action = spaces.Box(-self.tau_max, self.tau_max, shape=(1,), dtype=np.float64)
        low = np.array([-_BIG, -_BIG, -_BIG, -_BIG, -self.angle_limit])
        obs = spaces.Box(low, -low, dtype=np.float64)
        return action, obs

    def target_from_options(self, options: dict | None, rng: np.random.Generator) -> float:
        if not options:
            return self.target_angle
        unknown = set(options) - {"target_angle", "random_target"}
        if unknown:
            raise PlantParameterError(
                f"unknown reset option(s) {sorted(unknown)}; known: random_target, target_angle"
            )
        if options.get("random_target", False):
            return float(rng.uniform(-self.target_range, self.target_range))
        if "target_angle" in options:
            return _real(
                "target_angle", options["target_angle"], -self.angle_limit, self.angle_limit
            )
        return self.target_angle

    def check_action(self, action, batch: int | None) -> tuple[np.ndarray, np.ndarray]:
        """Return (applied torque, clipped flag); floats or arrays of shape (batch,)."""
        if (
            batch is None
            and type(action) is np.ndarray
            and action.shape == (1,)
            and action.dtype == np.float64
        ):  # fast path for the common case
            v = float(action[0])
            if not math.isfinite(v):
                raise ActionError(f"action must be finite, got {plain_number(action)}")
            c = min(max(v, -self.tau_max), self.tau_max)
            return c, c != v
        try:
            a = np.asarray(action, dtype=np.float64)
        except (TypeError, ValueError):
            raise ActionError(
                f"action must be numeric hub torque(s) in N m, got {action!r}"
            ) from None
        if batch is None:
            if a.shape not in ((1,), ()):
                raise ActionError(
                    f"action must have shape (1,) (hub torque in N m), got {a.shape}"
                )
            a = float(a.reshape(()))
        else:
            if a.shape not in ((batch, 1), (batch,)):
                raise ActionError(
                    f"actions must have shape ({batch}, 1) (hub torque in N m), got {a.shape}"
                )
            a = a.reshape(batch)
        bad = ~np.isfinite(a)
        if np.any(bad):
            where = "" if batch is None else f" for env(s) {np.flatnonzero(bad).tolist()}"
            raise ActionError(f"action must be finite, got {plain_number(action)}{where}")
        clipped = np.clip(a, -self.tau_max, self.tau_max)
        return clipped, clipped != a

    def advance(self, x: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """One exact ZOH step of the state(s) ``x`` (..., n_x) for torque(s) ``tau``."""
        return self.stepper.step(x, tau)

    def outputs(self, x: np.ndarray) -> np.ndarray:
        """Noise-free outputs ``C x`` (..., 4) (the lumped FD model has no feedthrough)."""
        return self.stepper.outputs(x)

    def reward(self, y: np.ndarray, target, tau) -> tuple[np.ndarray, np.ndarray]:
        err = y[..., 0] - target
        r = -(
            self.angle_weight * err**2
            + self.tip_weight * y[..., 2] ** 2
            + self.torque_weight * (tau / self.tau_max) ** 2
        )
        return r, np.abs(y[..., 0]) > self.angle_limit


class _NoiseStream:
    """Measurement noise of one environment, drawn in chunks from its generator."""

    def __init__(self):
        self.buffer = np.empty((0, 4))
        self.pos = 0

    def draw(self, rng: np.random.Generator) -> np.ndarray:
        if self.pos >= self.buffer.shape[0]:
            self.buffer = rng.standard_normal((_NOISE_CHUNK, 4))
            self.pos = 0
        z = self.buffer[self.pos]
        self.pos += 1
        return z


def _render_frame(cfg: _Config, x: np.ndarray, target: float, size: int = 500) -> np.ndarray:
    """Top view of the hub and the deflected beam (true scale), (size, size, 3) uint8."""
    p = cfg.params
    n = p.n_sections
    theta = x[0]
    xs = beam.node_positions(p)
    y = np.concatenate([[0.0], x[1 : n + 1]])
    w = y - xs * theta  # elastic deflection in the rotating frame
    ct, st = math.cos(theta), math.sin(theta)
    px = xs * ct - w * st
    py = xs * st + w * ct
    canvas = Canvas(size, size, background=(255, 255, 255))
    scale = 0.45 * size / p.length
    origin = (size / 2.0, size / 2.0)
    # target direction (thin grey) and rigid reference line (light blue)
    tx, ty = canvas.to_pixels(
        [0.0, p.length * math.cos(target)], [0.0, p.length * math.sin(target)], scale, origin
    )
    canvas.polyline(tx, ty, (180, 180, 180), 1.0)
    rx, ry = canvas.to_pixels([0.0, p.length * ct], [0.0, p.length * st], scale, origin)
    canvas.polyline(rx, ry, (170, 200, 255), 1.0)
    bx, by = canvas.to_pixels(px, py, scale, origin)
    canvas.polyline(bx, by, (30, 60, 160), max(3.0, size / 150))
    canvas.circle(origin[0], origin[1], max(6.0, size / 25), (90, 90, 90))
    hx, hy = canvas.to_pixels([0.06 * ct], [0.06 * st], scale, origin)
    canvas.circle(float(hx[0]), float(hy[0]), max(2.0, size / 120), (230, 230, 230))
    if p.payload_mass > 0:
        canvas.circle(float(bx[-1]), float(by[-1]), max(4.0, size / 60), (200, 40, 40))
    return canvas.frame()


class FlexibleManipulatorEnv(gymnasium.Env):
    """Single-link flexible manipulator: regulate the hub angle with little tip vibration.

    **Dynamics.** Linear finite-difference Euler-Bernoulli beam on a motor hub
    (:mod:`flexid.envs.beam`), exact ZOH at ``dt``; optional smoothed hub Coulomb friction.

    **Action.** Hub torque [N m], ``Box(-tau_max, tau_max, (1,), float64)``.  A scalar is
    accepted too.  Rule for out-of-range finite actions: the torque is clipped to the action
    space and the applied torque is reported in ``info["applied_torque"]`` (with
    ``info["clipped"]``).  NaN/inf or a wrong shape raise :class:`flexid.errors.ActionError`.

    **Observation** (float64, shape (5,)): ``[theta (rad), theta' (rad/s), w(l) (m),
    y''(l) (m/s^2), theta_ref (rad)]``; the first four are the plant outputs plus
    measurement noise (``noise_std``), the last is the set point.  The physical entries are
    unbounded (bounds are the largest finite float64); theta_ref lies in
    ``[-angle_limit, angle_limit]``.  The tip acceleration is ``C x`` (the lumped FD model has
    no torque feedthrough).

    **Reward** (per step, from the noise-free outputs after the step)::

        r = -(angle_weight * (theta - theta_ref)^2
              + tip_weight * w(l)^2
              + torque_weight * (tau / tau_max)^2)

    with defaults 1, 100 and 0.01: 1 cm of tip deflection costs as much as 0.1 rad of angle
    error, and a full-scale torque as much as 0.1 rad.

    **Episode.** Starts at rest at theta = 0.  ``reset(seed=..., options=...)`` with options
    ``{"target_angle": value}`` or ``{"random_target": True}`` (uniform in
    ``[-target_range, target_range]``).  Terminates when ``|theta| > angle_limit``;
    truncation after ``max_episode_steps`` (2000 = 2 s at 1 ms) comes from the registration.

    ``info`` holds ``applied_torque`` [N m], ``clipped``, ``outputs`` (noise-free outputs,
    shape (4,)) and ``target_angle``.

    Parameters
    ----------
    render_mode : {None, "rgb_array"}
        ``"rgb_array"``: :meth:`render` returns a top view (500 x 500 x 3 uint8) of the hub
        and the deflected beam at true scale, with the rigid line (light blue) and the
        target direction (grey).
    dt : float
        Sample time [s], in (0, 0.1]; default 1e-3.  The torque is held over each step
        (exact zero-order hold).
    tau_max : float
        Torque limit [N m], > 0; default 0.3.  The action space is ``[-tau_max, tau_max]``.
    noise_std : float or sequence of 4 float
        Standard deviation of additive Gaussian measurement noise on hub angle [rad], hub
        velocity [rad/s], tip deflection [m] and tip acceleration [m/s^2]; default 0.  The
        plant's own sensor noise (``tachometer_noise``) adds to it in quadrature, and the hub
        angle is read in the encoder's steps first (``encoder_counts``).  The measurement and
        actuation chain are physical parameters (below); pass
        ``**flexid.envs.beam.IDEAL_SENSORS`` to switch it off.
    target_angle : float
        Hub angle set point theta_ref [rad] used when ``reset`` has no options; default 0.5.
    target_range : float, optional
        ``reset(options={"random_target": True})`` draws theta_ref uniformly in
        ``[-target_range, target_range]`` [rad]; at most ``angle_limit``; default
        ``min(1, angle_limit)``.
    angle_limit : float
        Safe hub-angle range [rad]: the episode terminates when ``|theta| > angle_limit``;
        default pi/2.
    angle_weight, tip_weight, torque_weight : float
        Reward weights (>= 0), defaults 1 [1/rad^2], 100 [1/m^2], 0.01 [-].
    **physics
        Any field of :class:`flexid.envs.beam.BeamParameters` (``payload_mass``,
        ``n_sections``, ``damping_ratios``, ``hub_coulomb_friction``, ...).

    Raises
    ------
    PlantParameterError
        For any invalid value (the message names the parameter and its allowed range).
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array"], "render_fps": 50}
    plant: ClassVar[Plant] = PLANT

    def __init__(
        self,
        render_mode: str | None = None,
        *,
        dt: float = 1e-3,
        tau_max: float = 0.3,
        noise_std=0.0,
        target_angle: float = 0.5,
        target_range: float | None = None,
        angle_limit: float = math.pi / 2,
        angle_weight: float = 1.0,
        tip_weight: float = 100.0,
        torque_weight: float = 0.01,
        **physics,
    ):
        self._cfg = _Config(
            dt, tau_max, noise_std, target_angle, target_range, angle_limit,
            angle_weight, tip_weight, torque_weight, render_mode, physics,
        )  # fmt: skip
        self.params = self._cfg.params
        self.dt = self._cfg.dt
        self.render_mode = render_mode
        self.action_space, self.observation_space = self._cfg.spaces()
        self.state = np.zeros(self._cfg.n_states)
        self.target = self._cfg.target_angle
        self._noise = _NoiseStream()

    def _observe(self, y: np.ndarray) -> np.ndarray:
        obs = np.empty(5)
        obs[:4] = y
        if self._cfg.encoder_step:
            obs[:1] = sensors.quantise(obs[:1], self._cfg.encoder_step)
        if self._cfg.noisy:
            obs[:4] += self._cfg.noise_std * self._noise.draw(self.np_random)
        obs[4] = self.target
        return obs

    def reset(
        self, *, seed: int | None = None, options: dict | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start an episode at rest at theta = 0.

        Parameters
        ----------
        seed : int, optional
            Seed of the environment's generator (measurement noise, random targets); None
            keeps the current generator.
        options : dict, optional
            ``{"target_angle": theta_ref}`` (rad, within ``angle_limit``) or
            ``{"random_target": True}`` (uniform in ``[-target_range, target_range]``);
            default: the constructor's ``target_angle``.

        Returns
        -------
        observation : ndarray, shape (5,)
            ``[theta, theta', w(l), y''(l), theta_ref]`` as in the class docstring.
        info : dict
            ``outputs`` (noise-free outputs, shape (4,)) and ``target_angle`` [rad].

        Raises
        ------
        PlantParameterError
            For an unknown option or a target outside ``[-angle_limit, angle_limit]``.
        """
        super().reset(seed=seed)
        if seed is not None:
            self._noise = _NoiseStream()
        self.target = self._cfg.target_from_options(options, self.np_random)
        self.state = np.zeros(self._cfg.n_states)
        y = self._cfg.outputs(self.state)
        return self._observe(y), {"outputs": y, "target_angle": self.target}

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Apply a hub torque for one sample time.

        Parameters
        ----------
        action : array_like, shape (1,) or ()
            Hub torque [N m]; finite values outside ``[-tau_max, tau_max]`` are clipped.

        Returns
        -------
        observation : ndarray, shape (5,)
            As in :meth:`reset`.
        reward : float
            The class docstring's reward, from the noise-free outputs after the step.
        terminated : bool
            ``|theta| > angle_limit``.
        truncated : bool
            Always False (truncation comes from the registration's ``max_episode_steps``).
        info : dict
            ``applied_torque`` [N m], ``clipped``, ``outputs`` (shape (4,)) and
            ``target_angle`` [rad].

        Raises
        ------
        ActionError
            For a NaN or infinite action or one of the wrong shape.
        """
        tau, clipped = self._cfg.check_action(action, None)
        self.state = self._cfg.advance(self.state, tau)
        y = self._cfg.outputs(self.state)
        reward, terminated = self._cfg.reward(y, self.target, tau)
        info = {
            "applied_torque": float(tau),
            "clipped": bool(clipped),
            "outputs": y,
            "target_angle": self.target,
        }
        return self._observe(y), float(reward), bool(terminated), False, info

    def render(self) -> np.ndarray | None:
        """The current frame, in ``"rgb_array"`` render mode.

        Returns
        -------
        ndarray of uint8, shape (500, 500, 3), or None
            Top view of the hub and the deflected beam; None when ``render_mode`` is None.
        """
        if self.render_mode == "rgb_array":
            return _render_frame(self._cfg, self.state, self.target)
        return None


class FlexibleManipulatorVectorEnv(
    BatchedVectorEnv, single_env=FlexibleManipulatorEnv, config_type=_Config
):
    """``num_envs`` flexible manipulators stepped together with one matrix product.

    Parameters
    ----------
    num_envs : int
        Number of sub-environments, >= 1; default 1.
    render_mode : {None, "rgb_array"}
        ``"rgb_array"``: :meth:`render` returns one :class:`FlexibleManipulatorEnv` frame
        (500 x 500 x 3 uint8) per sub-environment.
    max_episode_steps : int or None
        Steps after which a sub-environment is truncated, >= 1; default 2000 (as the
        registration); None: never.
    **kwargs
        The keyword arguments of :class:`FlexibleManipulatorEnv` (``dt`` [s], ``tau_max``
        [N m], ``noise_std``, ``target_angle`` [rad], ``target_range`` [rad],
        ``angle_limit`` [rad], the reward weights and any physical parameter), with the
        same defaults.

    Raises
    ------
    PlantParameterError
        For any invalid value (the message names the parameter and its allowed range).

    Notes
    -----
    Same spaces (``single_action_space``, ``single_observation_space``), reward and
    termination as :class:`FlexibleManipulatorEnv`.  The state is a (num_envs, n_x) array.
    Autoreset is Gymnasium's default ``NEXT_STEP`` mode: the step after a
    termination/truncation resets that sub-environment (its action is ignored) and returns
    its first observation with reward 0 and ``terminated = truncated = False``; an autoreset
    reuses the ``options`` of the last :meth:`reset` call.

    Seeding rule (as ``SyncVectorEnv``): ``reset(seed=s)`` seeds sub-environment ``i`` with
    ``s + i`` (a list of seeds is used as is); every sub-environment has its own generator,
    so a rollout equals that of ``num_envs`` single environments seeded the same way.

    ``infos`` holds ``applied_torque`` (num_envs,), ``clipped`` (num_envs,) and ``outputs``
    (num_envs, 4), noise-free.
    """

    def __init__(
        self,
        num_envs: int = 1,
        render_mode: str | None = None,
        *,
        max_episode_steps: int | None = 2000,
        **kwargs: Any,
    ) -> None:
        super().__init__(num_envs, render_mode, max_episode_steps, kwargs)
        nx = self._cfg.n_states
        self.state = np.zeros((self.num_envs, nx))
        self.targets = np.full(self.num_envs, self._cfg.target_angle)
        self._noise = [_NoiseStream() for _ in range(self.num_envs)]
        self._options: dict | None = None

    def _reset_one(self, i: int) -> None:
        self.targets[i] = self._cfg.target_from_options(self._options, self._rngs[i])
        self.state[i] = 0.0
        self.steps[i] = 0

    def _observe(self, y: np.ndarray) -> np.ndarray:
        obs = np.empty((self.num_envs, 5))
        obs[:, :4] = y
        if self._cfg.encoder_step:
            obs[:, 0] = sensors.quantise(obs[:, 0], self._cfg.encoder_step)
        if self._cfg.noisy:
            z = np.stack([s.draw(r) for s, r in zip(self._noise, self._rngs)])
            obs[:, :4] += self._cfg.noise_std * z
        obs[:, 4] = self.targets
        return obs

    def reset(
        self, *, seed: int | list[int] | None = None, options: dict | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Reset all sub-environments.

        Parameters
        ----------
        seed : int or list of int, optional
            An int ``s`` seeds sub-environment ``i`` with ``s + i``; a list gives one seed
            per sub-environment.  None keeps the current generators.
        options : dict, optional
            As in :meth:`FlexibleManipulatorEnv.reset`; also used by later autoresets.

        Returns
        -------
        observations : ndarray, shape (num_envs, 5)
            One observation row per sub-environment.
        infos : dict
            ``outputs`` (num_envs, 4), noise-free, and ``target_angle`` (num_envs,) [rad].

        Raises
        ------
        PlantParameterError
            For a list of seeds of the wrong length or an invalid option.
        """
        seeds = self._seed(seed)
        if seeds is not None:
            self._noise = [_NoiseStream() for _ in range(self.num_envs)]
            self._np_random, self._np_random_seed = seeding.np_random(seeds[0])
        if options is not None:
            self._cfg.target_from_options(options, np.random.default_rng(0))  # validate
        self._options = options
        for i in range(self.num_envs):
            self._reset_one(i)
        self.prev_done[:] = False
        y = self._cfg.outputs(self.state)
        return self._observe(y), {"outputs": y, "target_angle": self.targets.copy()}

    def step(
        self, actions: Any
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Step all sub-environments by one sample time.

        Parameters
        ----------
        actions : array_like, shape (num_envs, 1) or (num_envs,)
            Hub torques [N m]; finite values outside ``[-tau_max, tau_max]`` are clipped.
            The action of a sub-environment being autoreset is ignored.

        Returns
        -------
        observations : ndarray, shape (num_envs, 5)
            One observation row per sub-environment.
        rewards : ndarray, shape (num_envs,)
            Rewards (0 for a sub-environment being autoreset).
        terminated : ndarray of bool, shape (num_envs,)
            ``|theta| > angle_limit``.
        truncated : ndarray of bool, shape (num_envs,)
            The episode reached ``max_episode_steps``.
        infos : dict
            ``applied_torque`` (num_envs,) [N m], ``clipped`` (num_envs,) and ``outputs``
            (num_envs, 4), noise-free.

        Raises
        ------
        ActionError
            For NaN or infinite actions or actions of the wrong shape.
        """
        tau, clipped = self._cfg.check_action(actions, self.num_envs)
        done = self.prev_done
        tau = np.where(done, 0.0, tau)
        clipped = clipped & ~done
        self.state = self._cfg.advance(self.state, tau)
        self.steps += 1
        for i in np.flatnonzero(done):
            self._reset_one(int(i))
        y = self._cfg.outputs(self.state)
        reward, terminated = self._cfg.reward(y, self.targets, tau)
        truncated = self._end_step(done, reward, terminated)
        infos = {"applied_torque": tau, "clipped": clipped, "outputs": y}
        return self._observe(y), reward, terminated, truncated, infos

    def render(self) -> tuple[np.ndarray, ...] | None:
        """The current frames, in ``"rgb_array"`` render mode.

        Returns
        -------
        tuple of ndarray, or None
            One (500, 500, 3) uint8 frame per sub-environment; None when ``render_mode`` is
            None.
        """
        if self.render_mode == "rgb_array":
            return tuple(
                _render_frame(self._cfg, self.state[i], float(self.targets[i]))
                for i in range(self.num_envs)
            )
        return None
