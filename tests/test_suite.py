"""The benchmark suite: its definition and version, running it into a store, reading it back.

The problems here are small versions of the suite's (ARX(2,2,1) and OE(2,2,1) on a few
hundred samples) so that a run takes seconds; the built-in settings are checked for what
they contain, not run.
"""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from flexid.cli import main
from flexid.config import DataSpec, ModelSpec
from flexid.errors import DataError, UnknownNameError
from flexid.jobs.statistics import fe_to_target
from flexid.jobs.store import ResultStore
from flexid.jobs.suite import (
    PRECISIONS,
    SETTINGS,
    Suite,
    SuiteVersionError,
    _holm,
    _problem,
    get_suite,
    load_suite,
    run_suite,
)


def tiny_suite(seed: int = 0) -> Suite:
    man = DataSpec(plant="manipulator", preset="paper-manipulator", n_samples=400, seed=seed)
    rotor = DataSpec(plant="twin-rotor", preset="paper-twin-rotor", n_samples=300, seed=seed)
    problems = (
        _problem("manipulator", ModelSpec(na=2, nb=2, nk=1), "one-step", man, f"seed{seed}"),
        _problem("manipulator", ModelSpec(na=2, nb=2, nk=1), "simulation", man, f"seed{seed}"),
        _problem(
            "twin-rotor", ModelSpec(structure="oe", nb=2, nf=2, nk=1), "simulation", rotor,
            f"seed{seed}",
        ),
    )
    return Suite("small", problems, budget_per_dim=25, runs=2)


@pytest.fixture(scope="module")
def ran(tmp_path_factory):
    store = tmp_path_factory.mktemp("suite") / "suite.sqlite"
    suite = tiny_suite()
    result = run_suite(suite, ["random-search", "de"], store=store)
    return suite, store, result


# ------------------------------------------------------------------ definition and version
def test_the_built_in_settings_hold_every_structure_and_cost():
    for setting in SETTINGS:
        suite = get_suite(setting)
        names = [p.name for p in suite.problems]
        assert len(names) == len(set(names))
        assert {p.structure for p in suite.problems} == {"arx", "oe", "bj", "greybox", "ss"}
        assert {p.cost for p in suite.problems} == {"one-step", "simulation"}
        assert {p.plant for p in suite.problems} == {"manipulator", "twin-rotor"}
        assert len(suite.version) == 12
    small, full = get_suite("small"), get_suite("full")
    assert len(small.problems) == 18 and len(full.problems) == 90
    assert (small.budget_per_dim, small.runs) == (500, 3)
    # the small setting's instances are the full one's at the preset's noise
    assert {p.name for p in small.problems} <= {p.name for p in full.problems}
    with pytest.raises(UnknownNameError, match=r"suite setting 'medium'.*full, small"):
        get_suite("medium")


def test_the_version_changes_with_a_definition_and_only_then():
    a, b = tiny_suite(), tiny_suite()
    assert a.version == b.version  # the same definitions, built twice
    assert tiny_suite(seed=1).version != a.version  # other data
    changed = replace(a.problems[0], spec=replace(a.problems[0].spec,
                                                  model=ModelSpec(na=3, nb=2, nk=1)))  # fmt: skip
    assert replace(a, problems=(changed, *a.problems[1:])).version != a.version
    # runs and budget are the experiment's: the same problems, the same version
    assert replace(a, runs=5, budget_per_dim=7).version == a.version
    assert a.subset(["oe"]).version == a.version


def test_a_record_file_enters_the_version_by_its_bytes(tmp_path):
    rng = np.random.default_rng(0)
    lines = ["u,y"] + [f"{a!r},{b!r}" for a, b in rng.standard_normal((300, 2)).tolist()]
    (tmp_path / "robot_arm.csv").write_text("\n".join(lines) + "\n")
    first = get_suite("small", records=tmp_path)
    assert {p.plant for p in first.problems} == {"manipulator", "twin-rotor", "robot-arm"}
    lines[5] = "0.5,0.25"
    (tmp_path / "robot_arm.csv").write_text("\n".join(lines) + "\n")
    assert get_suite("small", records=tmp_path).version != first.version
    with pytest.raises(DataError, match=r"robot_arm\.csv is not a folder of records"):
        get_suite("small", records=tmp_path / "robot_arm.csv")
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(DataError, match="holds none of the suite's records"):
        get_suite("small", records=empty)


def test_subsets_by_problem_group_and_an_unknown_name():
    suite = get_suite("small")
    assert {p.structure for p in suite.subset(["oe"]).problems} == {"oe"}
    assert {p.plant for p in suite.subset(["twin-rotor"]).problems} == {"twin-rotor"}
    one = suite.problems[3].name
    assert [p.name for p in suite.subset([one]).problems] == [one]
    with pytest.raises(UnknownNameError, match="'nonsense'; known: arx, bj, greybox"):
        suite.subset(["nonsense"])


# ------------------------------------------------------------------ running and reading
def test_a_rerun_resumes_from_the_store(ran):
    suite, store, first = ran
    with ResultStore(store, readonly=True) as db:
        before = {c["key"]: db.runs(c["key"]) for c in db.comparisons()}
    again = run_suite(suite, ["random-search", "de"], store=store)
    with ResultStore(store, readonly=True) as db:
        after = {c["key"]: db.runs(c["key"]) for c in db.comparisons()}
    assert after == before  # nothing ran again, nothing was added
    assert again.table() == first.table()
    assert len(before) == len(suite.problems)
    # each problem has its budget in multiples of its dimension, and every run spent it
    for name, result in first.results.items():
        assert result.spec.budget == suite.budget_per_dim * first.dims[name]
        for records in result.records.values():
            assert [r["nfev"] for r in records] == [result.spec.budget] * suite.runs


def test_one_pool_serves_every_problem_and_computes_the_references(ran, tmp_path, monkeypatch):
    """With workers, the suite's tasks share one pool (as many processes as workers, started
    once for every problem) and the references are tasks of it: the main process's route to
    a reference is made to fail, and the numbers are those of one process."""
    from flexid.jobs import _compare

    started = []
    real_init = _compare._Worker.__init__

    def counted(self, mp, *args, **kwargs):
        started.append(1)
        real_init(self, mp, *args, **kwargs)

    def refuse(ctx):
        raise AssertionError("a reference was computed in the main process")

    monkeypatch.setattr(_compare._Worker, "__init__", counted)
    monkeypatch.setattr(_compare, "_least_squares_record", refuse)
    suite, _, serial = ran
    pooled = run_suite(suite, ["random-search", "de"], store=tmp_path / "pool.sqlite", workers=2)
    assert len(started) == 2
    assert pooled.version == serial.version  # the same references
    assert pooled.table() == serial.table()


def test_a_dask_cluster_gives_the_numbers_of_one_process(ran, tmp_path):
    distributed = pytest.importorskip("distributed")
    suite, _, serial = ran
    with (
        distributed.LocalCluster(
            n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None
        ) as cluster,
        distributed.Client(cluster) as client,
    ):
        remote = run_suite(suite, ["random-search", "de"], store=tmp_path / "dask.sqlite",
                           scheduler=client)  # fmt: skip
    assert remote.version == serial.version
    assert remote.table() == serial.table()


def test_results_say_which_version_and_references_they_ran(ran):
    suite, store, result = ran
    assert result.version.startswith(suite.version + "+")
    with ResultStore(store, readonly=True) as db:
        names = sorted(c["name"] for c in db.comparisons())
    assert names == sorted(suite.comparison_name(p) for p in suite.problems)
    assert all(f"@{suite.version}/" in n for n in names)


def test_an_optimiser_added_later_joins_the_others(ran, tmp_path):
    suite, store, _ = ran
    copy = tmp_path / "copy.sqlite"
    copy.write_bytes(store.read_bytes())
    more = run_suite(suite.subset(["oe"]), ["pso"], store=copy)
    assert sorted(more.labels) == ["de", "pso", "random-search"]
    # the problems pso did not run are read with their optimisers alone
    whole = load_suite(copy, suite)
    assert whole.results["twin-rotor/oe(2,2,1)/simulation/seed0"].records.keys() == {
        "random-search", "de", "pso"}  # fmt: skip
    assert [r["problems"] for r in whole.ranking()] == [1, 1, 1]  # only oe has all three


def test_another_version_in_the_store_is_refused(ran):
    _, store, _ = ran
    other = tiny_suite(seed=3)  # other data: another version, the same suite name
    with pytest.raises(SuiteVersionError, match=r"holds suite flexid-sysid-small version"):
        load_suite(store, other)


def test_the_ecdf_counts_every_problem_target_and_run(ran):
    suite, _, result = ran
    for label, curve in result.ecdf().items():
        # by hand: every (problem, target, run), the FE / dimension at which it was reached
        times, total = [], 0
        for name, res in result.results.items():
            targets = res.reference_cost * (1 + np.asarray(PRECISIONS))
            for r in res.records[label]:
                total += len(targets)
                for t in targets:
                    fe = fe_to_target(r["history"], t)
                    if np.isfinite(fe):
                        times.append(fe / result.dims[name])
        assert curve["triples"] == total == len(result.results) * len(PRECISIONS) * suite.runs
        np.testing.assert_array_equal(curve["x"], np.sort(times))
        assert curve["fraction"][-1] == pytest.approx(len(times) / total)
        # the area: the mean over triples of the share of log10(FE/dim) in [0, log10 budget]
        # after the triple was reached, here integrated on a fine grid (1e-5 of the width)
        grid = np.linspace(0, math.log10(suite.budget_per_dim), 200_001)
        on = np.searchsorted(np.log10(np.maximum(curve["x"], 1)), grid, side="right") / total
        assert curve["area"] == pytest.approx(np.mean(on), abs=1e-4)
    per_group = result.ecdf({"structure": "arx"})
    assert per_group["de"]["triples"] == 2 * len(PRECISIONS) * suite.runs


def test_the_table_marks_references_not_at_a_verified_minimum(ran):
    _, _, result = ran
    verified = {name: result.verified(name) for name in result.results}
    # least squares is the exact optimum of ARX's one-step cost; the OE reference measures
    # first-order optimality off the cap
    assert verified["manipulator/arx(2,2,1)/one-step/seed0"] is True
    oe = result.results["twin-rotor/oe(2,2,1)/simulation/seed0"].reference["output_error"]
    assert verified["twin-rotor/oe(2,2,1)/simulation/seed0"] is bool(
        oe["local_minimum"] and not oe["on_cap"])  # fmt: skip
    for row in result.table():
        assert row["verified"] is verified[row["problem"]]
        assert row["below"] <= row["runs"] and row["solved"] <= row["runs"]


def test_holm_by_hand():
    assert _holm([0.01, 0.04, 0.03]) == pytest.approx([0.03, 0.06, 0.06])
    out = _holm([0.2, math.nan, 0.01])
    assert out[1] != out[1] and out[0] == pytest.approx(0.2) and out[2] == pytest.approx(0.02)


def test_the_ioh_export_has_one_function_per_problem(ran, tmp_path):
    iohinspector = pytest.importorskip("iohinspector")
    _, _, result = ran
    folder = result.export_ioh(tmp_path)
    manager = iohinspector.DataManager()
    for sub in sorted(folder.iterdir()):
        manager.add_folder(str(sub))
    overview = manager.overview
    assert set(overview["algorithm_name"].to_list()) == {"random-search", "de"}
    assert overview["function_id"].n_unique() == len(result.results)
    assert len(overview) == 2 * len(result.results) * result.suite.runs
    best = sorted(overview["best_y"].to_list())
    stored = sorted(r["cost"] for res in result.results.values()
                    for records in res.records.values() for r in records)  # fmt: skip
    assert best == stored  # written with the shortest round-trip text: bit for bit


# ------------------------------------------------------------------ command line
def test_the_command_line_lists_runs_and_reports(tmp_path, capsys):
    store, out = tmp_path / "s.sqlite", tmp_path / "report"
    assert main(["suite", "list", "--json"]) == 0
    listed = json.loads(capsys.readouterr().out)
    assert listed["version"] == get_suite("small").version and len(listed["problems"]) == 18
    one = "twin-rotor/arx(5,5,1)/one-step/seed0"
    common = ["--problems", one, "--runs", "1", "--budget-per-dim", "3", "--store", str(store)]
    ran = ["suite", "run", "--optimisers", "random-search", "--no-progress", "-o", str(out)]
    assert main([*ran, *common]) == 0
    assert "Suite flexid-sysid-small" in capsys.readouterr().out
    assert (out / "problems.md").exists()  # the run writes its report too
    assert main(["suite", "report", "-o", str(out), *common]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["ecdf.png", "ioh", "problems.md",
                                                     "summary.txt"]  # fmt: skip
    assert one in (out / "problems.md").read_text()


@pytest.mark.parametrize(
    "argv, message",
    [
        (["run", "--optimisers", "no-such-optimiser"], "no-such-optimiser"),
        (["run", "--optimisers", "de", "--problems", "nonsense"], "'nonsense'"),
        (["run"], "needs --optimisers"),
        (["report"], "no such result store"),
        (["run", "--optimisers", "de", "--runs", "0"], "--runs"),
    ],
)
def test_bad_input_is_one_line_and_writes_nothing(tmp_path, capsys, argv, message):
    store, out = tmp_path / "s.sqlite", tmp_path / "out"
    rc = main(["suite", *argv, "--store", str(store), "-o", str(out)])
    err = capsys.readouterr().err
    assert rc == 2 and message in err and len(err.strip().splitlines()) == 1
    assert list(tmp_path.iterdir()) == []


def test_a_record_without_the_channels_a_problem_reads(tmp_path, capsys):
    rng = np.random.default_rng(0)
    lines = ["torque,accel"] + [f"{a!r},{b!r}" for a, b in rng.standard_normal((300, 2)).tolist()]
    (tmp_path / "robot_arm.csv").write_text("\n".join(lines) + "\n")
    store = tmp_path / "s.sqlite"
    rc = main(["suite", "run", "--records", str(tmp_path), "--problems", "robot-arm",
               "--optimisers", "de", "--store", str(store)])  # fmt: skip
    err = capsys.readouterr().err
    assert rc == 2 and "robot_arm.csv" in err and "'u'" in err
    assert not store.exists()
