"""SQLite result store: every finished run is written at once, so an interrupted comparison resumes.

One file holds any number of comparisons.  A comparison is keyed by a hash of everything
that determines its numbers (data, model orders, cost, search box, budget, optimisers and
their hyper-parameters, seeds), so rerunning the same comparison finds its finished runs and
skips them, while a changed comparison gets a new key.  Each run is one row, written in its
own transaction as soon as it finishes; SQLite's journal makes the write atomic, so killing
the process at any moment (even ``kill -9``) leaves either the whole row or none of it.

Notes
-----
The file has two tables.

``comparisons(key, name, spec, created)``
    ``spec`` is the JSON of the comparison's specification.
``runs(key, label, run, seed, status, error, payload, created)``
    One row per (comparison, optimiser label, run index); ``status`` is ``"ok"`` or
    ``"failed"``; ``payload`` is the JSON of the run record (costs, FE, history, fits...).
"""

from __future__ import annotations

import json
import os
import sqlite3
import time
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

from .errors import StoreError

__all__ = ["ResultStore"]

_SCHEMA = """
CREATE TABLE IF NOT EXISTS comparisons (
    key      TEXT PRIMARY KEY,
    name     TEXT NOT NULL,
    spec     TEXT NOT NULL,
    created  REAL NOT NULL
);
CREATE TABLE IF NOT EXISTS runs (
    key      TEXT NOT NULL REFERENCES comparisons(key),
    label    TEXT NOT NULL,
    run      INTEGER NOT NULL,
    seed     INTEGER NOT NULL,
    status   TEXT NOT NULL CHECK (status IN ('ok', 'failed')),
    error    TEXT,
    payload  TEXT NOT NULL,
    created  REAL NOT NULL,
    PRIMARY KEY (key, label, run)
);
CREATE TABLE IF NOT EXISTS meta (
    name   TEXT PRIMARY KEY,
    value  TEXT NOT NULL
);
"""
_STORE_VERSION = "1"


class ResultStore:
    """A comparison result store in one SQLite file.

    Parameters
    ----------
    path : path-like
        The SQLite file; created (with its folder) if missing.
    readonly : bool, optional
        Open an existing store for reading only (``flexid report``).

    Raises
    ------
    StoreError
        If the file cannot be opened or is not a flexid store.
    """

    def __init__(self, path: str | os.PathLike, *, readonly: bool = False) -> None:
        self.path = Path(path)
        if readonly and not self.path.is_file():
            raise StoreError(f"{self.path}: no such result store")
        try:
            if not readonly:
                self.path.parent.mkdir(parents=True, exist_ok=True)
            uri = f"file:{self.path}?mode=ro" if readonly else f"file:{self.path}"
            self._db = sqlite3.connect(uri, uri=True, timeout=30.0, isolation_level=None)
            if not readonly:
                self._db.execute("PRAGMA journal_mode=WAL")
                self._db.execute("PRAGMA synchronous=NORMAL")
                self._db.executescript(_SCHEMA)
                self._db.execute(
                    "INSERT OR IGNORE INTO meta(name, value) VALUES ('flexid_store', ?)",
                    (_STORE_VERSION,),
                )
            row = self._db.execute("SELECT value FROM meta WHERE name = 'flexid_store'").fetchone()
        except sqlite3.DatabaseError as exc:
            raise StoreError(f"{self.path}: not a readable flexid result store ({exc})") from None
        except OSError as exc:
            raise StoreError(f"{self.path}: cannot open ({exc})") from None
        if row is None:
            raise StoreError(f"{self.path}: not a flexid result store")

    # ----------------------------------------------------------------- context manager
    def close(self) -> None:
        """Close the database connection."""
        self._db.close()

    def __enter__(self) -> ResultStore:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ----------------------------------------------------------------- comparisons
    def add_comparison(self, key: str, name: str, spec: Mapping[str, Any]) -> None:
        """Record a comparison, or update the one stored under the same key.

        A rerun with the same key (more runs, other optimisers) replaces the stored name and
        specification; the runs already finished stay.

        Parameters
        ----------
        key : str
            The comparison's key (:attr:`flexid.ComparisonSpec.key`).
        name : str
            Its name.
        spec : mapping
            Its specification (:meth:`flexid.ComparisonSpec.to_dict`), stored as JSON.

        Raises
        ------
        StoreError
            If the write fails (for example in a read-only store).
        """
        self._execute(
            "INSERT INTO comparisons(key, name, spec, created) VALUES (?, ?, ?, ?) "
            "ON CONFLICT(key) DO UPDATE SET name = excluded.name, spec = excluded.spec",
            (key, name, json.dumps(spec, sort_keys=True), time.time()),
        )

    def comparisons(self) -> list[dict[str, Any]]:
        """All comparisons in the store, oldest first.

        Returns
        -------
        list of dict
            One dict per comparison: ``key``, ``name``, ``spec`` (dict), ``created``
            (seconds since the epoch) and ``n_runs`` (stored runs, failed ones included).
        """
        rows = self._query(
            "SELECT c.key, c.name, c.spec, c.created, COUNT(r.run) FROM comparisons c "
            "LEFT JOIN runs r ON r.key = c.key GROUP BY c.key ORDER BY c.created, c.key"
        )
        return [
            {"key": k, "name": n, "spec": json.loads(s), "created": t, "n_runs": c}
            for k, n, s, t, c in rows
        ]

    def comparison(self, key: str) -> dict[str, Any]:
        """One comparison by key.

        Parameters
        ----------
        key : str
            The key, or a prefix of it that only one comparison has.

        Returns
        -------
        dict
            ``key`` (the full key), ``name``, ``spec`` (dict) and ``created`` (seconds since
            the epoch).

        Raises
        ------
        StoreError
            If no comparison or more than one matches.
        """
        rows = self._query(
            "SELECT key, name, spec, created FROM comparisons WHERE key LIKE ?", (key + "%",)
        )
        if not rows:
            raise StoreError(f"{self.path}: no comparison with key {key!r}")
        if len(rows) > 1:
            raise StoreError(f"{self.path}: key prefix {key!r} is ambiguous")
        k, n, s, t = rows[0]
        return {"key": k, "name": n, "spec": json.loads(s), "created": t}

    # ----------------------------------------------------------------- runs
    def finished(self, key: str, *, include_failed: bool = True) -> set[tuple[str, int]]:
        """The runs already stored for a comparison.

        Parameters
        ----------
        key : str
            The comparison's full key.
        include_failed : bool, optional
            Count failed runs as finished too (default True); False lists ``ok`` runs only,
            so that failed ones are run again.

        Returns
        -------
        set of (str, int)
            ``(optimiser label, run index)`` pairs.
        """
        sql = "SELECT label, run FROM runs WHERE key = ?"
        if not include_failed:
            sql += " AND status = 'ok'"
        return {(label, int(run)) for label, run in self._query(sql, (key,))}

    def write_run(self, key: str, record: Mapping[str, Any]) -> None:
        """Write one finished run at once (its own transaction).

        Writing the same (key, label, run) again replaces the row, so a retried failed run
        does not duplicate.

        Parameters
        ----------
        key : str
            The comparison's full key.
        record : mapping
            The run record, stored whole as JSON (NaN and infinity allowed).  It needs
            ``label`` (str), ``run`` (int), ``seed`` (int) and ``status`` (``"ok"`` or
            ``"failed"``); ``error`` (str) is optional.

        Raises
        ------
        StoreError
            If the record is not JSON-serialisable or the write fails.
        KeyError
            If a required key is missing.
        """
        try:
            payload = json.dumps(record, sort_keys=True, allow_nan=True)
        except (TypeError, ValueError) as exc:
            raise StoreError(f"run record is not JSON-serialisable: {exc}") from None
        self._execute(
            "INSERT OR REPLACE INTO runs(key, label, run, seed, status, error, payload, created) "
            "VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
            (
                key,
                str(record["label"]),
                int(record["run"]),
                int(record["seed"]),
                str(record["status"]),
                record.get("error"),
                payload,
                time.time(),
            ),
        )

    def runs(self, key: str) -> list[dict[str, Any]]:
        """All run records of a comparison.

        Parameters
        ----------
        key : str
            The comparison's full key.

        Returns
        -------
        list of dict
            The records as written by :meth:`write_run`, ordered by label then run index
            (empty for an unknown key).
        """
        rows = self._query("SELECT payload FROM runs WHERE key = ? ORDER BY label, run", (key,))
        return [json.loads(p) for (p,) in rows]

    def iter_runs(self, key: str) -> Iterator[dict[str, Any]]:
        """Iterate over the run records of a comparison without loading them all.

        Parameters
        ----------
        key : str
            The comparison's full key.

        Yields
        ------
        dict
            One record as written by :meth:`write_run`, ordered by label then run index.
        """
        cursor = self._db.execute(
            "SELECT payload FROM runs WHERE key = ? ORDER BY label, run", (key,)
        )
        for (payload,) in cursor:
            yield json.loads(payload)

    def count(self, key: str) -> dict[str, int]:
        """Number of stored runs of a comparison, by status.

        Parameters
        ----------
        key : str
            The comparison's full key.

        Returns
        -------
        dict of str to int
            ``{"ok": n_ok, "failed": n_failed}``.
        """
        counts = {"ok": 0, "failed": 0}
        for status, n in self._query(
            "SELECT status, COUNT(*) FROM runs WHERE key = ? GROUP BY status", (key,)
        ):
            counts[status] = int(n)
        return counts

    # ----------------------------------------------------------------- internals
    def _execute(self, sql: str, args: tuple = ()) -> None:
        try:
            with self._db:
                self._db.execute(sql, args)
        except sqlite3.DatabaseError as exc:
            raise StoreError(f"{self.path}: write failed ({exc})") from None

    def _query(self, sql: str, args: tuple = ()) -> list[tuple]:
        try:
            return self._db.execute(sql, args).fetchall()
        except sqlite3.DatabaseError as exc:
            raise StoreError(f"{self.path}: read failed ({exc})") from None
