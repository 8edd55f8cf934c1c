"""Tests of flexid.data: IOData construction, checks, split/detrend/select and file I/O."""

from __future__ import annotations

import json

import numpy as np
import pytest

from flexid.data import IOData, load, save
from flexid.errors import DataError, DataFileError
from numerics import EPS, assert_close_to_terms


@pytest.fixture
def record() -> IOData:
    rng = np.random.default_rng(0)
    u = rng.uniform(-0.3, 0.3, (120, 2))
    y = np.column_stack([np.cumsum(u[:, 0]), u[:, 1] ** 2])
    return IOData(
        u,
        y,
        dt=0.001,
        input_names=["torque", "voltage"],
        output_names=["angle", "power"],
        input_units=["N m", "V"],
        output_units=["rad", "W"],
        metadata={"plant": "test", "seed": 3, "params": {"a": np.float64(1.5), "n": np.int64(4)}},
    )


def test_shapes_and_defaults():
    d = IOData(np.arange(5.0), np.ones(5))
    assert d.u.shape == (5, 1) and d.y.shape == (5, 1)
    assert d.dt == 1.0
    assert d.input_names == ("u",) and d.output_names == ("y",)
    assert d.input_units == ("",)
    np.testing.assert_allclose(d.time, np.arange(5.0))
    multi = IOData(np.zeros((4, 2)), np.zeros((4, 3)))
    assert multi.input_names == ("u1", "u2")
    assert multi.output_names == ("y1", "y2", "y3")


def test_arrays_are_read_only_copies():
    u = np.arange(4.0)
    d = IOData(u, u)
    u[0] = 99.0
    assert d.u[0, 0] == 0.0
    with pytest.raises(ValueError):
        d.u[0, 0] = 1.0


@pytest.mark.parametrize(
    ("u", "y", "dt", "match"),
    [
        (np.array([0.0, np.nan, 1.0]), np.zeros(3), 1.0, r"input 'u'.*nan.*sample 1"),
        (np.zeros(3), np.array([0.0, 1.0, np.inf]), 1.0, r"output 'y'.*inf.*sample 2"),
        (np.zeros(3), np.zeros(4), 1.0, "different lengths.*3.*4"),
        (np.zeros(1), np.zeros(1), 1.0, "at least 2 samples"),
        (np.zeros(0), np.zeros(0), 1.0, "at least 2 samples"),
        (np.zeros(3), np.zeros(3), 0.0, "positive"),
        (np.zeros(3), np.zeros(3), -0.1, "positive"),
        (np.zeros(3), np.zeros(3), float("nan"), "positive and finite"),
        (np.zeros(3), np.zeros(3), "fast", "must be a number"),
        (np.zeros((3, 2, 2)), np.zeros(3), 1.0, "1-D .* or 2-D"),
        (["a", "b"], np.zeros(2), 1.0, "numeric"),
    ],
)
def test_bad_records_raise(u, y, dt, match):
    with pytest.raises(DataError, match=match):
        IOData(u, y, dt)


def test_nan_in_second_channel_names_channel_and_sample():
    u = np.zeros((5, 2))
    u[3, 1] = np.nan
    with pytest.raises(DataError, match=r"input 'voltage'.*sample 3"):
        IOData(u, np.zeros(5), input_names=["torque", "voltage"])


def test_wrong_number_of_names():
    with pytest.raises(DataError, match="input_names"):
        IOData(np.zeros((3, 2)), np.zeros(3), input_names=["one"])


def test_split_fraction_and_index(record):
    est, val = record.split()
    assert est.n_samples == 80 and val.n_samples == 40
    np.testing.assert_array_equal(np.vstack([est.u, val.u]), record.u)
    assert est.metadata["split"] == {"part": "estimation", "start": 0, "stop": 80}
    assert val.metadata["split"]["start"] == 80
    assert "split" not in record.metadata
    a, b = record.split(index=100)
    assert (a.n_samples, b.n_samples) == (100, 20)
    a, b = record.split(0.5)
    assert a.n_samples == 60
    a, b = record.split(index=-20)
    assert a.n_samples == 100


@pytest.mark.parametrize(
    "kwargs",
    [
        {"fraction": 0.0},
        {"fraction": 1.0},
        {"index": 1},
        {"index": 119},
        {"fraction": 0.5, "index": 3},
        {"index": 2.5},
    ],
)
def test_bad_split(record, kwargs):
    with pytest.raises(DataError):
        record.split(**kwargs)


@pytest.mark.numerics
def test_detrend(record):
    shifted = record.replace(y=record.y + np.array([5.0, -2.0]))
    d = shifted.detrend()
    # zero up to rounding: the mean is an n-term sum (n u relative to mean|y|, any order),
    # subtracting it rounds each sample, and the mean of the result is another n-term sum
    n = shifted.n_samples
    bound = (n + 1) * EPS * (np.abs(shifted.y).mean(axis=0) + np.abs(d.y).mean(axis=0))
    assert_close_to_terms(d.y.mean(axis=0), 0.0, bound, 1.0)
    np.testing.assert_allclose(d.metadata["detrend"]["y_mean"], shifted.y.mean(axis=0))
    t = np.arange(50.0)
    # a line exactly: the residual of a backward-stable least-squares fit (LAPACK) of
    # m = 50 samples on n = 2 regressors is at most 2 gamma_mn (|b| + |A|_F |x|) = 2.7e-11
    # here (|b| = 408; scipy's regressors [t / N, 1] give |A|_F |x| = 820), plus the
    # residual's own rounding (3 u |b|_inf = 3e-14): 1e-10 holds on any machine
    line = IOData(t, 2.0 * t + 1.0).detrend("linear")
    np.testing.assert_allclose(line.y, 0.0, atol=1e-10)
    with pytest.raises(DataError):
        record.detrend("quadratic")


def test_select_and_slice(record):
    s = record.select(inputs="voltage", outputs=["power", 0])
    assert s.input_names == ("voltage",) and s.output_names == ("power", "angle")
    assert s.output_units == ("W", "rad")
    np.testing.assert_array_equal(s.y[:, 0], record.y[:, 1])
    assert record[10:20].n_samples == 10
    with pytest.raises(DataError, match="no output channel 'speed'"):
        record.select(outputs="speed")
    with pytest.raises(DataError, match="out of range"):
        record.select(inputs=5)
    with pytest.raises(TypeError):
        record[3]


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_round_trip_is_exact(record, tmp_path, suffix):
    path = save(record, tmp_path / f"rec{suffix}")
    back = load(path)
    assert back == record
    assert back.metadata["params"] == {"a": 1.5, "n": 4}
    assert back.input_units == ("N m", "V")


def test_same_record_gives_identical_bytes(record, tmp_path):
    for suffix in (".csv", ".npz"):
        a = record.save(tmp_path / f"a{suffix}").read_bytes()
        b = record.save(tmp_path / f"b{suffix}").read_bytes()
        assert a == b


def test_npz_is_read_without_pickle(tmp_path):
    path = tmp_path / "evil.npz"
    np.savez(path, u=np.zeros(3), y=np.zeros(3), meta=np.array([{"x": 1}], dtype=object))
    with pytest.raises(DataFileError, match="not a readable flexid NPZ"):
        load(path)
    np.savez(tmp_path / "partial.npz", u=np.zeros(3))
    with pytest.raises(DataFileError, match="lacks"):
        load(tmp_path / "partial.npz")


def test_plain_csv_with_default_column_names(tmp_path):
    path = tmp_path / "plain.csv"
    path.write_text("t,u,y\n0.0,1,2\n0.1,3,4\n0.2,5,6\n")
    d = load(path)
    assert d.input_names == ("u",) and d.output_names == ("y",)
    assert d.dt == pytest.approx(0.1)
    np.testing.assert_array_equal(d.y[:, 0], [2, 4, 6])


def test_plain_csv_with_named_columns_and_assumed_dt(tmp_path):
    path = tmp_path / "rig.csv"
    path.write_text("voltage,angle,other\n1,2,3\n4,5,6\n7,8,9\n")
    d = IOData.from_csv(path, inputs="voltage", outputs=["angle"])
    assert d.metadata["dt_assumed"] is True and d.dt == 1.0
    d = IOData.from_csv(path, inputs=[0], outputs=[2], dt=0.5)
    np.testing.assert_array_equal(d.y[:, 0], [3, 6, 9])
    with pytest.raises(DataError, match="cannot tell inputs from outputs"):
        IOData.from_csv(path)
    with pytest.raises(DataError, match="no column 'speed'"):
        IOData.from_csv(path, inputs="voltage", outputs="speed")


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("", "no header row"),
        ("u,y\n1,2\n3\n", r"line 3: 1 field\(s\), expected 2"),
        ("u,y\n1,2\n3,abc\n", r"line 3, column 'y': 'abc' is not a number"),
        ("1,2\n3,4\n", "header row"),
        ("# flexid-iodata {not json\nu,y\n1,2\n", "malformed flexid metadata"),
    ],
)
def test_malformed_csv(tmp_path, text, match):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(DataFileError, match=match):
        load(path)


def test_csv_with_nan_names_position(tmp_path):
    path = tmp_path / "nan.csv"
    path.write_text("u,y\n1,2\n3,nan\n5,6\n")
    with pytest.raises(DataError, match=r"output 'y'.*sample 1"):
        load(path)


def test_missing_and_unknown_files(tmp_path):
    with pytest.raises(DataFileError, match="no such file"):
        load(tmp_path / "missing.csv")
    with pytest.raises(DataFileError, match="unknown data file type"):
        load(tmp_path / "data.xlsx")
    with pytest.raises(DataFileError, match="is a directory"):
        IOData.from_csv(tmp_path)
    binary = tmp_path / "binary.csv"
    binary.write_bytes(b"\xff\xfe\x00\x01")
    with pytest.raises(DataFileError, match="not a text file"):
        load(binary)
    with pytest.raises(DataFileError, match="unknown output type"):
        save(IOData(np.zeros(3), np.zeros(3)), tmp_path / "x.mat")


def test_dat_file(tmp_path):
    path = tmp_path / "arm.dat"
    rows = "\n".join(f"  {0.1 * k:.7e}\t{-0.2 * k:.7e}" for k in range(10))
    path.write_text("% DaISy style comment\n" + rows + "\n")
    d = load(path, inputs=0, outputs=1, dt=0.01)
    assert d.n_samples == 10 and d.dt == 0.01
    np.testing.assert_allclose(d.y[:, 0], -0.2 * np.arange(10))
    with pytest.raises(DataError, match="name the input and output columns"):
        load(path)
    with pytest.raises(DataError, match="out of range"):
        load(path, inputs=0, outputs=2)
    ragged = tmp_path / "ragged.dat"
    ragged.write_text("1 2\n3 4 5\n")
    with pytest.raises(DataFileError, match=r"line 2: 3 column\(s\), expected 2"):
        load(ragged, inputs=0, outputs=1)
    words = tmp_path / "words.dat"
    words.write_text("1 2\n3 x\n")
    with pytest.raises(DataFileError, match="line 2: 'x' is not a number"):
        load(words, inputs=0, outputs=1)


def test_describe_and_repr(record):
    text = record.describe()
    assert "torque [N m]" in text and "angle [rad]" in text
    assert "N=120" in repr(record)


def test_metadata_must_survive_json(record, tmp_path):
    path = record.save(tmp_path / "m.csv")
    first = path.read_text().splitlines()[0]
    header = json.loads(first.split(" ", 2)[2])
    assert header["metadata"]["plant"] == "test"


def test_real_robot_arm_if_present():
    from pathlib import Path

    path = Path(__file__).resolve().parents[2] / "shared" / "data" / "real" / "robot_arm.csv"
    if not path.exists():
        pytest.skip("shared real data not present")
    d = load(path)
    assert d.n_samples == 1024 and d.input_names == ("u",) and d.output_names == ("y",)
