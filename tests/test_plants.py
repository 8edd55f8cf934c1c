"""The plant registry (flexid.data.plants) is the one plant interface: ``generate``, the CLI and the
Gymnasium registration read it, and the environments take their names and units from it.

A third plant is one physics module and one ``register_plant`` call: with its pure functions
(a transition, its outputs, its initial state) it gets the generic environment
(``flexid.envs.plant_env``), or it names a thin environment of its own.  The tests that
register a plant with its own environment run in a fresh interpreter; the tank with pure
functions is registered here and removed after each test, so the process-wide registries
(flexid's and Gymnasium's) of the other tests stay as they are.
"""

from __future__ import annotations

import dataclasses
import subprocess
import sys
import textwrap
import warnings

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import flexid  # also registers the environments
from flexid.data.plants import PLANTS, Plant, check_plant, get_plant, register_plant
from flexid.envs import MANIPULATOR_ID, TWIN_ROTOR_ID, manipulator, sensors, twin_rotor
from flexid.errors import PlantParameterError, UnknownNameError

# A toy plant: a first-order lag, its physics and a thin environment that reads its names
# and units from the registry.
TOY_MODULE = '''
from dataclasses import dataclass

import gymnasium
import numpy as np
from gymnasium import spaces

OUTPUT_NAMES = ("level",)
OUTPUT_UNITS = ("m",)
IDEAL_SENSORS = {}


@dataclass(frozen=True)
class LagParameters:
    gain: float = 2.0
    tau: float = 0.5


def simulate(u, params, dt):
    a = np.exp(-dt / params.tau)
    y = np.zeros(len(u))
    for k in range(1, len(u)):
        y[k] = a * y[k - 1] + (1 - a) * params.gain * u[k - 1]
    return y[:, None]


def measure(y, params):
    return np.array(y, dtype=float)


def noise_floor(params):
    return np.zeros(1)


class LagEnv(gymnasium.Env):
    def __init__(self):
        from flexid.data.plants import get_plant

        self.plant = get_plant("lag")
        self.params = LagParameters()
        self.observation_names = self.plant.output_names
        self.action_space = spaces.Box(-1.0, 1.0, (1,), np.float64)
        self.observation_space = spaces.Box(-np.inf, np.inf, (1,), np.float64)
        self.y = 0.0

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        self.y = 0.0
        return np.array([self.y]), {}

    def step(self, action):
        u = float(np.clip(action[0], -1.0, 1.0))
        self.y = float(simulate(np.array([u, 0.0]), self.params, self.plant.dt)[1, 0])
        return np.array([self.y]), -self.y**2, False, False, {}
'''

REGISTER = """
from flexid.data.plants import Plant, register_plant

register_plant(
    Plant(
        name="lag",
        module="toy_lag_plant",
        parameters="LagParameters",
        input_names=("valve",),
        input_units=("V",),
        dt=0.1,
        n_samples=50,
        signal_options={"low": -1.0, "high": 1.0},
        env_id="toy/Lag-v0",
        simulate=lambda module, u, params, dt: (module.simulate(u[:, 0], params, dt), u),
        env_entry_point="toy_lag_plant:LagEnv",
        max_episode_steps=7,
    )
)
"""

CHECK = """
import gymnasium
import numpy as np
import flexid

data = flexid.generate("lag", seed=0)
assert tuple(data.input_names) == ("valve",) and tuple(data.output_names) == ("level",)
assert tuple(data.input_units) == ("V",) and tuple(data.output_units) == ("m",)
assert data.y.shape == (50, 1) and np.any(data.y != 0)
env = gymnasium.make("toy/Lag-v0")
assert env.spec.max_episode_steps == 7
assert env.unwrapped.observation_names == ("level",)
env.reset(seed=0)
steps = 0
while True:
    steps += 1
    *_, terminated, truncated, _ = env.step(np.array([0.5]))
    if terminated or truncated:
        break
assert steps == 7
# the plants of flexid are still there, under their ids
for name in ("flexid/FlexibleManipulator-v0", "flexid/TwinRotor-v0"):
    assert gymnasium.spec(name).id == name
"""


def _run(tmp_path, *blocks: str) -> None:
    (tmp_path / "toy_lag_plant.py").write_text(TOY_MODULE)
    code = f"import sys\nsys.path.insert(0, {str(tmp_path)!r})\n" + "\n".join(
        textwrap.dedent(block) for block in blocks
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr


def test_a_third_plant_registered_after_gymnasium_is_imported(tmp_path):
    _run(tmp_path, "import gymnasium, flexid", REGISTER, CHECK)


def test_a_third_plant_registered_before_gymnasium_is_imported(tmp_path):
    _run(
        tmp_path,
        "import flexid",
        REGISTER,
        "assert 'gymnasium' not in sys.modules",  # registered when Gymnasium is imported
        CHECK,
    )


def test_the_gymnasium_registration_is_read_from_the_registry():
    assert {MANIPULATOR_ID, TWIN_ROTOR_ID} == {p.env_id for p in PLANTS.values()}
    for plant in PLANTS.values():
        spec = gymnasium.spec(plant.env_id)
        assert spec.entry_point == plant.env_entry_point
        assert spec.vector_entry_point == plant.vector_entry_point
        assert spec.max_episode_steps == plant.max_episode_steps
    # the ids the README and users know
    assert MANIPULATOR_ID == "flexid/FlexibleManipulator-v0"
    assert TWIN_ROTOR_ID == "flexid/TwinRotor-v0"


def test_the_environments_take_their_names_and_units_from_the_registry():
    man, trs = get_plant("manipulator"), get_plant("twin-rotor")
    for cls in (manipulator.FlexibleManipulatorEnv, manipulator.FlexibleManipulatorVectorEnv):
        assert cls.plant is man
    for cls in (twin_rotor.TwinRotorEnv, twin_rotor.TwinRotorVectorEnv):
        assert cls.plant is trs
    assert manipulator.OBSERVATION_NAMES[:-1] == man.output_names
    assert twin_rotor.OBSERVATION_NAMES[:4] == trs.output_names
    assert twin_rotor.OBSERVATION_UNITS[:4] == trs.output_units
    assert twin_rotor.ACTION_NAMES == trs.input_names == ("main_rotor", "tail_rotor")
    assert len(twin_rotor.OBSERVATION_NAMES) == twin_rotor.TwinRotorEnv().observation_space.shape[0]
    assert "pitch (rad)" in twin_rotor.TwinRotorEnv.__doc__
    assert "main_rotor (V)" in twin_rotor.TwinRotorEnv.__doc__


def test_a_name_is_registered_once_and_unknown_names_raise():
    with pytest.raises(PlantParameterError, match="already registered"):
        register_plant(get_plant("manipulator"))
    with pytest.raises(UnknownNameError):
        get_plant("no-such-plant")


def test_a_registered_plant_brings_its_presets_and_its_comparison(capsys):
    """The registry is the only list of plants: a third plant's preset, built-in comparison
    and command-line help come from its record alone."""
    import dataclasses

    from flexid.cli import main
    from flexid.config import default_spec
    from flexid.data.datasets import PRESETS
    from flexid.data.plants import PLANTS

    man = get_plant("manipulator")
    copy = dataclasses.replace(
        man, name="beam-copy", env_id="flexid/BeamCopy-v0", env_entry_point=None,
        vector_entry_point=None,
        presets={"short-beam": {**man.presets["paper-manipulator"], "n_samples": 300}},
        comparison={**man.comparison, "preset": "short-beam"},
    )
    register_plant(copy)
    try:
        assert PRESETS["short-beam"]["plant"] == "beam-copy"
        spec = default_spec(plant="beam-copy", runs=1, budget=50, optimisers=["de"])
        assert spec.data.plant == "beam-copy" and spec.data.preset == "short-beam"
        assert spec.model == default_spec().model
        with pytest.raises(SystemExit):
            main(["compare", "--help"])
        assert "manipulator | twin-rotor | beam-copy" in " ".join(
            capsys.readouterr().out.split()
        )
        record = flexid.generate("beam-copy", preset="short-beam", seed=0)
        assert record.n_samples == 300
    finally:
        PLANTS.pop("beam-copy")
    assert "short-beam" not in PRESETS


# ------------------------------------------------------------ the pure functions of a plant
# A tank behind a valve with a level sensor, given as pure functions only: the generic
# environment (flexid.envs.plant_env) is its Gymnasium environment.
OUTPUT_NAMES = ("level",)
OUTPUT_UNITS = ("m",)
IDEAL_SENSORS = {"level_noise": 0.0}


@dataclasses.dataclass(frozen=True)
class TankParameters:
    gain: float = 2.0  # m/V
    tau: float = 0.5  # s
    level_noise: float = 1e-3  # m
    overflow: float = 1.5  # m


def tank_step(x, u, params, dt):
    a = np.exp(-dt / params.tau)
    return a * x + (1.0 - a) * params.gain * u


def tank_outputs(x, u, params, dt):
    return np.array(x, dtype=float)


def tank_rest(params, dt):
    return np.zeros(1)


def measure(y, params):
    return sensors.quantise(np.asarray(y, dtype=float), 1e-4)  # a 0.1 mm gauge


def noise_floor(params):
    return np.array([params.level_noise])


def tank_overflows(x, params, dt):
    return x[:, 0] > params.overflow


TANK = dict(
    name="tank",
    module=__name__,
    parameters="TankParameters",
    input_names=("valve",),
    input_units=("V",),
    dt=0.1,
    n_samples=80,
    signal_options={"low": -1.0, "high": 1.0},
    env_id="test/Tank-v0",
    simulate=lambda module, u, params, dt: (np.zeros((len(u), 1)), u),
    max_episode_steps=30,
    transition=tank_step,
    output="tank_outputs",  # a name in the module, as the built-in plants give them
    initial_state=tank_rest,
    input_limits=lambda params: (np.array([0.0]), np.array([1.0])),  # a valve opens, 0-1 V
    terminal=tank_overflows,
)


@pytest.fixture
def tank():
    """The tank registered (with its environment), and gone again after the test."""
    plant = register_plant(Plant(**TANK))
    try:
        yield plant
    finally:
        PLANTS.pop("tank", None)
        gymnasium.envs.registration.registry.pop("test/Tank-v0", None)


def test_a_plant_with_a_transition_gets_the_generic_environment(tank):
    spec = gymnasium.spec("test/Tank-v0")
    assert spec.entry_point == "flexid.envs.plant_env:PlantEnv"
    assert spec.kwargs == {"plant": "tank"} and spec.max_episode_steps == 30
    env = gymnasium.make("test/Tank-v0", tau=0.4)
    assert env.unwrapped.observation_names == ("level",)
    assert env.unwrapped.action_names == ("valve",)
    assert env.action_space.shape == (1,) and env.observation_space.shape == (1,)
    p = env.unwrapped.params
    assert p == TankParameters(tau=0.4)
    obs, info = env.reset(seed=4)
    np.testing.assert_array_equal(info["state"], [0.0])
    noise = np.random.default_rng(4)  # the env's generator: gymnasium seeds it so
    assert obs[0] == measure(np.zeros(1), p)[0] + 1e-3 * noise.standard_normal(1)[0]
    rng = np.random.default_rng(0)
    x = np.zeros((1, 1))
    steps = 0
    while True:
        a = rng.uniform(-1.2, 1.2, 1)  # some out of the box: clipped
        obs, reward, terminated, truncated, info = env.step(a)
        steps += 1
        u = 0.5 + 0.5 * np.clip(a, -1.0, 1.0)  # [-1, 1] onto the valve's 0-1 V
        np.testing.assert_array_equal(info["applied_input"], u)
        # the env calls the plant's transition on the same batch of one: the same numbers
        x = tank_step(x, u[None], p, 0.1)
        np.testing.assert_array_equal(info["state"], x[0])
        np.testing.assert_array_equal(obs, measure(x[0], p) + 1e-3 * noise.standard_normal(1))
        assert reward == -float(x[0, 0] ** 2)  # the default reward, noise-free
        assert terminated is bool(x[0, 0] > 1.5)
        if terminated or truncated:
            break
    # the random valve (0.5 V on average) keeps the level near 1 m, below the overflow: the
    # episode ends by the registration's truncation
    assert steps == 30 and truncated and x[0, 0] < 1.5


def test_the_generic_environment_passes_gymnasiums_checker(tank):
    env = gymnasium.make("test/Tank-v0")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the checker's advice is a warning: none is given
        check_env(env.unwrapped)


def test_the_generic_environment_terminates_by_the_plants_test(tank):
    env = gymnasium.make("test/Tank-v0", sensors="ideal")
    env.reset(seed=0)
    levels = []
    while True:
        obs, _, terminated, truncated, info = env.step(np.array([1.0]))
        levels.append(info["state"][0])
        if terminated or truncated:
            break
    # the open valve fills the tank towards 2 m: it overflows 1.5 m after
    # ceil(ln(1 - 1.5 / 2) / ln(exp(-0.2))) = 7 steps; "ideal" sensors: no noise, the gauge's
    # steps only
    assert terminated and not truncated and len(levels) == 7
    assert obs[0] == measure(levels[-1], None) and levels[-2] <= 1.5 < levels[-1]


def test_the_generic_vector_environment_equals_single_environments(tank):
    n, seed, steps = 3, 7, 70
    venv = gymnasium.make_vec("test/Tank-v0", num_envs=n, vectorization_mode="vector_entry_point")
    assert venv.unwrapped.max_episode_steps == 30  # the registration's
    rng = np.random.default_rng(1)
    actions = rng.uniform(-1.0, 1.0, (steps, n, 1))
    actions[:, 0] = 1.0  # env 0 overflows (terminates), the others truncate
    vo = [venv.reset(seed=seed)[0]]
    vr, vt, vu = [], [], []
    for k in range(steps):
        o, r, te, tr, _ = venv.step(actions[k])
        vo.append(o)
        vr.append(r)
        vt.append(te)
        vu.append(tr)
    for i in range(n):
        env = gymnasium.make("test/Tank-v0")
        so = [env.reset(seed=seed + i)[0]]
        sr, st, su = [], [], []
        done = False
        for k in range(steps):
            if done:  # NEXT_STEP autoreset: this step resets, its action ignored
                o, _ = env.reset()
                so.append(o)
                sr.append(0.0)
                st.append(False)
                su.append(False)
                done = False
                continue
            o, r, te, tr, _ = env.step(actions[k, i])
            done = te or tr
            so.append(o)
            sr.append(r)
            st.append(te)
            su.append(tr)
        # one transition function on a batch of n or of one: elementwise arithmetic on the
        # same numbers, the same noise draws from the same seeds: exact
        np.testing.assert_array_equal(np.array(vo)[:, i], np.array(so))
        np.testing.assert_array_equal(np.array(vr)[:, i], sr)
        np.testing.assert_array_equal(np.array(vt)[:, i], st)
        np.testing.assert_array_equal(np.array(vu)[:, i], su)
    assert np.any(vt) and np.any(vu)


def _tank_with(**changes):
    return Plant(**{**TANK, "name": "bad-tank", "env_id": "test/BadTank-v0", **changes})


@pytest.mark.parametrize(
    "changes, match",
    [
        ({"transition": lambda x, u, params: x}, r"transition must take \(x, u, params, dt\)"),
        ({"output": "no_such_function"}, "output 'no_such_function' is not a function of module"),
        ({"transition": lambda x, u, params, dt: x[:, 0]},
         r"transition\(x \(2, 1\), u \(2, 1\), params, dt\) must return states .* shape \(2,\)"),
        ({"output": lambda x, u, params, dt: np.hstack([x, x])},
         r"output\(.*\) must return outputs .*level.* got shape \(2, 2\)"),
        ({"initial_state": lambda params, dt: np.zeros((1, 1))},
         r"initial_state\(params, dt\) must return a state of shape \(n_x,\), got shape"),
        ({"transition": lambda x, u, params, dt: x + np.nan},
         r"transition\(.*\) returned non-finite values"),
        ({"transition": lambda x, u, params, dt: x @ np.ones((3, 1))},
         r"transition\(x, u, params, dt\) raised ValueError"),
        ({"input_limits": lambda params: (np.ones(1), np.zeros(1))},
         "every low must be < its high"),
        ({"terminal": lambda x, params, dt: x[:, 0]}, r"terminal\(.*\) must return bool \(B,\)"),
        ({"reward": lambda x, u, x_next: x}, r"reward must take \(x, u, x_next, params, dt\)"),
    ],
)  # fmt: skip
def test_a_plant_with_a_bad_pure_function_is_refused(changes, match):
    with pytest.raises(PlantParameterError, match=match) as caught:
        register_plant(_tank_with(**changes))
    assert "plant 'bad-tank'" in str(caught.value)
    assert "bad-tank" not in PLANTS and "test/BadTank-v0" not in gymnasium.registry


def test_a_plant_record_with_an_incomplete_contract_is_refused():
    with pytest.raises(PlantParameterError, match="a transition needs output and initial_state"):
        _tank_with(output=None, initial_state=None)
    with pytest.raises(PlantParameterError, match="reward must be a function or the name"):
        _tank_with(reward=3.0)
    with pytest.raises(PlantParameterError, match="gives no transition"):
        Plant(**{**TANK, "transition": None, "output": None, "initial_state": None}).functions()


@pytest.mark.parametrize("name", ["manipulator", "twin-rotor"])
def test_the_built_in_plants_meet_the_contract(name):
    plant = get_plant(name)
    f = check_plant(plant)  # registered unchecked, to keep `import flexid` light
    module = plant.physics()
    assert f.transition is module.step_states
    assert f.output is module.outputs and f.initial_state is module.initial_state
