"""SQLite result store: every finished run is written at once, so an interrupted comparison resumes.

One file holds any number of comparisons.  A comparison is keyed by a hash of everything
that determines its numbers (data, model orders, cost, search box, budget, optimisers and
their hyper-parameters, seeds), so rerunning the same comparison finds its finished runs and
skips them, while a changed comparison gets a new key.  Each run is one row, written in its
own transaction as soon as it finishes; SQLite's journal makes the write atomic, so killing
the process at any moment (even ``kill -9``) leaves either the whole row or none of it.  A
row whose record cannot be read back (a damaged payload) is skipped with a
:class:`~flexid.errors.StoreWarning` naming it and counts as not finished, so a rerun of its
comparison runs it again and replaces it.

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
import warnings
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

from ..errors import StoreError, StoreWarning

__all__ = ["ResultStore"]

_STORE_VERSION = "1"
# One transaction: a file holds either all of flexid's tables and its marker row or none
_SCHEMA = f"""
BEGIN;
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
INSERT OR IGNORE INTO meta(name, value) VALUES ('flexid_store', '{_STORE_VERSION}');
COMMIT;
"""
#: The columns each table of a flexid store has (those of ``_SCHEMA``).
_COLUMNS = {
    "comparisons": ("key", "name", "spec", "created"),
    "runs": ("key", "label", "run", "seed", "status", "error", "payload", "created"),
    "meta": ("name", "value"),
}
_SQLITE_READONLY = 8  # primary result code of SQLITE_READONLY and its extended codes
_SQLITE_IOERR = 10  # SQLITE_IOERR: a write the file system refused (a full disk among them)
_SQLITE_FULL = 13  # SQLITE_FULL: "database or disk is full"
#: Free bytes below which an I/O error of a write is read as a full disk: SQLite writes a
#: store in pages of 4 KiB plus its log, so a folder with less than this cannot take a run.
_FULL_BELOW = 1 << 20


class ResultStore:
    """A comparison result store in one SQLite file.

    Opening never writes into a file that is not a flexid store: an existing non-empty file
    must be one (or an SQLite database without tables), else it is left byte for byte as it
    was.  A store opened ``readonly`` is read without creating ``-wal`` or ``-shm`` files
    when no writer is at work, so a store in a folder the user cannot write can be read.

    Parameters
    ----------
    path : path-like
        The SQLite file; created (with its folder) if missing.
    readonly : bool, optional
        Open an existing store for reading only (``flexid report``).

    Raises
    ------
    StoreError
        If the file cannot be opened, is not a flexid store, or is read-only and
        ``readonly`` is False.
    """

    def __init__(self, path: str | os.PathLike, *, readonly: bool = False) -> None:
        self.path = Path(path)
        if readonly and not self.path.is_file():
            raise StoreError(f"{self.path}: no such result store")
        try:
            self._db = self._open_readonly() if readonly else self._open_for_writing()
        except sqlite3.DatabaseError as exc:
            full = _full_disk_message(self.path, exc)
            if full is not None:
                raise StoreError(full) from None
            raise StoreError(f"{self.path}: not a readable flexid result store ({exc})") from None
        except OSError as exc:
            full = _full_disk_message(self.path, exc)
            raise StoreError(full or f"{self.path}: cannot open ({exc})") from None

    def _open_readonly(self) -> sqlite3.Connection:
        db = self._connect_readonly()
        try:
            problem = _schema_problem(db, empty_ok=False)
        except BaseException:
            db.close()
            raise
        if problem is not None:
            db.close()
            raise StoreError(f"{self.path}: not a flexid result store ({problem})")
        return db

    def _connect_readonly(self) -> sqlite3.Connection:
        # With no log beside the file, every committed row is in the file itself: read it as
        # immutable, which creates no -wal/-shm files and needs no write access to the
        # folder.  A log means a writer may be at work: then read through SQLite's locks.
        # (A writer that starts while an immutable read is under way changes the file only
        # when it checkpoints, after 1000 pages or when it closes.)
        logs = (self.path.with_name(self.path.name + suffix) for suffix in ("-wal", "-journal"))
        query = "mode=ro" if any(p.exists() for p in logs) else "mode=ro&immutable=1"
        uri = f"{self.path.absolute().as_uri()}?{query}"
        return sqlite3.connect(uri, uri=True, timeout=30.0, isolation_level=None)

    def _open_for_writing(self) -> sqlite3.Connection:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        if self.path.exists() and not os.access(self.path, os.W_OK):
            raise StoreError(self._readonly_message("no permission to write the file"))
        if not os.access(self.path.parent, os.W_OK | os.X_OK):
            raise StoreError(
                self._readonly_message(
                    f"no permission to write its folder {self.path.parent}, where SQLite "
                    "keeps the store's -wal and -shm files"
                )
            )
        if self.path.is_file() and self.path.stat().st_size > 0:
            # checked read-only, before the first write: a foreign file stays as it was
            probe = self._connect_readonly()
            try:
                problem = _schema_problem(probe, empty_ok=True)
            finally:
                probe.close()
            if problem is not None:
                raise StoreError(
                    f"{self.path}: not a flexid result store ({problem}); it was left "
                    "untouched: give another store file"
                )
        db = sqlite3.connect(
            self.path.absolute().as_uri(), uri=True, timeout=30.0, isolation_level=None
        )
        try:
            db.execute("PRAGMA journal_mode=WAL")
            db.execute("PRAGMA synchronous=NORMAL")
            db.executescript(_SCHEMA)
        except sqlite3.DatabaseError as exc:
            db.close()
            if _is_readonly_error(exc):
                raise StoreError(self._readonly_message(str(exc))) from None
            raise
        return db

    def _readonly_message(self, why: str) -> str:
        return (
            f"{self.path}: the result store is read-only ({why}); runs cannot be written "
            "into it (flexid report reads it as it is)"
        )

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

        A damaged run record (see :meth:`runs`) is not finished: a rerun replaces it.

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
        return {
            (r["label"], r["run"])
            for r in self._records(key)
            if include_failed or r["status"] == "ok"
        }

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

        Warns
        -----
        StoreWarning
            Naming, in one line, the damaged records left out: a payload that is not UTF-8
            JSON of a run record, or whose label, run index or status is not its row's.
        """
        return list(self._records(key))

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

        Warns
        -----
        StoreWarning
            At the end, naming the damaged records left out (as :meth:`runs`).
        """
        yield from self._records(key)

    def has_run(self, key: str, label: str, run: int) -> bool:
        """Whether the store has a row for this run, readable or damaged.

        Tells a damaged record (:meth:`runs` leaves it out) from one not written yet.

        Parameters
        ----------
        key : str
            The comparison's full key.
        label : str
            The optimiser's label (``"ls"`` for the least-squares row).
        run : int
            The run index.

        Returns
        -------
        bool
        """
        return bool(
            self._query(
                "SELECT 1 FROM runs WHERE key = ? AND label = ? AND run = ?", (key, label, run)
            )
        )

    def count(self, key: str) -> dict[str, int]:
        """Number of stored runs of a comparison, by status.

        Parameters
        ----------
        key : str
            The comparison's full key.

        Returns
        -------
        dict of str to int
            ``{"ok": n_ok, "failed": n_failed}``, by the rows' status (damaged records
            included).
        """
        counts = {"ok": 0, "failed": 0}
        for status, n in self._query(
            "SELECT status, COUNT(*) FROM runs WHERE key = ? GROUP BY status", (key,)
        ):
            counts[status] = int(n)
        return counts

    # ----------------------------------------------------------------- internals
    def _records(self, key: str) -> Iterator[dict[str, Any]]:
        """The readable run records of a comparison; one warning names the damaged ones."""
        # read as bytes and decoded here: SQLite returns TEXT that is not UTF-8 as it is, and
        # the sqlite3 module would raise on it instead of returning the row
        sql = (
            "SELECT CAST(label AS BLOB), run, status, CAST(payload AS BLOB) FROM runs "
            "WHERE key = ? ORDER BY label, run"
        )
        damaged = []
        try:
            for label, run, status, payload in self._db.execute(sql, (key,)):
                record = _decode_run(label, run, status, payload)
                if record is None:
                    damaged.append(f"{_text(label)!r} run {run}")
                else:
                    yield record
        except sqlite3.DatabaseError as exc:
            raise StoreError(f"{self.path}: read failed ({exc})") from None
        if damaged:
            warnings.warn(
                f"{self.path}: comparison {self._name(key)!r} [{key}]: skipped "
                f"{len(damaged)} damaged run record(s) (not UTF-8 JSON of their run): "
                f"{', '.join(damaged)}; a rerun of the comparison runs them again",
                StoreWarning,
                stacklevel=1,  # one place: the same damage met twice in one command shows once
            )

    def _name(self, key: str) -> str:
        """The name of a comparison, for messages ("?" if it cannot be read)."""
        try:
            row = self._db.execute(
                "SELECT CAST(name AS BLOB) FROM comparisons WHERE key = ?", (key,)
            ).fetchone()
        except sqlite3.DatabaseError:
            return "?"
        return "?" if row is None else _text(row[0])

    def _execute(self, sql: str, args: tuple = ()) -> None:
        try:
            with self._db:
                self._db.execute(sql, args)
        except sqlite3.DatabaseError as exc:
            full = _full_disk_message(self.path, exc)
            raise StoreError(full or f"{self.path}: write failed ({exc})") from None

    def _query(self, sql: str, args: tuple = ()) -> list[tuple]:
        try:
            return self._db.execute(sql, args).fetchall()
        except sqlite3.DatabaseError as exc:
            raise StoreError(f"{self.path}: read failed ({exc})") from None


def _text(value: bytes | str | None) -> str:
    """A stored name as text, whatever bytes it holds."""
    if isinstance(value, bytes):
        return value.decode("utf-8", errors="replace")
    return str(value)


def _decode_run(label: bytes, run: Any, status: Any, payload: bytes | None) -> dict | None:
    """The run record of one row, or None if its payload is damaged.

    A payload is damaged when it is not UTF-8, not JSON, not an object, or names another
    label, run index or status than its row (a row is found by those columns).
    """
    if not isinstance(label, bytes) or not isinstance(payload, bytes):
        return None
    try:
        record = json.loads(payload.decode("utf-8"))
        label_text = label.decode("utf-8")
    except ValueError:  # UnicodeDecodeError and json.JSONDecodeError are ValueErrors
        return None
    if not isinstance(record, dict):
        return None
    same = (str(record.get("label")), record.get("run"), str(record.get("status")))
    return record if same == (label_text, run, status) else None


def _full_disk_message(path: Path, exc: BaseException) -> str | None:
    """The message for a write the disk had no room for, or None for any other failure.

    SQLite says "database or disk is full" (SQLITE_FULL), or only "disk I/O error" when the
    log could not grow; the second is read as a full disk when the store's folder has less
    than ``_FULL_BELOW`` bytes free.  SQLite rolls back a transaction it cannot finish, so
    every run written before is still in the store.
    """
    import errno
    import shutil

    code = getattr(exc, "sqlite_errorcode", None)
    primary = None if code is None else code & 0xFF
    if primary != _SQLITE_FULL and getattr(exc, "errno", None) != errno.ENOSPC:
        if primary != _SQLITE_IOERR and "disk I/O error" not in str(exc):
            return None
        try:
            if shutil.disk_usage(path.absolute().parent).free >= _FULL_BELOW:
                return None
        except OSError:
            return None
    return (
        f"{path}: the disk is full; the store is intact (its runs are kept): free space, rerun"
    )


def _is_readonly_error(exc: sqlite3.DatabaseError) -> bool:
    """Whether SQLite refused a write because the file or its folder is read-only."""
    code = getattr(exc, "sqlite_errorcode", None)  # Python >= 3.11
    if code is not None:
        return code & 0xFF == _SQLITE_READONLY
    return "readonly database" in str(exc)


def _schema_problem(db: sqlite3.Connection, *, empty_ok: bool) -> str | None:
    """Why the database ``db`` is not a flexid store, or None if it is one.

    Only reads.  A database without tables passes when ``empty_ok`` (it becomes a store).
    """
    objects = [
        (kind, name)
        for kind, name in db.execute("SELECT type, name FROM sqlite_master").fetchall()
        if not name.startswith("sqlite_")  # SQLite's own (autoindexes, statistics)
    ]
    if not objects:
        return None if empty_ok else "it has no tables"
    foreign = sorted(
        f"{kind} {name!r}" for kind, name in objects if kind != "table" or name not in _COLUMNS
    )
    if foreign:
        return f"it has {', '.join(foreign)}, which a flexid store has not"
    tables = {name for _, name in objects}
    for table in sorted(tables):
        columns = {row[1] for row in db.execute(f"PRAGMA table_info({table})")}
        missing = [c for c in _COLUMNS[table] if c not in columns]
        if missing:
            return f"its table {table!r} has no column(s) {', '.join(missing)}"
    absent = [table for table in _COLUMNS if table not in tables]
    if absent:
        return f"it has no table(s) {', '.join(map(repr, absent))}"
    if db.execute("SELECT 1 FROM meta WHERE name = 'flexid_store'").fetchone() is None:
        return "its table 'meta' has no flexid marker"
    return None
