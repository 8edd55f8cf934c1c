"""The registry of simulated plants: one record per plant, read by ``generate`` and the CLI.

Each plant is a physics module in :mod:`flexid.envs` with the same shape: a frozen parameter
dataclass, pure batched physics (``simulate``), its measurement chain (``measure``,
``noise_floor`` and the ``IDEAL_SENSORS`` overrides that switch it off) and the names and
units of its outputs (``OUTPUT_NAMES``, ``OUTPUT_UNITS``).  :class:`Plant` ties a name to that
module, the names and units of its inputs, its defaults and its Gymnasium environment.
:mod:`flexid.envs` registers the environment of every plant here with Gymnasium, and the
environments read the names and units of their actions and observations from their record.
A third plant is one new physics module, its thin environment and one :func:`register_plant`
call.
"""

from __future__ import annotations

import dataclasses
import importlib
import sys
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .errors import PlantParameterError, UnknownNameError

__all__ = ["PLANTS", "Plant", "all_presets", "get_plant", "register_plant"]


@dataclass(frozen=True)
class Plant:
    """How to simulate and measure one plant.

    Attributes
    ----------
    name : str
        Registry name, e.g. ``"manipulator"``.
    module : str
        Import path of the physics module.
    parameters : str
        Name of the parameter dataclass in ``module``.
    input_names, input_units : tuple of str
        Inputs, in the order of ``simulate``'s input columns.
    dt, n_samples : float, int
        Default sample time [s] and record length.
    signal_options : mapping
        Default options of the level signals (amplitude of the excitation).
    env_id : str
        Gymnasium id of its environment.
    simulate : callable
        ``simulate(module, u (N, n_u), params, dt) -> (y (N, n_y), u_applied (N, n_u))``.
    env_entry_point : str or None
        ``"module:Class"`` of its Gymnasium environment; None: no environment is registered.
    vector_entry_point : str or None
        ``"module:Class"`` of its vector environment (``gymnasium.make_vec(...,
        vectorization_mode="vector_entry_point")``), if any.
    max_episode_steps : int or None
        Episode length the Gymnasium registration gives the environment.
    presets : mapping
        Named records of it (:func:`flexid.datasets.generate`'s ``preset``): each a mapping
        of ``generate``'s options and a ``description``.
    comparison : mapping
        Its built-in comparison (``flexid compare --plant NAME``,
        :func:`flexid.config.default_spec`): ``preset`` (the record), ``arx_order`` (``na``
        when only ARX orders are given) and ``model`` (the
        :class:`~flexid.config.ModelSpec` fields of its default model).  Empty: the plant
        has none.
    """

    name: str
    module: str
    parameters: str
    input_names: tuple[str, ...]
    input_units: tuple[str, ...]
    dt: float
    n_samples: int
    signal_options: Mapping[str, Any]
    env_id: str
    simulate: Callable[..., tuple[np.ndarray, np.ndarray]] = field(repr=False)
    env_entry_point: str | None = None
    vector_entry_point: str | None = None
    max_episode_steps: int | None = None
    presets: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    comparison: Mapping[str, Any] = field(default_factory=dict)

    def physics(self) -> Any:
        """The physics module (imported on first use).

        Returns
        -------
        module
            The module named by :attr:`module`.
        """
        return importlib.import_module(self.module)

    @property
    def output_names(self) -> tuple[str, ...]:
        """Names of the outputs, in the order of ``simulate``'s output columns."""
        return tuple(self.physics().OUTPUT_NAMES)

    @property
    def output_units(self) -> tuple[str, ...]:
        """Units of the outputs, in the order of :attr:`output_names`."""
        return tuple(self.physics().OUTPUT_UNITS)

    def make_parameters(
        self, overrides: Mapping[str, Any] | None = None, *, sensors: str = "lab"
    ) -> Any:
        """The parameter dataclass with ``overrides``; ``sensors="ideal"`` switches the chain off.

        Parameters
        ----------
        overrides : mapping, optional
            Parameter values that differ from the dataclass defaults, by field name.
        sensors : {"lab", "ideal"}
            ``"ideal"`` applies the physics module's ``IDEAL_SENSORS`` values first (a given
            override still wins).

        Returns
        -------
        dataclass instance
            The plant's parameters.

        Raises
        ------
        PlantParameterError
            An unknown parameter name, a bad value or an unknown ``sensors`` rule.
        """
        module = self.physics()
        cls = getattr(module, self.parameters)
        if sensors not in ("lab", "ideal"):
            raise PlantParameterError(f"sensors must be 'lab' or 'ideal', got {sensors!r}")
        values = dict(module.IDEAL_SENSORS) if sensors == "ideal" else {}
        given = dict(overrides or {})
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(given) - known)
        if unknown:
            raise PlantParameterError(
                f"{self.name}: unknown parameter(s) {', '.join(map(repr, unknown))}; "
                f"known: {', '.join(sorted(known))}"
            )
        for key, value in given.items():  # lists from JSON/TOML become tuples
            values[key] = tuple(value) if isinstance(value, list) else value
        return cls(**values)

    def measure(self, y: np.ndarray, params: Any) -> np.ndarray:
        """Sampled outputs read through the plant's digital sensors.

        Parameters
        ----------
        y : ndarray, shape (N, n_y)
            Simulated outputs, in :attr:`output_units`.
        params : dataclass instance
            The plant's parameters (encoder resolution and the like).

        Returns
        -------
        ndarray, shape (N, n_y)
            The outputs as the sensors report them (e.g. quantised angles).
        """
        return self.physics().measure(y, params)

    def noise_floor(self, params: Any) -> np.ndarray:
        """Each output's own sensor-noise standard deviation.

        Parameters
        ----------
        params : dataclass instance
            The plant's parameters.

        Returns
        -------
        ndarray, shape (n_y,)
            Standard deviations, in :attr:`output_units`.
        """
        return self.physics().noise_floor(params)


def _simulate_manipulator(module, u, params, dt):
    return module.simulate(u[:, 0], params, dt=dt), u


def _simulate_twin_rotor(module, u, params, dt):
    return module.simulate(u, params, dt=dt), module.clip_inputs(u, params)


PLANTS: dict[str, Plant] = {}
"""Registered plants by name."""


def register_plant(plant: Plant) -> Plant:
    """Add ``plant`` to :data:`PLANTS` (a name may be registered once).

    Its environment is registered with Gymnasium too: now if :mod:`flexid.envs` is loaded,
    else when it is.

    Parameters
    ----------
    plant : Plant
        The plant's record.

    Returns
    -------
    Plant
        ``plant`` itself.

    Raises
    ------
    PlantParameterError
        When a plant of that name is already registered.
    """
    if plant.name in PLANTS:
        raise PlantParameterError(f"a plant named {plant.name!r} is already registered")
    PLANTS[plant.name] = plant
    envs = sys.modules.get("flexid.envs")
    register = getattr(envs, "register_environments", None)  # None while it is importing
    if register is not None:
        register()
    return plant


def all_presets() -> dict[str, dict[str, Any]]:
    """Every registered plant's presets (:attr:`Plant.presets`), each with its ``plant``.

    Returns
    -------
    dict
        ``preset name -> {"plant": plant name, **settings}``.
    """
    return {
        name: {"plant": plant.name, **settings}
        for plant in PLANTS.values()
        for name, settings in plant.presets.items()
    }


def get_plant(name: str) -> Plant:
    """The registered plant ``name``.

    Parameters
    ----------
    name : str
        Registry name, e.g. ``"manipulator"`` or ``"twin-rotor"``.

    Returns
    -------
    Plant
        Its record.

    Raises
    ------
    UnknownNameError
        When no plant has that name (the message lists the known ones).
    """
    try:
        return PLANTS[name]
    except (KeyError, TypeError):
        raise UnknownNameError("plant", name, PLANTS) from None


register_plant(
    Plant(
        name="manipulator",
        module="flexid.envs.beam",
        parameters="BeamParameters",
        input_names=("torque",),
        input_units=("N m",),
        dt=1e-3,
        n_samples=2000,
        signal_options={"low": -0.3, "high": 0.3},
        env_id="flexid/FlexibleManipulator-v0",
        simulate=_simulate_manipulator,
        env_entry_point="flexid.envs.manipulator:FlexibleManipulatorEnv",
        vector_entry_point="flexid.envs.manipulator:FlexibleManipulatorVectorEnv",
        max_episode_steps=2000,
        presets={
            "paper-manipulator": {
                "description": "Nasir & Tokhi 4.1: 2,300 samples at 1 ms, random +-0.3 N m "
                "torque, end-point acceleration",
                "signal": "uniform",
                "signal_options": {"low": -0.3, "high": 0.3},
                "n_samples": 2300,
                "dt": 1e-3,
                "outputs": ["tip_acceleration"],
                "noise_std": "1%",
            },
        },
        # output error OE(16,16,1) passes every validation test on the lab record, where no
        # ARX order does
        comparison={
            "preset": "paper-manipulator",
            "arx_order": 8,
            "model": {"structure": "oe", "nb": 16, "nf": 16, "nk": 1},
        },
    )
)
register_plant(
    Plant(
        name="twin-rotor",
        module="flexid.envs.twin_rotor_physics",
        parameters="TwinRotorParameters",
        input_names=("main_rotor", "tail_rotor"),
        input_units=("V", "V"),
        dt=0.1,
        n_samples=3000,
        signal_options={"low": -1.0, "high": 1.0},
        env_id="flexid/TwinRotor-v0",
        simulate=_simulate_twin_rotor,
        env_entry_point="flexid.envs.twin_rotor:TwinRotorEnv",
        vector_entry_point="flexid.envs.twin_rotor:TwinRotorVectorEnv",
        max_episode_steps=600,
        presets={
            "paper-twin-rotor": {
                "description": "Nasir & Tokhi 4.1: vertical channel, 8,000 samples at 0.1 s, "
                "random +-1 V held 0.1 s on the main rotor, pitch",
                "signal": "uniform",
                "signal_options": {"low": -1.0, "high": 1.0},
                "n_samples": 8000,
                "dt": 0.1,
                "outputs": ["pitch"],
                "inputs": ["main_rotor"],
                "plant_params": {"lock_yaw": True},
                "noise_std": 0.0,
            },
        },
        # no linear structure passes on the twin rotor (gravity and Coulomb friction): the
        # paper's ARX(5,5,1); its own physics pass (structure "greybox", twin-rotor-pitch)
        comparison={
            "preset": "paper-twin-rotor",
            "arx_order": 5,
            "model": {"na": 5, "nb": 5, "nk": 1},
        },
    )
)
