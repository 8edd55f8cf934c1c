"""Tests of the IOHprofiler export and of the ECDF of (run, target) pairs.

The export is read back with a small parser written here from the format's description (not
with flexid's writer), and every run's (FE, best-so-far) sequence is checked against the
store.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from flexid import compare, load_result
from flexid.cli import main
from flexid.config import ComparisonSpec, SearchSpec
from flexid.errors import ConfigError, StoreError
from flexid.jobs.store import ResultStore
from flexid.report import comparison_ecdf, ecdf_fraction, ecdf_targets, export_ioh, write_report
from helpers import tiny_spec


def _spec(name: str, numerator: str) -> ComparisonSpec:
    return tiny_spec(name, search=SearchSpec(numerator=numerator), targets=(1.0, 0.1))


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    """Two tiny comparisons (b fitted: dimension na = 2; b searched: na + nb = 4), and a
    failed run written into the first, as a crashed optimiser leaves it."""
    path = tmp_path_factory.mktemp("ioh") / "r.sqlite"
    with ResultStore(path) as s:
        first = compare(_spec("fitted b", "fit"), store=s, progress=False)
        compare(_spec("searched b", "search"), store=s, progress=False)
        s.write_run(
            first.key,
            {"label": "random-search", "run": 1, "seed": 7, "status": "failed",
             "error": "RuntimeError: boom"},
        )
    return path


# ------------------------------------------------------------------ an independent reader
def _read_dat(path: Path, header: str) -> list[list[tuple[int, float]]]:
    """Blocks of (evaluations, value) rows, one per run, each opened by ``header``."""
    blocks: list[list[tuple[int, float]]] = []
    for line in path.read_text(encoding="utf-8").splitlines():
        if line == header:
            blocks.append([])
            continue
        fe, value = line.split(" ")
        blocks[-1].append((int(fe), float(value)))
    return blocks


def _read_json_export(folder: Path) -> dict[str, dict]:
    """``algorithm name -> {"meta": json, "runs": {instance: [(fe, best), ...]}}``."""
    out = {}
    for meta_path in folder.glob("*/IOHprofiler_f*_*.json"):
        meta = json.loads(meta_path.read_text(encoding="utf-8"))
        (scenario,) = meta["scenarios"]
        blocks = _read_dat(meta_path.parent / scenario["path"], "evaluations raw_y")
        instances = [r["instance"] for r in scenario["runs"]]
        assert len(blocks) == len(instances)
        out[meta["algorithm"]["name"]] = {"meta": meta, "runs": dict(zip(instances, blocks))}
    return out


def _read_info_export(folder: Path) -> dict[str, dict]:
    """``algId -> {"header": {key: value}, "runs": {instance: [(fe, best), ...]},
    "summary": {instance: (evals, best)}}`` from the three-line ``.info`` files."""
    out = {}
    for info_path in folder.glob("*/IOHprofiler_f*_*.info"):
        first, comment, third = info_path.read_text(encoding="utf-8").splitlines()
        assert comment == "%"
        header = dict(
            (k.strip(), v.strip().strip('"'))
            for k, v in (pair.split("=", 1) for pair in first.split(", "))
        )
        datafile, *entries = [e.strip() for e in third.split(",")]
        summary = {}
        for entry in entries:
            instance, rest = entry.split(":")
            evals, best = rest.split("|")
            summary[int(instance)] = (int(evals), float(best))
        blocks = _read_dat(info_path.parent / datafile, '"function evaluation" "best-so-far f(x)"')
        out[header["algId"]] = {
            "header": header,
            "runs": dict(zip(summary, blocks)),
            "summary": summary,
        }
    return out


def _stored_runs(store: Path) -> dict[str, dict]:
    """``key -> {label: {run: record}}`` of the finished optimiser runs."""
    out: dict[str, dict] = {}
    with ResultStore(store, readonly=True) as s:
        for entry in s.comparisons():
            for r in s.runs(entry["key"]):
                if r["label"] != "ls" and r["status"] == "ok":
                    out.setdefault(entry["key"], {}).setdefault(r["label"], {})[r["run"]] = r
    return out


# ------------------------------------------------------------------ export
def test_json_export_reads_back_as_the_store(store, tmp_path):
    folders = export_ioh(store, tmp_path)
    stored = _stored_runs(store)
    results = {r.key: r for r in load_result(store)}
    assert len(folders) == 2
    for folder in folders:
        key = next(k for k in stored if folder.name.endswith(k[:8]))
        result = results[key]
        exported = _read_json_export(folder)
        assert set(exported) == {"sda", "random-search"}
        for label, runs in stored[key].items():
            meta = exported[label]["meta"]
            assert meta["function_id"] == 1 and meta["maximization"] is False
            assert meta["attributes"] == ["evaluations", "raw_y"]
            (scenario,) = meta["scenarios"]
            # the search vector: a only when b is fitted, a and b when it is searched
            assert scenario["dimension"] == (2 if result.spec.search.numerator == "fit" else 4)
            attrs = {k: v for d in meta["experiment_attributes"] for k, v in d.items()}
            # written with repr, so the float reads back bit for bit
            assert float(attrs["reference_cost"]) == result.reference_cost
            assert set(exported[label]["runs"]) == set(runs)
            for entry in scenario["runs"]:
                record = runs[entry["instance"]]
                h = record["history"]
                # exact to the evaluation: the first (finite) evaluation opens the run, each
                # row lowers the best, the last is the run's last FE
                assert h["fe"][0] == 1 and h["fe"][-1] == record["nfev"]
                assert np.all(np.diff(h["fe"]) > 0) and np.all(np.diff(h["best"][:-1]) < 0)
                assert entry["best"]["x"] == record["x"]
                assert len(record["x"]) == scenario["dimension"]
                # exact: the writer uses the shortest round-trip text of each double
                assert exported[label]["runs"][entry["instance"]] == list(zip(h["fe"], h["best"]))
                assert entry["evals"] == record["nfev"] == h["fe"][-1]
                assert entry["best"]["y"] == record["cost"] == h["best"][-1]
                first = h["best"].index(h["best"][-1])
                assert entry["best"]["evals"] == h["fe"][first]
                assert entry["seed"] == record["seed"]
    readme = (folders[0].parent / folders[0].name / "README.md").read_text()
    assert "reference cost" in readme


def test_failed_runs_are_left_out_and_listed(store, tmp_path):
    (folder,) = [f for f in export_ioh(store, tmp_path) if f.name.startswith("fitted-b")]
    exported = _read_json_export(folder)
    assert set(exported["random-search"]["runs"]) == {0}
    assert set(exported["sda"]["runs"]) == {0, 1}
    assert "random-search run 1 (RuntimeError: boom)" in (folder / "README.md").read_text()


def test_info_layout_reads_back_as_the_store(store, tmp_path):
    stored = _stored_runs(store)
    for folder in export_ioh(store, tmp_path, layout="info"):
        key = next(k for k in stored if folder.name.endswith(k[:8]))
        exported = _read_info_export(folder)
        for label, runs in stored[key].items():
            header = exported[label]["header"]
            assert header["maximization"] == "F" and header["funcId"] == "1"
            assert set(exported[label]["runs"]) == set(runs)
            for run, record in runs.items():
                h = record["history"]
                assert exported[label]["runs"][run] == list(zip(h["fe"], h["best"]))
                assert exported[label]["summary"][run] == (record["nfev"], record["cost"])


def test_reexport_replaces_and_a_failure_leaves_nothing(store, tmp_path, monkeypatch):
    from flexid.jobs import _ioh

    folders = export_ioh(store, tmp_path)
    stale = folders[0] / "stale.dat"
    stale.write_text("old")
    assert export_ioh(store, tmp_path) == folders
    assert not stale.exists()
    before = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))

    calls = {"n": 0}
    original = _ioh._write_algorithm

    def fail_on_second(*args, **kwargs):
        calls["n"] += 1
        if calls["n"] == 2:
            raise OSError("disk full")
        return original(*args, **kwargs)

    monkeypatch.setattr(_ioh, "_write_algorithm", fail_on_second)
    with pytest.raises(OSError, match="disk full"):
        export_ioh(store, tmp_path)
    # the earlier export is whole, and no temporary folder is left behind
    assert sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*")) == before


def test_bad_input_raises_before_writing(store, tmp_path):
    with pytest.raises(ConfigError, match="layout"):
        export_ioh(store, tmp_path / "a", layout="csv")
    empty = tmp_path / "empty.sqlite"
    ResultStore(empty).close()
    with pytest.raises(ConfigError, match="no comparison"):
        export_ioh(empty, tmp_path / "b")
    with pytest.raises(StoreError):
        export_ioh(tmp_path / "missing.sqlite", tmp_path / "c")
    broken = _store_with(store, tmp_path / "broken.sqlite", lambda r: r.pop("history"))
    with pytest.raises(StoreError, match="no history"):
        export_ioh(broken, tmp_path / "d")
    # a run recorded without its best search point (an older flexid's store)
    old = _store_with(store, tmp_path / "old.sqlite", lambda r: r.pop("x"))
    with pytest.raises(StoreError, match="sda' run 0 has no best search point"):
        export_ioh(old, tmp_path / "e")
    assert not any((tmp_path / n).exists() for n in "abcde")


def test_a_run_whose_first_cost_is_not_finite_still_opens_at_evaluation_1(store, tmp_path):
    def first_infinite(r):
        # the first evaluation's cost was +inf: the history starts at the second
        r["history"] = {"fe": r["history"]["fe"][1:], "best": r["history"]["best"][1:]}

    path = _store_with(store, tmp_path / "inf.sqlite", first_infinite)
    (folder,) = export_ioh(path, tmp_path / "out")
    block = _read_json_export(folder)["sda"]["runs"][0]
    assert block[0] == (1, float("inf")) and block[1][0] > 1


def _store_with(store: Path, path: Path, change) -> Path:
    """A copy of the first comparison with ``change`` applied to its first sda run."""
    with ResultStore(store, readonly=True) as src, ResultStore(path) as dst:
        entry = src.comparisons()[0]
        dst.add_comparison(entry["key"], entry["name"], entry["spec"])
        for r in src.runs(entry["key"]):
            if r["label"] == "sda" and r["run"] == 0:
                change(r)
            dst.write_run(entry["key"], r)
    return path


def test_iohinspector_reads_the_export_as_the_store(store, tmp_path):
    """An independent IOHprofiler reader loads every run with the store's numbers."""
    iohinspector = pytest.importorskip("iohinspector")
    stored = _stored_runs(store)
    for folder in export_ioh(store, tmp_path):
        key = next(k for k in stored if folder.name.endswith(k[:8]))
        manager = iohinspector.DataManager()
        manager.add_folder(str(folder))
        # iohinspector splits a .dat file into runs where evaluations == 1 and joins them
        # to the JSON's runs in order
        frame = manager.load(monotonic=False, include_meta_data=True)
        loaded = {}
        for row in frame.select(["algorithm_name", "instance", "evaluations", "raw_y"]).rows():
            loaded.setdefault((row[0], row[1]), []).append((row[2], row[3]))
        expected = {
            (label, run): list(zip(r["history"]["fe"], r["history"]["best"]))
            for label, runs in stored[key].items()
            for run, r in runs.items()
        }
        # the text is the shortest round-trip form of each double: read back bit for bit
        assert loaded == expected
        overview = manager.overview
        assert sorted(overview["best_y"].to_list()) == sorted(
            r["cost"] for runs in stored[key].values() for r in runs.values()
        )


# ------------------------------------------------------------------ ECDF
def test_ecdf_fraction_by_hand():
    histories = [
        {"fe": [10, 20, 40], "best": [5.0, 3.0, 1.0]},
        {"fe": [10, 30], "best": [4.0, 2.0]},
    ]
    targets = [4.5, 2.5, 1.5]
    # (run, target) pairs reached: none before the first batch; at 10 run 2 reaches 4.5;
    # at 20 run 1 too; at 30 run 2 reaches 2.5; at 40 run 1 reaches all three; 1.5 is
    # never reached by run 2, so the curve stops at 5 of 6.
    got = ecdf_fraction(histories, targets, [5, 10, 20, 30, 40, 1000])
    # exact: k / 6 for small integers k is computed once, the same way on any machine
    assert got.tolist() == [0.0, 1 / 6, 2 / 6, 3 / 6, 5 / 6, 5 / 6]
    assert np.isnan(ecdf_fraction([], targets, [1])).all()
    assert np.isnan(ecdf_fraction(histories, [], [1])).all()


def test_ecdf_targets_by_hand():
    # precisions 10 -> 0.01, one to a decade: 10, 1, 0.1, 0.01
    got = ecdf_targets(100.0, [150.0, 1100.0, float("inf")], 0.01, per_decade=1)
    # geomspace and the product carry a few ulps of rounding; 1e-12 is far above that
    np.testing.assert_allclose(got, [1100.0, 200.0, 110.0, 101.0], rtol=1e-12)
    assert ecdf_targets(100.0, [100.5], 0.01).tolist() == [101.0]
    assert ecdf_targets(float("nan"), [1.0], 0.1).size == 0
    assert ecdf_targets(0.0, [1.0], 0.1).size == 0
    with pytest.raises(ConfigError, match="hardest"):
        ecdf_targets(1.0, [2.0], 0.0)
    with pytest.raises(ConfigError, match="per_decade"):
        ecdf_targets(1.0, [2.0], 0.1, per_decade=0)


def test_comparison_ecdf_ends_at_the_final_costs(store):
    result = load_result(store)[0]
    ecdf = comparison_ecdf(result)
    targets = ecdf["targets"]
    assert targets.size >= 2 and np.all(np.diff(targets) < 0)
    assert targets[-1] == pytest.approx(result.reference_cost * 1.1, rel=1e-12)
    for label, curve in ecdf["curves"].items():
        ok = [r for r in result.records[label] if r["status"] == "ok"]
        assert curve["runs"] == len(ok)
        assert curve["fe"][0] == 1 and np.all(np.diff(curve["fraction"]) >= 0)
        # at FE 1 only the first evaluations count, and the easiest target is the worst of
        # them over all optimisers: reached at FE 1 by every run
        firsts = np.array([r["history"]["best"][0] for r in ok])
        assert all(r["history"]["fe"][0] == 1 for r in ok)
        at_one = (firsts[:, None] <= targets[None, :]).mean()
        assert curve["fraction"][0] == pytest.approx(at_one, abs=1e-15)
        assert curve["fraction"][0] >= 1 / targets.size
        finals = np.array([r["cost"] for r in ok])
        expected = (finals[:, None] <= targets[None, :]).mean()
        # the same comparisons of the same doubles, counted in another order: exact up to
        # the one division, done the same way
        assert curve["fraction"][-1] == pytest.approx(expected, abs=1e-15)


def test_report_has_the_ecdf(store, tmp_path):
    text = write_report(store, tmp_path / "r", figures=False).read_text()
    assert "### ECDF of (run, target) pairs" in text and "| sda | 2 |" in text
    pytest.importorskip("matplotlib")
    write_report(store, tmp_path / "f")
    assert len(list((tmp_path / "f").glob("*-ecdf.png"))) == 2


# ------------------------------------------------------------------ command line
def _run(argv, capsys):
    status = main([str(a) for a in argv])
    out = capsys.readouterr()
    return status, out.out, out.err


def test_cli_round_trip(store, tmp_path, capsys):
    status, out, err = _run(["report", store, "--format", "ioh", "-o", tmp_path / "x"], capsys)
    assert status == 0, err
    assert out.startswith("wrote ") and "json layout" in out
    stored = _stored_runs(store)
    for folder in (tmp_path / "x").iterdir():
        exported = _read_json_export(folder)
        key = next(k for k in stored if folder.name.endswith(k[:8]))
        for label, runs in stored[key].items():
            for run, record in runs.items():
                h = record["history"]
                assert exported[label]["runs"][run] == list(zip(h["fe"], h["best"]))
    status, out, err = _run(["report", store, "--format", "ioh-info", "-o", tmp_path / "y"], capsys)
    assert status == 0, err
    assert len(list((tmp_path / "y").glob("*/*/*.info"))) == 4


@pytest.mark.parametrize(
    ("case", "word"),
    [("format", "invalid choice"), ("empty", "no comparison"), ("history", "no history")],
)
def test_cli_bad_input_one_line_status_2(case, word, store, tmp_path, capsys):
    target, fmt = store, "ioh"
    if case == "format":
        fmt = "pdf"
    elif case == "empty":
        target = tmp_path / "empty.sqlite"
        ResultStore(target).close()
    else:
        target = _store_with(store, tmp_path / "broken.sqlite", lambda r: r.pop("history"))
    status, _, err = _run(["report", target, "--format", fmt, "-o", tmp_path / "o"], capsys)
    assert status == 2
    assert len(err.strip().splitlines()) == 1 and word in err
    assert not (tmp_path / "o").exists()
    assert not re.search(r"Traceback", err)
