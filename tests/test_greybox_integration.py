"""Grey-box models through identify, compare, the configuration files and the command line.

A user's model is a Python file (``path.py:NAME``), the way a user writes one; it runs on the
NumPy route everywhere.  What is checked: every optimiser's run in a comparison is the run
``minimize`` makes on the model's own cost with the same seed (the same initial population,
the exact budget), the reference recovers the parameters, a spawned worker finds the model
from its file, a store resumes and an edited model file is a new comparison, and bad input is
a typed error (one line with exit status 2 on the command line).
"""

from __future__ import annotations

import json
import math
import textwrap
from pathlib import Path

import numpy as np
import pytest

import flexid
from flexid.cli import main
from flexid.config import ComparisonSpec, DataSpec, ModelSpec, OptimiserSpec, load_config
from flexid.costs.greybox import GreyBoxCost
from flexid.errors import ConfigError, DataError, UnknownNameError
from flexid.models.greybox_library import (
    available_greybox_models,
    greybox_model,
    register_greybox_model,
)

TRUE = {"k": 80.0, "c": 1.5}

MODEL_FILE = textwrap.dedent(
    '''
    """A damped spring, the test's own physics."""
    import numpy as np

    from flexid import GreyBoxModel, GreyParameter


    def f(x, u, p):
        return np.column_stack([x[:, 1], (u[:, 0] - p.k * x[:, 0] - p.c * x[:, 1]) / p.m])


    MODEL = GreyBoxModel(
        "spring", f, lambda x, u, p: x[:, :1],
        states=("position", "velocity"), inputs=("force",), outputs=("position",),
        parameters=(
            GreyParameter("m", 2.0, 0.1, 10.0, "kg", fixed=True),
            GreyParameter("k", 50.0, 1.0, 1000.0, "N/m"),
            GreyParameter("c", 1.0, 0.01, 50.0, "N s/m"),
        ),
        substep=0.01,
    )
    NOT_A_MODEL = 3
    '''
)


@pytest.fixture
def model_file(tmp_path: Path) -> Path:
    path = tmp_path / "spring_model.py"
    path.write_text(MODEL_FILE)
    return path


def _record(model_file: Path, n: int = 240, noise: float = 1e-4) -> flexid.IOData:
    """The model at TRUE, driven by steps held 0.2 s, with position-sensor noise."""
    model = greybox_model(f"{model_file}:MODEL").with_parameters(**TRUE)
    rng = np.random.default_rng(3)
    force = np.repeat(rng.uniform(-3.0, 3.0, n // 10), 10)
    y = model.simulate(model.nominal, force, 0.02)[0, :, 0] + noise * rng.standard_normal(n)
    return flexid.IOData(force, y, dt=0.02, input_names=["force"], output_names=["position"])


# ---------------------------------------------------------------------- models by name
def test_a_model_is_found_by_file_and_name(model_file):
    model = greybox_model(f"{model_file}:MODEL")
    assert model.name == "spring" and model.free == ("k", "c")
    with pytest.raises(ConfigError, match=r"has no 'NOPE'.*its models: MODEL"):
        greybox_model(f"{model_file}:NOPE")
    with pytest.raises(ConfigError, match="is a int, not a GreyBoxModel"):
        greybox_model(f"{model_file}:NOT_A_MODEL")
    with pytest.raises(ConfigError, match="no file"):
        greybox_model(f"{model_file.parent / 'missing.py'}:MODEL")
    broken = model_file.parent / "broken.py"
    broken.write_text("raise RuntimeError('bad physics')\n")
    with pytest.raises(ConfigError, match="RuntimeError: bad physics"):
        greybox_model(f"{broken}:MODEL")
    with pytest.raises(UnknownNameError, match="twin-rotor-pitch"):
        greybox_model("nope")


def test_register_and_entry_point(model_file, tmp_path, monkeypatch):
    model = greybox_model(f"{model_file}:MODEL")
    register_greybox_model("test-spring", model)
    try:
        assert "test-spring" in available_greybox_models()
        assert greybox_model("test-spring", k=60.0).parameter("k").value == 60.0
        with pytest.raises(ConfigError, match="built-in"):
            register_greybox_model("twin-rotor-pitch", model)
    finally:
        from flexid.models import greybox_library as greybox_models

        greybox_models._REGISTERED.pop("test-spring")
    # an installed package's entry point (what `pip install` writes), found by name
    site = tmp_path / "site"
    info = site / "spring_pkg-0.1.dist-info"
    info.mkdir(parents=True)
    info.joinpath("METADATA").write_text("Metadata-Version: 2.1\nName: spring-pkg\nVersion: 0.1\n")
    info.joinpath("entry_points.txt").write_text(
        "[flexid.greybox_models]\nspring = spring_model:MODEL\n"
    )
    monkeypatch.syspath_prepend(str(site))
    monkeypatch.syspath_prepend(str(model_file.parent))
    assert "spring" in available_greybox_models()
    assert greybox_model("spring").free == ("k", "c")


# ---------------------------------------------------------------------- identify
def test_identify_fits_a_user_model_by_the_reference_and_by_an_optimiser(model_file):
    data = _record(model_file)
    model = greybox_model(f"{model_file}:MODEL")
    ref = flexid.identify(data, structure=model)  # default: the reference ("pem")
    se = ref.output_error.std_errors
    for name, value in TRUE.items():
        # noise of 1e-4 m on a ~1e-2 m response: the estimate is within a few standard errors
        assert abs(ref.model.parameter(name).value - value) <= 4 * se[name], name
    assert ref.output_error.local_minimum
    assert ref.validation.fit_simulation > 99 and ref.validation.start == 160
    assert "grey-box model spring identified by pem" in ref.summary()
    json.dumps(ref.to_dict(), allow_nan=False)

    de = flexid.identify(data, structure="greybox", greybox=f"{model_file}:MODEL",
                         optimiser="de", budget=2000, seed=1)
    assert de.result.nfev == 2000
    # the optimiser's cost is the problem's cost at its answer (the same map, both routes)
    again = GreyBoxCost(model, data.split(2 / 3)[0])(de.model.theta[None, :])[0]
    assert de.cost_value == pytest.approx(again, rel=1e-12)
    assert de.cost_value <= 1.5 * ref.cost_value


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"structure": "greybox"}, ConfigError, "needs the model"),
        ({"structure": "oe", "greybox": "twin-rotor-pitch"}, ConfigError, "not of structure"),
        ({"structure": "greybox", "greybox": "nope"}, UnknownNameError, "grey-box model"),
        ({"optimiser": "ls"}, ConfigError, "no least-squares estimate"),
        ({"na": 2}, ConfigError, "does not take na"),
        ({"predictor": "one-step"}, ConfigError, "no one-step predictor"),
        ({"detrend": "quadratic"}, UnknownNameError, "quadratic"),
        ({"initial": "zero"}, ConfigError, "initial must be .estimate."),
    ],
)
def test_identify_refuses_what_a_greybox_model_cannot_take(model_file, kwargs, error, match):
    data = _record(model_file, n=60)
    kwargs.setdefault("structure", greybox_model(f"{model_file}:MODEL"))
    with pytest.raises(error, match=match):
        flexid.identify(data, **kwargs)


def test_identify_names_a_missing_channel(model_file):
    data = _record(model_file, n=60)
    wrong = flexid.IOData(data.u, data.y, dt=data.dt, input_names=["u"], output_names=["y"])
    with pytest.raises(DataError, match=r"reads input column\(s\) \['force'\]"):
        flexid.identify(wrong, structure=greybox_model(f"{model_file}:MODEL"))


# ---------------------------------------------------------------------- compare
def _spec(model_file: Path, record: Path, **changes) -> ComparisonSpec:
    fields = {
        "name": "spring",
        "data": DataSpec(file=str(record)),
        "model": ModelSpec(structure="greybox", greybox=f"{model_file}:MODEL"),
        "optimisers": (OptimiserSpec("de"), OptimiserSpec("pso")),
        "runs": 2,
        "budget": 600,
    }
    fields.update(changes)
    return ComparisonSpec(**fields)


def test_compare_runs_are_minimize_on_the_models_cost(model_file, tmp_path):
    record = tmp_path / "spring.csv"
    data = _record(model_file)
    data.to_csv(record)
    spec = _spec(model_file, record)
    assert spec.cost.predictor == "simulation"
    result = flexid.compare(spec, store=tmp_path / "s.sqlite", progress=False)
    est = flexid.load(record).split(2 / 3)[0]
    problem = GreyBoxCost(greybox_model(f"{model_file}:MODEL"), est).problem()
    for label, runs in result.records.items():
        for r in runs:
            direct = flexid.minimize(label, problem, 600, seed=r["seed"])
            assert r["nfev"] == 600 and r["history"]["fe"][-1] == 600
            # the same seed, initial population and budget: the same run, to the last bit
            assert r["cost"] == direct.fun
    assert result.start_label == "nominal values"
    assert "grey-box reference" in result.reference_note
    ref = result.reference["output_error"]
    assert ref["local_minimum"] and ref["cost"] < result.reference["cost"]
    assert "nominal values" in result.summary()
    # a rerun reads every run from the store
    again = flexid.compare(spec, store=tmp_path / "s.sqlite", progress=False)
    assert again.elapsed < result.elapsed
    assert [r["cost"] for r in again.records["de"]] == [r["cost"] for r in result.records["de"]]


def test_compare_in_worker_processes_equals_serial(model_file, tmp_path):
    record = tmp_path / "spring.csv"
    _record(model_file, n=180).to_csv(record)
    spec = _spec(model_file, record, budget=200, optimisers=(OptimiserSpec("de"),))
    serial = flexid.compare(spec, store=None, progress=False)
    workers = flexid.compare(spec, store=None, progress=False, workers=2)
    assert [r["cost"] for r in workers.records["de"]] == [r["cost"] for r in serial.records["de"]]


def test_an_edited_model_file_is_another_comparison(model_file, tmp_path):
    record = tmp_path / "spring.csv"
    _record(model_file, n=60).to_csv(record)
    key = _spec(model_file, record).key
    model_file.write_text(MODEL_FILE.replace('"N s/m"', '"N*s/m"'))
    assert _spec(model_file, record).key != key


def test_toml_config_names_the_model_and_its_parameters(model_file, tmp_path):
    record = tmp_path / "spring.csv"
    _record(model_file, n=180).to_csv(record)
    config = tmp_path / "cmp.toml"
    config.write_text(
        textwrap.dedent(
            f"""
            [data]
            file = "{record.name}"
            [model]
            structure = "greybox"
            greybox = "{model_file.name}:MODEL"
            [model.parameters]
            k = 70.0
            c = {{fixed = true, value = 1.5}}
            [run]
            runs = 1
            budget = 100
            [[optimisers]]
            name = "de"
            """
        )
    )
    (spec,) = load_config(config)
    model = spec.model.greybox_model()
    assert model.free == ("k",) and model.parameter("k").value == 70.0
    result = flexid.compare(spec, store=None, progress=False)
    assert result.records["de"][0]["nfev"] == 100 and len(result.records["de"][0]["x"]) == 1


@pytest.mark.parametrize(
    ("model", "match"),
    [
        ({"structure": "greybox"}, "needs greybox"),
        ({"structure": "greybox", "greybox": "x.py:M", "na": 2}, "has no orders"),
        ({"structure": "oe", "nb": 2, "nf": 2, "greybox": "x"}, "belong to structure"),
        ({"structure": "greybox", "greybox": "x", "parameters": [1]}, "must be a table"),
    ],
)
def test_model_spec_refuses_a_bad_greybox_table(model, match):
    with pytest.raises(ConfigError, match=match):
        ModelSpec(**model)


# ---------------------------------------------------------------------- command line
def test_cli_identify_and_compare_a_user_model(model_file, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    _record(model_file).to_csv(tmp_path / "spring.csv")
    ref = f"{model_file}:MODEL"
    assert main(["identify", "spring.csv", "--structure", "greybox", "--greybox", ref,
                 "--set", "k=60", "--fix", "c", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["structure"] == {"structure": "greybox", "name": "spring"}
    assert out["model"]["parameters"]["c"] == {
        "value": 1.0, "lower": 0.01, "upper": 50.0, "unit": "N s/m", "fixed": True
    }
    assert math.isfinite(out["reference"]["std_errors"]["k"])
    assert main(["list", "greybox"]) == 0
    assert "twin-rotor-pitch: main_rotor -> pitch" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["identify", "spring.csv", "--structure", "greybox"], "needs --greybox NAME"),
        (["identify", "spring.csv", "--structure", "oe", "--greybox", "x"], "not oe"),
        (["identify", "spring.csv", "--na", "2", "--set", "k=3"], "--structure greybox"),
        (["identify", "spring.csv", "--structure", "greybox", "--greybox", "none.py:M"],
         "no file"),
        (["identify", "spring.csv", "--structure", "greybox", "--greybox", "MODEL_REF",
          "--set", "q=1"], "'q'"),
        (["identify", "spring.csv", "--structure", "greybox", "--greybox", "MODEL_REF",
          "--nf", "2"], "does not take nf"),
        (["compare", "--plant", "twin-rotor", "--structure", "greybox", "--greybox",
          "twin-rotor-pitch", "--na", "3"], "has no orders"),
        (["compare", "--plant", "manipulator", "--structure", "greybox", "--greybox",
          "twin-rotor-pitch", "--runs", "1", "--budget", "10"], "main_rotor"),
    ],
)
def test_cli_refuses_bad_greybox_input_in_one_line(
    argv, message, model_file, tmp_path, capsys, monkeypatch
):
    monkeypatch.chdir(tmp_path)
    _record(model_file, n=60).to_csv(tmp_path / "spring.csv")
    argv = [a.replace("MODEL_REF", f"{model_file}:MODEL") for a in argv]
    assert main([*argv, "--store", "s.sqlite"] if argv[0] == "compare" else argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["spring.csv", "spring_model.py"]


# ---------------------------------------------------------------------- select
def test_select_ranks_a_greybox_model_beside_polynomial_ones(model_file):
    # the spring is second order (linear: OE(2,2) would hold it too); a first-order OE cannot
    data = _record(model_file, n=600)
    sel = flexid.select(
        data, structures=["oe", f"greybox:{model_file}:MODEL"], orders=[{"nb": 1, "nf": 1}],
        starts=1,
    )
    grey = next(c for c in sel.candidates if c.kind == "greybox")
    assert grey.label == "grey-box spring" and grey.n_params == 2 and grey.orders == {}
    assert grey.passed and grey.stable and grey.local_minimum
    assert grey.fit_simulation > 99
    assert sel.best is grey
    json.dumps(sel.to_dict(), allow_nan=False)
    assert "grey-box" in sel.summary()


def test_a_greybox_candidate_is_fitted_once_over_a_grid_of_delays():
    # nk="auto" repeats the polynomial grid at each estimated delay and at nk = 1 (here three:
    # the twin rotor's two inputs act on the pitch with different delays); a grey-box
    # model's delays are its own equations', so it is one candidate however many delays
    record = flexid.generate("twin-rotor", seed=0, n_samples=1000).select(outputs=["pitch"])
    sel = flexid.select(
        record, structures=["arx", "greybox:twin-rotor-pitch"], orders=[{"na": 2, "nb": 2}],
        nk="auto", starts=0, progress=False,
    )
    kinds = [c.kind for c in sel.candidates]
    assert kinds.count("arx") == 3 and kinds.count("greybox") == 1


def test_cli_select_takes_a_greybox_candidate(model_file, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    _record(model_file, n=600).to_csv(tmp_path / "spring.csv")
    assert main(["select", "spring.csv", "--structures", f"oe,greybox:{model_file}:MODEL",
                 "--orders", "nb=1", "--orders", "nf=1"]) == 0
    assert "recommended: grey-box spring" in capsys.readouterr().out


def test_the_greybox_experiment_config_reads():
    root = Path(__file__).resolve().parents[1]
    (spec,) = load_config(root / "experiments" / "twin-rotor-greybox.toml")
    model = spec.model.greybox_model()
    assert model.name == "twin-rotor-pitch" and spec.cost.predictor == "simulation"
    assert spec.data.n_samples == 3000 and spec.runs == 10
