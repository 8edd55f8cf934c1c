"""Estimation and validation records of the user's choice: sample ranges, a separate
validation record, in the API, the command line and the TOML configs."""

from __future__ import annotations

import json

import numpy as np
import pytest

import flexid
from flexid.cli import main
from flexid.config import load_config
from flexid.data import IOData, prepare_data, split_parts
from flexid.errors import DataError


def ramp(n=100):
    rng = np.random.default_rng(0)
    return IOData(rng.normal(size=n), np.arange(n, dtype=float), dt=0.1)


@pytest.mark.parametrize(
    ("split", "est", "val"),
    [
        ("0:60,70:", (0, 60), (70, 100)),
        (((10, 50), (-30, None)), (10, 50), (70, 100)),
        ([[60, 100], [0, 40]], (60, 100), (0, 40)),  # validation before estimation
        (0.5, (0, 50), (50, 100)),
        (80, (0, 80), (80, 100)),
        (None, (0, 67), (67, 100)),
    ],
)
def test_split_parts_takes_fractions_indices_and_ranges(split, est, val):
    a, b = split_parts(ramp(), split)
    for part, (start, stop) in ((a, est), (b, val)):
        np.testing.assert_array_equal(part.y[:, 0], np.arange(start, stop))
        assert (part.metadata["split"]["start"], part.metadata["split"]["stop"]) == (start, stop)


@pytest.mark.parametrize(
    ("split", "match"),
    [
        ("0:60,50:", "overlap: the validation part must be held out"),
        ("0:60", "needs two of them"),
        ("0:60,a:b", "must be a sample range START:STOP"),
        (((0, 1), (10, 20)), "at least 2 samples"),
        (((0, 50), (60, 120)), "within the 100-sample record"),
    ],
)
def test_bad_ranges_say_what_is_wrong(split, match):
    with pytest.raises(DataError, match=match):
        split_parts(ramp(), split)


def test_a_separate_validation_record_with_an_estimation_range():
    data, other = ramp(), ramp(50)
    with pytest.warns(flexid.DataWarning, match="drifts"):  # the ramp is all drift
        est, val = prepare_data(data, split="20:80", validation=other)
    np.testing.assert_array_equal(est.y[:, 0], np.arange(20, 80))
    assert val.n_samples == 50
    with pytest.raises(DataError, match="the estimation range must be a sample range"):
        prepare_data(data, split=0.5, validation=other)


def arx_record(path, n=600, seed=0):
    rng = np.random.default_rng(seed)
    u = rng.uniform(-1, 1, n)
    y = np.zeros(n)
    for t in range(2, n):
        y[t] = 1.5 * y[t - 1] - 0.7 * y[t - 2] + 0.5 * u[t - 1] + 0.25 * u[t - 2]
    y += 0.01 * rng.normal(size=n)
    IOData(u, y, dt=0.01).to_csv(path)
    return path


def test_identify_and_select_take_ranges_and_a_validation_file(tmp_path, capsys):
    first, second = arx_record(tmp_path / "a.csv"), arx_record(tmp_path / "b.csv", seed=1)
    argv = ["identify", str(first), "--na", "2", "--nb", "2", "--nk", "1", "--optimiser", "ls",
            "--json"]  # fmt: skip
    assert main([*argv, "--split", "100:400,450:"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["data"]["n_estimation"] == 300 and out["data"]["n_validation"] == 150
    assert main([*argv, "--validation", str(second), "--split", ":500"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["data"]["n_estimation"] == 500 and out["data"]["n_validation"] == 600
    assert out["validation"]["fit_simulation"] > 99  # the same system, noise 1 %
    # the API gives the same numbers
    ident = flexid.identify(str(first), 2, 2, 1, optimiser="ls", validation=str(second),
                            split=(0, 500))  # fmt: skip
    assert ident.validation.fit_simulation == out["validation"]["fit_simulation"]
    sel = ["select", str(first), "--structures", "arx", "--orders", "na=2", "--orders", "nb=2",
           "--nk", "1", "--json", "--no-progress"]  # fmt: skip
    assert main([*sel, "--validation", str(second)]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["n_estimation"] == 600 and out["n_validation"] == 600
    # an overlap: one line, exit status 2
    assert main([*argv, "--split", "0:400,300:"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "overlap" in err[0]


def test_a_comparison_config_takes_ranges(tmp_path):
    """A TOML config's ranges (and linear detrend) reach the comparison: its least-squares row
    is identify's least squares on the same parts."""
    record = arx_record(tmp_path / "a.csv")
    config = tmp_path / "c.toml"
    config.write_text(
        f'[data]\nfile = "{record}"\nsplit = [[0, 300], [350, 600]]\ndetrend = "linear"\n'
        '[model]\nna = 2\nnb = 2\nnk = 1\n[[optimisers]]\nname = "de"\n'
        "[run]\nruns = 1\nbudget = 200\n",
        encoding="utf-8",
    )
    (spec,) = load_config(config)
    assert spec.data.split == [[0, 300], [350, 600]] and spec.data.detrend == "linear"
    ls = flexid.compare(spec, store=tmp_path / "s.sqlite").reference
    ident = flexid.identify(str(record), 2, 2, 1, optimiser="ls", split="0:300,350:",
                            detrend="linear")  # fmt: skip
    np.testing.assert_allclose(ls["theta"], ident.model.theta, rtol=1e-12)
    assert ls["validation"]["fit_simulation"] == pytest.approx(
        ident.validation.fit_simulation, abs=1e-9
    )
