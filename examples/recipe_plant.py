"""Recipe: a third plant, as ``docs/architecture.md`` ("A new plant") says.

Run:  python examples/recipe_plant.py

A first-order lag (a tank's level behind a valve), in the shape every plant has: a frozen
parameter dataclass, pure batched physics (``step`` advances any number of tanks one
sample; ``simulate`` is that step over a record), the measurement chain (``measure``,
``noise_floor``, ``IDEAL_SENSORS``) and the names and units of its outputs; a thin
Gymnasium environment that calls the same ``step`` and reads its names and units from the
registry; and one ``register_plant`` call with its presets and its built-in comparison.
``flexid.generate``, ``gymnasium.make``, ``flexid compare --plant`` (``default_spec``) and
the command line's help then know it.  The script checks that least squares recovers the
plant's exact discretisation from an ideal-sensor record.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces

import flexid
from flexid.config import default_spec
from flexid.plants import Plant, get_plant, register_plant

OUTPUT_NAMES = ("level",)
OUTPUT_UNITS = ("m",)
IDEAL_SENSORS: dict[str, Any] = {"level_noise": 0.0}


@dataclass(frozen=True)
class LagParameters:
    """The tank.

    Attributes
    ----------
    gain : float
        Steady-state level per valve volt [m/V].
    tau : float
        Time constant [s].
    level_noise : float
        Standard deviation of the level sensor's noise [m].
    """

    gain: float = 2.0
    tau: float = 0.5
    level_noise: float = 1e-3


def step(level: np.ndarray, valve: np.ndarray, params: LagParameters, dt: float) -> np.ndarray:
    """One sample of any number of tanks: the exact discretisation, the input held.

    Parameters
    ----------
    level : ndarray, shape (B,)
        Levels [m] now.
    valve : ndarray, shape (B,)
        Valve voltages [V] held over the sample.
    params : LagParameters
    dt : float
        Sample time [s].

    Returns
    -------
    ndarray, shape (B,)
        Levels one sample later.
    """
    a = np.exp(-dt / params.tau)
    return a * level + (1.0 - a) * params.gain * valve


def simulate(u: np.ndarray, params: LagParameters, dt: float) -> np.ndarray:
    """The level over a record from rest: ``step`` sample by sample.

    Parameters
    ----------
    u : ndarray, shape (N,)
        Valve voltages [V].
    params : LagParameters
    dt : float
        Sample time [s].

    Returns
    -------
    ndarray, shape (N, 1)
        Levels [m], read before each sample's input acts.
    """
    y = np.zeros((u.size, 1))
    level = np.zeros(1)
    for k in range(u.size):  # one tank: the recursion is the record's
        y[k, 0] = level[0]
        level = step(level, u[k : k + 1], params, dt)
    return y


def measure(y: np.ndarray, params: LagParameters) -> np.ndarray:
    """The sensor's reading (this one reads exactly; its noise is added by ``generate``).

    Parameters
    ----------
    y : ndarray, shape (N, 1)
    params : LagParameters

    Returns
    -------
    ndarray, shape (N, 1)
    """
    return np.array(y, dtype=float)


def noise_floor(params: LagParameters) -> np.ndarray:
    """The level sensor's noise standard deviation [m].

    Parameters
    ----------
    params : LagParameters

    Returns
    -------
    ndarray, shape (1,)
    """
    return np.array([params.level_noise])


class LagEnv(gymnasium.Env):
    """The tank as a Gymnasium environment: the physics' ``step``, nothing re-implemented."""

    def __init__(self) -> None:
        self.plant = get_plant("lag")
        self.params = LagParameters()
        self.action_space = spaces.Box(-1.0, 1.0, (1,), np.float64)
        self.observation_space = spaces.Box(-np.inf, np.inf, (1,), np.float64)
        self.level = np.zeros(1)

    def reset(
        self, *, seed: int | None = None, options: dict | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        self.level = np.zeros(1)
        return self.level.copy(), {}

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        valve = np.clip(np.asarray(action, dtype=float).reshape(1), -1.0, 1.0)
        self.level = step(self.level, valve, self.params, self.plant.dt)
        return self.level.copy(), -float(self.level[0] ** 2), False, False, {}


register_plant(
    Plant(
        name="lag",
        module=__name__,  # this file; a package names its physics module
        parameters="LagParameters",
        input_names=("valve",),
        input_units=("V",),
        dt=0.1,
        n_samples=600,
        signal_options={"low": -1.0, "high": 1.0},
        env_id="recipe/Lag-v0",
        simulate=lambda module, u, params, dt: (module.simulate(u[:, 0], params, dt), u),
        env_entry_point=f"{__name__}:LagEnv",
        max_episode_steps=50,
        presets={"lag-steps": {"description": "random steps held 1 s", "signal": "aprbs",
                               "n_samples": 600}},
        comparison={"preset": "lag-steps", "arx_order": 1, "model": {"na": 1, "nb": 1}},
    )
)


def main() -> None:
    """Run the checks the docstring at the top of the file describes, one line each."""
    record = flexid.generate("lag", preset="lag-steps", sensors="ideal", seed=0)
    ident = flexid.identify(record, na=1, nb=1, nk=1, optimiser="ls")
    a = np.exp(-0.1 / 0.5)
    a_hat, b_hat = -ident.model.a[1], ident.model.b[0][0]  # A = 1 + a1 q^-1, B = b1 q^-1
    exact = np.allclose([a_hat, b_hat], [a, (1 - a) * 2.0], rtol=1e-9)
    print(f"least squares recovers the exact discretisation: {exact}")
    env = gymnasium.make("recipe/Lag-v0")
    obs, _ = env.reset(seed=0)
    for _ in range(5):
        obs, *_ = env.step(np.array([1.0]))
    print(f"the environment steps the same physics: {np.isclose(obs[0], 2.0 * (1 - a**5))}")
    spec = default_spec(plant="lag", runs=1, budget=100)
    print(f"built-in comparison from the record: {spec.data.preset == 'lag-steps'}")


if __name__ == "__main__":
    main()
