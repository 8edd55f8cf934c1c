"""Command-line failures leave no traces and speak in the user's terms.

An invalid command is refused before anything is opened, simulated or written; error
messages name what the user typed; diverged fits print as ``< -999``; the compare footer
says what it counts.
"""

from __future__ import annotations

import math
import re
import sqlite3
from pathlib import Path

import numpy as np
import pytest

import flexid.data.datasets
from flexid import identify
from flexid.cli import main
from flexid.config import ComparisonSpec, DataSpec, ModelSpec, OptimiserSpec
from flexid.data import IOData, load
from flexid.errors import BudgetError, DataFileError, FlexidError
from flexid.models.arx import ARXStructure
from flexid.validation import validate
from test_cli import _record


def _run(argv, capsys):
    status = main([str(a) for a in argv])
    out = capsys.readouterr()
    return status, out.out, out.err


def _one_line_error(status: int, err: str) -> str:
    assert status == 2, err
    lines = [line for line in err.strip().splitlines() if line.strip()]
    assert len(lines) == 1, err
    assert "Traceback" not in err
    return lines[0]


def _files(folder: Path) -> set[str]:
    return {str(p.relative_to(folder)) for p in folder.rglob("*")}


# ------------------------------------------------------------------ 1. compare leaves nothing
SMALL = ["--plant", "manipulator", "--na", "2", "--runs", "1", "--budget", "100"]
BAD_COMPARE = [
    (["--optimisers", "pso,nosuchopt"], "nosuchopt"),
    (["--optimisers", "pso", "--cost", "bogus"], "bogus"),
    (["--optimisers", "pso", "--predictor", "bogus"], "bogus"),
    (["--optimisers", "pso", "--nb", "0", "--na", "0"], "parameters"),
    (["--optimisers", "pso", "--runs", "0"], "--runs"),
    (["--optimisers", "pso", "--budget", "0"], "--budget"),
    (["--optimisers", "pso", "--workers", "0"], "--workers"),
]


@pytest.mark.parametrize("with_store", [True, False], ids=["--store", "default store"])
@pytest.mark.parametrize(("extra", "word"), BAD_COMPARE, ids=[w for _, w in BAD_COMPARE])
def test_compare_invalid_spec_leaves_no_store(
    extra, word, with_store, tmp_path, monkeypatch, capsys
):
    monkeypatch.chdir(tmp_path)
    store = ["--store", "x.sqlite"] if with_store else []
    status, _, err = _run(["compare", *SMALL, *extra, *store, "--no-progress"], capsys)
    line = _one_line_error(status, err)
    assert word in line, line
    assert _files(tmp_path) == set()  # no x.sqlite, no flexid-results/


def _config(path: Path, optimisers: str, comparisons: str = "") -> Path:
    path.write_text(
        'name = "t"\n'
        '[data]\nplant = "manipulator"\nn_samples = 300\nseed = 1\n'
        'outputs = ["tip_acceleration"]\n'
        "[model]\nna = 2\n"
        "[run]\nruns = 1\nbudget = 100\n" + optimisers + comparisons
    )
    return path


@pytest.mark.parametrize("with_store", [True, False], ids=["--store", "default store"])
def test_compare_bad_hyperparameter_in_config_leaves_no_store(
    with_store, tmp_path, monkeypatch, capsys
):
    monkeypatch.chdir(tmp_path)
    _config(tmp_path / "c.toml", '[[optimisers]]\nname = "sda"\nparams = { colour = 1 }\n')
    store = ["--store", "x.sqlite"] if with_store else []
    status, _, err = _run(["compare", "c.toml", *store, "--no-progress"], capsys)
    assert "colour" in _one_line_error(status, err)
    assert _files(tmp_path) == {"c.toml"}


def test_compare_invalid_second_comparison_leaves_no_store(tmp_path, monkeypatch, capsys):
    """A config with several comparisons is checked whole before the first one runs."""
    monkeypatch.chdir(tmp_path)
    _config(
        tmp_path / "c.toml",
        "",
        '[[comparison]]\nname = "good"\noptimisers = [{ name = "random-search" }]\n'
        '[[comparison]]\nname = "bad"\noptimisers = [{ name = "nosuchopt" }]\n',
    )
    status, out, err = _run(["compare", "c.toml", "--no-progress", "--no-figures"], capsys)
    assert "nosuchopt" in _one_line_error(status, err)
    assert out == ""
    assert _files(tmp_path) == {"c.toml"}


def test_compare_malformed_config_leaves_nothing(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "c.toml").write_text("name = \n[data\n")
    status, _, err = _run(["compare", "c.toml", "--no-progress"], capsys)
    assert "TOML" in _one_line_error(status, err)
    assert _files(tmp_path) == {"c.toml"}


def test_library_compare_checks_the_spec_before_opening_the_store(tmp_path):
    from flexid import check_spec, compare

    spec = ComparisonSpec(
        name="bad",
        data=DataSpec(plant="manipulator", n_samples=300, outputs=["tip_acceleration"]),
        model=ModelSpec(na=2, nb=2, nk=1),
        optimisers=(OptimiserSpec("sda", {"colour": 1}),),
        runs=1,
        budget=100,
    )
    store = tmp_path / "sub" / "x.sqlite"
    with pytest.raises(FlexidError, match="colour"):
        check_spec(spec)
    with pytest.raises(FlexidError, match="colour"):
        compare(spec, store=store)
    assert _files(tmp_path) == set()


# ------------------------------------------------------------------ 2. generate: path first
@pytest.mark.parametrize("name", ["x.txt", "folder.csv"])
def test_generate_checks_the_output_before_simulating(name, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    if name == "folder.csv":
        (tmp_path / name).mkdir()
    calls = []

    def spy(*args, **kwargs):
        calls.append((args, kwargs))
        raise AssertionError("the plant was simulated before the output path was checked")

    monkeypatch.setattr(flexid.data.datasets, "generate", spy)
    status, _, err = _run(["generate", "manipulator", "--samples", "10", "--out", name], capsys)
    line = _one_line_error(status, err)
    assert "--out" in line and name in line, line
    assert calls == []
    assert _files(tmp_path) == ({"folder.csv"} if name == "folder.csv" else set())


# ------------------------------------------------------------------ 3. --budget named
@pytest.mark.parametrize(
    ("extra", "option"),
    [(["--budget", "0"], "--budget"), (["--budget", "10", "--iterations", "0"], "--iterations")],
)
def test_identify_bad_budget_names_the_option(extra, option, tmp_path, capsys):
    path = _record(tmp_path / "rec.csv")
    argv = ["identify", path, "--na", "2", "--nb", "2", "--optimiser", "pso", *extra]
    line = _one_line_error(*_run(argv, capsys)[::2])
    assert option in line and "max_fe" not in line and "max_iter" not in line, line


@pytest.mark.parametrize("budget", [0, -5, "many", {"max_fe": 0}])
def test_library_identify_bad_budget_says_budget(budget, tmp_path):
    path = _record(tmp_path / "rec.csv")
    with pytest.raises(BudgetError, match=r"^budget\b"):
        identify(path, 2, 2, optimiser="pso", budget=budget)


# ------------------------------------------------------------------ 4. a folder is a folder
def test_identify_on_a_folder_says_folder(tmp_path, capsys):
    line = _one_line_error(*_run(["identify", tmp_path, "--na", "2"], capsys)[::2])
    assert "folder" in line and "unknown data file type" not in line, line


@pytest.mark.parametrize("name", ["plain", "looks-like.csv"])
def test_load_of_a_folder_says_folder(name, tmp_path):
    folder = tmp_path / name
    folder.mkdir()
    with pytest.raises(DataFileError, match="is a folder, not a data file"):
        load(folder)


# ------------------------------------------------------------------ 5. diverged fits
def test_format_fit_is_shared_and_caps_diverged_fits():
    from flexid.jobs import _comparison_result as compare_module
    from flexid.validation.diagnostics import format_fit

    assert format_fit(-1.4e113) == "< -999"
    assert format_fit(-math.inf) == "< -999"
    assert format_fit(-999.0) == "-999.00"
    assert format_fit(97.0421) == "97.04"
    assert format_fit(math.nan) == "-" and format_fit(None) == "-"
    assert compare_module._fit is format_fit  # the comparison tables use the same formatter


def _unstable_report(n: int = 300):
    """A model with a pole at 1.5: its free run grows to ~1e52, finite but absurd."""
    rng = np.random.default_rng(1)
    u = rng.uniform(-1, 1, n)
    y = np.convolve(u, [0.0, 0.5, 0.3])[:n] + 0.01 * rng.standard_normal(n)
    model = ARXStructure(1, 1, 1).model([-1.5, 0.5], dt=0.01)
    return validate(model, IOData(u, y, dt=0.01), initial="measured")


def test_validation_summary_prints_a_huge_negative_fit_as_below_floor():
    report = _unstable_report()
    assert math.isfinite(report.fit_simulation) and report.fit_simulation < -1e40
    assert not report.simulation_diverged
    text = report.summary()
    (line,) = [ln for ln in text.splitlines() if "simulation (free run)" in ln]
    assert "< -999 %" in line, line
    assert not re.search(r"\d{12,}", text), text


def test_identify_summary_and_cli_print_a_diverged_fit_as_below_floor(tmp_path, capsys):
    """In the paper's coefficient box [1.6, 1.7] every pole is at about -1.65: unstable."""
    path = _record(tmp_path / "rec.csv")
    args = dict(optimiser="random-search", bounds=(1.6, 1.7), budget=50, seed=0,
                parametrisation="coefficients", penalty_kind="flat", init="uniform")
    ident = identify(path, 1, 1, **args)
    # the unstable free run grows as 1.65^t: far below the floor under any initial rule
    assert ident.validation.fit_simulation < -1e9
    text = ident.summary()
    # the estimation and validation records, and the closing warning line
    assert text.count("< -999 %") == 3 and "held-out simulation fit is < -999 %" in text
    assert not re.search(r"\d{12,}", text)
    argv = [
        "identify", path, "--na", "1", "--nb", "1", "--optimiser", "random-search",
        "--bounds", "1.6,1.7", "--budget", "50", "--no-progress",
        "--parametrisation", "coefficients", "--penalty", "flat", "--init", "uniform",
    ]  # fmt: skip
    status, out, err = _run(argv, capsys)
    assert status == 0, err
    assert out.count("< -999 %") == 3  # as in the summary: both records and the warning
    assert not re.search(r"\d{12,}", out), out


# ------------------------------------------------------------------ 6. what is counted
def test_compare_footer_says_what_it_counts(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    argv = [
        "compare", "--plant", "manipulator", "--optimisers", "sda,random-search",
        "--runs", "2", "--budget", "200", "--na", "2", "--store", "x.sqlite",
        "--no-progress", "--no-figures",
    ]  # fmt: skip
    status, out, err = _run(argv, capsys)
    assert status == 0, err
    assert "4 optimiser runs (+ the least squares row) in store x.sqlite" in out, out
    with sqlite3.connect(tmp_path / "x.sqlite") as db:
        (rows,) = db.execute("SELECT COUNT(*) FROM runs").fetchone()
    assert rows == 4 + 1
