"""Tests of flexid.jobs.store: the SQLite result store."""

from __future__ import annotations

import sqlite3

import pytest

from flexid.errors import StoreError
from flexid.jobs.store import ResultStore


def _record(label: str, run: int, status: str = "ok", **extra) -> dict:
    return {
        "label": label,
        "run": run,
        "seed": 100 + run,
        "status": status,
        "cost": 1.0 + run,
        **extra,
    }


def test_write_and_read_back(tmp_path):
    path = tmp_path / "sub" / "r.sqlite"
    with ResultStore(path) as store:
        store.add_comparison("k1", "demo", {"a": 1})
        store.add_comparison("k1", "renamed", {"a": 2})  # the latest specification wins
        store.write_run("k1", _record("sda", 0))
        store.write_run(
            "k1", _record("sda", 1, history={"fe": [1, 2], "best": [3.0, float("inf")]})
        )
        store.write_run("k1", _record("bfa", 0, status="failed", error="ValueError: boom"))
        assert store.finished("k1") == {("sda", 0), ("sda", 1), ("bfa", 0)}
        assert store.finished("k1", include_failed=False) == {("sda", 0), ("sda", 1)}
        assert store.count("k1") == {"ok": 2, "failed": 1}
        runs = store.runs("k1")
        assert [(r["label"], r["run"]) for r in runs] == [("bfa", 0), ("sda", 0), ("sda", 1)]
        assert runs[2]["history"]["best"][1] == float("inf")
        assert list(store.iter_runs("k1")) == runs
        assert store.comparison("k")["name"] == "renamed"
        assert store.comparisons()[0]["n_runs"] == 3
    with ResultStore(path, readonly=True) as store:
        assert store.count("k1")["ok"] == 2


def test_rewriting_a_run_replaces_it(tmp_path):
    with ResultStore(tmp_path / "r.sqlite") as store:
        store.add_comparison("k", "x", {})
        store.write_run("k", _record("pso", 0, status="failed", error="E"))
        store.write_run("k", _record("pso", 0))
        assert store.count("k") == {"ok": 1, "failed": 0}


def test_each_run_is_committed_at_once(tmp_path):
    path = tmp_path / "r.sqlite"
    store = ResultStore(path)
    store.add_comparison("k", "x", {})
    store.write_run("k", _record("de", 0))
    # another connection sees the row before the first is closed
    other = sqlite3.connect(path)
    assert other.execute("SELECT COUNT(*) FROM runs").fetchone()[0] == 1
    other.close()
    store.close()


def test_bad_stores(tmp_path):
    with pytest.raises(StoreError, match="no such result store"):
        ResultStore(tmp_path / "missing.sqlite", readonly=True)
    junk = tmp_path / "junk.sqlite"
    junk.write_bytes(b"this is not sqlite" * 100)
    with pytest.raises(StoreError, match="not a readable flexid result store"):
        ResultStore(junk)
    other = tmp_path / "other.sqlite"
    con = sqlite3.connect(other)
    con.execute("CREATE TABLE x (a)")
    con.commit()
    con.close()
    with pytest.raises(StoreError, match=r"not a (readable )?flexid result store"):
        ResultStore(other, readonly=True)
    with ResultStore(tmp_path / "ok.sqlite") as store:
        with pytest.raises(StoreError, match="no comparison"):
            store.comparison("nope")
        with pytest.raises(StoreError, match="not JSON"):
            store.write_run("k", _record("x", 0, thing=object()))
