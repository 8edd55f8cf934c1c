"""Tests of reading MATLAB ``.mat`` files: plain variables, iddata-like structures, errors.

Every file is written here by :func:`scipy.io.savemat` (v4 and v5 formats) or by hand (a
v7.3 header), so the tests need no MATLAB.  MAT files store IEEE-754 doubles as they are,
so values read back must equal the values written, bit for bit.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.io import savemat

from flexid import load
from flexid.cli import main
from flexid.errors import DataError, DataFileError

N = 120


@pytest.fixture
def signals():
    rng = np.random.default_rng(7)
    u = rng.standard_normal((N, 2))
    # noise keeps the ARX regressors of the command-line tests full rank
    y = np.convolve(u[:, 0], [0.0, 0.5, 0.25])[:N] - 0.3 * u[:, 1] + 0.1 * rng.standard_normal(N)
    return u, y


def write_v73(path, hdf5_at: int = 512) -> None:
    """A file that starts like a MATLAB v7.3 file: the 128-byte MAT header, then HDF5."""
    text = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Nov 23 2026 HDF5 schema 1.00 ."
    header = text.ljust(116, b" ") + bytes(8) + b"\x00\x02" + b"IM"
    path.write_bytes(header.ljust(hdf5_at, b"\x00") + b"\x89HDF\r\n\x1a\n" + bytes(64))


# ---------------------------------------------------------------------- plain variables
def test_plain_u_y_and_ts_round_trip(tmp_path, signals):
    u, y = signals
    path = tmp_path / "rig.mat"
    savemat(path, {"u": u, "y": y, "Ts": 0.002})
    data = load(path)
    np.testing.assert_array_equal(data.u, u)
    np.testing.assert_array_equal(data.y[:, 0], y)
    assert data.dt == 0.002
    assert data.input_names == ("u[0]", "u[1]") and data.output_names == ("y",)
    assert data.metadata["source"] == str(path) and data.metadata["mat_format"] == "5"
    assert "dt_assumed" not in data.metadata


def test_named_variables_row_and_column_vectors(tmp_path, signals):
    u, y = signals
    path = tmp_path / "rig.mat"
    # MATLAB row vectors (1, N) and column vectors (N, 1) are both one channel
    savemat(path, {"torque": u[:, 0][None, :], "accel": y[:, None], "dt": 0.01})
    data = load(path, inputs="torque", outputs=["accel"])
    assert data.input_names == ("torque",) and data.output_names == ("accel",)
    np.testing.assert_array_equal(data.u[:, 0], u[:, 0])
    np.testing.assert_array_equal(data.y[:, 0], y)
    assert data.dt == 0.01


def test_columns_of_one_matrix_by_index_and_by_name(tmp_path, signals):
    u, y = signals
    path = tmp_path / "daisy.mat"
    savemat(path, {"X": np.column_stack([u, y])})
    data = load(path, inputs=[0, 1], outputs=2, dt=0.1)
    np.testing.assert_array_equal(data.u, u)
    np.testing.assert_array_equal(data.y[:, 0], y)
    assert data.input_names == ("X[0]", "X[1]") and data.output_names == ("X[2]",)
    same = load(path, inputs=["X[0]", "X[1]"], outputs="X[2]", dt=0.1)
    assert same == data
    picked = load(path, inputs=1, outputs=2, variable="X")
    np.testing.assert_array_equal(picked.u[:, 0], u[:, 1])
    assert picked.metadata["dt_assumed"] is True and picked.dt == 1.0


def test_dt_from_a_time_vector(tmp_path, signals):
    u, y = signals
    path = tmp_path / "t.mat"
    savemat(path, {"u": u[:, 0], "y": y, "t": np.arange(N) * 0.25})
    assert load(path).dt == 0.25  # multiples of 0.25 and their differences are exact


def test_given_dt_wins_over_the_file(tmp_path, signals):
    u, y = signals
    path = tmp_path / "rig.mat"
    savemat(path, {"u": u, "y": y, "Ts": 0.002})
    assert load(path, dt=0.5).dt == 0.5


def test_v4_format(tmp_path, signals):
    u, y = signals
    path = tmp_path / "old.mat"
    savemat(path, {"u": u[:, 0], "y": y, "Ts": np.array([[0.05]])}, format="4")
    data = load(path)
    np.testing.assert_array_equal(data.u[:, 0], u[:, 0])
    np.testing.assert_array_equal(data.y[:, 0], y)
    assert data.dt == 0.05 and data.metadata["mat_format"] == "4"


# ---------------------------------------------------------------------- structures
def iddata_struct(u, y, **fields):
    return {"y": y[:, None], "u": u, "Ts": 5.0, "TimeUnit": "milliseconds", **fields}


def test_iddata_like_struct_with_names_units_and_time_unit(tmp_path, signals):
    u, y = signals
    path = tmp_path / "rig.mat"
    struct = iddata_struct(
        u,
        y,
        InputName=np.array(["torque", "voltage"], dtype=object),
        InputUnit=np.array(["N m", "V"], dtype=object),
        OutputName=np.array(["tip"], dtype=object),
        OutputUnit="m/s^2",
        Notes="bench test",
    )
    savemat(path, {"data": struct})
    data = load(path)
    np.testing.assert_array_equal(data.u, u)
    np.testing.assert_array_equal(data.y[:, 0], y)
    assert data.dt == 5.0 * 1e-3  # the same product in the test and the reader
    assert data.input_names == ("torque", "voltage") and data.output_names == ("tip",)
    assert data.input_units == ("N m", "V") and data.output_units == ("m/s^2",)
    assert data.metadata["mat_variable"] == "data"
    chosen = load(path, inputs="voltage", outputs=0)
    assert chosen.input_names == ("voltage",)
    np.testing.assert_array_equal(chosen.u[:, 0], u[:, 1])


def test_struct_with_inputdata_outputdata_fields(tmp_path, signals):
    u, y = signals
    path = tmp_path / "rig.mat"
    savemat(path, {"exp": {"OutputData": y, "InputData": u[:, 0], "Ts": 0.1}})
    data = load(path)
    np.testing.assert_array_equal(data.y[:, 0], y)
    assert data.dt == 0.1 and data.input_names == ("u",) and data.output_names == ("y",)


def test_struct_without_ts_assumes_one_second(tmp_path, signals):
    u, y = signals
    path = tmp_path / "rig.mat"
    savemat(path, {"exp": {"y": y, "u": u[:, 0]}})
    data = load(path)
    assert data.dt == 1.0 and data.metadata["dt_assumed"] is True


def test_several_structs_need_variable(tmp_path, signals):
    u, y = signals
    path = tmp_path / "two.mat"
    savemat(path, {"a": {"y": y, "u": u[:, 0], "Ts": 0.1}, "b": {"y": -y, "u": u, "Ts": 0.2}})
    with pytest.raises(DataError, match=r"several structures.*a, b.*variable="):
        load(path)
    data = load(path, variable="b")
    assert data.n_inputs == 2 and data.dt == 0.2
    np.testing.assert_array_equal(data.y[:, 0], -y)


# ---------------------------------------------------------------------- errors
def test_v73_file_names_the_fix(tmp_path):
    path = tmp_path / "new.mat"
    write_v73(path)
    with pytest.raises(DataFileError, match=r"new\.mat: a MATLAB v7\.3 \(HDF5\).*-v7.*h5py"):
        load(path)
    bare = tmp_path / "bare.mat"  # an HDF5 file renamed to .mat
    bare.write_bytes(b"\x89HDF\r\n\x1a\n" + bytes(100))
    with pytest.raises(DataFileError, match=r"v7\.3"):
        load(bare)


def test_v73_header_without_hdf5_superblock_is_still_named(tmp_path):
    """The version field of the MAT header says 7.3 even where the HDF5 part is damaged."""
    path = tmp_path / "cut.mat"
    write_v73(path, hdf5_at=600)
    with pytest.raises(DataFileError, match=r"v7\.3"):
        load(path)


@pytest.mark.parametrize(
    "payload, match",
    [
        (b"", "empty file"),
        (b"not a MAT file at all, just text " * 8, "not a readable MAT file"),
    ],
)
def test_not_a_mat_file(tmp_path, payload, match):
    path = tmp_path / "bad.mat"
    path.write_bytes(payload)
    with pytest.raises(DataFileError, match=match):
        load(path)


def test_truncated_and_missing_files(tmp_path, signals):
    u, y = signals
    full = tmp_path / "full.mat"
    savemat(full, {"u": u, "y": y})
    cut = tmp_path / "cut.mat"
    for size in (300, 3, 10):  # inside the data, and inside the header
        cut.write_bytes(full.read_bytes()[:size])
        with pytest.raises(DataFileError, match=r"cut\.mat"):
            load(cut)
    with pytest.raises(DataFileError, match="no such file"):
        load(tmp_path / "missing.mat")


def _bad_value_cases(u, y):
    y_nan = y.copy()
    y_nan[7] = np.nan
    return [
        ({"u": u, "y": y_nan}, {}, DataError, r"variable 'y' has 1 non-finite.*sample 7"),
        ({"u": u + 1j, "y": y}, {}, DataError, r"variable 'u' is complex"),
        ({"u": "volts", "y": y}, {}, DataError, r"variable 'u' is text"),
        ({"u": u[:100], "y": y}, {}, DataError, r"100 samples.*120"),
        ({"u": u, "y": y}, {"inputs": "v", "outputs": "y"}, DataError, r"no variable 'v'"),
        ({"X": u}, {"inputs": 5, "outputs": 0}, DataError, r"column 5 out of range.*'X'"),
        ({"X": u}, {}, DataError, r"no variables u and y.*variables: X"),
        ({"u": u, "y": y}, {"inputs": "u"}, DataError, "name both"),
        ({"u": u, "y": y, "Ts": -1.0}, {}, DataError, r"variable 'Ts'.*positive"),
        ({"u": u, "y": np.zeros((N, 2, 2))}, {}, DataError, r"variable 'y' has shape"),
        ({"u": np.zeros((0, 0)), "y": y}, {}, DataError, r"variable 'u' is empty"),
        (
            {"s": {"y": np.array([y, y[:50]], dtype=object), "u": u}},
            {},
            DataFileError,
            r"variable 's', field 'y' is a cell array.*getexp",
        ),
        (
            {"s": np.array([{"y": y, "u": u}, {"y": y, "u": u}])},
            {},
            DataFileError,
            r"variable 's' is an array of 2 structures",
        ),
        ({"s": {"y": y, "u": np.zeros((0, 0))}}, {}, DataError, r"'s' has no input.*time series"),
        ({"s": {"u": u}}, {"variable": "s"}, DataError, r"'s' has no output field"),
        (
            {"s": {"y": y, "u": u[:, 0], "Ts": 1.0, "TimeUnit": "fortnights"}},
            {},
            DataError,
            r"'TimeUnit': unknown unit 'fortnights'",
        ),
        ({"s": {"y": y, "u": u[:, 0]}}, {"outputs": "pitch"}, DataError, r"structure 's'.*pitch"),
        ({"u": u, "y": y}, {"variable": "z"}, DataError, r"no variable 'z'"),
    ]


def test_bad_values_raise_typed_errors_naming_file_and_variable(tmp_path, signals):
    u, y = signals
    for k, (variables, options, error, match) in enumerate(_bad_value_cases(u, y)):
        path = tmp_path / f"bad{k}.mat"
        savemat(path, variables)
        with pytest.raises(error, match=match) as info:
            load(path, **options)
        assert f"bad{k}.mat" in str(info.value), (k, str(info.value))


def test_matlab_object_gets_the_struct_fix(tmp_path, monkeypatch, signals):
    """An iddata saved as an object reaches Python as an opaque value scipy cannot decode."""
    import scipy.io
    from scipy.io.matlab import MatlabOpaque

    u, y = signals
    path = tmp_path / "obj.mat"
    savemat(path, {"u": u, "y": y})
    opaque = MatlabOpaque(np.zeros(1, dtype=[("s0", "O"), ("s1", "O"), ("s2", "O")]))
    monkeypatch.setattr(scipy.io, "loadmat", lambda *a, **k: {"data": opaque})
    with pytest.raises(DataFileError, match=r"'data' is a MATLAB object.*struct\(data\)"):
        load(path)


# ---------------------------------------------------------------------- command line
def test_cli_identifies_from_a_mat_struct(tmp_path, signals, capsys):
    u, y = signals
    path = tmp_path / "rig.mat"
    other = {"y": y, "u": u[:, 0], "Ts": 0.2}
    savemat(path, {"exp": iddata_struct(u, y), "other": other})
    assert main(["identify", str(path), "--na", "2", "--optimiser", "ls"]) == 2
    assert "--variable" in capsys.readouterr().err
    argv = ["identify", str(path), "--na", "2", "--nb", "3,3", "--optimiser", "ls", "--json"]
    assert main([*argv, "--variable", "exp", "--max-lag", "10"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["data"]["dt"] == 0.005 and result["data"]["inputs"] == ["u1", "u2"]
    assert result["data"]["n_estimation"] + result["data"]["n_validation"] == N


def test_cli_plain_variables_and_columns(tmp_path, signals, capsys):
    u, y = signals
    path = tmp_path / "daisy.mat"
    savemat(path, {"X": np.column_stack([u, y])})
    argv = ["identify", str(path), "--na", "2", "--optimiser", "ls", "--json", "--max-lag", "10"]
    assert main([*argv, "--inputs", "0", "--outputs", "2", "--dt", "0.1"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["data"]["inputs"] == ["X[0]"] and result["data"]["output"] == "X[2]"
    assert result["data"]["dt"] == 0.1


def test_cli_mat_errors_are_one_line(tmp_path, capsys):
    path = tmp_path / "new.mat"
    write_v73(path)
    assert main(["identify", str(path), "--na", "2"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "v7.3" in err and "-v7" in err
    csv = tmp_path / "r.csv"
    csv.write_text("u,y\n1,2\n3,4\n")
    assert main(["identify", str(csv), "--na", "2", "--variable", "x"]) == 2
    assert "--variable is for MATLAB .mat files" in capsys.readouterr().err
