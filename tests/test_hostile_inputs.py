"""Inputs and results a hostile (or unlucky) user meets: one clear line each.

A finite sample too large to square names itself once; no message shows a NumPy repr; a full
disk under a store says so and that the store is intact; no line a summary prints is longer
than a terminal; an unstable model's fit says it is one; the old reference spelling ``"oe"``
warns and runs ``"pem"`` (``tests/test_estimation.py``).
"""

from __future__ import annotations

import sqlite3
from dataclasses import replace

import numpy as np
import pytest

import flexid.jobs.store
from flexid import compare, identify, select
from flexid._table import LINE_WIDTH
from flexid.cli import main
from flexid.data import IOData
from flexid.errors import DataError, StoreError, check_finite, plain_number
from flexid.jobs.store import ResultStore
from helpers import tiny_spec


def _run(argv, capsys):
    status = main([str(a) for a in argv])
    out = capsys.readouterr()
    return status, out.out, out.err


def _arx_record(n: int = 400, seed: int = 0, pole: float = 0.9) -> IOData:
    """A first-order record ``y(t) = pole y(t-1) + u(t-1) + e``: stable for ``pole < 1``."""
    rng = np.random.default_rng(seed)
    u = rng.uniform(-1, 1, n)
    y = np.zeros(n)
    for t in range(1, n):
        y[t] = pole * y[t - 1] + u[t - 1]
    return IOData(u, y + 0.05 * rng.standard_normal(n), dt=0.01)


# ------------------------------------------------------------------ a huge finite sample
def test_a_huge_finite_sample_is_named_with_its_magnitude_once(tmp_path, capsys):
    record = _arx_record()
    y = record.y.copy()
    y[123, 0] = 1e308  # finite, but its square (and any sum of squares) is inf
    path = tmp_path / "huge.csv"
    rows = zip(record.u[:, 0].tolist(), y[:, 0].tolist())
    path.write_text("u,y\n" + "".join(f"{a!r},{b!r}\n" for a, b in rows))
    for extra in (["--optimiser", "ls", "--na", "1", "--nb", "1", "--nk", "1"],
                  ["--optimiser", "pso", "--na", "1", "--nb", "1", "--nk", "1", "--budget", "50"],
                  ["--structure", "oe", "--nb", "1", "--nf", "1", "--nk", "1"]):  # fmt: skip
        status, out, err = _run(["identify", path, *extra], capsys)
        assert status == 2 and out == ""
        lines = err.strip().splitlines()
        assert len(lines) == 1, err  # no RuntimeWarning screens before it
        assert "sample 123" in lines[0] and "1e+308" in lines[0] and "rescale" in lines[0]
    with pytest.raises(DataError, match=r"output 'y' sample 123 = 1e\+308"):
        IOData(record.u, y)


def test_the_magnitude_limit_keeps_every_sum_of_squares_finite():
    """Just below the limit a record's sum of squares is finite with the stated headroom;
    just above it is refused (so the bound is the one the message states)."""
    n = 1000
    limit = np.sqrt(np.finfo(np.float64).max / (n * 1e6))
    y = np.full(n, 0.999 * limit)
    with np.errstate(over="raise"):
        assert np.isfinite(1e3 * np.sqrt(y @ y) * 1e3)  # the paper's 1e3 scale, twice over
    IOData(np.ones(n), y)
    y[-1] = 1.001 * limit
    with pytest.raises(DataError, match=f"sample {n - 1}"):
        IOData(np.ones(n), y)


def test_messages_show_numbers_not_numpy_reprs():
    assert plain_number(np.float64(np.inf)) == "inf"
    assert plain_number(np.array([np.nan, 0.5])) == "[nan, 0.5]"
    assert plain_number(np.int64(7)) == "7"
    assert plain_number(np.complex128(1 + 2j)) == "(1+2j)"
    assert plain_number("x") == "'x'"  # a string as typed, quoted
    with pytest.raises(DataError) as caught:
        check_finite(np.array([1.0, np.inf]), "output 'y'")
    assert "np.float64" not in str(caught.value) and "the first is inf" in str(caught.value)
    from flexid.envs.manipulator import FlexibleManipulatorEnv

    env = FlexibleManipulatorEnv()
    env.reset(seed=0)
    with pytest.raises(flexid.errors.ActionError) as caught:
        env.step(np.array([np.nan]))
    assert "np.float64" not in str(caught.value) and "array(" not in str(caught.value)


# ------------------------------------------------------------------ a full disk under a store
class _FullDisk:
    """A connection whose every statement fails as SQLite does when the disk is full."""

    def __init__(self, message: str, code: int) -> None:
        self.message, self.code = message, code

    def execute(self, *args, **kwargs):
        exc = sqlite3.OperationalError(self.message)
        exc.sqlite_errorcode = self.code
        raise exc

    executescript = execute

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        pass

    def close(self) -> None:
        pass


@pytest.mark.parametrize(("message", "code", "free"), [
    ("disk I/O error", 778, 0),  # SQLITE_IOERR_WRITE: the log could not grow, nothing free
    ("database or disk is full", 13, 10**9),  # SQLITE_FULL says so whatever is free
])  # fmt: skip
def test_a_full_disk_under_a_store_says_so_and_that_the_store_is_intact(
    tmp_path, monkeypatch, message, code, free
):
    path = tmp_path / "results.sqlite"
    monkeypatch.setattr(
        flexid.jobs.store.sqlite3, "connect", lambda *a, **k: _FullDisk(message, code)
    )
    monkeypatch.setattr("shutil.disk_usage", lambda p: type("U", (), {"free": free})())
    with pytest.raises(StoreError) as caught:
        ResultStore(path)
    text = str(caught.value)
    assert "disk is full" in text and "intact" in text and "not a readable" not in text


def test_a_disk_io_error_with_room_to_spare_is_not_called_a_full_disk(tmp_path, monkeypatch):
    monkeypatch.setattr(flexid.jobs.store.sqlite3, "connect",
                        lambda *a, **k: _FullDisk("disk I/O error", 778))  # fmt: skip
    monkeypatch.setattr("shutil.disk_usage", lambda p: type("U", (), {"free": 10**9})())
    with pytest.raises(StoreError, match="not a readable flexid result store"):
        ResultStore(tmp_path / "results.sqlite")


def test_a_write_that_meets_a_full_disk_keeps_the_stored_runs(tmp_path, monkeypatch):
    path = tmp_path / "results.sqlite"
    with ResultStore(path) as store:
        store.add_comparison("k", "name", {"a": 1})
        db = store._db
        store._db = _FullDisk("database or disk is full", 13)
        with pytest.raises(StoreError, match="disk is full; the store is intact"):
            store.add_comparison("k2", "other", {"a": 2})
        store._db = db
    with ResultStore(path, readonly=True) as store:
        assert [c["key"] for c in store.comparisons()] == ["k"]


# ------------------------------------------------------------------ lines of a summary
def _long_lines(text: str) -> list[str]:
    return [line for line in text.splitlines() if len(line) > LINE_WIDTH]


def test_identify_prints_no_line_longer_than_the_terminal(tmp_path, capsys):
    path = tmp_path / "rec.csv"
    _arx_record(600).to_csv(path)
    for extra in (["--optimiser", "ls", "--na", "4", "--nb", "4", "--nk", "1"],
                  ["--optimiser", "pso", "--na", "2", "--nb", "2", "--nk", "1", "--budget", "300"],
                  ["--structure", "oe", "--nb", "4", "--nf", "4", "--nk", "1"]):  # fmt: skip
        status, out, err = _run(["identify", path, *extra], capsys)
        assert status == 0, err
        assert "search space:" in out or "search" in out
        assert _long_lines(out + err) == []


@pytest.mark.parametrize("what", ["optimisers", "plants", "presets", "greybox", "signals"])
def test_the_lists_print_no_line_longer_than_the_terminal(capsys, what):
    status, out, err = _run(["list", what], capsys)
    assert status == 0 and out
    assert _long_lines(out + err) == []
    status, out, _ = _run(["list", "optimisers", "--long"], capsys)
    assert status == 0 and _long_lines(out) == []


def test_select_and_compare_print_no_line_longer_than_the_terminal(tmp_path, capsys):
    """Their tables are wider than a terminal: printed in blocks of columns, each repeating
    the row names; the paths a user gave are the only longer lines allowed."""
    path = tmp_path / "rec.csv"
    _arx_record(600).to_csv(path)
    status, out, err = _run(["select", path, "--structures", "arx,oe", "--orders", "nb=1,2",
                             "--nk", "1"], capsys)  # fmt: skip
    assert status == 0, err
    assert "recommended" in out and _long_lines(out + err) == []
    status, out, err = _run(["compare", "--plant", "manipulator", "--na", "2", "--runs", "2",
                             "--budget", "100", "--optimisers", "pso,de", "--no-figures",
                             "--no-progress", "--store", tmp_path / "r.sqlite"],
                            capsys)  # fmt: skip
    assert status == 0, err
    assert "FE to" in out and "p (Holm)" in out  # every column is there, in some block
    assert [line for line in _long_lines(out + err) if str(tmp_path) not in line] == []


# ------------------------------------------------------------------ an unstable model's fit
@pytest.mark.filterwarnings("ignore::flexid.errors.DataWarning")  # the unstable record drifts
def test_the_fit_of_an_unstable_model_says_so_on_its_own_line():
    data = _arx_record(300, pole=1.01)  # 1.01^300 = 20: the record stays finite
    ident = identify(data, 1, 1, 1, optimiser="ls")
    assert not ident.model.is_stable
    lines = ident.validation.summary().splitlines()
    sim = next(i for i, line in enumerate(lines) if "simulation (free run)" in line)
    assert "UNSTABLE model" in lines[sim + 1] and "diverges" in lines[sim + 1]
    assert "samples only" in lines[sim + 1]
    shown = ident._repr_html_()  # the notebook's table says it too, and the verdict's level
    assert "(UNSTABLE model)" in shown
    assert "FAIL at 5 %" in shown or "PASS at 5 %" in shown
    stable = identify(_arx_record(300), 1, 1, 1, optimiser="ls")
    assert "UNSTABLE model" not in stable.validation.summary()


@pytest.mark.filterwarnings("ignore::flexid.errors.DataWarning")
def test_select_says_when_an_unstable_candidate_ranks_above_a_stable_one():
    data = _arx_record(300, pole=1.01)
    grid = {"arx": [{"na": 1, "nb": 1}, {"na": 0, "nb": 2}]}  # FIR candidates are stable
    choice = select(data, structures=("arx",), orders=grid, nk=1, criterion="simulation")
    ranked = [c for c in choice.ranked() if c.ok]
    assert not ranked[0].stable and any(c.stable for c in ranked[1:])
    text = choice.summary()
    row = next(x for x in text.splitlines() if x.lstrip().startswith("1 "))
    assert ranked[0].label in row and " !" in row
    flat = " ".join(text.split())  # the note is wrapped to the terminal's width
    assert f"ranked by simulation above stable candidates: {ranked[0].label}" in flat
    assert choice.best.stable  # the recommendation stays a stable one


def test_compare_marks_an_unstable_rows_fit(tmp_path):
    result = compare(tiny_spec("unstable-mark"), store=tmp_path / "r.sqlite", progress=False)
    assert "!: an UNSTABLE model" not in result.summary()
    shown = replace(result, reference={**result.reference, "stable": False})
    text = shown.summary()
    row = next(line for line in text.splitlines()
               if line.startswith(shown.start_label) and "[" in line)  # the validation row
    assert " !" in row
    assert "!: an UNSTABLE model" in text



def test_a_csv_saved_with_a_bom_keeps_its_time_column(tmp_path):
    """A spreadsheet's "CSV UTF-8" starts with a byte-order mark: it is not part of the first
    column's name, so the time column is found and the sample time read from it."""
    path = tmp_path / "bom.csv"
    t = np.arange(50) * 0.02
    rows = "".join(f"{a!r},{b!r},{c!r}\n" for a, b, c in zip(t.tolist(), np.sin(t).tolist(),
                                                           np.cos(t).tolist()))  # fmt: skip
    path.write_bytes(b"\xef\xbb\xbf" + ("t,u,y\n" + rows).encode())
    data = flexid.data.load(path)
    assert data.dt == pytest.approx(0.02) and data.input_names == ("u",)
