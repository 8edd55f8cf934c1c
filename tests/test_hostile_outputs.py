"""Outputs tried as a hostile user would (issue #45): nothing lost, nothing overwritten.

1. A second comparison of the same problem (other optimisers) writes figures of its own
   names: the first comparison's figures stay as they were, and the same comparison run
   again writes its own names again.
2. One comparison of a store that cannot be read (its least-squares row damaged, or not
   written yet because the reference is still computing) is left out of the report in one
   line; the other comparisons are reported. With none readable, one error line.
3. An output that cannot be written (a full disk, a read-only folder, a path naming an
   existing file, the store itself) ends in one line naming the path and the cause, exit
   status 2, no partial file, and the store as it was.

A full disk is simulated by an ``open`` that, for files opened for writing in the output
folder, writes a few bytes and then raises ``ENOSPC``; read-only folders need a user who is
not root (root writes anyway), so those cases skip as root.
"""

from __future__ import annotations

import builtins
import errno
import os
import re
import shutil
import sqlite3
import stat
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import pytest

from flexid import compare, load_result
from flexid.cli import main
from flexid.jobs.store import ResultStore
from helpers import tiny_spec
from test_cli import _record

AS_ROOT = hasattr(os, "geteuid") and os.geteuid() == 0
pytest.importorskip("matplotlib")


def _run(argv, capsys):
    status = main([str(a) for a in argv])
    out = capsys.readouterr()
    return status, out.out, out.err


def _lines(text: str) -> list[str]:
    return [line for line in text.splitlines() if line.strip()]


def _one_line_error(status: int, err: str, tmp_path: Path) -> str:
    assert status == 2, err
    assert "Traceback" not in err, err
    (line,) = _lines(err)
    assert line.startswith("flexid: error: "), line
    assert len(line.replace(str(tmp_path), "")) <= 100, line  # less the temporary folder
    return line


def _listing(folder: Path) -> dict[str, bytes | None]:
    """Every file under ``folder`` with its bytes, and every folder (None)."""
    return {
        str(p.relative_to(folder)): p.read_bytes() if p.is_file() else None
        for p in folder.rglob("*")
    }


def _unlock(tmp_path: Path) -> None:
    """Give back the write permission a read-only case took (to read the store after)."""
    if (tmp_path / "locked").exists():
        (tmp_path / "locked").chmod(stat.S_IRWXU)


class _FullFile:
    """A file on a full disk: the first write takes a few bytes, then raises ENOSPC."""

    def __init__(self, handle):
        self._handle = handle

    def write(self, data):
        self._handle.write(data[:16])
        self._handle.flush()
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    def __getattr__(self, name):
        return getattr(self._handle, name)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self._handle.close()


def _full_disk(monkeypatch, folder: Path) -> None:
    """Files opened for writing under ``folder`` (made or not) find the disk full."""
    real_open = builtins.open
    folder = folder.absolute()

    def fake_open(file, mode="r", *args, **kwargs):
        handle = real_open(file, mode, *args, **kwargs)
        if isinstance(file, (str, os.PathLike)) and any(c in mode for c in "wax+"):
            if Path(file).absolute().is_relative_to(folder):
                return _FullFile(handle)
        return handle

    monkeypatch.setattr(builtins, "open", fake_open)


# ------------------------------------------------------------------ 1. figures of their own
COMPARE = ["compare", "--plant", "manipulator", "--na", "2", "--runs", "1", "--budget", "100",
           "--store", "r.sqlite", "--no-progress"]  # fmt: skip


def _pngs(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in folder.glob("*.png")}


def test_a_second_comparison_keeps_the_first_ones_figures(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    status, _, err = _run([*COMPARE, "--optimisers", "pso"], capsys)
    assert status == 0, err
    first = _pngs(tmp_path)
    status, out, err = _run([*COMPARE, "--optimisers", "de"], capsys)
    assert status == 0, err
    both = _pngs(tmp_path)
    assert {name: both[name] for name in first} == first  # not one byte of the first changed
    (shown,) = [line for line in out.splitlines() if line.startswith("figures:")]
    assert len(shown) <= 100, shown
    second = set(both) - set(first)
    assert len(second) == len(first)
    status, _, err = _run([*COMPARE, "--optimisers", "pso"], capsys)  # the same again
    assert status == 0, err
    assert _pngs(tmp_path).keys() == both.keys()  # its own names, no third set

    status, _, err = _run(["report", "r.sqlite", "-o", "rep", "--format", "html"], capsys)
    assert status == 0, err
    sources = re.findall(r"<img src='([^']+)'", (tmp_path / "rep" / "report.html").read_text())
    assert sources and all((tmp_path / "rep" / s).is_file() for s in sources)


def _prefix(spec) -> str:
    from flexid.report import figure_prefix

    return figure_prefix(SimpleNamespace(spec=spec, key=spec.key))  # what it reads of a result


def test_the_figure_names_tell_comparisons_apart():
    spec = tiny_spec("twin rotor / ARX (5,5,1)")
    other_params = (replace(spec.optimisers[0], params={"points": 12}), spec.optimisers[1])
    changed = [
        tiny_spec(spec.name, optimisers=spec.optimisers[:1]),
        tiny_spec(spec.name, optimisers=spec.optimisers[::-1]),
        tiny_spec(spec.name, optimisers=other_params),
        tiny_spec(spec.name, runs=3),
        tiny_spec(spec.name, budget=200),
    ]
    assert all(other.key == spec.key for other in changed[:4])  # one problem, one store key
    prefixes = {_prefix(s) for s in [spec, *changed]}
    assert len(prefixes) == 1 + len(changed)
    assert _prefix(tiny_spec(spec.name)) == _prefix(spec)  # the same comparison: same names
    assert all(p.startswith("twin-rotor-arx-5-5-1-") and "--" not in p for p in prefixes)


# ------------------------------------------------------------------ 2. one damaged comparison
@pytest.fixture(scope="module")
def two_comparisons(tmp_path_factory) -> tuple[Path, dict[str, str]]:
    """A store of two comparisons, ``kept`` and ``broken``; their keys by name."""
    path = tmp_path_factory.mktemp("two") / "r.sqlite"
    keys = {}
    with ResultStore(path) as db:
        for spec in (tiny_spec("kept"), tiny_spec("broken", budget=200)):
            keys[spec.name] = compare(spec, store=db, progress=False).key
    return path, keys


def _copy(store: Path, folder: Path) -> Path:
    copy = folder / "r.sqlite"
    shutil.copy(store, copy)
    return copy


def _damage_reference(store: Path, key: str) -> None:
    """One byte of the comparison's least-squares row that is never UTF-8."""
    con = sqlite3.connect(store)
    where = "WHERE key = ? AND label = 'ls'"
    ((payload,),) = con.execute(f"SELECT CAST(payload AS BLOB) FROM runs {where}", (key,))
    bad = payload[:2] + b"\xff" + payload[3:]
    con.execute(f"UPDATE runs SET payload = CAST(? AS TEXT) {where}", (bad, key))
    con.commit()
    con.close()


def _report(store: Path, out: Path, capsys) -> tuple[int, str, str]:
    return _run(["report", store, "-o", out, "--no-figures"], capsys)


def test_report_leaves_out_a_comparison_with_a_damaged_reference(two_comparisons, tmp_path,
                                                                 capsys):  # fmt: skip
    store = _copy(two_comparisons[0], tmp_path)
    _damage_reference(store, two_comparisons[1]["broken"])
    status, _, err = _report(store, tmp_path / "out", capsys)
    assert status == 0, err
    (line,) = _lines(err)
    assert line.startswith("flexid: warning: ") and len(line) <= 100, line
    assert "'broken'" in line and "damaged" in line and "least-squares" in line, line
    text = (tmp_path / "out" / "report.md").read_text()
    assert "## kept" in text and "## broken" not in text
    assert "'broken'" in text and "damaged" in text  # the report says what it left out


def test_report_leaves_out_a_comparison_still_computing(two_comparisons, tmp_path, capsys):
    store = _copy(two_comparisons[0], tmp_path)
    spec = tiny_spec("computing", budget=250)
    with ResultStore(store) as db:  # as compare() has it while its reference is computed
        db.add_comparison(spec.key, spec.name, spec.to_dict())
    status, _, err = _report(store, tmp_path / "out", capsys)
    assert status == 0, err
    (line,) = _lines(err)
    assert line.startswith("flexid: warning: ") and len(line) <= 100, line
    assert "'computing'" in line and "not finished" in line and "damaged" not in line, line
    text = (tmp_path / "out" / "report.md").read_text()
    assert "## kept" in text and "## broken" in text and "## computing" not in text


def test_report_with_no_readable_comparison_is_one_error(two_comparisons, tmp_path, capsys):
    store = _copy(two_comparisons[0], tmp_path)
    for key in two_comparisons[1].values():
        _damage_reference(store, key)
    status, _, err = _report(store, tmp_path / "out", capsys)
    line = _one_line_error(status, err, tmp_path)
    assert "nothing to report" in line and "'kept', 'broken'" in line and "damaged" in line
    assert not (tmp_path / "out").exists()


# ------------------------------------------------------------------ 3. outputs not written
def _readable(store: Path, n_runs: int) -> None:
    (result,) = load_result(store)
    assert sum(len(runs) for runs in result.records.values()) == n_runs


def _hostile(kind: str, tmp_path: Path, monkeypatch) -> tuple[Path, str]:
    """The output path of a case and the words its message must have."""
    if kind == "full disk":
        _full_disk(monkeypatch, tmp_path / "out")
        return tmp_path / "out", "no space left on device"
    if kind == "existing file":
        (tmp_path / "some_file.txt").write_text("mine\n")
        return tmp_path / "some_file.txt", "not a folder"
    if AS_ROOT:
        pytest.skip("root writes into read-only folders")
    folder = tmp_path / "locked"
    folder.mkdir()
    folder.chmod(stat.S_IRUSR | stat.S_IXUSR)
    return folder / "missing", "permission denied"


KINDS = ["full disk", "existing file", "read-only folder"]


@pytest.mark.parametrize("kind", KINDS)
def test_compare_figures_that_cannot_be_written(kind, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    figures, cause = _hostile(kind, tmp_path, monkeypatch)
    before = _listing(tmp_path)
    status, out, err = _run([*COMPARE, "--optimisers", "pso", "--figures", figures], capsys)
    line = _one_line_error(status, err, tmp_path)
    assert f"cannot write figures to {figures}: {cause}" in line, line
    assert line.endswith("; 1 run stored in r.sqlite"), line
    assert "1 optimiser run (+ the least squares row)" in out  # the summary was printed
    after = _listing(tmp_path)
    assert set(after) == set(before) | {"r.sqlite"}, after.keys()  # no PNG, no temporary
    assert all(after[name] == before[name] for name in before)
    _unlock(tmp_path)
    _readable(tmp_path / "r.sqlite", 1)


@pytest.mark.parametrize("kind", [*KINDS, "the store"])
def test_report_that_cannot_be_written(kind, two_comparisons, tmp_path, monkeypatch, capsys):
    store = _copy(two_comparisons[0], tmp_path)
    if kind == "the store":
        out, cause = store, "not a folder"
    else:
        out, cause = _hostile(kind, tmp_path, monkeypatch)
    before = _listing(tmp_path)
    status, _, err = _run(["report", store, "-o", out], capsys)
    line = _one_line_error(status, err, tmp_path)
    assert f"cannot write the report to {out}: {cause}" in line, line
    assert _listing(tmp_path) == before  # no MD, no PNG, no temporary; the store as it was
    _unlock(tmp_path)
    monkeypatch.undo()
    with ResultStore(store, readonly=True) as db:
        assert len(db.comparisons()) == 2


@pytest.mark.parametrize("kind", KINDS)
def test_identify_figures_that_cannot_be_written(kind, tmp_path, monkeypatch, capsys):
    record = _record(tmp_path / "rec.csv")
    figures, cause = _hostile(kind, tmp_path, monkeypatch)
    before = _listing(tmp_path)
    status, out, err = _run(["identify", record, "--na", "2", "--figures", figures], capsys)
    line = _one_line_error(status, err, tmp_path)
    assert f"cannot write figures to {figures}: {cause}" in line, line
    assert line.endswith("; results printed above") and "fit" in out  # nothing is lost
    assert _listing(tmp_path) == before
    _unlock(tmp_path)
