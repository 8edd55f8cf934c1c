"""Record files: CSV, DAT and MATLAB ``.mat`` files read into arrays, and atomic writes.

Nothing here builds an :class:`~flexid.data.IOData`: a reader returns the arrays and the
keyword arguments of a record (:class:`RecordParts`), which :mod:`flexid.data` turns into
one, so the file formats sit below the record type and never import it.

MATLAB files (formats v4, v5 and v7). Two layouts are understood:

* **an iddata-like structure**: a struct variable with the fields ``y`` and ``u`` (or
  ``OutputData`` and ``InputData``) and ``Ts``, as MATLAB gives with ``s = struct(data)``
  or ``s = get(data)`` for an ``iddata`` object; ``OutputName``/``InputName``,
  ``OutputUnit``/``InputUnit`` and ``TimeUnit`` are used when present;
* **plain variables**: ``inputs``/``outputs`` name the variables (``"u"``), one column of
  a matrix (``"X[1]"``, 0-based) or, as integers, columns of the file's only matrix; by
  default the variables ``u``/``u<k>`` are inputs and ``y``/``y<k>`` outputs, as in a CSV
  file.  The sample time is ``dt``, else a ``Ts``/``dt`` variable, else the step of a
  ``t``/``time`` variable, else 1.0 (recorded as assumed).

MATLAB stores one channel per column, so an ``(N, k)`` matrix is ``N`` samples of ``k``
channels; row and column vectors are both one channel.  v7.3 files are HDF5, which
:func:`scipy.io.loadmat` does not read: they get an error that says how to convert them.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import re
import warnings
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from .._validate import is_integer
from ..errors import DataError, DataFileError, _unreadable, check_finite

__all__ = [
    "CSV_MAGIC",
    "RecordParts",
    "median_step",
    "read_csv",
    "read_dat",
    "read_mat",
    "write_bytes",
    "write_files",
    "write_text",
]

#: First characters of the metadata line of a CSV file written by flexid.
CSV_MAGIC = "# flexid-iodata "


class RecordParts(NamedTuple):
    """A record as a file holds it: what :class:`~flexid.data.IOData` is built from.

    Attributes
    ----------
    u : ndarray, shape (N, n_u)
    y : ndarray, shape (N, n_y)
    dt : float
        Sample time [s].
    options : dict
        The other keyword arguments of :class:`~flexid.data.IOData` (names, units,
        metadata).
    channels : tuple or None
        ``(inputs, outputs, where)``: the channels to keep of the record
        (:meth:`~flexid.data.IOData.select`), and what in the file they are chosen from (for
        the error message); None keeps all.
    """

    u: np.ndarray
    y: np.ndarray
    dt: float
    options: dict[str, Any]
    channels: tuple[Any, Any, str] | None = None

_HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
#: MATLAB writes a 512-byte text header before the HDF5 superblock of a v7.3 file.
_V73_USERBLOCK = 512
_V73_FIX = (
    "in MATLAB save it again with save(file, ..., '-v7') (v7.3 files are HDF5, which "
    "scipy.io.loadmat cannot read), or read the arrays with h5py and build "
    "flexid.IOData(u, y, dt)"
)
_OBJECT_FIX = (
    "scipy cannot read MATLAB objects; in MATLAB convert it first, e.g. s = struct(data) "
    "or s.u = data.u; s.y = data.y; s.Ts = data.Ts, and save s with -v7"
)
_COLUMN = re.compile(r"^(?P<name>.+)\[(?P<col>\d+)\]$")
#: Seconds per unit of iddata's ``TimeUnit`` (MATLAB's names).
_TIME_UNITS = {
    "": 1.0,
    "seconds": 1.0,
    "nanoseconds": 1e-9,
    "microseconds": 1e-6,
    "milliseconds": 1e-3,
    "minutes": 60.0,
    "hours": 3600.0,
    "days": 86400.0,
    "weeks": 604800.0,
}
_SAMPLE_TIME_NAMES = ("Ts", "ts", "TS", "dt", "Dt", "DT")
_TIME_NAMES = ("t", "time", "Time", "T")


def read_mat(
    path: str | os.PathLike,
    inputs: Sequence[str | int] | str | int | None = None,
    outputs: Sequence[str | int] | str | int | None = None,
    dt: float | None = None,
    *,
    variable: str | None = None,
    metadata: Mapping[str, Any] | None = None,
) -> RecordParts:
    """The parts of the record in a MATLAB file (:meth:`flexid.data.IOData.from_mat`).

    Parameters
    ----------
    path : path-like
    inputs, outputs, dt, variable, metadata
        As :meth:`flexid.data.IOData.from_mat` takes them.

    Returns
    -------
    RecordParts
    """
    path = Path(path)
    contents, version = _load(path)
    meta: dict[str, Any] = {"source": str(path), "mat_format": version}
    struct_name = _pick_struct(path, contents, variable, inputs, outputs)
    if struct_name is not None:
        data = _from_struct(path, struct_name, contents[struct_name], inputs, outputs, dt, meta)
    else:
        data = _from_variables(path, contents, variable, inputs, outputs, dt, meta)
    if metadata:
        data.options["metadata"].update(metadata)
    return data


# ---------------------------------------------------------------------- reading
def _load(path: Path) -> tuple[dict[str, Any], str]:
    """The file's variables (structs as dicts, cells as lists/object arrays) and format."""
    from scipy.io import loadmat
    from scipy.io.matlab import MatReadError, matfile_version

    try:
        with open(path, "rb") as handle:
            head = handle.read(_V73_USERBLOCK + len(_HDF5_SIGNATURE))
    except OSError as exc:
        raise _unreadable(path, exc) from None
    if head.startswith(_HDF5_SIGNATURE) or head[_V73_USERBLOCK:].startswith(_HDF5_SIGNATURE):
        raise DataFileError(f"{path}: a MATLAB v7.3 (HDF5) file; {_V73_FIX}")
    if not head:
        raise DataFileError(f"{path}: empty file, not a MAT file")
    try:
        with open(path, "rb") as handle:
            major, _minor = matfile_version(handle)
        if major == 2:
            raise NotImplementedError("v7.3")
        contents = loadmat(path, simplify_cells=True, chars_as_strings=True)
    except NotImplementedError:
        raise DataFileError(f"{path}: a MATLAB v7.3 (HDF5) file; {_V73_FIX}") from None
    except (MatReadError, ValueError, TypeError, OSError, EOFError, KeyError, IndexError) as exc:
        # MatReadError (a file cut inside its header) derives from Exception alone
        raise DataFileError(f"{path}: not a readable MAT file ({exc})") from None
    variables = {k: v for k, v in contents.items() if not k.startswith("__")}
    return variables, "4" if major == 0 else "5"


def _is_struct(value: Any) -> bool:
    return isinstance(value, dict)


def _looks_like_iddata(value: Any) -> bool:
    if not _is_struct(value):
        return False
    keys = {k.lower() for k in value}
    return bool(keys & {"y", "outputdata"})


def _pick_struct(
    path: Path, contents: Mapping[str, Any], variable: str | None, inputs: Any, outputs: Any
) -> str | None:
    """The name of the structure to read, or ``None`` for plain variables."""
    if variable is not None:
        if variable not in contents:
            raise DataError(f"{path}: no variable {variable!r}; variables: {_listing(contents)}")
        value = contents[variable]
        if _is_struct(value):
            return variable
        _reject_special(path, variable, value)
        return None
    for name, value in contents.items():
        _reject_special(path, name, value, only_objects=True)
    named = _requested_variables(inputs) | _requested_variables(outputs)
    if named and named <= set(contents):
        return None
    candidates = [k for k, v in contents.items() if _looks_like_iddata(v)]
    if not candidates:
        for name, value in contents.items():
            if isinstance(value, list) and any(_looks_like_iddata(v) for v in value):
                _reject_special(path, name, value)
    if len(candidates) > 1:
        raise DataError(
            f"{path}: several structures hold a record ({', '.join(candidates)}); choose one "
            "with variable=... (--variable on the command line)"
        )
    return candidates[0] if candidates else None


def _requested_variables(which: Any) -> set[str]:
    if which is None or isinstance(which, (int, np.integer)):
        return set()
    items = [which] if isinstance(which, str) else list(which)
    out = set()
    for item in items:
        if isinstance(item, str):
            match = _COLUMN.match(item)
            out.add(match.group("name") if match else item)
    return out


def _reject_special(path: Path, name: str, value: Any, only_objects: bool = False) -> None:
    """Raise for a MATLAB object or a struct array, which flexid cannot read as a record."""
    from scipy.io.matlab import MatlabFunction, MatlabOpaque

    if isinstance(value, (MatlabOpaque, MatlabFunction)):
        raise DataFileError(f"{path}: variable {name!r} is a MATLAB object; {_OBJECT_FIX}")
    if only_objects:
        return
    if isinstance(value, list) and value and all(_is_struct(v) for v in value):
        raise DataFileError(
            f"{path}: variable {name!r} is an array of {len(value)} structures; flexid reads "
            "one record: save one element, e.g. s = s(1)"
        )


def _listing(contents: Mapping[str, Any]) -> str:
    return ", ".join(sorted(contents)) or "none"


# ---------------------------------------------------------------------- values
def _numeric(path: Path, what: str, value: Any) -> np.ndarray:
    """A real float array of 1 or 2 dimensions, ``(N,)`` or ``(N, k)``; errors name ``what``."""
    if hasattr(value, "toarray"):  # a MATLAB sparse matrix
        value = value.toarray()
    if isinstance(value, (str, bytes)):
        raise DataError(f"{path}: {what} is text ({value[:40]!r}), not numbers")
    if _is_struct(value):
        raise DataError(f"{path}: {what} is a structure, not numbers")
    array = np.asarray(value)
    if array.dtype == object or isinstance(value, list):
        raise DataFileError(
            f"{path}: {what} is a cell array; a multi-experiment record (cells of signals) "
            "is not supported: save one experiment, e.g. getexp(data, 1) in MATLAB"
        )
    if array.dtype.kind == "c":
        raise DataError(f"{path}: {what} is complex; flexid needs real signals")
    if array.dtype.kind not in "biuf":
        raise DataError(f"{path}: {what} is not numeric (type {array.dtype})")
    array = array.astype(float)
    if array.ndim == 0:
        array = array.reshape(1)
    if array.size == 0:
        raise DataError(f"{path}: {what} is empty")
    if array.ndim > 2:
        raise DataError(
            f"{path}: {what} has shape {array.shape}; a signal is a vector or a "
            "(samples x channels) matrix"
        )
    check_finite(array, f"{path}: {what}")
    return array


def _columns(array: np.ndarray) -> np.ndarray:
    return array[:, None] if array.ndim == 1 else array


def _scalar_time(path: Path, what: str, value: Any) -> float | None:
    """A positive sample time from a scalar; ``None`` for MATLAB's empty ``[]``."""
    if isinstance(value, np.ndarray) and value.size == 0:
        return None
    array = _numeric(path, what, value)
    if array.size != 1:
        raise DataError(f"{path}: {what} must be one number (the sample time), got {array.size}")
    ts = float(array.reshape(-1)[0])
    if not (math.isfinite(ts) and ts > 0):
        raise DataError(f"{path}: {what} must be a positive sample time, got {ts!r}")
    return ts


def _texts(value: Any) -> list[str] | None:
    """Names or units from a string, a cell array of strings or a char matrix."""
    if value is None:
        return None
    if isinstance(value, str):
        return [value]
    if isinstance(value, np.ndarray) and value.size == 0:
        return None
    items = np.asarray(value, dtype=object).reshape(-1).tolist()
    if not all(isinstance(item, str) for item in items):
        return None
    return [item.strip() for item in items]


def _field(struct: Mapping[str, Any], *names: str) -> tuple[str, Any] | None:
    """The first of ``names`` present in ``struct``, exact spelling first, then any case."""
    for name in names:
        if name in struct:
            return name, struct[name]
    lowered = {k.lower(): k for k in struct}
    for name in names:
        key = lowered.get(name.lower())
        if key is not None:
            return key, struct[key]
    return None


# ---------------------------------------------------------------------- structures
def _from_struct(
    path: Path,
    name: str,
    struct: Mapping[str, Any],
    inputs: Any,
    outputs: Any,
    dt: float | None,
    meta: dict[str, Any],
) -> RecordParts:
    meta["mat_variable"] = name
    found_y = _field(struct, "y", "OutputData")
    found_u = _field(struct, "u", "InputData")
    if found_y is None:
        raise DataError(
            f"{path}: structure {name!r} has no output field (y or OutputData); fields: "
            f"{_listing(struct)}"
        )
    if found_u is None or (isinstance(found_u[1], np.ndarray) and found_u[1].size == 0):
        raise DataError(
            f"{path}: structure {name!r} has no input (u or InputData): a time series; "
            "an ARX model needs an input"
        )
    y = _columns(_numeric(path, f"variable {name!r}, field {found_y[0]!r}", found_y[1]))
    u = _columns(_numeric(path, f"variable {name!r}, field {found_u[0]!r}", found_u[1]))
    if u.shape[0] != y.shape[0]:
        raise DataError(
            f"{path}: structure {name!r}: the input {found_u[0]!r} has {u.shape[0]} samples and "
            f"the output {found_y[0]!r} has {y.shape[0]}"
        )
    if dt is None:
        dt = _struct_sample_time(path, name, struct, u.shape[0], meta)

    def texts(field: str, count: int) -> list[str] | None:
        found = _field(struct, field)
        values = _texts(found[1]) if found else None
        if values is None or len(values) != count or not all(values):
            return None
        return values

    data = _record(
        path,
        u,
        y,
        dt,
        texts("InputName", u.shape[1]),
        texts("OutputName", y.shape[1]),
        meta,
        input_units=texts("InputUnit", u.shape[1]),
        output_units=texts("OutputUnit", y.shape[1]),
    )
    if inputs is not None or outputs is not None:
        data = data._replace(channels=(inputs, outputs, f"structure {name!r}"))
    return data


def _struct_sample_time(
    path: Path, name: str, struct: Mapping[str, Any], n_samples: int, meta: dict[str, Any]
) -> float:
    found = _field(struct, "Ts", "dt")
    ts = _scalar_time(path, f"variable {name!r}, field {found[0]!r}", found[1]) if found else None
    unit_field = _field(struct, "TimeUnit")
    unit = _texts(unit_field[1]) if unit_field else None
    unit_name = unit[0].lower() if unit else ""
    if unit_name not in _TIME_UNITS:
        raise DataError(
            f"{path}: variable {name!r}, field 'TimeUnit': unknown unit {unit[0]!r}; known: "
            f"{', '.join(sorted(k for k in _TIME_UNITS if k))}"
        )
    scale = _TIME_UNITS[unit_name]
    if ts is not None:
        return ts * scale
    instants = _field(struct, "SamplingInstants")
    if instants is not None and not (isinstance(instants[1], np.ndarray) and instants[1].size == 0):
        times = _numeric(path, f"variable {name!r}, field {instants[0]!r}", instants[1])
        where = f"{name}.{instants[0]}"
        return _step_of(times.reshape(-1), n_samples, path, where, meta) * scale
    meta["dt_assumed"] = True
    return 1.0


def _step_of(times: np.ndarray, n_samples: int, path: Path, what: str, meta: dict) -> float:
    """The median step of a time vector of ``n_samples`` entries; a note if not uniform."""
    if times.size != n_samples:
        raise DataError(
            f"{path}: the time vector {what!r} has {times.size} entries for {n_samples} samples"
        )
    step, uniform = median_step(times)
    if not (math.isfinite(step) and step > 0):
        raise DataError(f"{path}: the time vector {what!r} is not increasing")
    if not uniform:
        meta["dt_note"] = f"time vector {what!r} not uniform; dt is its median step"
    return step


# ---------------------------------------------------------------------- plain variables
def _from_variables(
    path: Path,
    contents: Mapping[str, Any],
    variable: str | None,
    inputs: Any,
    outputs: Any,
    dt: float | None,
    meta: dict[str, Any],
) -> RecordParts:
    def default(prefix: str) -> list[str]:
        return sorted(
            (k for k in contents if k == prefix or (k.startswith(prefix) and k[1:].isdigit())),
            key=lambda k: (len(k), k),
        )

    if inputs is None and outputs is None and variable is None:
        ins, outs = default("u"), default("y")
        if not ins or not outs:
            raise DataError(
                f"{path}: no iddata-like structure and no variables u and y; name the inputs "
                f"and outputs (inputs=..., outputs=..., or --inputs/--outputs); variables: "
                f"{_listing(contents)}"
            )
    else:
        if inputs is None or outputs is None:
            raise DataError(
                f"{path}: name both the inputs and the outputs (variables, 'X[j]' columns or "
                f"column indices); variables: {_listing(contents)}"
            )
        ins, outs = inputs, outputs
    u, u_names = _gather(path, contents, variable, ins, "input")
    y, y_names = _gather(path, contents, variable, outs, "output")
    if u.shape[0] != y.shape[0]:
        raise DataError(
            f"{path}: the inputs {u_names} have {u.shape[0]} samples and the outputs "
            f"{y_names} have {y.shape[0]} (MATLAB stores one channel per column)"
        )
    if dt is None:
        dt = _variables_sample_time(path, contents, u.shape[0], meta)
    return _record(path, u, y, dt, u_names, y_names, meta)


def _gather(
    path: Path, contents: Mapping[str, Any], variable: str | None, which: Any, kind: str
) -> tuple[np.ndarray, list[str]]:
    """Stack the requested variables/columns into ``(N, k)``; their channel names."""
    items = [which] if isinstance(which, (str, int, np.integer)) else list(which)
    if not items:
        raise DataError(f"{path}: no {kind}s named")
    blocks, names, lengths = [], [], []
    for item in items:
        if is_integer(item):
            source, column = _matrix_variable(path, contents, variable), int(item)
        elif isinstance(item, str):
            match = _COLUMN.match(item)
            if match and item not in contents:
                source, column = match.group("name"), int(match.group("col"))
            else:
                source, column = item, None
        else:
            raise DataError(f"{path}: {kind} {item!r} must be a variable name or a column index")
        if source not in contents:
            raise DataError(
                f"{path}: no variable {source!r} for the {kind}s; variables: {_listing(contents)}"
            )
        _reject_special(path, source, contents[source])
        array = _columns(_numeric(path, f"variable {source!r}", contents[source]))
        if column is None:
            blocks.append(array)
            names += (
                [source]
                if array.shape[1] == 1
                else [f"{source}[{j}]" for j in range(array.shape[1])]
            )
        else:
            if not 0 <= column < array.shape[1]:
                raise DataError(
                    f"{path}: {kind} column {column} out of range: variable {source!r} has "
                    f"{array.shape[1]} column(s)"
                )
            blocks.append(array[:, column : column + 1])
            names.append(f"{source}[{column}]" if array.shape[1] > 1 else source)
        lengths.append((source, array.shape[0]))
    if len({n for _, n in lengths}) > 1:
        listing = ", ".join(f"{s!r} {n}" for s, n in lengths)
        raise DataError(
            f"{path}: the {kind} variables have different numbers of samples ({listing})"
        )
    return np.hstack(blocks), names


def _matrix_variable(path: Path, contents: Mapping[str, Any], variable: str | None) -> str:
    """The variable integer columns refer to: ``variable`` or the file's only matrix."""
    if variable is not None:
        return variable
    matrices = [
        k
        for k, v in contents.items()
        if isinstance(v, np.ndarray) and v.dtype.kind in "biufc" and v.ndim == 2
    ]
    if len(matrices) != 1:
        raise DataError(
            f"{path}: column indices need one matrix, but the file has "
            f"{len(matrices)} ({', '.join(matrices) or 'none'}); name it with variable=... "
            "(--variable) or name the variables"
        )
    return matrices[0]


def _variables_sample_time(
    path: Path, contents: Mapping[str, Any], n_samples: int, meta: dict[str, Any]
) -> float:
    for name in _SAMPLE_TIME_NAMES:
        if name in contents:
            ts = _scalar_time(path, f"variable {name!r}", contents[name])
            if ts is not None:
                return ts
    for name in _TIME_NAMES:
        if name in contents:
            times = _numeric(path, f"variable {name!r}", contents[name])
            if times.ndim == 1 or 1 in times.shape:
                return _step_of(times.reshape(-1), n_samples, path, name, meta)
    meta["dt_assumed"] = True
    return 1.0


def _record(
    path: Path,
    u: np.ndarray,
    y: np.ndarray,
    dt: float,
    input_names: list[str] | None,
    output_names: list[str] | None,
    meta: dict[str, Any],
    **units: Any,
) -> RecordParts:
    options = {"input_names": input_names, "output_names": output_names, "metadata": meta}
    return RecordParts(u, y, dt, {**options, **units})


# ---------------------------------------------------------------------- text files
def _is_float(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


@contextmanager
def _text_file(path: Path) -> Iterator[None]:
    """Turn the errors of reading ``path`` as UTF-8 text into one-line DataFileErrors."""
    try:
        yield
    except DataFileError:  # an OSError too: already said in one line
        raise
    except UnicodeDecodeError:
        raise DataFileError(f"{path}: not a text file (cannot decode as UTF-8)") from None
    except OSError as exc:
        raise _unreadable(path, exc) from None


def _read_text(path: Path) -> str:
    with _text_file(path), open(path, encoding="utf-8-sig", newline="") as handle:
        return handle.read()


#: Characters of CSV text parsed at a time by :func:`read_csv` (whole lines, so a block may
#: be one line longer).  A block is held as Python strings (1 byte a character and about 50
#: a line) and, by NumPy's parser, as UCS4 (4 bytes a character): about 1.5 MB whatever the
#: file's size or line length.  Blocks of a few thousand lines are long enough that NumPy's
#: parser, not the Python loop over blocks, sets the pace.
_CSV_BLOCK_CHARS = 1 << 18


def read_csv(path: Path) -> tuple[dict | None, list[str], np.ndarray]:
    """The flexid metadata line, the column names and the numeric rows of a CSV file.

    The file is read in blocks of whole lines, about :data:`_CSV_BLOCK_CHARS` characters
    each, straight into one preallocated float64 table (its rows counted beforehand from the
    newline bytes), so a read needs the table plus one block: the file's text is never held
    whole, nor split into Python strings and lists (hundreds of bytes a sample).  Each block
    goes through :func:`numpy.loadtxt`; a block it refuses (a quoted cell, an empty row, a
    bad cell, a row of the wrong width) is read again row by row by :func:`_parse_rows`,
    which accepts exactly what :class:`float` does and names the line and the column of an
    error.  Both parse a number with the same correctly rounded conversion, so the table
    does not depend on which path read a block.

    Parameters
    ----------
    path : pathlib.Path
        The file.

    Returns
    -------
    header : dict or None
        The JSON of a ``# flexid-iodata`` first line, else None.
    columns : list of str
        The header row's column names.
    table : ndarray, shape (N, len(columns))
        The numeric rows (blank rows skipped).

    Raises
    ------
    DataFileError
        A missing, unreadable or non-UTF-8 file, no header row, an empty or numeric header,
        malformed metadata, a row of the wrong width or a cell that is not a number.
    """
    with _text_file(path):
        capacity = _count_lines(path)
        with open(path, encoding="utf-8-sig") as handle:  # a leading BOM is not a name
            return _read_csv_lines(path, handle, capacity)


def _count_lines(path: Path) -> int:
    """Lines of a file (a last line without a newline counts), from its newline bytes."""
    count, last = 0, b"\n"
    with open(path, "rb") as handle:
        while chunk := handle.read(1 << 20):
            count += chunk.count(b"\n")
            last = chunk[-1:]
    return count + (last != b"\n")


def _read_csv_lines(
    path: Path, handle: io.TextIOBase, capacity: int
) -> tuple[dict | None, list[str], np.ndarray]:
    """:func:`read_csv` on an open file of at most ``capacity`` lines (more only if it has
    lone ``\\r`` line ends: then the table grows)."""
    header: dict | None = None
    lineno = 0  # 1-based number of the last line read
    line = ""
    for line in handle:
        lineno += 1
        if lineno == 1 and line.startswith(CSV_MAGIC):
            try:
                header = json.loads(line[len(CSV_MAGIC) :])
            except json.JSONDecodeError as exc:
                raise DataFileError(f"{path}: line 1: malformed flexid metadata ({exc})") from None
            continue
        if line.strip() and not line.startswith("#"):
            break
    else:
        raise DataFileError(f"{path}: no header row and no data")
    head = next(csv.reader([line]), [])
    columns = [c.strip() for c in head]
    if not columns or any(not c for c in columns):
        raise DataFileError(f"{path}: line {lineno}: empty column name in the header")
    if all(_is_float(c) for c in columns):
        raise DataFileError(
            f"{path}: line {lineno}: the first row is numeric; a CSV file needs a "
            "header row with column names (use a .dat file for bare numbers)"
        )
    width = len(columns)
    table = np.empty((max(capacity - lineno, 0), width))
    filled = 0
    while lines := handle.readlines(_CSV_BLOCK_CHARS):
        block = _parse_block(lines, width, path, lineno + 1, columns)
        lineno += len(lines)
        if filled + block.shape[0] > table.shape[0]:
            grown = np.empty((2 * (filled + block.shape[0]), width))
            grown[:filled] = table[:filled]
            table = grown
        table[filled : filled + block.shape[0]] = block
        filled += block.shape[0]
    return header, columns, table[:filled]


def _parse_block(
    lines: list[str], width: int, path: Path, first_line: int, columns: list
) -> np.ndarray:
    """Rows of a block of CSV lines, shape (n, width): NumPy's parser, else row by row."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # loadtxt warns of a block with no data rows
            block = np.loadtxt(lines, delimiter=",", comments=None, dtype=float, ndmin=2)
    except ValueError:
        block = None
    if block is not None and block.shape[1] == width and block.shape[0] > 0:
        return block
    return _parse_rows(list(csv.reader(lines)), width, path, first_line, columns)


def write_text(path: Path, text: str) -> None:
    """Write ``text`` as UTF-8, atomically (:func:`write_bytes`)."""
    write_bytes(path, text.encode("utf-8"))


def write_bytes(path: Path, payload: bytes) -> None:
    """Write ``payload`` atomically: a temporary file in the same folder, then a rename.

    Raises
    ------
    DataFileError
        When the folder cannot be written; no temporary file is left behind.
    """
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    try:
        with open(tmp, "wb") as handle:
            handle.write(payload)
        os.replace(tmp, path)
    except OSError as exc:
        try:
            tmp.unlink()
        except OSError:
            pass
        raise DataFileError(f"{path}: cannot write ({exc.strerror or exc})") from None


def write_files(folder: Path, files: Sequence[tuple[str, bytes]], what: str) -> list[Path]:
    """Write a set of files into a folder (created), all of them or none.

    Each file is first written whole to a temporary file beside it; only when every one is
    written are they renamed into place, so a full disk or a refused write leaves neither a
    partial file nor a partial set (a rename is not a write: it needs no space).

    Parameters
    ----------
    folder : pathlib.Path
        Where the files go; it and its missing parents are created, and removed again if
        the set cannot be written.
    files : sequence of (str, bytes)
        File names in ``folder`` and their contents; existing files of these names are
        replaced.
    what : str
        What the files are, for the message (``"figures"``).

    Returns
    -------
    list of pathlib.Path
        The files written, in the order given.

    Raises
    ------
    DataFileError
        ``"cannot write <what> to <folder>: <cause>"`` when the folder cannot be made or a
        file cannot be written (no space left, no permission, the folder is a file).
    """
    folder = Path(folder)
    made: list[Path] = []
    staged: list[tuple[Path, Path]] = []
    try:
        made = _make_folder(folder)
        for name, payload in files:
            path = folder / name
            staged.append((path.with_name(f".{path.name}.tmp{os.getpid()}"), path))
            with open(staged[-1][0], "wb") as handle:
                handle.write(payload)
        for tmp, path in staged:
            os.replace(tmp, path)
    except OSError as exc:
        for tmp, _ in staged:
            try:
                tmp.unlink(missing_ok=True)
            except OSError:
                pass
        for made_folder in reversed(made):
            try:
                made_folder.rmdir()
            except OSError:  # not empty: someone else's files went in meanwhile
                break
        raise DataFileError(f"cannot write {what} to {folder}: {_cause(exc, folder)}") from None
    return [path for _, path in staged]


def _make_folder(folder: Path) -> list[Path]:
    """Create ``folder`` and its missing parents; the folders created, outermost first."""
    missing = []
    for part in (folder, *folder.parents):
        if part.exists() or part.is_symlink():
            break
        missing.append(part)
    for part in reversed(missing):
        part.mkdir()
    return list(reversed(missing))


def _cause(exc: OSError, folder: Path) -> str:
    """Why a folder could not be written, in a few lower-case words."""
    if folder.exists() and not folder.is_dir():
        return "not a folder"
    if isinstance(exc, (FileExistsError, NotADirectoryError)):
        return "a part of its path is not a folder"
    text = exc.strerror or str(exc)
    return text[:1].lower() + text[1:]


def median_step(times: np.ndarray) -> tuple[float, bool]:
    """The median step of a time vector and whether every step is within 0.1 % of it.

    Parameters
    ----------
    times : ndarray, shape (N,)
        Sample instants in seconds, N >= 2.

    Returns
    -------
    step : float
        The median of the N - 1 steps, in seconds (not checked here).
    uniform : bool
        Whether all steps are close to it (relative 1e-3, absolute 1e-12 s).
    """
    steps = np.diff(times)
    step = float(np.median(steps))
    return step, bool(np.allclose(steps, step, rtol=1e-3, atol=1e-12))


def _parse_rows(rows: list, width: int, path: Path, first_line: int, columns: list) -> np.ndarray:
    body = [(i, r) for i, r in enumerate(rows) if r and any(c.strip() for c in r)]
    table = np.empty((len(body), width))
    for k, (i, row) in enumerate(body):
        lineno = first_line + i
        if len(row) != width:
            raise DataFileError(f"{path}: line {lineno}: {len(row)} field(s), expected {width}")
        for j, cell in enumerate(row):
            try:
                table[k, j] = float(cell)
            except ValueError:
                raise DataFileError(
                    f"{path}: line {lineno}, column {columns[j]!r}: "
                    f"{cell.strip()!r} is not a number"
                ) from None
    return table


def read_dat(path: Path) -> np.ndarray:
    """The numeric table of a whitespace-separated (DaISy-style) file.

    Parameters
    ----------
    path : pathlib.Path
        The file; lines starting with ``%`` or ``#`` and blank lines are skipped, commas
        count as spaces.

    Returns
    -------
    ndarray, shape (N, width)

    Raises
    ------
    DataFileError
        A missing or unreadable file, no numeric rows, ragged rows or a non-numeric entry
        (the message gives the line).
    """
    text = _read_text(path)
    rows = []
    numbers: list[int] = []
    for lineno, line in enumerate(text.splitlines(), start=1):
        stripped = line.strip()
        if not stripped or stripped[0] in "%#":
            continue
        rows.append(stripped.replace(",", " ").split())
        numbers.append(lineno)
    if not rows:
        raise DataFileError(f"{path}: no numeric rows")
    width = len(rows[0])
    table = np.empty((len(rows), width))
    for i, (row, lineno) in enumerate(zip(rows, numbers)):
        if len(row) != width:
            raise DataFileError(
                f"{path}: line {lineno}: {len(row)} column(s), expected {width}"
            )
        try:
            table[i] = [float(v) for v in row]
        except ValueError:
            bad = next(v for v in row if not _is_float(v))
            raise DataFileError(f"{path}: line {lineno}: {bad!r} is not a number") from None
    return table
