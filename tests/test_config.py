"""Tests of flexid.config: comparison specifications and TOML files."""

from __future__ import annotations

import pytest

from flexid.config import ComparisonSpec, OptimiserSpec, default_spec, load_config
from flexid.errors import ConfigError, UnknownNameError

GOOD = """
name = "demo"
[data]
plant = "manipulator"
preset = "paper-manipulator"
seed = 3
[model]
na = 4
nb = 4
nk = 1
[cost]
metric = "rmse"
predictor = "simulation"
[search]
bounds = [-2.0, 2.0]
[run]
runs = 3
seed = 7
budget = [500, "schedule"]
targets = [0.5]
[validation]
max_lag = 10
[[optimisers]]
name = "sda"
params = { points = 10 }
[[optimisers]]
name = "sda"
label = "sda-big"
params = { points = 40 }
"""


def _write(tmp_path, text, name="c.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_load_good_config(tmp_path):
    specs = load_config(_write(tmp_path, GOOD))
    assert len(specs) == 2
    a, b = specs
    assert a.name == "demo @ 500 FE" and b.name == "demo @ paper loops"
    assert a.budget == 500 and a.max_fe == 500
    assert b.budget == "schedule" and b.max_fe == b.schedule_cap
    assert a.model.na == 4 and a.cost.predictor == "simulation"
    assert a.bounds == (-2.0, 2.0)
    assert [o.display for o in a.optimisers] == ["sda", "sda-big"]
    assert a.optimisers[1].params == {"points": 40}
    assert a.targets == (0.5,) and a.max_lag == 10 and a.runs == 3 and a.seed == 7
    assert a.key != b.key


def test_key_ignores_name_runs_and_optimisers():
    base = default_spec(runs=3)
    from dataclasses import replace

    assert replace(base, name="x", runs=10, optimisers=(OptimiserSpec("pso"),)).key == base.key
    assert replace(base, seed=1).key != base.key
    assert replace(base, budget=123).key != base.key


def test_round_trip_dict():
    spec = default_spec(plant="twin-rotor", optimisers=["pso", "de"], runs=2, budget=300)
    assert ComparisonSpec.from_dict(spec.to_dict()) == spec
    assert spec.model.na == 5 and spec.data.preset == "paper-twin-rotor"


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("[data]\nplant='manipulator'\ncolour='red'\n", r"unknown key\(s\) 'colour' in \[data\]"),
        ("[model]\nna=4\nfoo=1\n", r"unknown key\(s\) 'foo' in \[model\]"),
        ("[runs]\nruns=3\n", r"unknown key\(s\) 'runs' in \[top level\]"),
        ("[run]\nruns=0\n", r"\[run\] runs must be an integer in \[1, "),
        ("[run]\nbudget='lots'\n", "budget must be an integer, 'schedule' or"),
        ("[data]\nplant='manipulator'\nfile='x.csv'\n", "exactly one of"),
        ("[[optimisers]]\nparams={}\n", "needs a 'name'"),
        ("[[optimisers]]\nname='sda'\n[[optimisers]]\nname='sda'\n", "labels must be unique"),
        ("[[optimisers]]\nname='ls'\n", "least-squares reference"),
        ("name = [unclosed\n", "malformed TOML"),
    ],
)
def test_bad_configs(tmp_path, text, match):
    with pytest.raises(ConfigError, match=match):
        load_config(_write(tmp_path, text))


def test_missing_config(tmp_path):
    with pytest.raises(ConfigError, match="no such configuration file"):
        load_config(tmp_path / "nope.toml")
    with pytest.raises(ConfigError, match="is a directory"):
        load_config(tmp_path)


def test_relative_file_is_relative_to_config(tmp_path):
    path = _write(tmp_path, "[data]\nfile='rec.csv'\n")
    (spec,) = load_config(path)
    assert spec.data.file == str((tmp_path / "rec.csv").resolve())


def test_default_spec_unknown_plant():
    with pytest.raises(UnknownNameError, match="unknown plant 'boat'"):
        default_spec(plant="boat")


def test_comparison_tables(tmp_path):
    text = """
name = "exp"
[model]
na = 5
[run]
runs = 4
seed = 2
[[optimisers]]
name = "pso"
[[comparison]]
name = "loops"
budget = "schedule"
[[comparison]]
name = "equal"
budget = 900
runs = 6
optimisers = [ { name = "de", label = "DE" }, { name = "pso", params = { points = 20 } } ]
"""
    a, b = load_config(_write(tmp_path, text))
    assert (a.name, a.budget, a.runs, a.seed) == ("loops", "schedule", 4, 2)
    assert [o.name for o in a.optimisers] == ["pso"]
    assert (b.name, b.budget, b.runs) == ("equal", 900, 6)
    assert [o.display for o in b.optimisers] == ["DE", "pso"]
    assert b.optimisers[1].params == {"points": 20}
    assert a.model.na == b.model.na == 5
    with pytest.raises(ConfigError, match=r"unknown key\(s\) 'colour' in \[\[comparison\]\] #1"):
        load_config(_write(tmp_path, "[[comparison]]\ncolour = 1\n", "bad.toml"))
