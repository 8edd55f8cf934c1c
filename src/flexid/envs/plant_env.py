"""The generic Gymnasium environment of a plant that gives its pure functions.

A registered plant whose record gives a transition, an output and an initial state
(:class:`flexid.data.plants.PlantFunctions`) and no ``env_entry_point`` gets :class:`PlantEnv` (and
:class:`PlantVectorEnv` for ``gymnasium.make_vec``) under its ``env_id``: a thin shell that
calls those functions and holds no equations, as Gymnasium's functional environments
(``gymnasium.envs.phys2d``) are shells around one transition function.  The single
environment steps a batch of one, the vector environment a batch of ``num_envs``, through the
same function.

Observation: the plant's measured outputs, ``measure(output(x, 0))`` plus Gaussian noise of
the plant's ``noise_floor`` (none with ``sensors="ideal"``), in its output units.  Action: one
entry per input, normalised to ``[-1, 1]`` over the plant's input limits.  Reward and
termination: the plant's ``reward`` and ``terminal``, by default ``-sum(y**2)`` of the
noise-free outputs and never.
"""

from __future__ import annotations

from typing import Any, ClassVar

import gymnasium
import numpy as np
from gymnasium import spaces

from .._validate import positive_real
from ..data.plants import Plant, get_plant
from ..errors import ActionError, PlantParameterError
from ._vector import BatchedVectorEnv

__all__ = ["PlantEnv", "PlantVectorEnv"]


class _Config:
    """The plant, its functions and parameters, and the validated settings of both envs."""

    def __init__(
        self,
        plant: str | Plant,
        render_mode: str | None,
        dt: float | None,
        sensors: str,
        parameters: dict[str, Any],
    ) -> None:
        self.plant = plant if isinstance(plant, Plant) else get_plant(plant)
        if render_mode is not None:
            raise PlantParameterError(
                f"{self.plant.name}: the generic environment does not render; render_mode must "
                f"be None, got {render_mode!r}"
            )
        self.f = self.plant.functions()
        self.params = self.plant.make_parameters(parameters, sensors=sensors)
        self.dt = positive_real(
            self.plant.dt if dt is None else dt, f"{self.plant.name}: dt",
            error=PlantParameterError, unit="s",
        )
        low, high = (np.asarray(v, dtype=float) for v in self.f.input_limits(self.params))
        self.center = 0.5 * (low + high)
        self.half_range = 0.5 * (high - low)
        self.n_u = len(self.plant.input_names)
        self.n_y = len(self.plant.output_names)
        self.x0 = np.array(self.f.initial_state(self.params, self.dt), dtype=float)
        self.noise = np.asarray(self.plant.noise_floor(self.params), dtype=float)
        self.noisy = bool(np.any(self.noise > 0))

    def spaces(self) -> tuple[spaces.Box, spaces.Box]:
        """The action and observation spaces of one environment."""
        big = np.finfo(np.float64).max  # finite bounds: Gymnasium's checker flags infinite ones
        return (
            spaces.Box(-1.0, 1.0, (self.n_u,), np.float64),
            spaces.Box(-big, big, (self.n_y,), np.float64),
        )

    def inputs(self, action: Any, batch: int | None) -> np.ndarray:
        """Inputs (B, n_u) in the plant's units from normalised actions, clipped to the box."""
        a = np.asarray(action, dtype=float)
        shape = (self.n_u,) if batch is None else (batch, self.n_u)
        if a.shape != shape:
            raise ActionError(f"{self.plant.name}: action must have shape {shape}, got {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ActionError(f"{self.plant.name}: action must be finite, got {action!r}")
        a = np.clip(a.reshape(-1, self.n_u), -1.0, 1.0)
        return self.center + self.half_range * a

    def observe(self, x: np.ndarray, rngs: list[np.random.Generator]) -> np.ndarray:
        """Measured outputs (B, n_y) of states ``x`` (B, n_x), each row's noise from its rng.

        The outputs are read at zero input: the next input is not known yet.
        """
        y = self.f.output(x, np.zeros((x.shape[0], self.n_u)), self.params, self.dt)
        obs = np.array(self.plant.measure(np.asarray(y, dtype=float), self.params), dtype=float)
        if self.noisy:
            obs += np.stack([r.standard_normal(self.n_y) for r in rngs]) * self.noise
        return obs


class PlantEnv(gymnasium.Env):
    """A registered plant as a Gymnasium environment, stepped by its pure transition.

    Parameters
    ----------
    plant : str or Plant
        The plant (its registry name, or its record); its record must give a transition
        (:class:`flexid.data.plants.PlantFunctions`).
    render_mode : None
        The generic environment does not render.
    dt : float, optional
        Sample time [s], > 0; default the plant's ``dt``.
    sensors : {"lab", "ideal"}
        ``"ideal"`` switches the measurement chain off
        (:meth:`flexid.data.plants.Plant.make_parameters`).
    **parameters
        Fields of the plant's parameter dataclass that differ from its defaults.

    Raises
    ------
    PlantParameterError
        For an unknown plant or parameter, a bad value, or a plant without a transition.

    Notes
    -----
    Observation (float64, shape (n_y,)): the plant's outputs
    (:attr:`~flexid.data.plants.Plant.output_names`, in its output units) at zero input, read
    through its sensors (``measure``) with Gaussian noise of standard deviation
    ``noise_floor(params)`` drawn from the environment's generator.

    Action (float64, shape (n_u,)): the inputs (:attr:`~flexid.data.plants.Plant.input_names`)
    normalised to ``[-1, 1]`` over the plant's input limits, ``u = (low + high) / 2 + a (high
    - low) / 2``; finite out-of-range actions are clipped to the box, non-finite ones raise
    :class:`~flexid.errors.ActionError`.  The applied inputs are ``info["applied_input"]``.

    Reward and termination: the plant's ``reward(x, u, x_next, params, dt)`` and
    ``terminal(x_next, params, dt)`` (default ``-sum(y**2)`` over the noise-free outputs of
    the new state, and never); truncation comes from the registration's
    ``max_episode_steps``.  ``info["state"]`` is the state after the step (``state``, shape
    (n_x,), assignable).
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": []}
    plant: ClassVar[Plant | None] = None  # each instance has its own

    def __init__(
        self,
        plant: str | Plant,
        render_mode: str | None = None,
        *,
        dt: float | None = None,
        sensors: str = "lab",
        **parameters: Any,
    ) -> None:
        self._cfg = _Config(plant, render_mode, dt, sensors, parameters)
        self.plant = self._cfg.plant
        self.params = self._cfg.params
        self.dt = self._cfg.dt
        self.render_mode = render_mode
        self.observation_names = self.plant.output_names
        self.action_names = self.plant.input_names
        self.action_space, self.observation_space = self._cfg.spaces()
        self.state = self._cfg.x0.copy()

    def reset(
        self, *, seed: int | None = None, options: dict | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        self.state = self._cfg.x0.copy()
        return self._cfg.observe(self.state[None], [self.np_random])[0], {
            "state": self.state.copy()
        }

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        cfg = self._cfg
        u = cfg.inputs(action, None)
        x = np.asarray(self.state, dtype=float)[None]
        x_next = np.array(cfg.f.transition(x, u, cfg.params, cfg.dt), dtype=float)
        reward = float(cfg.f.reward(x, u, x_next, cfg.params, cfg.dt)[0])
        terminated = bool(cfg.f.terminal(x_next, cfg.params, cfg.dt)[0])
        self.state = x_next[0]
        obs = cfg.observe(x_next, [self.np_random])[0]
        info = {"state": self.state.copy(), "applied_input": u[0]}
        return obs, reward, terminated, False, info


class PlantVectorEnv(BatchedVectorEnv, single_env=PlantEnv, config_type=_Config):
    """``num_envs`` copies of a plant stepped together, one call of its transition per step.

    Parameters
    ----------
    num_envs : int
        Number of sub-environments, >= 1; default 1.
    render_mode : None
        The generic environment does not render.
    max_episode_steps : int or None
        Steps after which a sub-environment is truncated, >= 1; None (default): never
        (``gymnasium.make_vec`` passes the registration's).
    **kwargs
        The keyword arguments of :class:`PlantEnv` (``plant``, ``dt`` [s], ``sensors`` and
        the plant's parameters), with the same defaults.

    Raises
    ------
    PlantParameterError
        For an invalid argument (``num_envs`` and ``max_episode_steps`` included).

    Notes
    -----
    Same spaces, reward and termination as :class:`PlantEnv`.  Autoreset: Gymnasium's
    ``NEXT_STEP`` mode.  ``reset(seed=s)`` seeds sub-environment ``i`` with ``s + i``, so a
    rollout equals that of single environments seeded the same way.  ``state``
    (num_envs, n_x) holds the states (assignable).
    """

    def __init__(
        self,
        num_envs: int = 1,
        render_mode: str | None = None,
        *,
        max_episode_steps: int | None = None,
        **kwargs: Any,
    ) -> None:
        super().__init__(num_envs, render_mode, max_episode_steps, kwargs)
        self.plant = self._cfg.plant
        self.state = np.tile(self._cfg.x0, (self.num_envs, 1))

    def reset(
        self, *, seed: int | list[int] | None = None, options: dict | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        self._restart(seed)
        self.state = np.tile(self._cfg.x0, (self.num_envs, 1))
        return self._cfg.observe(self.state, self._rngs), {}

    def step(
        self, actions: Any
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        cfg = self._cfg
        u = cfg.inputs(actions, self.num_envs)
        done = self.prev_done
        x = np.asarray(self.state, dtype=float)
        x_next = np.array(cfg.f.transition(x, u, cfg.params, cfg.dt), dtype=float)
        reward = np.array(cfg.f.reward(x, u, x_next, cfg.params, cfg.dt), dtype=float)
        terminated = np.array(cfg.f.terminal(x_next, cfg.params, cfg.dt), dtype=bool)
        self.steps += 1
        if done.any():  # the autoreset step: these restart, their action ignored
            x_next[done] = cfg.x0
            self.steps[done] = 0
        self.state = x_next
        truncated = self._end_step(done, reward, terminated)
        return self._cfg.observe(x_next, self._rngs), reward, terminated, truncated, {
            "applied_input": u
        }
