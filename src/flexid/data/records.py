"""Input-output records: :class:`IOData`, splitting, detrending and file I/O.

An :class:`IOData` holds ``u`` of shape ``(N, n_u)`` and ``y`` of shape ``(N, n_y)`` sampled
every ``dt`` seconds, channel names and units, and free metadata (plant, parameters,
signal, seed, flexid version...).  It is checked on construction: finite values, equal
lengths, at least two samples, a positive sample time.

Notes
-----
File formats:

* **CSV** (``.csv``): flexid writes one comment line ``# flexid-iodata {json}`` with the
  sample time, the channel names, units and the metadata, then a header row
  ``time,<inputs...>,<outputs...>`` and one row per sample.  Plain CSV files with a header
  row are read too: name the input and output columns, or let flexid take columns called
  ``u``, ``u1``, ``u2``... as inputs and ``y``, ``y1``... as outputs; a column ``t`` or
  ``time`` gives the sample time.
* **NPZ** (``.npz``): arrays ``u``, ``y``, ``dt`` and a JSON string ``meta``; written and
  read without pickle.
* **DaISy-style** ``.dat`` / ``.txt``: whitespace-separated numbers, optional ``%`` or ``#``
  comment lines; the user names the input and output columns (0-based indices).
* **MATLAB** ``.mat`` (v4 to v7, read only): an iddata-like structure (fields ``y``, ``u``,
  ``Ts``...) or plain variables; see :meth:`IOData.from_mat`.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import warnings
import zipfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .._html import block, table
from .._json import jsonable
from .._validate import checked_keywords, integer, is_integer, positive_real, real
from ..errors import (
    DataError,
    DataFileError,
    DataWarning,
    UnknownKeywordError,
    UnknownNameError,
    _unreadable,
    check_finite,
)
from ._files import (
    CSV_MAGIC,
    RecordParts,
    median_step,
    read_csv,
    read_dat,
    read_mat,
    write_bytes,
    write_text,
)

__all__ = [
    "DETRENDS",
    "ESTIMATION_SHARE",
    "OFFSET_RATIO",
    "IOData",
    "detrend_kind",
    "detrend_pair",
    "is_records",
    "joined",
    "load",
    "prepare_data",
    "save",
    "split_parts",
]

#: The share of a record used for estimation when no split is given (the rest validates):
#: the first two thirds, as in Nasir & Tokhi's experiments.
ESTIMATION_SHARE = 2.0 / 3.0

_FORMAT_VERSION = 1


def _as_2d(values: Any, what: str) -> np.ndarray:
    try:
        array = np.array(values, dtype=float, copy=True)
    except (TypeError, ValueError) as exc:
        raise DataError(f"{what} must be numeric: {exc}") from None
    if array.ndim == 1:
        array = array[:, None]
    if array.ndim != 2:
        raise DataError(
            f"{what} must be 1-D (one channel) or 2-D (samples x channels), got shape {array.shape}"
        )
    return array


def _names(names: Sequence[str] | str | None, count: int, prefix: str, what: str) -> tuple:
    if names is None:
        if count == 1:
            return (prefix,)
        return tuple(f"{prefix}{i + 1}" for i in range(count))
    if isinstance(names, str):
        names = [names]
    names = tuple(str(n) for n in names)
    if len(names) != count:
        raise DataError(f"{what}: {len(names)} name(s) given for {count} channel(s)")
    return names


#: Headroom below float64's largest value kept by :func:`_check_magnitude`: the costs scale
#: a sum of squares (the paper's cost by 1e3) and the regressions sum products of lagged
#: samples, so squares summed over a record must stay finite with room to spare.
_HEADROOM = 1e6


def _check_magnitude(column: np.ndarray, what: str) -> None:
    """Refuse a finite sample so large that the record's sum of squares overflows float64.

    Every cost and regression of a record sums squares or products of its samples over the
    record; a sample beyond ``sqrt(max / (N * headroom))`` makes them infinite, and the user
    would read "regressors singular" or a screen of overflow warnings instead of the sample.
    """
    if column.dtype.kind not in "fc" or column.size == 0:
        return
    limit = math.sqrt(np.finfo(np.float64).max / (column.size * _HEADROOM))
    magnitude = np.abs(column)
    worst = int(np.argmax(magnitude))
    if magnitude[worst] > limit:
        raise DataError(
            f"{what} sample {worst} = {float(column[worst]):g} is too large to square (limit "
            f"{limit:.2g}); rescale the record"
        )


class IOData:
    """A sampled input-output record.

    Parameters
    ----------
    u : array_like, shape (N,) or (N, n_u)
        Input samples; one column per input channel (units in ``input_units``).
    y : array_like, shape (N,) or (N, n_y)
        Output samples; one column per output channel.
    dt : float, optional
        Sample time in seconds (default 1.0: "one sample").  Must be positive and finite.
    input_names, output_names : sequence of str, optional
        Channel names; default ``u``/``u1, u2...`` and ``y``/``y1, y2...``.
    input_units, output_units : sequence of str, optional
        Channel units (free text, e.g. ``"N m"``); default empty strings.
    metadata : mapping, optional
        Free JSON-serialisable information (plant, parameters, signal, seed...).

    Raises
    ------
    DataError
        On NaN or infinite samples (the message names the channel and the sample), on
        inputs and outputs of different lengths, on fewer than two samples, on a
        non-positive or non-finite ``dt`` and on name/unit lists of the wrong length.

    Examples
    --------
    >>> import numpy as np
    >>> from flexid import IOData
    >>> d = IOData(np.ones(10), np.arange(10.0), dt=0.01, input_names=["torque"])
    >>> d.n_samples, d.n_inputs, d.n_outputs
    (10, 1, 1)
    >>> est, val = d.split(0.7)
    >>> est.n_samples, val.n_samples
    (7, 3)
    """

    __slots__ = (
        "_u",
        "_y",
        "dt",
        "input_names",
        "input_units",
        "metadata",
        "output_names",
        "output_units",
    )

    def __init__(
        self,
        u: Any,
        y: Any,
        dt: float = 1.0,
        *,
        input_names: Sequence[str] | str | None = None,
        output_names: Sequence[str] | str | None = None,
        input_units: Sequence[str] | str | None = None,
        output_units: Sequence[str] | str | None = None,
        metadata: Mapping[str, Any] | None = None,
    ) -> None:
        u = _as_2d(u, "input u")
        y = _as_2d(y, "output y")
        if u.shape[0] != y.shape[0]:
            raise DataError(
                f"inputs and outputs have different lengths: u has {u.shape[0]} samples, "
                f"y has {y.shape[0]}"
            )
        if u.shape[0] < 2:
            raise DataError(f"a record needs at least 2 samples, got {u.shape[0]}")
        if u.shape[1] == 0 or y.shape[1] == 0:
            raise DataError(
                f"a record needs at least one input and one output channel, "
                f"got {u.shape[1]} input(s) and {y.shape[1]} output(s)"
            )
        dt = positive_real(dt, "sample time dt", error=DataError, unit="s")
        self.input_names = _names(input_names, u.shape[1], "u", "input_names")
        self.output_names = _names(output_names, y.shape[1], "y", "output_names")
        for array, names, kind in (
            (u, self.input_names, "input"),
            (y, self.output_names, "output"),
        ):
            for j, name in enumerate(names):
                check_finite(array[:, j], f"{kind} {name!r}")
                _check_magnitude(array[:, j], f"{kind} {name!r}")
        self.input_units = (
            _names(input_units, u.shape[1], "", "input_units")
            if input_units is not None
            else ("",) * u.shape[1]
        )
        self.output_units = (
            _names(output_units, y.shape[1], "", "output_units")
            if output_units is not None
            else ("",) * y.shape[1]
        )
        u.setflags(write=False)
        y.setflags(write=False)
        self._u = u
        self._y = y
        self.dt = dt
        self.metadata = dict(metadata or {})

    # ------------------------------------------------------------------ properties
    @property
    def u(self) -> np.ndarray:
        """Inputs, shape ``(N, n_u)`` (read-only)."""
        return self._u

    @property
    def y(self) -> np.ndarray:
        """Outputs, shape ``(N, n_y)`` (read-only)."""
        return self._y

    @property
    def n_samples(self) -> int:
        """Number of samples ``N``."""
        return self._u.shape[0]

    @property
    def n_inputs(self) -> int:
        """Number of input channels ``n_u``."""
        return self._u.shape[1]

    @property
    def n_outputs(self) -> int:
        """Number of output channels ``n_y``."""
        return self._y.shape[1]

    @property
    def time(self) -> np.ndarray:
        """Sample instants ``k * dt`` in seconds, shape ``(N,)``."""
        return np.arange(self.n_samples) * self.dt

    def __len__(self) -> int:
        return self.n_samples

    def __repr__(self) -> str:
        return (
            f"IOData(N={self.n_samples}, dt={self.dt:g} s, inputs={list(self.input_names)}, "
            f"outputs={list(self.output_names)})"
        )

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, IOData):
            return NotImplemented
        return (
            self.dt == other.dt
            and self.input_names == other.input_names
            and self.output_names == other.output_names
            and self.input_units == other.input_units
            and self.output_units == other.output_units
            and self.metadata == other.metadata
            and np.array_equal(self._u, other._u)
            and np.array_equal(self._y, other._y)
        )

    __hash__ = None  # type: ignore[assignment]

    # ------------------------------------------------------------------ derived records
    def replace(self, **changes: Any) -> IOData:
        """A copy with some fields replaced.

        Parameters
        ----------
        **changes
            New values of ``u`` (N, n_u), ``y`` (N, n_y), ``dt`` (s), ``input_names``,
            ``output_names``, ``input_units``, ``output_units`` or ``metadata``; the others
            are kept.  The result is validated as a new record.

        Returns
        -------
        IOData
            The new record.

        Raises
        ------
        TypeError
            For a field that IOData does not have.
        DataError
            If the new fields do not make a valid record.
        """
        fields = {
            "u": self._u,
            "y": self._y,
            "dt": self.dt,
            "input_names": self.input_names,
            "output_names": self.output_names,
            "input_units": self.input_units,
            "output_units": self.output_units,
            "metadata": self.metadata,
        }
        unknown = set(changes) - set(fields)
        if unknown:
            raise TypeError(f"IOData.replace() got unknown field(s): {sorted(unknown)}")
        fields.update(changes)
        u = fields.pop("u")
        y = fields.pop("y")
        dt = fields.pop("dt")
        return IOData(u, y, dt, **fields)

    def __getitem__(self, index: slice) -> IOData:
        """Samples ``index`` (a slice) as a new record with the same channels and metadata."""
        if not isinstance(index, slice):
            raise TypeError("IOData supports slicing by samples only, e.g. data[100:500]")
        return self.replace(u=self._u[index], y=self._y[index])

    def select(
        self,
        inputs: Sequence[str | int] | str | int | None = None,
        outputs: Sequence[str | int] | str | int | None = None,
    ) -> IOData:
        """Keep some channels, given by name or 0-based index.

        Parameters
        ----------
        inputs, outputs : str, int or sequence of them, optional
            Channels to keep, in the order given; ``None`` keeps all.

        Returns
        -------
        IOData
            The record with those channels (names and units follow), same ``dt`` and
            metadata.

        Raises
        ------
        DataError
            If a channel does not exist.
        """
        ui = self._channel_indices(inputs, self.input_names, "input")
        yi = self._channel_indices(outputs, self.output_names, "output")
        return self.replace(
            u=self._u[:, ui],
            y=self._y[:, yi],
            input_names=[self.input_names[i] for i in ui],
            output_names=[self.output_names[i] for i in yi],
            input_units=[self.input_units[i] for i in ui],
            output_units=[self.output_units[i] for i in yi],
        )

    @staticmethod
    def _channel_indices(which, names: tuple, kind: str) -> list[int]:
        if which is None:
            return list(range(len(names)))
        if isinstance(which, (str, int, np.integer)):
            which = [which]
        indices = []
        for item in which:
            if is_integer(item):
                if not -len(names) <= item < len(names):
                    raise DataError(
                        f"{kind} channel index {item} out of range; the record has "
                        f"{len(names)} {kind}(s): {list(names)}"
                    )
                indices.append(int(item) % len(names))
            elif item in names:
                indices.append(names.index(item))
            else:
                raise DataError(f"no {kind} channel {item!r}; the record has {list(names)}")
        return indices

    def split(
        self, fraction: float | None = None, *, index: int | None = None
    ) -> tuple[IOData, IOData]:
        """Split into an estimation and a validation record.

        Parameters
        ----------
        fraction : float, optional
            Share of the samples, in (0, 1), that goes to the first (estimation) record;
            the first ``round(fraction * N)`` samples.  Default 2/3, as in the paper.
        index : int, optional
            Split at this sample instead: samples ``[0, index)`` and ``[index, N)``.

        Returns
        -------
        estimation, validation : IOData
            Both keep the channels and metadata; ``metadata["split"]`` records the part.

        Raises
        ------
        DataError
            If both or an invalid ``fraction``/``index`` is given, or if either part would
            have fewer than two samples.
        """
        n = self.n_samples
        if fraction is not None and index is not None:
            raise DataError("give either fraction or index to split(), not both")
        if index is None:
            fraction = ESTIMATION_SHARE if fraction is None else fraction
            fraction = real(
                fraction, "split fraction", error=DataError, minimum=0, maximum=1,
                low_open=True, high_open=True,
            )
            index = round(fraction * n)
        index = integer(index, "split index", error=DataError)
        if index < 0:
            index += n
        if not 2 <= index <= n - 2:
            raise DataError(
                f"split at sample {index} leaves fewer than 2 samples in a part of a "
                f"{n}-sample record"
            )
        first = self[:index]
        second = self[index:]
        first.metadata["split"] = {"part": "estimation", "start": 0, "stop": index}
        second.metadata["split"] = {"part": "validation", "start": index, "stop": n}
        return first, second

    def detrend(self, kind: str = "constant") -> IOData:
        """Remove the mean (``"constant"``) or a least-squares line (``"linear"``) per channel.

        The removed offsets are stored in ``metadata["detrend"]`` (for ``"constant"``) so a
        model's output can be put back in physical units.

        Parameters
        ----------
        kind : {"constant", "linear"}, optional
            What is removed from each input and output channel (default ``"constant"``).

        Returns
        -------
        IOData
            The detrended record; ``metadata["detrend"]`` holds ``kind`` and, for
            ``"constant"``, the removed means ``u_mean`` (n_u,) and ``y_mean`` (n_y,).

        Raises
        ------
        DataError
            For another ``kind``.
        """
        if kind not in ("constant", "linear"):
            raise DataError(f"detrend kind must be 'constant' or 'linear', got {kind!r}")
        from scipy.signal import detrend as _detrend

        u = _detrend(self._u, axis=0, type=kind)
        y = _detrend(self._y, axis=0, type=kind)
        meta = dict(self.metadata)
        info: dict[str, Any] = {"kind": kind}
        if kind == "constant":
            info["u_mean"] = self._u.mean(axis=0).tolist()
            info["y_mean"] = self._y.mean(axis=0).tolist()
        meta["detrend"] = info
        return self.replace(u=u, y=y, metadata=meta)

    # ------------------------------------------------------------------ serialisation
    def _header(self) -> dict:
        return {
            "format": "flexid-iodata",
            "version": _FORMAT_VERSION,
            "dt": self.dt,
            "input_names": list(self.input_names),
            "output_names": list(self.output_names),
            "input_units": list(self.input_units),
            "output_units": list(self.output_units),
            "metadata": jsonable(self.metadata),
        }

    @classmethod
    def _from_header(cls, header: Mapping, u: np.ndarray, y: np.ndarray, source: str) -> IOData:
        try:
            return cls(
                u,
                y,
                header["dt"],
                input_names=header["input_names"],
                output_names=header["output_names"],
                input_units=header.get("input_units"),
                output_units=header.get("output_units"),
                metadata=header.get("metadata", {}),
            )
        except KeyError as exc:
            raise DataFileError(f"{source}: flexid header lacks the key {exc}") from None
        except DataError as exc:
            raise type(exc)(f"{source}: {exc}") from None

    def to_csv(self, path: str | os.PathLike) -> Path:
        """Write a CSV file with a JSON metadata line and a header row.

        Numbers are written with ``repr`` precision (17 significant digits), so reading the
        file back gives bit-identical arrays.

        Parameters
        ----------
        path : str or os.PathLike
            Destination file (overwritten).

        Returns
        -------
        pathlib.Path
            The path written; columns ``time`` (s), the inputs, then the outputs.
        """
        path = Path(path)
        buffer = io.StringIO()
        buffer.write(CSV_MAGIC + json.dumps(self._header(), sort_keys=True) + "\n")
        writer = csv.writer(buffer, lineterminator="\n")
        writer.writerow(["time", *self.input_names, *self.output_names])
        table = np.column_stack([self.time, self._u, self._y])
        for row in table:
            writer.writerow([repr(float(v)) for v in row])
        write_text(path, buffer.getvalue())
        return path

    def to_npz(self, path: str | os.PathLike) -> Path:
        """Write an ``.npz`` (arrays ``u``, ``y``, ``dt`` and JSON ``meta``), no pickle.

        Parameters
        ----------
        path : str or os.PathLike
            Destination file (overwritten; used as given, no suffix is added).

        Returns
        -------
        pathlib.Path
            The path written.
        """
        path = Path(path)
        meta = np.array(json.dumps(self._header(), sort_keys=True))
        buffer = io.BytesIO()
        np.savez(buffer, u=self._u, y=self._y, dt=np.array(self.dt), meta=meta)
        write_bytes(path, buffer.getvalue())
        return path

    def save(self, path: str | os.PathLike) -> Path:
        """Write to ``.csv`` or ``.npz`` according to the suffix.

        Parameters
        ----------
        path : str or os.PathLike
            Destination file; its suffix (``.csv`` or ``.npz``, any case) picks the format.

        Returns
        -------
        pathlib.Path
            The path written.

        Raises
        ------
        DataFileError
            For another suffix.
        """
        return save(self, path)

    @classmethod
    def from_npz(cls, path: str | os.PathLike) -> IOData:
        """Read a file written by :meth:`to_npz` (pickle is never allowed).

        Parameters
        ----------
        path : str or os.PathLike
            The ``.npz`` file.

        Returns
        -------
        IOData
            The record, with its names, units and metadata.

        Raises
        ------
        DataFileError
            If the file is missing, empty, unreadable or not an NPZ archive, or lacks the
            ``u``, ``y`` or ``meta`` arrays or a header key.
        DataError
            If the arrays do not make a valid record.
        """
        path = Path(path)
        try:
            with open(path, "rb") as handle:
                magic = handle.read(4)
            # np.load reads an empty file as EOFError, a .npy as one array, anything else
            # as a pickle it refuses: say what the file is instead
            if not magic:
                raise DataFileError(f"{path}: empty file, not an NPZ file")
            if magic != b"PK\x03\x04":
                what = "a single NumPy array (.npy)" if magic == b"\x93NUM" else "not a zip archive"
                raise DataFileError(f"{path}: {what}, not an NPZ file of u, y and meta")
            with np.load(path, allow_pickle=False) as archive:
                missing = {"u", "y", "meta"} - set(archive.files)
                if missing:
                    raise DataFileError(f"{path}: NPZ file lacks the array(s) {sorted(missing)}")
                u, y = archive["u"], archive["y"]
                header = json.loads(str(archive["meta"]))
        except DataFileError:
            raise
        except (FileNotFoundError, IsADirectoryError) as exc:
            raise _unreadable(path, exc) from None
        except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
            # EOFError and BadZipFile: a truncated or damaged archive
            raise DataFileError(f"{path}: not a readable flexid NPZ file ({exc})") from None
        return cls._from_header(header, u, y, str(path))

    @classmethod
    def from_csv(
        cls,
        path: str | os.PathLike,
        inputs: Sequence[str | int] | str | int | None = None,
        outputs: Sequence[str | int] | str | int | None = None,
        dt: float | None = None,
        *,
        metadata: Mapping[str, Any] | None = None,
    ) -> IOData:
        """Read a CSV file with a header row.

        Parameters
        ----------
        path : path-like
            The file.  A file written by :meth:`to_csv` restores everything; other
            arguments then select channels only.
        inputs, outputs : column names or 0-based indices, optional
            Which columns are inputs and outputs.  Default: columns named ``u``/``u<k>``
            are inputs and ``y``/``y<k>`` outputs.
        dt : float, optional
            Sample time in seconds.  Default: from a ``t``/``time`` column, else 1.0
            (recorded as assumed in ``metadata["dt_assumed"]``).
        metadata : mapping, optional
            Extra metadata to merge in.

        Returns
        -------
        IOData
            The record, inputs (N, n_u) and outputs (N, n_y).

        Raises
        ------
        DataFileError
            If the file is missing, empty, has no header, a row of the wrong width, or a
            cell that is not a number (the message gives the line and column).
        DataError
            On NaN/inf values, unknown column names, or too few samples.

        Warns
        -----
        DataWarning
            When the sample time is the median step of a time column whose steps differ
            (also noted in ``metadata["dt_note"]``), or when ``inputs`` or ``outputs``
            choose the time column (``t``/``time``).

        Notes
        -----
        The file is read in blocks into one preallocated table, so a read needs at most
        about three times the bytes of the record's float64 arrays, whatever its length.
        """
        path = Path(path)
        header, columns, table = read_csv(path)
        if header is not None:
            n_u = len(header.get("input_names", []))
            n_y = len(header.get("output_names", []))
            if table.shape[1] != 1 + n_u + n_y:
                raise DataFileError(
                    f"{path}: the header lists {n_u} input(s) and {n_y} output(s) but rows "
                    f"have {table.shape[1]} columns"
                )
            data = cls._from_header(header, table[:, 1 : 1 + n_u], table[:, 1 + n_u :], str(path))
            if inputs is not None or outputs is not None:
                data = data.select(inputs, outputs)
            if metadata:
                data.metadata.update(metadata)
            return data
        return _assemble(cls, table, columns, inputs, outputs, dt, path, metadata)

    @classmethod
    def from_dat(
        cls,
        path: str | os.PathLike,
        inputs: Sequence[int] | int,
        outputs: Sequence[int] | int,
        dt: float | None = None,
        *,
        input_names: Sequence[str] | None = None,
        output_names: Sequence[str] | None = None,
        metadata: Mapping[str, Any] | None = None,
    ) -> IOData:
        """Read a whitespace-separated numeric file (DaISy style).

        Parameters
        ----------
        path : path-like
            The file; lines starting with ``%`` or ``#`` and blank lines are skipped.
        inputs, outputs : int or sequence of int
            0-based column indices of the inputs and outputs (required: such files have
            no header).
        dt : float, optional
            Sample time in seconds; default 1.0, recorded as assumed.
        input_names, output_names : sequence of str, optional
            Channel names; default ``u``/``y`` style names.
        metadata : mapping, optional
            Extra metadata.

        Returns
        -------
        IOData
            The record, inputs (N, n_u) and outputs (N, n_y); ``metadata["source"]`` is the
            path.

        Raises
        ------
        DataFileError
            Missing or unreadable file, ragged rows, non-numeric entries.
        DataError
            Column indices out of range, NaN/inf, too few samples.
        """
        path = Path(path)
        table = read_dat(path)
        width = table.shape[1]
        ins = [inputs] if isinstance(inputs, (int, np.integer)) else list(inputs)
        outs = [outputs] if isinstance(outputs, (int, np.integer)) else list(outputs)
        for j in (*ins, *outs):
            if not is_integer(j) or not 0 <= j < width:
                raise DataError(f"{path}: column {j!r} out of range; the file has {width} columns")
        meta = {"source": str(path), **(metadata or {})}
        if dt is None:
            dt, meta["dt_assumed"] = 1.0, True
        return cls(
            table[:, ins],
            table[:, outs],
            dt,
            input_names=input_names,
            output_names=output_names,
            metadata=meta,
        )

    @classmethod
    def from_mat(
        cls,
        path: str | os.PathLike,
        inputs: Sequence[str | int] | str | int | None = None,
        outputs: Sequence[str | int] | str | int | None = None,
        dt: float | None = None,
        *,
        variable: str | None = None,
        metadata: Mapping[str, Any] | None = None,
    ) -> IOData:
        """Read a record from a MATLAB ``.mat`` file (v4, v5 or v7).

        Parameters
        ----------
        path : path-like
            The file.
        inputs, outputs : str, int or sequence of them, optional
            For an iddata-like structure: the channels to keep (names from
            ``InputName``/``OutputName`` or 0-based indices); default all.  For plain
            variables: variable names (every column of the variable), ``"name[j]"`` (column
            ``j`` of a matrix, 0-based) or integers (columns of the file's only matrix, or of
            ``variable``); default the variables named ``u``/``u<k>`` and ``y``/``y<k>``.
        dt : float, optional
            Sample time in seconds; overrides the file's.  Default: the structure's ``Ts``
            (converted from its ``TimeUnit``), a ``Ts``/``dt`` variable, the median step of a
            ``t``/``time`` variable, else 1.0 recorded as assumed in ``metadata["dt_assumed"]``.
        variable : str, optional
            The variable to read when the file holds several structures, or the matrix whose
            columns integer ``inputs``/``outputs`` index.
        metadata : mapping, optional
            Extra metadata to merge in.

        Returns
        -------
        IOData
            ``u`` of shape ``(N, n_u)`` and ``y`` of shape ``(N, n_y)``; ``metadata["source"]``
            is the file and ``metadata["mat_variable"]`` the structure read, if any.

        Raises
        ------
        DataFileError
            For a missing, unreadable or non-MAT file, a v7.3 (HDF5) file, a MATLAB object or a
            multi-experiment structure.
        DataError
            For a missing variable or field, non-numeric, complex, empty, 3-D or non-finite
            values, signals of different lengths, a bad sample time; the message names the file
            and the variable.
        """
        path = Path(path)
        parts = read_mat(path, inputs, outputs, dt, variable=variable, metadata=metadata)
        return cls._from_parts(parts, path)

    @classmethod
    def _from_parts(cls, parts: RecordParts, path: Path) -> IOData:
        """The record of a file's parts; an invalid record's error names the file."""
        try:
            data = cls(parts.u, parts.y, parts.dt, **parts.options)
        except DataError as exc:
            raise DataError(f"{path}: {exc}") from None
        if parts.channels is not None:
            inputs, outputs, where = parts.channels
            try:
                data = data.select(inputs, outputs)
            except DataError as exc:
                raise DataError(f"{path}: {where}: {exc}") from None
        return data

    def describe(self) -> str:
        """A short human-readable description: length, sample time, channel statistics.

        Returns
        -------
        str
            The ``repr`` line, then one line per channel with its unit, mean, standard
            deviation and range.
        """
        lines = [repr(self)]
        for kind, name, unit, mean, std, low, high in self._channel_stats():
            unit = f" [{unit}]" if unit else ""
            lines.append(f"  {kind:6s} {name}{unit}: mean {mean}, std {std}, range [{low}, {high}]")
        return "\n".join(lines)

    def _channel_stats(self) -> list[tuple[str, str, str, str, str, str, str]]:
        """Per channel, inputs first: kind, name, unit, then mean, std, min and max as text.

        The one formatting of the statistics shared by :meth:`describe` and the notebook
        display, so both show the same numbers.
        """
        rows = []
        for kind, names, units, array in (
            ("input", self.input_names, self.input_units, self._u),
            ("output", self.output_names, self.output_units, self._y),
        ):
            for j, name in enumerate(names):
                col = array[:, j]
                rows.append(
                    (
                        kind,
                        name,
                        units[j],
                        f"{col.mean():.4g}",
                        f"{col.std():.4g}",
                        f"{col.min():.4g}",
                        f"{col.max():.4g}",
                    )
                )
        return rows

    def _repr_html_(self) -> str:
        """The notebook display: the line of its ``repr`` and, one row per channel (kind,
        name, unit, mean, std, min, max), the numbers of :meth:`describe` formatted alike."""
        rows: list[Sequence[str]] = [["channel", "kind", "unit", "mean", "std", "min", "max"]]
        rows += [(name, kind, *stats) for kind, name, *stats in self._channel_stats()]
        return block(repr(self), table(rows, left=3))


# ---------------------------------------------------------------------- helpers
def _columns_of(table: np.ndarray, index: list[int]) -> np.ndarray:
    """Columns ``index`` of ``table``: a view when they are adjacent and in order (IOData
    copies its arrays anyway, so a large record is not copied twice)."""
    if index == list(range(index[0], index[0] + len(index))):
        return table[:, index[0] : index[0] + len(index)]
    return table[:, index]


def _assemble(cls, table, columns, inputs, outputs, dt, path, metadata) -> IOData:
    def resolve(which, kind):
        if isinstance(which, (str, int, np.integer)):
            which = [which]
        out = []
        for item in which:
            if is_integer(item):
                if not 0 <= item < len(columns):
                    raise DataError(
                        f"{path}: {kind} column {item} out of range ({len(columns)} columns)"
                    )
                out.append(int(item))
            elif item in columns:
                out.append(columns.index(item))
            else:
                raise DataError(f"{path}: no column {item!r} for the {kind}s; columns: {columns}")
        return out

    def default(prefix):
        return [
            j
            for j, c in enumerate(columns)
            if c.lower() == prefix or (c.lower().startswith(prefix) and c[1:].isdigit())
        ]

    ins = resolve(inputs, "input") if inputs is not None else default("u")
    outs = resolve(outputs, "output") if outputs is not None else default("y")
    if not ins or not outs:
        raise DataError(
            f"{path}: cannot tell inputs from outputs among columns {columns}; name them "
            "(inputs=..., outputs=..., or --inputs/--outputs on the command line)"
        )
    meta = {"source": str(path), **(metadata or {})}
    time_cols = [j for j, c in enumerate(columns) if c.lower() in ("t", "time")]
    for kind, chosen in (("input", ins), ("output", outs)):
        for j in sorted(set(chosen) & set(time_cols)):
            # read as asked, but a column counted from 0 or named "t" by mistake is the
            # clock, and a model of it fits nothing
            warnings.warn(
                f"{path}: the {kind} column {columns[j]!r} is the time axis, not a measured "
                f"signal (columns: {', '.join(columns)})",
                DataWarning,
                stacklevel=3,
            )
    if dt is None:
        if time_cols and table.shape[0] >= 2:
            times = table[:, time_cols[0]]
            dt, uniform = median_step(times)
            if not uniform:
                meta["dt_note"] = "time column not uniform; dt is its median step"
                steps = np.diff(times)
                warnings.warn(
                    f"{path}: the time column {columns[time_cols[0]]!r} is not uniform (steps "
                    f"from {steps.min():g} to {steps.max():g} s); the samples are read as "
                    f"equally spaced at its median step, dt = {dt:g} s",
                    DataWarning,
                    stacklevel=2,
                )
        else:
            dt, meta["dt_assumed"] = 1.0, True
    return cls(
        _columns_of(table, ins),
        _columns_of(table, outs),
        dt,
        input_names=[columns[j] for j in ins],
        output_names=[columns[j] for j in outs],
        metadata=meta,
    )


def _reader_options(reader: Any) -> set[str]:
    """The keyword options a reader takes (its parameters after ``path``)."""
    import inspect

    params = list(inspect.signature(reader).parameters)
    return set(params[params.index("path") + 1 :])


def _readers() -> dict[str, Any]:
    return {
        ".csv": IOData.from_csv, ".npz": _NPZ_OPTIONS, ".dat": IOData.from_dat,
        ".txt": IOData.from_dat, ".mat": IOData.from_mat,
    }


_NPZ_OPTIONS = ("inputs", "outputs")  # a .npz record is selected, not parsed


def _load_options() -> set[str]:
    """Every option of some reader (what :func:`load` takes at all)."""
    out: set[str] = set()
    for reader in _readers().values():
        out |= set(reader) if isinstance(reader, tuple) else _reader_options(reader)
    return out


@checked_keywords(also=_load_options)
def load(path: str | os.PathLike, **options: Any) -> IOData:
    """Read a record from ``.csv``, ``.npz``, ``.dat``/``.txt`` or ``.mat`` by the suffix.

    Keyword options are passed to :meth:`IOData.from_csv`, :meth:`IOData.from_npz`,
    :meth:`IOData.from_dat` or, for MATLAB files (v4-v7, plain variables or an iddata-like
    structure), :meth:`IOData.from_mat`.

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    **options
        Passed to the reader of the suffix (e.g. ``inputs``, ``outputs``, ``dt``).

    Returns
    -------
    IOData
        The record.

    Raises
    ------
    DataFileError
        For a folder, an unknown suffix, a missing or malformed file.

    Warns
    -----
    DataWarning
        When a CSV time column or a MATLAB time vector is not uniform and the sample time
        is its median step (the samples are then read as equally spaced).
    """
    path = Path(path)
    if path.is_dir():
        raise DataFileError(f"{path}: is a folder, not a data file (.csv, .npz, .dat or .mat)")
    suffix = path.suffix.lower()
    reader = _readers().get(suffix)
    if reader is not None:
        takes = set(reader) if isinstance(reader, tuple) else _reader_options(reader)
        extra = sorted(set(options) - takes)
        if extra:
            raise UnknownKeywordError(
                f"load() got option(s) {', '.join(map(repr, extra))}, which a {suffix} file "
                f"does not take; it takes {', '.join(sorted(takes))}"
            )
    if suffix == ".csv":
        return IOData.from_csv(path, **options)
    if suffix == ".npz":
        if options:
            data = IOData.from_npz(path)
            return data.select(options.get("inputs"), options.get("outputs"))
        return IOData.from_npz(path)
    if suffix in (".dat", ".txt"):
        if options.get("inputs") is None or options.get("outputs") is None:
            raise DataError(
                f"{path}: a .dat file has no header; name the input and output columns "
                "(0-based), e.g. inputs=0, outputs=1"
            )
        return IOData.from_dat(path, **options)
    if suffix == ".mat":
        data = IOData.from_mat(path, **options)
        note = data.metadata.get("dt_note")
        if note:  # a MAT file has no flexid metadata: the note is this read's
            warnings.warn(
                f"{path}: {note} (dt = {data.dt:g} s); the samples are read as equally spaced",
                DataWarning,
                stacklevel=2,
            )
        return data
    raise DataFileError(f"{path}: unknown data file type {suffix!r}; use .csv, .npz, .dat or .mat")


@checked_keywords
def save(data: IOData, path: str | os.PathLike) -> Path:
    """Write ``data`` to ``.csv`` or ``.npz`` according to the suffix; return the path.

    Parameters
    ----------
    data : IOData
        The record.
    path : str or os.PathLike
        Destination; ``.csv`` or ``.npz``.

    Returns
    -------
    pathlib.Path
        The path written.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".csv":
        return data.to_csv(path)
    if suffix == ".npz":
        return data.to_npz(path)
    raise DataFileError(f"{path}: unknown output type {suffix!r}; use .csv or .npz")


# ================================================================================ data
def prepare_data(
    data: IOData | str | os.PathLike,
    *,
    output: str | int | Sequence[str | int] | None = None,
    split: float | int | None = None,
    validation: IOData | str | os.PathLike | None = None,
    detrend: bool | str | None = False,
    load_options: Mapping[str, Any] | None = None,
    several: bool = False,
) -> tuple[IOData, IOData]:
    """Estimation and validation records from a record (or file) and a split rule.

    Parameters
    ----------
    data : IOData, path, or list of them
        The record; a path is read with :func:`flexid.data.load`.  A list (or tuple) of
        records: several estimation records (see Notes).
    output : str, int or sequence of them, optional
        The output channel to model when the record has several; with ``several``, the
        outputs to model (a sequence, or names joined by commas; default all).
    split : float, int, str or pair of ranges, optional
        A fraction in (0, 1) (default 2/3, the paper's rule), a sample index, or the two
        parts as sample ranges (:func:`split_parts`); with ``validation``, a range of
        ``data`` to estimate on.
    validation : IOData or path, optional
        A separate validation record; then all of ``data`` (or the range ``split``) is used
        for estimation.
    detrend : {False, None, True, "constant", "linear"}, optional
        ``"constant"`` (or True): remove the means of the estimation record from both
        (offsets from the estimation part only, so no validation information leaks into
        the model).  ``"linear"``: remove the estimation record's least-squares line, from
        a split record's validation part too (the line extended over its samples); a
        separate validation record loses its own line (its time axis is its own).  Without
        it, a :class:`~flexid.errors.DataWarning` says when a channel's offset or drift
        dwarfs its variation (:data:`OFFSET_RATIO`), and tells an output's drift that the
        input's running sums follow (an integrator's, to be modelled) from a sensor's.
    load_options : mapping, optional
        Options of :func:`load` for a path (``inputs``, ``outputs``, ``dt``, ...).
    several : bool, optional
        Keep several outputs (for a model family with several, a state-space model).

    Returns
    -------
    est : IOData or tuple of IOData
        The estimation record, one output (``several``: the chosen outputs); a tuple of them
        when ``data`` is several records.
    val : IOData
        The validation record, with the same outputs.

    Raises
    ------
    DataError
        A record with several outputs and no ``output`` chosen; several records whose
        channels or sample times differ, or without a ``validation`` record.

    Notes
    -----
    Several estimation records (a list of records or paths, MATLAB's ``merge``) are
    separate experiments of one system: a model is fitted to all of them at once, each with
    its own initial state.  They need a separate ``validation`` record (none is split off)
    and the same channels and sample time.  ``detrend="constant"`` removes the means of all
    the estimation samples together (one operating point, which the model describes) from
    every record; ``"linear"`` removes each record's own least-squares line.
    """
    options = dict(load_options or {})
    if is_records(data):
        return _prepare_records(data, output, split, validation, detrend, options)
    if not isinstance(data, IOData):
        data = load(data, **options)
    chosen = _outputs_chosen(output, several)
    if chosen is not None:
        data = data.select(outputs=chosen)
    if data.n_outputs != 1 and not several:
        raise DataError(
            f"the record has {data.n_outputs} outputs {list(data.output_names)}; the models here "
            "have one output: choose it (output=... or --output NAME)"
        )
    if validation is not None:
        val = validation if isinstance(validation, IOData) else load(validation, **options)
        if chosen is not None:
            val = val.select(outputs=chosen)
        est = data
        if split is not None:  # a range of the estimation record
            est = split_parts(data, split, validation=False)[0]
    else:
        est, val = split_parts(data, split)
    kind = detrend_kind(detrend)
    if kind is not None:
        # a split record's validation part: its samples' place after the estimation start
        shift = None if validation is not None else val.metadata.get("split", {}).get(
            "start", est.n_samples) - est.metadata.get("split", {}).get("start", 0)
        est, val = detrend_pair(est, val, kind, shift)
    else:
        _warn_offsets(est)
    return est, val


def _outputs_chosen(output: Any, several: bool) -> list | None:
    """The outputs ``output`` names: one, or with ``several`` a sequence or comma list."""
    if output is None:
        return None
    if not several:
        if isinstance(output, (list, tuple)):
            if len(output) != 1:
                raise DataError(
                    f"output={list(output)}: the models here have one output; choose one "
                    "(several outputs are modelled together by structure='ss')"
                )
            return list(output)
        return [output]
    if isinstance(output, str):
        return [name.strip() for name in output.split(",") if name.strip()]
    if isinstance(output, (list, tuple)):
        return list(output)
    return [output]


def is_records(data: Any) -> bool:
    """Whether ``data`` is several records (a list or tuple of records or paths).

    A tuple of two arrays ``(u, y)`` is one record, not two.

    Parameters
    ----------
    data : any

    Returns
    -------
    bool
    """
    if not isinstance(data, (list, tuple)) or not data:
        return False
    return all(isinstance(d, (IOData, str, os.PathLike)) for d in data)


def joined(records: Sequence[IOData]) -> IOData:
    """Several records one after another, as one (for what reads one record: checks, delay
    estimates); the first record's names, units, sample time and metadata.

    Parameters
    ----------
    records : sequence of IOData
        With the same channels.

    Returns
    -------
    IOData
    """
    first = records[0]
    return first.replace(u=np.vstack([r.u for r in records]),
                         y=np.vstack([r.y for r in records]))  # fmt: skip


def _prepare_records(
    data: Sequence[Any], output: Any, split: Any, validation: Any, detrend: Any,
    options: dict[str, Any],
) -> tuple[tuple[IOData, ...], IOData]:
    """:func:`prepare_data` of several estimation records."""
    if validation is None:
        raise DataError(
            f"{len(data)} estimation records need a separate validation record "
            "(validation=... / --validation FILE): none is split off"
        )
    if split is not None:
        raise DataError(
            "split with several estimation records: cut each record before (record[a:b]); "
            "the validation record is separate"
        )
    records = [d if isinstance(d, IOData) else load(d, **options) for d in data]
    val = validation if isinstance(validation, IOData) else load(validation, **options)
    if output is not None:
        records = [r.select(outputs=[output]) for r in records]
        val = val.select(outputs=[output])
    first = records[0]
    for i, r in enumerate([*records, val]):
        what = "the validation record" if i == len(records) else f"estimation record {i}"
        if r.n_outputs != 1:
            raise DataError(
                f"{what} has {r.n_outputs} outputs {list(r.output_names)}; the models here "
                "have one output: choose it (output=... or --output NAME)"
            )
        if r.n_inputs != first.n_inputs:
            raise DataError(
                f"{what} has {r.n_inputs} input(s), estimation record 0 has {first.n_inputs}"
            )
        if not np.isclose(r.dt, first.dt, rtol=1e-9, atol=0.0):
            raise DataError(
                f"{what} is sampled every {r.dt:g} s, estimation record 0 every {first.dt:g} s"
            )
    kind = detrend_kind(detrend)
    if kind == "constant":
        u0 = np.concatenate([r.u for r in records]).mean(axis=0)
        y0 = np.concatenate([r.y for r in records]).mean(axis=0)
        info = {"kind": "constant", "u_mean": u0.tolist(), "y_mean": y0.tolist(),
                "from": f"{len(records)} estimation records"}  # fmt: skip
        records = [r.replace(u=r.u - u0, y=r.y - y0, metadata={**r.metadata, "detrend": info})
                   for r in [*records, val]]  # fmt: skip
        val = records.pop()
    elif kind == "linear":
        records = [r.detrend("linear") for r in records]
        val = val.detrend("linear")
    else:
        for r in records:
            _warn_offsets(r)
    return tuple(records), val


def detrend_pair(
    est: IOData, val: IOData, kind: str, shift: int | None
) -> tuple[IOData, IOData]:
    """An estimation record and its validation record less the estimation record's offsets.

    Parameters
    ----------
    est, val : IOData
        The estimation and validation records.
    kind : {"constant", "linear"}
        Remove the estimation record's means, or its least-squares line per channel.
    shift : int or None
        Where ``val``'s first sample lies after ``est``'s first (``0`` when ``val`` is the
        whole record ``est`` begins, ``est.n_samples`` for the part after it): the line is
        extended there.  None: ``val`` is another experiment and loses its own line.

    Returns
    -------
    est, val : IOData
        Detrended, each with ``metadata["detrend"]`` saying what was removed.
    """
    if kind == "constant":
        u0, y0 = est.u.mean(axis=0), est.y.mean(axis=0)
        info = {"kind": "constant", "u_mean": u0.tolist(), "y_mean": y0.tolist(),
                "from": "estimation"}  # fmt: skip
        est = est.replace(u=est.u - u0, y=est.y - y0, metadata={**est.metadata, "detrend": info})
        val = val.replace(u=val.u - u0, y=val.y - y0, metadata={**val.metadata, "detrend": info})
        return est, val
    lines = {k: _line(getattr(est, k)) for k in ("u", "y")}
    info = {"kind": "linear", "from": "estimation",
            **{f"{k}_line": [c.tolist() for c in v] for k, v in lines.items()}}  # fmt: skip
    est = est.replace(**{k: getattr(est, k) - _line_values(lines[k], 0, est.n_samples)
                         for k in lines}, metadata={**est.metadata, "detrend": info})  # fmt: skip
    if shift is None:
        return est, val.detrend("linear")
    val = val.replace(**{k: getattr(val, k) - _line_values(lines[k], shift, val.n_samples)
                         for k in lines}, metadata={**val.metadata, "detrend": info})  # fmt: skip
    return est, val


def _range(value: Any, n: int, what: str) -> tuple[int, int]:
    """``(start, stop)`` of a sample range: a pair (``None`` for an open end) or ``"a:b"``."""
    if isinstance(value, str):
        parts = value.split(":")
        if len(parts) != 2:
            raise DataError(f"{what} must be a sample range START:STOP, got {value!r}")
        try:
            value = [int(p) if p.strip() else None for p in parts]
        except ValueError:
            raise DataError(f"{what} must be a sample range START:STOP, got {value!r}") from None
    if isinstance(value, slice):
        value = (value.start, value.stop)
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise DataError(f"{what} must be a sample range (start, stop), got {value!r}")
    start, stop = (
        default if v is None else integer(v, what, error=DataError)
        for v, default in zip(value, (0, n))
    )
    start, stop = (v + n if v < 0 else v for v in (start, stop))
    if not 0 <= start < stop <= n or stop - start < 2:
        raise DataError(
            f"{what} {start}:{stop} is not a range of at least 2 samples within the "
            f"{n}-sample record"
        )
    return start, stop


def split_parts(
    data: IOData, split: Any = None, *, validation: bool = True
) -> tuple[IOData, IOData | None]:
    """The estimation and validation parts of a record by a split rule.

    Parameters
    ----------
    data : IOData
    split : float, int, str or pair of ranges, optional
        A fraction in (0, 1) of the samples for estimation (default 2/3), a sample index
        (``[0, index)`` and ``[index, N)``), or the two parts as sample ranges: a pair of
        ``(start, stop)`` pairs (``None`` for an open end, negative counts from the end) or
        the text ``"START:STOP,START:STOP"`` (the command line's ``--split 0:1000,1000:``).
        Ranges must not overlap: the validation part is held out.
    validation : bool, optional
        False: ``split`` is the estimation range alone (a separate validation record).

    Returns
    -------
    estimation, validation : IOData
        With ``metadata["split"]`` (``part``, ``start``, ``stop``); validation None when
        ``validation`` is False.

    Raises
    ------
    DataError
        A fraction, index or range out of bounds, or overlapping ranges.
    """
    n = data.n_samples
    if isinstance(split, str) and ":" in split:
        split = split.split(",")
    ranges = isinstance(split, (list, tuple)) or isinstance(split, slice)
    if not validation:  # one range: a pair of ends, "START:STOP" or a slice
        if isinstance(split, list) and len(split) == 1:
            split = split[0]
        a, b = _range(split, n, "the estimation range")
        part = data[a:b]
        part.metadata["split"] = {"part": "estimation", "start": a, "stop": b}
        return part, None
    if not ranges:
        if is_integer(split) and split > 1:
            return data.split(index=int(split))
        return data.split(split)
    if isinstance(split, slice) or len(split) != 2:
        raise DataError(
            f"split as ranges needs two of them (estimation, validation), got {split!r}"
        )
    (a, b), (c, d) = (_range(r, n, what) for r, what in
                      zip(split, ("the estimation range", "the validation range")))  # fmt: skip
    if max(a, c) < min(b, d):
        raise DataError(
            f"the estimation range {a}:{b} and the validation range {c}:{d} overlap: the "
            "validation part must be held out"
        )
    est, val = data[a:b], data[c:d]
    est.metadata["split"] = {"part": "estimation", "start": a, "stop": b}
    val.metadata["split"] = {"part": "validation", "start": c, "stop": d}
    return est, val


#: A channel whose mean, or whose least-squares line's rise over the record, exceeds this
#: many standard deviations of what is left is dominated by an offset or drift.
OFFSET_RATIO = 3.0
DETRENDS = ("constant", "linear")


def detrend_kind(detrend: Any) -> str | None:
    """The detrending rule of ``prepare_data``'s ``detrend`` argument.

    Parameters
    ----------
    detrend : {False, None, True, "constant", "linear"}

    Returns
    -------
    str or None
        ``"constant"``, ``"linear"`` or None.

    Raises
    ------
    UnknownNameError
        Another value (the error is also a DataError).
    """
    if detrend is None or detrend is False:
        return None
    if detrend is True:
        return "constant"
    if isinstance(detrend, str) and detrend in DETRENDS:
        return detrend
    raise _UnknownDetrend("detrend rule", str(detrend), DETRENDS)


class _UnknownDetrend(UnknownNameError, DataError):
    pass


def _line(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per column, the least-squares line ``c0 + c1 t`` over ``t = 0 .. N - 1``."""
    t = np.arange(x.shape[0], dtype=float)
    c1, c0 = np.polyfit(t, x, 1) if x.shape[0] > 1 else (np.zeros(x.shape[1]), x[0])
    return np.asarray(c0, dtype=float), np.asarray(c1, dtype=float)


def _line_values(line: tuple[np.ndarray, np.ndarray], first: int, n: int) -> np.ndarray:
    t = np.arange(first, first + n, dtype=float)[:, None]
    return line[0][None, :] + line[1][None, :] * t


def _running_sums(u: np.ndarray) -> np.ndarray:
    """A constant, a line and each input's first and second running sums, shape (N, 2 + 2 m):
    a line plus what a plant's single and double integrators (a rigid-body velocity and
    angle) make of the input."""
    n = u.shape[0]
    first = np.cumsum(u, axis=0)
    regressors = np.column_stack(
        [np.ones(n), np.arange(n, dtype=float), first, np.cumsum(first, axis=0)]
    )
    # scaled columns: the running sums grow as N and N**2, the least squares stays conditioned
    scale = np.abs(regressors).max(axis=0)
    return regressors / np.where(scale > 0, scale, 1.0)


def _residual_spread(regressors: np.ndarray, x: np.ndarray) -> float:
    """The standard deviation of what the least-squares fit of ``x`` by ``regressors``
    leaves."""
    coef, *_ = np.linalg.lstsq(regressors, x, rcond=None)
    return float((x - regressors @ coef).std())


#: A drift about which the input's running sums leave less than this share of what the line
#: leaves is the plant's: an integrator's answer to the input. A sensor's drift under a stable
#: plant keeps about all of it (0.975 to 1.0 measured), the manipulator's hub angle 0.41, a pure
#: integrator none.
PLANT_DRIFT_SHARE = 0.5


def _warn_offsets(record: IOData) -> None:
    """A DataWarning naming each channel whose offset or drift dwarfs its variation.

    A record with a constant input says nothing here: no model is unique on it, and the
    estimation says so.
    """
    u_spread, u_mean = record.u.std(axis=0), np.abs(record.u.mean(axis=0))
    if np.any(u_spread <= 1e-8 * (u_mean + u_spread)):
        return
    found, plant = [], []
    sums = _running_sums(record.u)
    for kind, x, names in (("output", record.y, record.output_names),
                           ("input", record.u, record.input_names)):  # fmt: skip
        if x.shape[0] < 3:
            continue
        c0, c1 = _line(x)
        rest = x - _line_values((c0, c1), 0, x.shape[0])
        spread, left = x.std(axis=0), rest.std(axis=0)
        mean = x.mean(axis=0)
        rise = np.abs(c1) * (x.shape[0] - 1)
        for i, name in enumerate(names):
            if spread[i] > 0 and abs(mean[i]) > OFFSET_RATIO * spread[i]:
                found.append(f"{kind} {name!r} has mean {mean[i]:.4g} and standard deviation "
                             f"{spread[i]:.4g}: detrend='constant' (--detrend constant)")
            elif left[i] > 0 and rise[i] > OFFSET_RATIO * left[i]:
                drift = (f"{kind} {name!r} drifts by {rise[i]:.4g} over the estimation "
                         f"record against a variation of {left[i]:.4g} about the line")
                if (kind == "output"
                        and _residual_spread(sums, x[:, i]) < PLANT_DRIFT_SHARE * left[i]):
                    plant.append(drift)
                else:
                    found.append(f"{drift}: detrend='linear' (--detrend linear)")
    if plant:
        warnings.warn(
            "; ".join(plant) + ": the input's running sums follow the drift, so it is "
            "the plant's own motion (an integrator, as a rigid-body angle "
            "driven by torque), not a sensor's: keep it (detrending removes the motion) "
            "and use a structure with poles at z = 1 (--structure ss reaches them)",
            DataWarning, stacklevel=3,
        )
    if found:
        warnings.warn(
            "a linear model has no offset term, so it fits an offset or drift with its "
            "dynamics: " + "; ".join(found), DataWarning, stacklevel=3,
        )
