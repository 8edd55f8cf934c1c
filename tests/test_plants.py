"""The plant registry (flexid.plants) is the one plant interface: ``generate``, the CLI and the
Gymnasium registration read it, and the environments take their names and units from it.

A third plant is one physics module, its thin environment and one ``register_plant`` call; the
tests that register one run in a fresh interpreter, so the process-wide registries (flexid's
and Gymnasium's) of the other tests stay as they are.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap

import gymnasium
import pytest

import flexid  # also registers the environments
from flexid.envs import MANIPULATOR_ID, TWIN_ROTOR_ID, manipulator, twin_rotor
from flexid.errors import PlantParameterError, UnknownNameError
from flexid.plants import PLANTS, get_plant, register_plant

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
        from flexid.plants import get_plant

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
from flexid.plants import Plant, register_plant

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
    from flexid.datasets import PRESETS
    from flexid.plants import PLANTS

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
