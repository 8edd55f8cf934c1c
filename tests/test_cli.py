"""Tests of the command line: the main commands run, and bad input gives one line and status 2."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from flexid.cli import main
from flexid.data import IOData


def _record(path, n=400, seed=0):
    """A noise-free ARX(2,2,1) record written as CSV."""
    rng = np.random.default_rng(seed)
    u = rng.uniform(-1, 1, n)
    y = np.zeros(n)
    for t in range(2, n):
        y[t] = 1.5 * y[t - 1] - 0.7 * y[t - 2] + 0.5 * u[t - 1] + 0.25 * u[t - 2]
    IOData(u, y, dt=0.01).to_csv(path)
    return path


def _run(argv, capsys):
    status = main(argv)
    out = capsys.readouterr()
    return status, out.out, out.err


def _identify(tmp_path, capsys, *options):
    """``flexid identify`` on a fresh record with ``options``: must succeed; its stdout."""
    path = _record(tmp_path / "rec.csv")
    status, out, err = _run(["identify", str(path), *options], capsys)
    assert status == 0, err
    return out


def test_identify_json_gives_coefficients_fits_and_timings(tmp_path, capsys):
    out = _identify(tmp_path, capsys, "--na", "2", "--nb", "2", "--nk", "1", "--optimiser", "ls",
                    "--json")
    result = json.loads(out)
    theta = np.array(result["model"]["theta"])
    np.testing.assert_allclose(theta, [-1.5, 0.7, 0.5, 0.25], atol=1e-8)
    assert result["validation"]["fit_simulation"] > 99.99
    assert "timings" in result and result["model"]["stable"] is True


def test_identify_judges_its_verdicts_at_the_level_given(tmp_path, capsys):
    result = json.loads(_identify(tmp_path, capsys, "--na", "2", "--optimiser", "ls",
                                  "--alpha", "0.2", "--json"))  # fmt: skip
    assert result["validation"]["alpha"] == 0.2 == result["estimation"]["alpha"]
    assert all(t["alpha"] == 0.2 for t in result["validation"]["correlation_tests"])
    for bad in ("0", "1.5", "nan"):
        status, out, err = _run(["identify", str(tmp_path / "rec.csv"), "--na", "2",
                                 "--optimiser", "ls", "--alpha", bad], capsys)  # fmt: skip
        assert status == 2 and out == "" and "alpha" in err and len(err.splitlines()) == 1


def test_a_comparison_config_sets_its_level(tmp_path):
    from flexid.config import load_config
    from flexid.errors import ConfigError

    path = tmp_path / "c.toml"
    path.write_text('[data]\nplant = "manipulator"\n[validation]\nalpha = 0.01\n')
    (spec,) = load_config(path)
    assert spec.alpha == 0.01 and spec.key_material()["alpha"] == 0.01
    path.write_text('[data]\nplant = "manipulator"\n[validation]\nalpha = 2\n')
    with pytest.raises(ConfigError, match=r"\[validation\] alpha"):
        load_config(path)


def test_identify_with_an_optimiser(tmp_path, capsys):
    out = _identify(tmp_path, capsys, "--na", "2", "--optimiser", "de", "--budget", "3000",
                    "--seed", "3", "--no-progress")
    assert "fit" in out.lower() and "de" in out


def test_generate_writes_byte_identical_files(tmp_path, capsys):
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    for path in (a, b):
        status, _, err = _run(
            ["generate", "manipulator", "--signal", "prbs", "--samples", "300", "--seed", "4",
             "--out", str(path)],
            capsys,
        )
        assert status == 0, err
    assert a.read_bytes() == b.read_bytes()
    data = IOData.from_csv(a)
    assert data.n_samples == 300
    assert data.metadata["plant"] == "manipulator" and data.metadata["seed"] == 4


def test_compare_small_builtin_and_report(tmp_path, capsys):
    store = tmp_path / "r.sqlite"
    argv = [
        "compare", "--plant", "manipulator", "--optimisers", "sda,random-search",
        "--runs", "2", "--budget", "400", "--na", "2", "--store", str(store),
        "--no-progress", "--no-figures",
    ]
    status, out, err = _run(argv, capsys)
    assert status == 0, err
    assert "sda" in out and "least squares" in out
    status, out2, err = _run(argv, capsys)  # rerun: nothing new to do, same table
    assert status == 0, err
    assert out2.split("\n")[:8] == out.split("\n")[:8]
    status, out, err = _run(
        ["report", str(store), "--out", str(tmp_path / "rep"), "--no-figures"], capsys
    )
    assert status == 0, err
    assert (tmp_path / "rep" / "report.md").exists()


BAD = [
    (["identify", "{missing}", "--na", "2"], "missing"),
    (["identify", "{bad}", "--na", "2"], "bad"),
    (["identify", "{good}", "--na", "-1"], "order"),
    (["identify", "{good}", "--na", "2", "--optimiser", "no-such-thing"], "no-such-thing"),
    (["identify", "{good}", "--na", "2", "--optimiser", "sda", "--param", "radius=7"], "radius"),
    (["identify", "{good}", "--na", "2", "--optimiser", "sda", "--param", "colour=1"], "colour"),
    (["identify", "{good}", "--na", "150"], "sample"),
    (["compare", "--plant", "moon-lander"], "moon-lander"),
    (["compare", "{badconfig}"], "colour"),
    (["compare", "{missing}"], "missing"),
    (["generate", "manipulator", "--signal", "jazz", "--out", "{out}"], "jazz"),
    (["generate", "manipulator", "--samples", "-5", "--out", "{out}"], "samples"),
    (["report", "{missing}"], "missing"),
    (["identify"], "required"),
]


@pytest.mark.parametrize(("argv", "word"), BAD, ids=[" ".join(a[:3]) for a, _ in BAD])
def test_bad_input_gives_one_line_and_status_2(argv, word, tmp_path, capsys):
    good = _record(tmp_path / "good.csv")
    bad = tmp_path / "bad.csv"
    bad.write_text("u,y\n1,2\n3,oops\n4,5\n")
    badconfig = tmp_path / "bad.toml"
    badconfig.write_text('name = "x"\ncolour = "red"\n')
    paths = {
        "missing": str(tmp_path / "missing.csv"),
        "bad": str(bad),
        "good": str(good),
        "badconfig": str(badconfig),
        "out": str(tmp_path / "out.csv"),
    }
    argv = [a.format(**paths) for a in argv]
    status, _, err = _run(argv, capsys)
    assert status == 2
    lines = [line for line in err.strip().splitlines() if line.strip()]
    assert len(lines) == 1, err
    assert "Traceback" not in err
    assert word.lower() in err.lower(), err


def test_entry_point_runs_as_a_module(tmp_path):
    out = subprocess.run(
        [sys.executable, "-m", "flexid", "list", "optimisers"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert out.returncode == 0, out.stderr
    for name in ("hbcsd", "bfa", "sda", "pso", "de"):
        assert name in out.stdout
    bad = subprocess.run(
        [sys.executable, "-m", "flexid", "identify", str(tmp_path / "nope.csv"), "--na", "2"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert bad.returncode == 2
    assert len(bad.stderr.strip().splitlines()) == 1


def test_compare_sets_the_data_seed_apart_from_the_runs_seed(tmp_path, capsys):
    from flexid.cli import main

    argv = ["compare", "--plant", "twin-rotor", "--optimisers", "random-search", "--runs", "1",
            "--budget", "50", "--no-progress", "--no-figures", "--store",
            str(tmp_path / "s.sqlite")]
    assert main([*argv, "--data-seed", "3"]) == 0
    assert "paper-twin-rotor (seed 3)" in capsys.readouterr().out
    config = tmp_path / "c.toml"
    config.write_text('[data]\nplant = "twin-rotor"\n')
    assert main(["compare", str(config), "--data-seed", "3"]) == 2
    assert "--data-seed applies to the built-in comparison" in capsys.readouterr().err


def test_every_subcommand_help_says_what_it_does_with_an_example_and_defaults(capsys):
    import pytest as _pytest

    from flexid.cli import build_parser, main

    commands = build_parser()._subparsers._group_actions[0].choices
    for name in commands:
        with _pytest.raises(SystemExit):
            main([name, "--help"])
        out = capsys.readouterr().out
        assert f"example:\n  flexid {name}" in out, name
    with _pytest.raises(SystemExit):
        main(["identify", "--help"])
    out = " ".join(capsys.readouterr().out.split())
    assert "--budget BUDGET function evaluations (default 20000)" in out
    assert "--max-lag MAX_LAG lags of the correlation tests (default 25)" in out


def test_every_option_says_its_default():
    """Every option that takes a value says what happens without it (a value, or 'none')."""
    import argparse

    from flexid.cli import _Formatter, build_parser

    formatter = _Formatter("flexid")
    silent = []
    for name, parser in build_parser()._subparsers._group_actions[0].choices.items():
        for action in parser._actions:
            if (
                not action.option_strings
                or action.help == argparse.SUPPRESS
                or isinstance(action, (argparse._HelpAction, argparse._StoreTrueAction))
            ):
                continue
            text = formatter._get_help_string(action)
            if "default" not in text and "required" not in text:
                silent.append(f"{name} {action.option_strings[0]}")
    assert not silent, silent


def test_compare_param_sets_an_optimisers_hyper_parameter(tmp_path, capsys):
    store = str(tmp_path / "s.sqlite")
    argv = ["compare", "--optimisers", "de,pso", "--runs", "1", "--budget", "60", "--store",
            store, "--no-figures", "--json"]
    assert main([*argv, "--param", "de.weight=0.7"]) == 0
    (result,) = json.loads(capsys.readouterr().out)
    params = {o["name"]: o["params"] for o in result["spec"]["optimisers"]}
    assert params == {"de": {"weight": 0.7}, "pso": {}}
    for bad, message in (
        ("weight=0.7", "ambiguous with 2 optimisers"),
        ("ga.x=1", "'ga' is not an optimiser of this comparison"),
        ("de.nope=1", "unknown hyper-parameter(s) 'nope'"),
    ):
        assert main([*argv, "--param", bad]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and message in err[0], err


def test_compare_with_a_config_refuses_the_built_in_models_options(tmp_path, capsys):
    config = tmp_path / "c.toml"
    config.write_text('[data]\nplant = "twin-rotor"\n[run]\nruns = 1\nbudget = 20\n')
    assert main(["compare", str(config), "--na", "3"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "na set the built-in comparison's model" in err[0]


def test_compare_param_reads_an_optimiser_label_with_a_dash(tmp_path, capsys):
    argv = ["compare", "--optimisers", "cmaes-bipop", "--runs", "1", "--budget", "40",
            "--store", str(tmp_path / "s.sqlite"), "--no-figures", "--json",
            "--param", "cmaes-bipop.population=6"]
    assert main(argv) == 0
    (result,) = json.loads(capsys.readouterr().out)
    assert result["spec"]["optimisers"][0]["params"] == {"population": 6}
