"""A configuration file is checked against one schema before any work: every bad key, type,
range or byte is one line naming the file, the table and the key.

The faults are those of issue 45, item 4, tried as a hostile user would.
"""

from __future__ import annotations

import glob
import warnings
from pathlib import Path

import numpy as np
import pytest

from flexid.cli import main
from flexid.config import (
    CONFIG_SCHEMA,
    ComparisonSpec,
    CostSpec,
    DataSpec,
    ModelSpec,
    SearchSpec,
    load_config,
)
from flexid.data import load
from flexid.errors import ConfigError, DataWarning

ROOT = Path(__file__).resolve().parents[1]
#: A comparison that would run in well under a second, were it run.
TINY = '[model]\nna = 2\n[run]\nruns = 1\nbudget = 20\n[[optimisers]]\nname = "random-search"\n'


@pytest.fixture(autouse=True)
def _in_tmp_path(tmp_path, monkeypatch):
    """Every test in a fresh folder, so a file is named as the user typed it: bad.toml."""
    monkeypatch.chdir(tmp_path)


def _bad(tmp_path: Path, text: str | bytes) -> Path:
    path = Path("bad.toml")
    if isinstance(text, bytes):
        path.write_bytes(text)
    else:
        path.write_text(text, encoding="utf-8")
    return path


def _refused(tmp_path: Path, text: str | bytes) -> str:
    """The message of the ConfigError a config is refused with (one short line)."""
    with pytest.raises(ConfigError) as info:
        load_config(_bad(tmp_path, text))
    message = str(info.value)
    assert "\n" not in message and len(message) <= 100, message
    return message


def _cli(tmp_path: Path, monkeypatch, capsys, text: str | bytes) -> str:
    """``flexid compare bad.toml``: status 2, one line, nothing written beside the file."""
    _bad(tmp_path, text)
    status = main(["compare", "bad.toml", "--no-progress", "--no-figures"])
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert status == 2 and len(lines) == 1, err
    assert lines[0].startswith("flexid: error: bad.toml: ") and len(lines[0]) <= 100, lines[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.toml"]
    return lines[0]


# ------------------------------------------------------------------ the faults of the issue
def test_a_data_file_that_is_a_number_names_the_file_table_and_key(tmp_path, monkeypatch, capsys):
    text = "[data]\nfile = 123\n"
    assert _refused(tmp_path, text) == (
        "bad.toml: [data] file must be a string or an array of them, got 123 (an integer)"
    )
    assert "[data] file" in _cli(tmp_path, monkeypatch, capsys, text)


def test_invalid_utf8_names_the_file_and_the_byte_offset(tmp_path, monkeypatch, capsys):
    text = b'name = "caf\xe9"\n'
    assert _refused(tmp_path, text) == (
        "bad.toml: not UTF-8 text: byte 0xe9 at offset 11 (line 1, column 12)"
    )
    assert "offset 11" in _cli(tmp_path, monkeypatch, capsys, text)


def test_a_config_saved_with_a_bom_reads_as_the_csv_files_do(tmp_path):
    path = _bad(tmp_path, "\ufeffname = 'bom'\n" + TINY)
    (spec,) = load_config(path)
    assert spec.name == "bom" and spec.runs == 1
    assert path.read_bytes().startswith(b"\xef\xbb\xbf")


def test_an_optimiser_name_that_is_a_number_says_so(tmp_path):
    assert _refused(tmp_path, "[[optimisers]]\nname = 42\n") == (
        "bad.toml: [[optimisers]] #1 name must be a string, got 42 (an integer)"
    )
    assert _refused(tmp_path, "[[optimisers]]\nparams = {}\n").endswith("needs a 'name'")


def test_a_comparison_name_that_is_a_number_is_refused(tmp_path):
    assert _refused(tmp_path, "name = 7\n" + TINY) == (
        "bad.toml: name must be a string, got 7 (an integer)"
    )


def test_a_number_of_runs_that_would_never_end_is_refused(tmp_path, monkeypatch, capsys):
    huge = "9223372036854775807"
    message = _refused(tmp_path, f"[run]\nruns = {huge}\n")
    assert message == f"bad.toml: [run] runs must be an integer in [1, 10000], got {huge}"
    entry = f'[[comparison]]\nname = "c"\nruns = {huge}\n'
    assert _refused(tmp_path, entry).startswith("bad.toml: [[comparison]] #1 runs must be")
    assert "[run] runs" in _cli(tmp_path, monkeypatch, capsys, f"[run]\nruns = {huge}\n")
    with pytest.raises(ConfigError, match=r"\[run\] runs must be an integer in \[1, 10000\]"):
        ComparisonSpec(runs=10_001)  # a spec built in Python has the file's bounds


def _plain_csv(path: Path, time: str = "t") -> Path:
    """A CSV without flexid's header: a time column, one input, one output."""
    rng = np.random.default_rng(0)
    u = rng.uniform(-1, 1, 200).tolist()
    y = np.convolve(u, [0.0, 0.5, 0.3])[:200].tolist()
    rows = [f"{time},u,y"] + [f"{0.01 * k:.2f},{a!r},{b!r}" for k, (a, b) in enumerate(zip(u, y))]
    path.write_text("\n".join(rows) + "\n")
    return path


@pytest.mark.parametrize(
    ("time", "options", "column", "kind"),
    [
        ("t", {"inputs": [0], "outputs": ["y"]}, "t", "input"),
        ("t", {"inputs": ["t"], "outputs": ["y"]}, "t", "input"),
        ("time", {"inputs": ["u"], "outputs": [0, "y"]}, "time", "output"),
    ],
)
def test_the_time_column_chosen_as_a_channel_warns(tmp_path, time, options, column, kind):
    path = _plain_csv(tmp_path / "rec.csv", time)
    with pytest.warns(DataWarning, match=rf"rec\.csv: the {kind} column {column!r} is the time"):
        load(path, **options)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        load(path, inputs=["u"], outputs=["y"])  # the usual choice: no warning


def test_a_configs_input_on_the_time_axis_warns_before_any_run(tmp_path):
    from flexid import check_spec

    _plain_csv(tmp_path / "rec.csv")
    path = _bad(tmp_path, '[data]\nfile = "rec.csv"\ninputs = [0]\noutputs = ["y"]\n' + TINY)
    (spec,) = load_config(path)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_spec(spec)
    said = [str(w.message) for w in caught if issubclass(w.category, DataWarning)]
    assert any("rec.csv: the input column 't' is the time axis" in m for m in said), said


# ------------------------------------------------------------------ every field, one schema
BAD = [
    # (table text, the start of the message after "bad.toml: ")
    ("description = 3\n", "description must be a string"),
    ("name = 2020-01-01\n", "name must be a string, got 2020-01-01 (a date or time)"),
    ("data = 3\n", "[data] must be a table, got 3 (an integer)"),
    ("optimisers = 3\n", "[[optimisers]] must be an array of tables, got 3"),
    ("optimisers = [3]\n", "[[optimisers]] #1 must be a table, got 3"),
    ("[data]\nplant = 5\n", "[data] plant must be a string, got 5"),
    ("[data]\nplant = 'manipulator'\nn_samples = 'many'\n", "[data] n_samples must be an"),
    (f"[data]\nplant = 'manipulator'\nn_samples = {2**62}\n", "[data] n_samples must be an"),
    ("[data]\nplant = 'manipulator'\nseed = -1\n", "[data] seed must be an integer >= 0"),
    ("[data]\nplant = 'manipulator'\nseed = 'x'\n", "[data] seed must be an integer"),
    ("[data]\nplant = 'manipulator'\nnoise_std = -1\n", "[data] noise_std must be"),
    ("[data]\nplant = 'manipulator'\nnoise_std = [0.1, -1]\n", "[data] noise_std #2 must be"),
    ("[data]\nplant = 'manipulator'\nsignal_options = 3\n", "[data] signal_options must be a"),
    ("[data]\nplant = 'manipulator'\nsensors = 1\n", "[data] sensors must be a string"),
    ("[data]\nfile = ['a.csv', 2]\n", "[data] file #2 must be a string"),
    ("[data]\nfile = 'r.csv'\ndt = 'x'\n", "[data] dt must be a number"),
    ("[data]\nfile = 'r.csv'\ndt = -1\n", "[data] dt must be a number > 0, got -1"),
    ("[data]\nfile = 'r.csv'\ndt = nan\n", "[data] dt must be a finite number > 0"),
    ("[data]\nfile = 'r.csv'\ninputs = 1.5\n", "[data] inputs must be a string, an integer"),
    ("[data]\nfile = 'r.csv'\ninputs = [-1]\n", "[data] inputs #1 must be an integer >= 0"),
    ("[data]\nfile = 'r.csv'\nsplit = true\n", "[data] split must be"),
    ("[data]\nfile = 'r.csv'\nsplit = [[0, 'x'], [1, 2]]\n", "[data] split #1 #2 must be"),
    ("[data]\nfile = 'r.csv'\noutput = 1.5\n", "[data] output must be a string or an integer"),
    ("[data]\nfile = 'r.csv'\ndetrend = 1\n", "[data] detrend must be a boolean or a string"),
    ("[model]\nna = 'x'\n", "[model] na must be an integer"),
    ("[model]\nna = 9223372036854775807\n", "[model] na must be an integer in [0, 1000]"),
    ("[model]\nnb = [2, 2.5]\n", "[model] nb #2 must be an integer"),
    ("[model]\nnk = -1\n", "[model] nk must be an integer"),
    ("[model]\nstructure = 3\n", "[model] structure must be a string"),
    ("[model]\noptions = 3\n", "[model] options must be a table"),
    ("[cost]\nmetric = 3\n", "[cost] metric must be a string"),
    ("[cost]\npredictor = 3\n", "[cost] predictor must be a string"),
    ("[cost]\nweight = 'x'\n", "[cost] weight must be a number"),
    ("[cost]\npenalty = -1\n", "[cost] penalty must be"),
    ("[search]\nparametrisation = 3\n", "[search] parametrisation must be a string"),
    ("[search]\nr_max = 5\n", "[search] r_max must be"),
    ("[search]\nk_max = 'x'\n", "[search] k_max must be a number"),
    ("[search]\nreal_pairs = -1\n", "[search] real_pairs must be an integer"),
    ("[search]\nbounds = true\n", "[search] bounds must be"),
    ("[search]\nbounds = [-1, 'x']\n", "[search] bounds #2 must be a number"),
    ("[run]\nseed = -1\n", "[run] seed must be an integer >= 0"),
    ("[run]\nbudget = 'lots'\n", "[run] budget must be an integer, 'schedule' or an array of them"),
    (f"[run]\nbudget = {2**62}\n", "[run] budget must be an integer in [1, 10000000]"),
    ("[run]\nbudget = [100, 0]\n", "[run] budget #2 must be an integer in [1, 10000000]"),
    (f"[run]\nschedule_cap = {2**62}\n", "[run] schedule_cap must be an integer in [1, 1000"),
    ("[run]\ntargets = 0.1\n", "[run] targets must be an array"),
    ("[run]\ntargets = ['x']\n", "[run] targets #1 must be a number"),
    ("[validation]\nmax_lag = 1e9\n", "[validation] max_lag must be an integer"),
    ("[validation]\nalpha = 'x'\n", "[validation] alpha must be a number"),
    ("[validation]\ninitial = 0\n", "[validation] initial must be a string"),
    ("[compare]\nrun_timeout = 'x'\n", "[compare] run_timeout must be a number"),
    ("[[optimisers]]\nname = 'pso'\nlabel = 3\n", "[[optimisers]] #1 label must be a string"),
    ("[[optimisers]]\nname = 'pso'\nparams = 3\n", "[[optimisers]] #1 params must be a table"),
    (
        "[[comparison]]\nbudget = [1, 2]\n",
        "[[comparison]] #1 budget must be an integer or 'schedule', got [1, 2] (an array)",
    ),
    ("[[comparison]]\nname = 1\n", "[[comparison]] #1 name must be a string"),
    (
        "[[comparison]]\noptimisers = [{ name = 'pso' }, { name = 2 }]\n",
        "[[comparison]] #1 optimisers #2 name must be a string",
    ),
]


@pytest.mark.parametrize(("text", "start"), BAD, ids=[t.replace("\n", " ") for t, _ in BAD])
def test_every_field_is_checked_against_the_schema(tmp_path, text, start):
    message = _refused(tmp_path, text)
    assert message.startswith(f"bad.toml: {start}"), message


def test_unknown_keys_are_still_refused_in_one_short_line(tmp_path):
    message = _refused(tmp_path, "[data]\nplant = 'manipulator'\ncolour = 'red'\n")
    assert message.startswith("bad.toml: unknown key(s) 'colour' in [data]"), message
    message = _refused(tmp_path, "[data]\nplant = 'manipulator'\nn_sample = 10\n")
    assert message.endswith("did you mean 'n_samples'?"), message


def test_the_schema_has_every_field_of_the_specs():
    fields = {
        "data": set(DataSpec.__dataclass_fields__) - {"digest"},  # set by compare, not by a file
        "model": set(ModelSpec.__dataclass_fields__),
        "cost": set(CostSpec.__dataclass_fields__),
        "search": {"bounds", *SearchSpec.__dataclass_fields__},
    }
    for table, names in fields.items():
        assert set(CONFIG_SCHEMA[table]) == names, table


@pytest.mark.parametrize("path", sorted(glob.glob(str(ROOT / "experiments" / "*.toml"))))
def test_the_experiments_pass_the_schema(path):
    assert load_config(path)
