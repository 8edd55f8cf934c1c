"""The registry of simulated plants: one record per plant, read by ``generate`` and the CLI.

Each plant is a physics module in :mod:`flexid.envs` with the same shape: a frozen parameter
dataclass, pure batched physics (``simulate``), its measurement chain (``measure``,
``noise_floor`` and the ``IDEAL_SENSORS`` overrides that switch it off) and the names and
units of its outputs (``OUTPUT_NAMES``, ``OUTPUT_UNITS``).  :class:`Plant` ties a name to that
module, the names and units of its inputs, its defaults and its Gymnasium environment.

A plant's pure functions (:class:`PlantFunctions`) are part of the record: the transition
(a batch of states one sample later), the outputs read from a state and the initial state, as
in Gymnasium's functional environments, where one transition function serves the single, the
vector and the compiled environment.  A plant that gives them needs no environment class of
its own: :mod:`flexid.envs` registers the generic :class:`~flexid.envs.plant_env.PlantEnv`
(and its vector version) under its ``env_id``.  The built-in environments keep their own fast
routes, and the tests hold those to the plant's transition.

:mod:`flexid.envs` registers the environment of every plant here with Gymnasium, and the
environments read the names and units of their actions and observations from their record.
A third plant is one new physics module and one :func:`register_plant` call.
"""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import sys
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import FlexidError, PlantParameterError, UnknownNameError

__all__ = [
    "PLANTS",
    "PURE_FUNCTIONS",
    "Plant",
    "PlantFunctions",
    "all_presets",
    "check_plant",
    "get_plant",
    "register_plant",
]

PURE_FUNCTIONS = ("transition", "output", "initial_state", "input_limits", "reward", "terminal")
"""The fields of :class:`Plant` that name (or hold) its pure functions, in the order of the
fields of :class:`PlantFunctions`."""

# The positional arguments each pure function is called with, for the signature check.
_ARGUMENTS = {
    "transition": ("x", "u", "params", "dt"),
    "output": ("x", "u", "params", "dt"),
    "initial_state": ("params", "dt"),
    "input_limits": ("params",),
    "reward": ("x", "u", "x_next", "params", "dt"),
    "terminal": ("x", "params", "dt"),
}


@dataclass(frozen=True)
class PlantFunctions:
    """A plant's pure functions, resolved from its record (:meth:`Plant.functions`).

    Every function is pure (no state of its own, no random numbers) and batched over a
    leading axis ``B``; ``params`` is the plant's parameter dataclass and ``dt`` the sample
    time [s].  ``n_x`` is the number of states, ``n_u`` of inputs (:attr:`Plant.input_names`)
    and ``n_y`` of outputs (:attr:`Plant.output_names`); states, inputs and outputs are in
    the units of the physics module (inputs :attr:`Plant.input_units`, outputs
    :attr:`Plant.output_units`).

    Attributes
    ----------
    transition : callable
        ``transition(x, u, params, dt) -> x_next``: states ``x`` (B, n_x) one sample later,
        ``x_next`` (B, n_x), with the inputs ``u`` (B, n_u) held over the sample (zero-order
        hold).  The inputs are within :attr:`input_limits` (the caller clips them).
    output : callable
        ``output(x, u, params, dt) -> y``: the outputs (B, n_y) of states ``x`` (B, n_x)
        with inputs ``u`` (B, n_u) acting (they matter only for a direct feed-through),
        before the measurement chain (:meth:`Plant.measure`, :meth:`Plant.noise_floor`).
    initial_state : callable
        ``initial_state(params, dt) -> x0``: the state (n_x,) an episode or a record starts
        from.
    input_limits : callable
        ``input_limits(params) -> (low, high)``: the inputs' finite ranges, each (n_u,),
        ``low < high``.  Default: the excitation's range, ``signal_options["low"]`` and
        ``["high"]``, for every input.
    reward : callable
        ``reward(x, u, x_next, params, dt) -> r``: the reward (B,) of a transition.  Default:
        ``-sum(y**2)`` over the outputs ``y = output(x_next, 0, params, dt)`` of the new
        states (regulation of every output to zero, in its own units).
    terminal : callable
        ``terminal(x, params, dt) -> done``: bool (B,), true where a state ends an episode.
        Default: never (episodes end by the registration's ``max_episode_steps``).
    """

    transition: Callable[..., np.ndarray]
    output: Callable[..., np.ndarray]
    initial_state: Callable[..., np.ndarray]
    input_limits: Callable[[Any], tuple[np.ndarray, np.ndarray]]
    reward: Callable[..., np.ndarray]
    terminal: Callable[..., np.ndarray]



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
        ``"module:Class"`` of its Gymnasium environment.  None: the generic
        :class:`~flexid.envs.plant_env.PlantEnv` when the plant gives a ``transition``, else
        no environment is registered.
    vector_entry_point : str or None
        ``"module:Class"`` of its vector environment (``gymnasium.make_vec(...,
        vectorization_mode="vector_entry_point")``), if any (with the generic environment,
        None gives :class:`~flexid.envs.plant_env.PlantVectorEnv`).
    max_episode_steps : int or None
        Episode length the Gymnasium registration gives the environment.
    presets : mapping
        Named records of it (:func:`flexid.data.datasets.generate`'s ``preset``): each a mapping
        of ``generate``'s options and a ``description``.
    comparison : mapping
        Its built-in comparison (``flexid compare --plant NAME``,
        :func:`flexid.config.default_spec`): ``preset`` (the record), ``arx_order`` (``na``
        when only ARX orders are given) and ``model`` (the
        :class:`~flexid.config.ModelSpec` fields of its default model).  Empty: the plant
        has none.
    transition, output, initial_state : str, callable or None
        The plant's pure functions (:class:`PlantFunctions` gives their signatures, shapes and
        units): a function, or the name of one in :attr:`module`.  ``output`` and
        ``initial_state`` are needed with ``transition``; None (all three): the plant has no
        pure transition, and no generic environment.
    input_limits, reward, terminal : str, callable or None
        Optional pure functions (:class:`PlantFunctions`), a function or a name in
        :attr:`module`; None: the defaults documented there.
    modes : str, callable or None
        ``modes(params, inputs) -> (frequency, damping)``: the plant's own modes at the
        operating point of constant ``inputs`` (n_u,) (None: 0), natural frequencies [Hz]
        and damping ratios, each (k,) (:meth:`true_modes`); a function or a name in
        :attr:`module`.  None: the plant does not know them.
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
    transition: str | Callable[..., np.ndarray] | None = field(default=None, repr=False)
    output: str | Callable[..., np.ndarray] | None = field(default=None, repr=False)
    initial_state: str | Callable[..., np.ndarray] | None = field(default=None, repr=False)
    input_limits: str | Callable[..., Any] | None = field(default=None, repr=False)
    reward: str | Callable[..., np.ndarray] | None = field(default=None, repr=False)
    terminal: str | Callable[..., np.ndarray] | None = field(default=None, repr=False)
    modes: str | Callable[..., tuple[np.ndarray, np.ndarray]] | None = field(
        default=None, repr=False)  # fmt: skip

    def __post_init__(self) -> None:
        for name in PURE_FUNCTIONS:
            value = getattr(self, name)
            if value is not None and not isinstance(value, str) and not callable(value):
                raise PlantParameterError(
                    f"plant {self.name!r}: {name} must be a function or the name of one in "
                    f"{self.module!r}, got {value!r}"
                )
        if self.transition is not None and (self.output is None or self.initial_state is None):
            missing = [n for n in ("output", "initial_state") if getattr(self, n) is None]
            raise PlantParameterError(
                f"plant {self.name!r}: a transition needs {' and '.join(missing)} too"
            )

    def physics(self) -> Any:
        """The physics module (imported on first use).

        Returns
        -------
        module
            The module named by :attr:`module`.
        """
        return importlib.import_module(self.module)

    def functions(self) -> PlantFunctions:
        """The plant's pure functions, names resolved in :attr:`module`, defaults filled in.

        Returns
        -------
        PlantFunctions
            Its transition, output, initial state, input limits, reward and terminal test.

        Raises
        ------
        PlantParameterError
            When the plant gives no ``transition``, a name is not a function of the module,
            or a function cannot take the arguments :class:`PlantFunctions` gives it.
        """
        if self.transition is None:
            raise PlantParameterError(
                f"plant {self.name!r} gives no transition (Plant.transition), so it has no "
                "pure step function and no generic environment"
            )
        found = {name: self._resolve(name) for name in PURE_FUNCTIONS}
        if found["input_limits"] is None:
            found["input_limits"] = self._default_limits
        if found["reward"] is None:
            found["reward"] = _negative_output_energy(found["output"])
        if found["terminal"] is None:
            found["terminal"] = _never
        return PlantFunctions(**found)

    def true_modes(
        self, params: Any = None, *, inputs: Any = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """The plant's own modes, what an identified model's modes are scored against.

        Parameters
        ----------
        params : dataclass instance or mapping, optional
            The plant's parameters, or the overrides of a record's metadata (its
            ``"parameters"``); default the plant's defaults.
        inputs : array_like or mapping, optional
            The operating point's inputs (a record's mean input), in :attr:`input_names`
            order, or ``name -> value`` (inputs not named are 0); default 0.  A nonlinear
            plant's modes are its linearisation's there.

        Returns
        -------
        frequency : ndarray, shape (k,)
            Natural frequencies [Hz], increasing.
        damping : ndarray, shape (k,)
            Damping ratios [-].

        Raises
        ------
        PlantParameterError
            When the plant gives no :attr:`modes`, or bad parameters.
        """
        if self.modes is None:
            raise PlantParameterError(f"plant {self.name!r} does not give its modes")
        function = getattr(self.physics(), self.modes) if isinstance(self.modes, str) else (
            self.modes)  # fmt: skip
        if params is None or isinstance(params, Mapping):
            params = self.make_parameters(params)
        if isinstance(inputs, Mapping):
            unknown = sorted(set(inputs) - set(self.input_names))
            if unknown:
                raise PlantParameterError(f"{self.name}: no input {unknown[0]!r}; its inputs "
                                          f"are {list(self.input_names)}")  # fmt: skip
            inputs = [float(inputs.get(n, 0.0)) for n in self.input_names]
        frequency, damping = function(params, inputs)
        return np.asarray(frequency, dtype=float), np.asarray(damping, dtype=float)

    def _resolve(self, name: str) -> Callable[..., Any] | None:
        """The function a pure-function field names (or holds), its signature checked."""
        value = getattr(self, name)
        if value is None:
            return None
        where = f"plant {self.name!r}: {name}"
        if isinstance(value, str):
            function = getattr(self.physics(), value, None)
            if not callable(function):
                raise PlantParameterError(
                    f"{where} {value!r} is not a function of module {self.module!r}"
                )
            where += f" ({self.module}.{value})"
        else:
            function = value
        arguments = _ARGUMENTS[name]
        try:
            signature = inspect.signature(function)
        except (TypeError, ValueError):  # a builtin without a signature: trust the call
            return function
        try:
            signature.bind(*arguments)
        except TypeError:
            raise PlantParameterError(
                f"{where} must take ({', '.join(arguments)}), its signature is {signature}"
            ) from None
        return function

    def _default_limits(self, params: Any) -> tuple[np.ndarray, np.ndarray]:
        """The excitation's range for every input (``signal_options`` low and high)."""
        n_u = len(self.input_names)
        low = float(self.signal_options.get("low", -1.0))
        high = float(self.signal_options.get("high", 1.0))
        return np.full(n_u, low), np.full(n_u, high)

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
    from ..envs.twin_rotor_steppers import simulate  # the fast route of the physics module

    return simulate(u, params, dt=dt), module.clip_inputs(u, params)


def _negative_output_energy(output: Callable[..., np.ndarray]) -> Callable[..., np.ndarray]:
    """The default reward: ``-sum(y**2)`` of the new states' outputs at zero input."""

    def reward(x, u, x_next, params, dt):
        y = output(x_next, np.zeros_like(u), params, dt)
        return -np.sum(np.square(y), axis=1)

    return reward


def _never(x, params, dt):
    """The default terminal test: no state ends an episode."""
    return np.zeros(np.shape(x)[0], dtype=bool)


def _checked_array(where: str, value: Any, shape: tuple[int, ...], what: str) -> np.ndarray:
    """``value`` as a finite float array of ``shape``, else a PlantParameterError."""
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise PlantParameterError(f"{where} must return {what}, got {value!r}") from None
    if array.shape != shape:
        raise PlantParameterError(
            f"{where} must return {what}, shape {shape}, got shape {array.shape}"
        )
    if not np.all(np.isfinite(array)):
        raise PlantParameterError(f"{where} returned non-finite values: {array!r}")
    return array


def check_plant(plant: Plant) -> PlantFunctions:
    """Check a plant's pure functions on its default parameters: signatures and shapes.

    Each function is called once, on a batch of two copies of the initial state with the
    inputs at the two ends of their limits, at the default sample time; every result must
    be finite and of the shape :class:`PlantFunctions` states.  :func:`register_plant` runs
    this for every plant that gives a ``transition``.

    Parameters
    ----------
    plant : Plant
        The record to check.

    Returns
    -------
    PlantFunctions
        Its pure functions.

    Raises
    ------
    PlantParameterError
        Naming the plant, the function (and its module) and what is wrong: a missing
        function, a signature that does not take the documented arguments, a call that
        raises, or a result of the wrong shape or not finite.
    """
    f = plant.functions()
    params = plant.make_parameters()
    dt = plant.dt
    n_u, n_y = len(plant.input_names), len(plant.output_names)

    def call(name: str, *args: Any) -> Any:
        try:
            return getattr(f, name)(*args)
        except FlexidError:
            raise
        except Exception as exc:
            raise PlantParameterError(
                f"plant {plant.name!r} ({plant.module}): {name}"
                f"({', '.join(_ARGUMENTS[name])}) raised {type(exc).__name__}: {exc}"
            ) from exc

    def where(name: str, shapes: str) -> str:
        return f"plant {plant.name!r} ({plant.module}): {name}({shapes})"

    x0 = np.asarray(call("initial_state", params, dt), dtype=float)
    if x0.ndim != 1 or x0.size == 0:
        raise PlantParameterError(
            f"{where('initial_state', 'params, dt')} must return a state of shape (n_x,), "
            f"got shape {x0.shape}"
        )
    n_x = x0.size
    x0 = _checked_array(where("initial_state", "params, dt"), x0, (n_x,), "a state (n_x,)")
    limits = call("input_limits", params)
    if not isinstance(limits, (tuple, list)) or len(limits) != 2:
        raise PlantParameterError(
            f"{where('input_limits', 'params')} must return (low, high), got {limits!r}"
        )
    low, high = (
        _checked_array(where("input_limits", "params"), v, (n_u,), f"{n_u} limits (n_u,)")
        for v in limits
    )
    if not np.all(low < high):
        raise PlantParameterError(
            f"{where('input_limits', 'params')}: every low must be < its high, got {low}, {high}"
        )
    x = np.stack([x0, x0])
    u = np.stack([low, high])
    shapes = f"x (2, {n_x}), u (2, {n_u}), params, dt"
    x_next = _checked_array(
        where("transition", shapes), call("transition", x, u, params, dt), (2, n_x),
        "states (B, n_x)",
    )
    _checked_array(
        where("output", shapes), call("output", x, u, params, dt), (2, n_y),
        f"outputs (B, n_y) (n_y = {n_y}: {', '.join(plant.output_names)})",
    )
    _checked_array(
        where("reward", f"x (2, {n_x}), u (2, {n_u}), x_next (2, {n_x}), params, dt"),
        call("reward", x, u, x_next, params, dt), (2,), "rewards (B,)",
    )
    done = np.asarray(call("terminal", x_next, params, dt))
    if done.shape != (2,) or done.dtype != bool:
        raise PlantParameterError(
            f"{where('terminal', f'x (2, {n_x}), params, dt')} must return bool (B,), got "
            f"{done.dtype} of shape {done.shape}"
        )
    return f


PLANTS: dict[str, Plant] = {}
"""Registered plants by name."""


def register_plant(plant: Plant) -> Plant:
    """Add ``plant`` to :data:`PLANTS` (a name may be registered once).

    A plant that gives a ``transition`` has its pure functions checked first
    (:func:`check_plant`, which imports its module).  Its environment is registered with
    Gymnasium too (its ``env_entry_point``, or the generic
    :class:`~flexid.envs.plant_env.PlantEnv` when it has none and gives a transition): now if
    :mod:`flexid.envs` is loaded, else when it is.

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
        When a plant of that name is already registered, or its pure functions fail
        :func:`check_plant`.
    """
    if plant.name in PLANTS:
        raise PlantParameterError(f"a plant named {plant.name!r} is already registered")
    if plant.transition is not None:
        check_plant(plant)
    return _add(plant)


def _add(plant: Plant) -> Plant:
    """Put a plant in the registry and register its environment (no checks).

    The built-in plants come this way: checking them would import their physics (SciPy, the
    compiled kernels) with ``import flexid``; the tests check them instead.
    """
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


_add(
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
        transition="step_states",
        output="outputs",
        initial_state="initial_state",
        modes="modes",
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
_add(
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
        transition="step_states",
        output="outputs",
        initial_state="initial_state",
        input_limits="input_limits",
        modes="modes",
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
