"""Recipe: a third plant, as ``docs/architecture.md`` ("A new plant") says.

Run:  python examples/recipe_plant.py

A first-order lag (a tank's level behind a valve), in the shape every plant has: a frozen
parameter dataclass; its pure functions, batched over any number of tanks (``step_states``
advances the states one sample, ``outputs`` reads the level from a state, ``initial_state``
is rest); ``simulate``, that step over a record; the measurement chain (``measure``,
``noise_floor``, ``IDEAL_SENSORS``) and the names and units of its outputs; and one
``register_plant`` call with its pure functions, its presets and its built-in comparison.
There is no environment class: ``gymnasium.make("recipe/Lag-v0")`` is flexid's generic
environment around ``step_states``.  ``flexid.generate``, ``flexid compare --plant``
(``default_spec``) and the command line's help know the plant too.  The script checks that
least squares recovers the plant's exact discretisation from an ideal-sensor record, and that
the environment steps the same function.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import gymnasium
import numpy as np

import flexid
from flexid.config import default_spec
from flexid.data.plants import Plant, register_plant

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


def step_states(
    level: np.ndarray, valve: np.ndarray, params: LagParameters, dt: float
) -> np.ndarray:
    """One sample of any number of tanks: the exact discretisation, the input held.

    The plant's transition: the state is the level.

    Parameters
    ----------
    level : ndarray, shape (B, 1)
        Levels [m] now.
    valve : ndarray, shape (B, 1)
        Valve voltages [V] held over the sample.
    params : LagParameters
    dt : float
        Sample time [s].

    Returns
    -------
    ndarray, shape (B, 1)
        Levels one sample later.
    """
    a = np.exp(-dt / params.tau)
    return a * level + (1.0 - a) * params.gain * valve


def outputs(level: np.ndarray, valve: np.ndarray, params: LagParameters, dt: float) -> np.ndarray:
    """The outputs of states: the level itself (the valve does not act on it at once).

    Parameters
    ----------
    level : ndarray, shape (B, 1)
        Levels [m].
    valve : ndarray, shape (B, 1)
        Valve voltages [V]; not used.
    params : LagParameters
    dt : float
        Sample time [s].

    Returns
    -------
    ndarray, shape (B, 1)
        Levels [m].
    """
    return np.array(level, dtype=float)


def initial_state(params: LagParameters, dt: float) -> np.ndarray:
    """An empty tank.

    Parameters
    ----------
    params : LagParameters
    dt : float
        Sample time [s].

    Returns
    -------
    ndarray, shape (1,)
        Level [m].
    """
    return np.zeros(1)


def simulate(u: np.ndarray, params: LagParameters, dt: float) -> np.ndarray:
    """The level over a record from rest: ``step_states`` sample by sample.

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
    level = initial_state(params, dt)[None]
    for k in range(u.size):  # one tank: the recursion is the record's
        y[k] = outputs(level, u[k : k + 1, None], params, dt)[0]
        level = step_states(level, u[k : k + 1, None], params, dt)
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
        env_id="recipe/Lag-v0",  # no env_entry_point: flexid's generic environment
        simulate=lambda module, u, params, dt: (module.simulate(u[:, 0], params, dt), u),
        transition="step_states",
        output="outputs",
        initial_state="initial_state",
        # the valve's range: the default, the excitation's signal_options low and high;
        # reward -level^2 and no termination: the defaults too
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
    env = gymnasium.make("recipe/Lag-v0", sensors="ideal")  # the sensor's noise off
    obs, _ = env.reset(seed=0)
    for _ in range(5):
        obs, *_ = env.step(np.array([1.0]))  # the valve fully open: 1 V
    print(f"the environment steps the same physics: {np.isclose(obs[0], 2.0 * (1 - a**5))}")
    spec = default_spec(plant="lag", runs=1, budget=100)
    print(f"built-in comparison from the record: {spec.data.preset == 'lag-steps'}")


if __name__ == "__main__":
    main()
