"""The result store does not mix, lose or write what it should not (issue #25).

1. A comparison on a data file is keyed by the numbers the file held, not only by its path:
   a rerun on an edited file is a new comparison, never runs of two records in one.
2. A damaged run record (broken JSON, bytes that are not UTF-8) is named in one warning and
   skipped; the other rows are read, and a rerun runs the damaged one again.
3. A file that is not a flexid store is refused before anything is written into it.
4. Reading a store writes nothing beside it, so a store in a read-only folder can be reported;
   a read-only store given to ``compare`` is called read-only.

Tests of file permissions skip as root (root writes read-only files); the others run as any
user, and the "writes nothing" checks compare the folder's listing and the file's bytes and
modification time before and after.
"""

from __future__ import annotations

import json
import os
import sqlite3
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from flexid import compare, load_result
from flexid.cli import main
from flexid.config import load_config
from flexid.errors import ConfigError, StoreError, StoreWarning
from flexid.jobs.store import ResultStore
from flexid.report import write_report
from helpers import small_spec, tiny_spec

AS_ROOT = hasattr(os, "geteuid") and os.geteuid() == 0


def _state(path: Path) -> tuple:
    """The file's bytes and modification time, and the names in its folder."""
    return path.read_bytes(), path.stat().st_mtime_ns, sorted(os.listdir(path.parent))


# --------------------------------------------------------------------- 1. data file digest
def _write_record(path: Path, noise_seed: int) -> None:
    """A 300-sample ARX(2, 2) record; ``noise_seed`` picks the measurement noise."""
    rng = np.random.default_rng(7)
    u = rng.uniform(-1.0, 1.0, 300)
    y = np.zeros(300)
    for k in range(2, 300):
        y[k] = 1.5 * y[k - 1] - 0.7 * y[k - 2] + u[k - 1] + 0.5 * u[k - 2]
    y += 0.05 * np.random.default_rng(noise_seed).standard_normal(300)
    rows = "".join(f"{float(a)!r},{float(b)!r}\n" for a, b in zip(u, y))
    path.write_text("u,y\n" + rows)


def _write_config(folder: Path, runs: int) -> Path:
    path = folder / "recorded.toml"
    path.write_text(
        f"""
name = "recorded"
[data]
file = "rec.csv"
inputs = ["u"]
outputs = ["y"]
dt = 0.01
[model]
na = 2
nb = 2
nk = 1
[run]
runs = {runs}
seed = 3
budget = 200
targets = [1.0]
[[optimisers]]
name = "random-search"
"""
    )
    return path


def test_an_edited_data_file_starts_a_new_comparison(tmp_path):
    store = tmp_path / "r.sqlite"
    record = tmp_path / "rec.csv"
    _write_record(record, noise_seed=0)
    (spec,) = load_config(_write_config(tmp_path, runs=2))
    first = compare(spec, store=store)

    _write_record(record, noise_seed=1)  # the same path, other numbers
    (spec,) = load_config(_write_config(tmp_path, runs=4))
    seen = []
    second = compare(spec, store=store, progress=seen.append)
    assert second.key != first.key
    assert sorted(r["run"] for r in seen) == [0, 1, 2, 3]  # no run taken from the old record
    assert second.reference["cost"] != first.reference["cost"]  # least squares on the new one
    stored = {r.key: r for r in load_result(store)}
    assert [r["run"] for r in stored[first.key].records["random-search"]] == [0, 1]
    assert [r["run"] for r in stored[second.key].records["random-search"]] == [0, 1, 2, 3]
    assert stored[second.key].spec.data.digest == second.spec.data.digest
    assert len(second.spec.data.digest) == 64

    # the key follows the numbers: the first record back in the file resumes its comparison
    _write_record(record, noise_seed=0)
    seen.clear()
    third = compare(spec, store=store, progress=seen.append)
    assert third.key == first.key
    assert sorted(r["run"] for r in seen) == [2, 3]
    assert third.reference["cost"] == first.reference["cost"]


def test_simulated_records_keep_their_keys_and_the_digest_is_not_a_config_key(tmp_path):
    # the keys of comparisons on simulated plants are those existing stores hold
    assert small_spec().key == "efc368186474062a"
    assert tiny_spec("x").key == "0472da5c569e61c3"
    assert "digest" not in small_spec().to_dict()["data"]
    _write_record(tmp_path / "rec.csv", noise_seed=0)
    path = _write_config(tmp_path, runs=1)
    path.write_text(path.read_text().replace('dt = 0.01', 'dt = 0.01\ndigest = "0"'))
    with pytest.raises(ConfigError, match=r"unknown key.*'digest'"):
        load_config(path)


def test_a_store_written_without_digests_is_still_reported(tmp_path):
    store = tmp_path / "r.sqlite"
    _write_record(tmp_path / "rec.csv", noise_seed=0)
    (spec,) = load_config(_write_config(tmp_path, runs=1))
    result = compare(spec, store=store)
    old_spec = result.spec.to_dict()
    del old_spec["data"]["digest"]  # as flexid wrote file comparisons before the digest
    con = sqlite3.connect(store)
    con.execute("UPDATE comparisons SET spec = ?", (json.dumps(old_spec, sort_keys=True),))
    con.commit()
    con.close()
    (again,) = load_result(store)
    assert again.key == result.key and again.spec.data.digest is None
    assert again.records == result.records
    assert write_report(store, tmp_path / "out", figures=False).exists()


# --------------------------------------------------------------------- 2. damaged rows
def _damage(store: Path, label: str, run: int, how: str) -> None:
    """Break one byte of a stored run's payload, written as TEXT as flexid writes it."""
    con = sqlite3.connect(store)
    where = "WHERE label = ? AND run = ?"
    (payload,) = con.execute(f"SELECT CAST(payload AS BLOB) FROM runs {where}", (label, run))
    payload = payload[0]
    if how == "json":
        bad = payload.replace(b'"', b"'", 1)  # one quote of a key: no longer JSON
    else:
        bad = payload[:2] + b"\xff" + payload[3:]  # a byte that is never UTF-8, in a key
    assert len(bad) == len(payload) and bad != payload
    con.execute(f"UPDATE runs SET payload = CAST(? AS TEXT) {where}", (bad, label, run))
    con.commit()
    con.close()


def _numbers(records: dict) -> dict:
    """The run records without their wall times (a rerun run takes its own time)."""
    return {
        label: [{k: v for k, v in r.items() if k != "wall_time"} for r in runs]
        for label, runs in records.items()
    }


def _store_warnings(caught) -> list[str]:
    return [str(w.message) for w in caught if issubclass(w.category, StoreWarning)]


@pytest.mark.parametrize("how", ["json", "utf-8"])
def test_a_damaged_run_is_named_and_the_rest_is_read(tmp_path, how):
    store = tmp_path / "r.sqlite"
    first = compare(tiny_spec("damaged"), store=store)
    _damage(store, "sda", 1, how)

    with pytest.warns(StoreWarning) as caught:
        (result,) = load_result(store)
    (message,) = _store_warnings(caught)
    assert "\n" not in message
    assert "'damaged'" in message and first.key in message and "'sda' run 1" in message
    assert [r["run"] for r in result.records["sda"]] == [0]
    assert [r["run"] for r in result.records["random-search"]] == [0, 1]
    assert result.records["random-search"] == first.records["random-search"]

    with pytest.warns(StoreWarning):
        text = write_report(store, tmp_path / "out", figures=False).read_text()
    assert "| sda" in text
    with ResultStore(store, readonly=True) as db, pytest.warns(StoreWarning):
        assert ("sda", 1) not in db.finished(first.key)
        assert len(list(db.iter_runs(first.key))) == 4  # least squares + 3 of 4 runs


def test_report_names_a_damaged_run_in_one_line(tmp_path, capsys):
    store = tmp_path / "r.sqlite"
    compare(tiny_spec("damaged"), store=store)
    _damage(store, "random-search", 0, "utf-8")
    capsys.readouterr()
    status = main(["report", str(store), "-o", str(tmp_path / "out"), "--no-figures"])
    err = capsys.readouterr().err
    assert status == 0, err
    assert err.startswith("flexid: warning:") and err.count("flexid: warning:") == 1, err
    assert "'random-search' run 0" in " ".join(err.split())  # one warning, however wrapped


@pytest.mark.parametrize("how", ["json", "utf-8"])
@pytest.mark.parametrize("row", [("sda", 1), ("ls", 0)], ids=["optimiser run", "least squares"])
def test_a_rerun_replaces_a_damaged_run(tmp_path, how, row):
    store = tmp_path / "r.sqlite"
    spec = tiny_spec("damaged")
    first = compare(spec, store=store)
    _damage(store, *row, how)

    seen = []
    with pytest.warns(StoreWarning, match=f"'{row[0]}' run {row[1]}"):
        again = compare(spec, store=store, progress=seen.append)
    rerun = [] if row[0] == "ls" else [row]  # least squares is not an optimiser run
    assert [(r["label"], r["run"]) for r in seen] == rerun
    assert again.reference["cost"] == first.reference["cost"]
    assert _numbers(again.records) == _numbers(first.records)

    with warnings.catch_warnings():
        warnings.simplefilter("error", StoreWarning)  # the damaged row was replaced
        (back,) = load_result(store)
        with ResultStore(store, readonly=True) as db:
            assert db.count(first.key) == {"ok": 5, "failed": 0}
    assert _numbers(back.records) == _numbers(first.records)


# --------------------------------------------------------------------- 3. foreign files
def _unrelated(path: Path) -> None:
    con = sqlite3.connect(path)
    con.execute("CREATE TABLE notes (id INTEGER PRIMARY KEY, text TEXT)")
    con.execute("INSERT INTO notes(text) VALUES ('keep me')")
    con.commit()
    con.close()


def _foreign_runs(path: Path) -> None:
    con = sqlite3.connect(path)
    con.execute("CREATE TABLE runs (id INTEGER PRIMARY KEY, result REAL)")
    con.execute("INSERT INTO runs(result) VALUES (1.5)")
    con.commit()
    con.close()


def _text(path: Path) -> None:
    path.write_bytes(b"a text file, not a database\n" * 50)


FOREIGN = {
    "unrelated database": (_unrelated, "table 'notes'"),
    "foreign runs table": (_foreign_runs, "'runs'"),
    "text file": (_text, "not a readable flexid result store"),
}


@pytest.mark.parametrize("kind", list(FOREIGN))
def test_a_foreign_file_is_refused_and_left_as_it_was(tmp_path, kind):
    make, why = FOREIGN[kind]
    path = tmp_path / "other.db"
    make(path)
    before = _state(path)
    for open_it in (
        lambda: ResultStore(path),
        lambda: ResultStore(path, readonly=True),
        lambda: compare(tiny_spec("foreign", runs=1), store=path),
    ):
        with pytest.raises(StoreError) as caught:
            open_it()
        message = str(caught.value)
        assert str(path) in message and why in message and "\n" not in message
        assert _state(path) == before


def test_an_sqlite_file_without_tables_becomes_a_store(tmp_path):
    empty = tmp_path / "empty.db"
    con = sqlite3.connect(empty)
    con.execute("CREATE TABLE t (a)")
    con.execute("DROP TABLE t")
    con.commit()
    con.close()
    assert empty.stat().st_size > 0
    zero = tmp_path / "zero.db"
    zero.touch()
    for path in (empty, zero):
        with ResultStore(path) as db:
            db.add_comparison("k", "x", {})
        with ResultStore(path, readonly=True) as db:
            assert db.comparison("k")["name"] == "x"


# --------------------------------------------------------------------- 4. read-only stores
def test_reading_a_store_writes_nothing(tmp_path):
    store = tmp_path / "results" / "r.sqlite"
    result = compare(tiny_spec("read only"), store=store)
    before = _state(store)
    with ResultStore(store, readonly=True) as db:
        assert db.count(result.key) == {"ok": 5, "failed": 0}
    (again,) = load_result(store)
    assert again.records == result.records
    write_report(store, tmp_path / "out", figures=False)
    assert _state(store) == before  # no -wal, -shm or journal file, the same bytes


def test_a_reader_sees_the_runs_of_a_writer_at_work(tmp_path):
    path = tmp_path / "r.sqlite"
    record = {"label": "de", "run": 0, "seed": 1, "status": "ok", "cost": 2.0}
    with ResultStore(path) as writer:
        writer.add_comparison("k", "x", {})
        writer.write_run("k", record)
        assert path.with_name(path.name + "-wal").exists()  # the row is in the log yet
        with ResultStore(path, readonly=True) as reader:
            assert reader.runs("k") == [record]


def test_a_store_that_may_not_be_written_is_called_read_only(tmp_path, monkeypatch):
    """Write permission denied as ``os.access`` reports it (root's is simulated)."""
    store = tmp_path / "r.sqlite"
    spec = tiny_spec("read only", runs=1)
    compare(spec, store=store)
    before = _state(store)
    access = os.access

    def no_write(path, mode, *args, **kwargs):
        if Path(path) == store and mode & os.W_OK:
            return False
        return access(path, mode, *args, **kwargs)

    monkeypatch.setattr(os, "access", no_write)
    with pytest.raises(StoreError, match="read-only") as caught:
        compare(replace(spec, runs=2), store=store)
    assert "not readable" not in str(caught.value) and str(store) in str(caught.value)
    assert _state(store) == before


@pytest.mark.skipif(AS_ROOT, reason="root writes read-only files")
def test_compare_on_a_read_only_store_file_says_read_only(tmp_path):
    store = tmp_path / "r.sqlite"
    spec = tiny_spec("read only", runs=1)
    compare(spec, store=store)
    store.chmod(0o444)
    before = _state(store)
    with pytest.raises(StoreError, match="read-only"):
        compare(replace(spec, runs=2), store=store)
    assert _state(store) == before


@pytest.mark.skipif(AS_ROOT, reason="root writes in read-only folders")
def test_report_on_a_store_in_a_read_only_folder(tmp_path, capsys):
    folder = tmp_path / "results"
    store = folder / "r.sqlite"
    compare(tiny_spec("read only"), store=store)
    before = _state(store)
    folder.chmod(0o555)
    try:
        status = main(["report", str(store), "-o", str(tmp_path / "out"), "--no-figures"])
        err = capsys.readouterr().err
        assert status == 0, err
        assert _state(store) == before
    finally:
        folder.chmod(0o755)
