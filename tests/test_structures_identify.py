"""ARMAX, OE and BJ through identify, compare and the command line.

Known systems are made with ``scipy.signal.lfilter`` from a seeded innovation sequence; the
reference (Levenberg-Marquardt, :func:`flexid.fit.prediction_error.pem`) must recover them within
4 of its own standard errors, and DE and CMA-ES, at an equal budget, must reach the
reference's minimum (the prediction-error cost of these low orders has one basin in the
stable set).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy import signal

from flexid import identify
from flexid.cli import main
from flexid.config import ComparisonSpec, DataSpec, ModelSpec, OptimiserSpec, spec_from_mapping
from flexid.data import IOData
from flexid.errors import ConfigError, ModelOrderError, UnknownNameError
from flexid.models.polynomial import structure

N = 1800
B_TRUE = np.array([0.5, 0.3])
F_TRUE = np.array([1.0, -1.5, 0.7])  # poles at radius 0.84
C_TRUE = np.array([1.0, 0.5])
D_TRUE = np.array([1.0, -0.8])


def _record(kind: str, seed: int = 0) -> IOData:
    rng = np.random.default_rng(seed)
    u = np.sign(rng.standard_normal(N))  # a random binary input, persistently exciting
    e = 0.1 * rng.standard_normal(N)
    y = signal.lfilter(np.r_[0.0, B_TRUE], F_TRUE, u)
    if kind == "bj":
        y = y + signal.lfilter(C_TRUE, D_TRUE, e)
    elif kind == "armax":  # A y = B u + C e with A = F
        y = y + signal.lfilter(C_TRUE, F_TRUE, e)
    else:
        y = y + e
    return IOData(u[:, None], y[:, None], dt=0.01)


CASES = {
    "oe": (structure("oe", nb=2, nf=2), np.r_[B_TRUE, F_TRUE[1:]]),
    "bj": (
        structure("bj", nb=2, nc=1, nd=1, nf=2),
        np.r_[B_TRUE, C_TRUE[1:], D_TRUE[1:], F_TRUE[1:]],
    ),
    "armax": (structure("armax", na=2, nb=2, nc=1), np.r_[F_TRUE[1:], B_TRUE, C_TRUE[1:]]),
}


@pytest.mark.parametrize("kind", sorted(CASES))
def test_reference_recovers_a_known_system_within_its_standard_errors(kind):
    s, truth = CASES[kind]
    ident = identify(_record(kind), structure=kind, **s.orders, optimiser="pem")
    model = ident.model
    assert model.structure == s
    z = np.abs(model.theta - truth) / model.param_std
    # each estimate is asymptotically normal around the truth: 4 standard errors is a
    # two-sided 6e-5 event per parameter
    assert z.max() < 4.0, (z, model.theta)
    assert ident.output_error.local_minimum


@pytest.mark.parametrize("optimiser", ["de", "cmaes"])
@pytest.mark.parametrize("kind", ["armax", "oe", "bj"])
def test_de_and_cmaes_reach_the_references_minimum_at_an_equal_budget(kind, optimiser):
    s, truth = CASES[kind]
    data = _record(kind, seed=1)
    ref = identify(data, structure=s, optimiser="pem", cost="rmse")
    found = identify(data, structure=s, optimiser=optimiser, cost="rmse", budget=3000, seed=0)
    # one basin: the search ends at the reference's minimum, within the estimate's own
    # uncertainty (one standard error per parameter), and its cost to 1e-4 relative
    std = ref.model.param_std
    assert np.all(np.abs(found.model.theta - ref.model.theta) < std)
    assert found.cost_value <= ref.cost_value * (1 + 1e-4)
    assert np.all(np.abs(found.model.theta - truth) < 4 * std)


def test_arx_by_name_is_the_arx_path_unchanged():
    data = _record("oe")
    old = identify(data, 2, 2, 1, optimiser="pso", budget=600, seed=3)
    new = identify(data, structure="arx", na=2, nb=2, nk=1, optimiser="pso", budget=600, seed=3)
    np.testing.assert_array_equal(old.model.theta, new.model.theta)
    assert old.cost_value == new.cost_value
    assert new.to_dict()["structure"] == {"structure": "arx", "na": 2, "nb": [2], "nk": [1]}


def test_identify_names_the_structure_and_the_rule_everywhere():
    s, _ = CASES["bj"]
    ident = identify(_record("bj"), structure=s, optimiser="ls")
    text = ident.summary()
    assert text.startswith("BJ(nb=2, nc=1, nd=1, nf=2, nk=1) identified by ls")
    assert "initial state estimated by least squares" in text
    d = json.loads(json.dumps(ident.to_dict(), allow_nan=False))
    assert d["structure"]["structure"] == "bj" and d["model"]["structure"] == "bj"
    assert d["validation"]["initial"] == "estimate"


@pytest.mark.parametrize(
    ("kwargs", "error", "words"),
    [
        ({"structure": "oe", "nb": 2, "nf": 2, "nc": 1}, ModelOrderError, "no order nc"),
        ({"structure": "boxjenkins", "nb": 2}, UnknownNameError, "armax, arx, bj, oe"),
        ({"na": 2, "nf": 2}, ModelOrderError, "structure='armax', 'oe' or 'bj'"),
        ({"structure": "bj", "nb": 2, "nc": 1, "nd": 1, "nf": 2, "predictor": "simulation"},
         ConfigError, "noise model"),
        ({"structure": "oe", "nb": 600, "nf": 600}, ModelOrderError, "too few samples"),
        ({"structure": structure("oe", nb=2, nf=2), "nb": 3}, ModelOrderError, "not both"),
        ({"structure": "oe", "nb": 2, "nf": 2, "validate_initial": "backcast"},
         UnknownNameError, "estimate"),
    ],
)
def test_bad_structure_arguments_get_a_typed_error(kwargs, error, words):
    with pytest.raises(error, match=words):
        identify(_record("oe"), optimiser="ls", **kwargs)


# ================================================================================ compare
def _spec(**model) -> ComparisonSpec:
    return ComparisonSpec(
        name="oe-small",
        data=DataSpec(plant="manipulator", preset="paper-manipulator", n_samples=900),
        model=ModelSpec(**model),
        optimisers=(OptimiserSpec("de"),),
        runs=1,
        budget=200,
    )


def test_compare_runs_a_structure_and_shows_the_reference_row(tmp_path):
    from flexid import compare, load_result

    spec = _spec(structure="oe", nb=4, nf=4)
    result = compare(spec, store=tmp_path / "r.sqlite")
    text = result.summary()
    assert "OE(nb=4, nf=4, nk=1)" in text and "reference (LM)" in text
    assert "validated with initial state estimate" in text
    # the reference says whether it ended at a first-order minimum (stored with it)
    oe = result.reference["output_error"]
    assert isinstance(oe["local_minimum"], bool) and isinstance(oe["on_cap"], bool)
    note = "did not end at a verified local minimum"
    assert (note in text) == (not oe["local_minimum"] and oe["cost"] == result.reference_cost)
    (again,) = load_result(tmp_path / "r.sqlite")
    assert again.spec.model == spec.model and again.key == result.key


def test_config_tables_take_a_structure_and_refuse_what_it_does_not_have():
    (spec,) = spec_from_mapping(
        {"model": {"structure": "bj", "nb": 4, "nc": 1, "nd": 1, "nf": 4},
         "validation": {"initial": "zero"}}
    )
    assert spec.model.describe() == "BJ(nb=4, nc=1, nd=1, nf=4, nk=1)"
    assert spec.validate_initial == "zero" and spec.cost.initial == "estimate"
    (arx,) = spec_from_mapping({})
    assert arx.model.na == 8 and arx.cost.initial == "measured"  # ARX as before
    with pytest.raises(UnknownNameError, match="structure"):
        ModelSpec(structure="narx")
    from flexid import check_spec

    with pytest.raises(ConfigError, match=r"\[model\].*no order nc"):
        check_spec(_spec(structure="oe", nb=4, nf=4, nc=1))


# ================================================================================ CLI
def _cli(argv, capsys) -> tuple[int, str, str]:
    status = main([str(a) for a in argv])
    out = capsys.readouterr()
    return status, out.out, out.err


@pytest.fixture
def record_csv(tmp_path) -> Path:
    path = tmp_path / "rec.csv"
    _record("oe").save(path)
    return path


def test_cli_identifies_a_structure_as_json(record_csv, capsys):
    status, out, err = _cli(
        ["identify", record_csv, "--structure", "oe", "--nb", "2", "--nf", "2",
         "--optimiser", "pem", "--json"],
        capsys,
    )
    assert status == 0, err
    d = json.loads(out)
    assert d["structure"]["structure"] == "oe" and d["optimiser"] == "pem"
    assert d["validation"]["initial"] == "estimate" and d["validation"]["fit_simulation"] > 90


@pytest.mark.parametrize(
    ("extra", "words"),
    [
        (["--structure", "oe", "--nb", "2", "--nf", "2", "--nc", "1"], "no order nc"),
        (["--structure", "nope", "--nb", "2"], "unknown model structure 'nope'"),
        (["--structure", "bj", "--nb", "2", "--nc", "1", "--nd", "1", "--nf", "2",
          "--predictor", "simulation"], "noise model"),
        (["--structure", "oe", "--nb", "900", "--nf", "900"], "too few samples"),
        (["--structure", "oe", "--nb", "2"], "needs the order"),
    ],
)
def test_cli_bad_structures_are_one_line_and_status_2(record_csv, capsys, extra, words):
    status, out, err = _cli(["identify", record_csv, "--optimiser", "ls", *extra], capsys)
    assert status == 2 and out == ""
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and words in lines[0], err


def test_cli_compare_with_a_bad_structure_writes_nothing(tmp_path, capsys):
    store = tmp_path / "out" / "r.sqlite"
    status, _, err = _cli(
        ["compare", "--structure", "oe", "--nb", "4", "--nf", "4", "--nc", "1",
         "--optimisers", "de", "--runs", "1", "--budget", "50", "--store", store,
         "--no-progress"],
        capsys,
    )
    assert status == 2 and "no order nc" in err
    assert not (tmp_path / "out").exists()


def test_cli_select_recommends_the_true_structure_and_refuses_bad_orders(record_csv, capsys):
    status, out, err = _cli(
        ["select", record_csv, "--structures", "oe", "--orders", "nb=1,2", "--orders",
         "nf=1,2", "--json", "--no-progress"],
        capsys,
    )
    assert status == 0, err
    d = json.loads(out)
    best = d["candidates"][d["best"]]  # "best" indexes the candidates
    assert best["label"] == "OE(nb=2, nf=2, nk=1)" and best["passed"]
    status, out, err = _cli(["select", record_csv, "--structures", "oe", "--orders", "nq=1"],
                            capsys)
    assert status == 2 and out == "" and len(err.strip().splitlines()) == 1, err
