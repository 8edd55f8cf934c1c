"""A comparison survives its optimisers and its signals (issue #25, points 5 and 6).

* SIGTERM or SIGINT to ``flexid compare --workers 2`` stops the workers (a hung one too),
  keeps every finished run and leaves no process of the command behind; a rerun resumes.
* An optimiser that raises ``SystemExit`` or ``GeneratorExit``, kills its worker process
  (``os._exit``) or never returns is one failed run with its reason; the other runs go on.
  ``run_timeout`` (``--run-timeout``, ``[compare] run_timeout``) bounds a run even when the
  optimiser never returns, in worker processes and in the serial mode.

The misbehaving optimisers are a plugin module written to a folder with a ``.dist-info``
declaring them in the ``flexid.optimisers`` entry-point group, as an installed plugin would
be: worker processes (which start afresh) and ``flexid`` subprocesses find them by name.
"""

from __future__ import annotations

import os
import signal
import sqlite3
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import pytest

from flexid import compare
from flexid.cli import main
from flexid.config import ComparisonSpec, OptimiserSpec, load_config
from flexid.errors import ConfigError
from flexid.jobs.store import ResultStore
from flexid.optimisers import reload_plugins, unregister
from helpers import tiny_spec

PLUGIN_MODULE = "flexid_robustness_plugins"
PLUGIN_SOURCE = '''
"""Optimisers that misbehave after their first population (flexid's robustness tests)."""

import os
import time

from flexid.optimisers import Optimiser, Param


class _Misbehaving(Optimiser):
    points = Param(int, 5, "points of the first population", low=1)

    def search(self, space, rng):
        yield space.initial_population(self.points)
        self.misbehave()

    def misbehave(self):
        raise NotImplementedError


class Quits(_Misbehaving):
    """Raises SystemExit(3), as a script's sys.exit would."""

    name = "test-quits"

    def misbehave(self):
        raise SystemExit(3)


class GeneratorExits(_Misbehaving):
    """Raises GeneratorExit from its search."""

    name = "test-generator-exit"

    def misbehave(self):
        raise GeneratorExit("deliberate")


class Crashes(_Misbehaving):
    """Ends its process at once, as a segfault or os._exit in a C extension would."""

    name = "test-crashes"

    def misbehave(self):
        os._exit(7)


class Hangs(_Misbehaving):
    """Never returns."""

    name = "test-hangs"

    def misbehave(self):
        while True:
            time.sleep(0.05)
'''
PLUGINS = {
    "test-quits": "Quits",
    "test-generator-exit": "GeneratorExits",
    "test-crashes": "Crashes",
    "test-hangs": "Hangs",
}

#: Generous deadlines that end as soon as the condition holds (a loaded 2-core machine).
DEADLINE = 20.0


@pytest.fixture(scope="module")
def plugin_site(tmp_path_factory) -> Path:
    """A folder holding the plugin module and a ``.dist-info`` that declares its optimisers."""
    site = tmp_path_factory.mktemp("site")
    (site / f"{PLUGIN_MODULE}.py").write_text(PLUGIN_SOURCE)
    info = site / "flexid_robustness_plugins-0.1.dist-info"
    info.mkdir()
    info.joinpath("METADATA").write_text(
        "Metadata-Version: 2.1\nName: flexid-robustness-plugins\nVersion: 0.1\n"
    )
    entries = "".join(f"{name} = {PLUGIN_MODULE}:{cls}\n" for name, cls in PLUGINS.items())
    info.joinpath("entry_points.txt").write_text("[flexid.optimisers]\n" + entries)
    return site


@pytest.fixture
def plugins(plugin_site, monkeypatch):
    """The misbehaving optimisers, registered here and found by worker processes (which
    start with this process's ``sys.path``)."""
    monkeypatch.syspath_prepend(str(plugin_site))
    reload_plugins()
    yield plugin_site
    for name in PLUGINS:
        unregister(name)


def _flexid(options: str, *paths: str | Path) -> list[str]:
    """The command ``flexid`` with the space-separated ``options`` and then ``paths``."""
    return [sys.executable, "-m", "flexid", *options.split(), *map(str, paths)]


def _default_sigint() -> None:
    """In the child before it runs flexid: SIGINT handled by default, not ignored."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _env(site: Path) -> dict[str, str]:
    """The environment of a ``flexid`` subprocess that finds the plugin."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(
        [str(site), *filter(None, [env.get("PYTHONPATH")]), *sys.path]
    )
    return env


def _spec(*optimisers: str, runs: int = 2, **changes) -> ComparisonSpec:
    """A tiny comparison of ``optimisers`` (SDA at its defaults when named ``"sda"``)."""
    opts = tuple(OptimiserSpec(o) for o in optimisers)
    return tiny_spec("robust", optimisers=opts, runs=runs, **changes)


def _by_label(result) -> dict[str, list[tuple[str, str | None]]]:
    return {
        label: [(r["status"], r.get("error")) for r in records]
        for label, records in result.records.items()
    }


# ================================================================ 6. BaseException in a run
@pytest.mark.parametrize(
    ("name", "error"),
    [("test-quits", "SystemExit: 3"), ("test-generator-exit", "GeneratorExit: deliberate")],
)
def test_base_exception_of_an_optimiser_is_a_failed_run(plugins, tmp_path, name, error):
    store = tmp_path / "r.sqlite"
    result = compare(_spec(name, "sda"), store=store)
    assert _by_label(result)[name] == [("failed", error)] * 2
    assert [s for s, _ in _by_label(result)["sda"]] == ["ok", "ok"]
    assert f"{name}: failed runs: {error}" in result.summary()
    with ResultStore(store) as db:
        assert db.count(result.key) == {"ok": 3, "failed": 2}
    seen: list[dict] = []  # a rerun keeps the failed runs and does not die either
    compare(_spec(name, "sda"), store=store, progress=seen.append)
    assert seen == []


def test_systemexit_of_a_plugin_does_not_end_the_command(plugins, tmp_path):
    """``flexid compare`` records the run and exits 0, this time and on every rerun."""
    store = tmp_path / "r.sqlite"
    cmd = _flexid(
        "compare --plant twin-rotor --na 2 --optimisers test-quits,sda --runs 1 --budget 200 "
        "--no-figures --no-progress --store",
        store,
    )
    for _ in range(2):
        done = subprocess.run(cmd, capture_output=True, text=True, timeout=120, env=_env(plugins))
        assert done.returncode == 0, done.stderr
        assert "test-quits: failed runs: SystemExit: 3" in done.stdout
    with sqlite3.connect(store) as con:
        rows = dict(con.execute("SELECT label, status FROM runs").fetchall())
    assert rows == {"ls": "ok", "sda": "ok", "test-quits": "failed"}


# ================================================================ 6. a worker that dies
@pytest.mark.slow
def test_dead_worker_is_a_failed_run_and_is_replaced(plugins):
    result = compare(_spec("test-crashes", "sda"), workers=2)
    runs = _by_label(result)
    assert runs["test-crashes"] == [("failed", "worker process died (exit code 7)")] * 2
    assert [s for s, _ in runs["sda"]] == ["ok", "ok"]
    # the runs the surviving and the replacement workers did are the serial runs' numbers
    serial = compare(_spec("sda"))
    assert [r["cost"] for r in result.records["sda"]] == [r["cost"] for r in serial.records["sda"]]


# ================================================================ 6. the per-run time limit
def test_run_timeout_ends_a_run_that_never_returns_in_serial_mode(plugins):
    """``workers=1`` with a time limit runs each run in a child process, which is killed."""
    t0 = time.monotonic()
    result = compare(_spec("sda", "test-hangs", runs=1), run_timeout=1)
    runs = _by_label(result)
    assert runs["test-hangs"] == [("failed", "time limit of 1 s exceeded")]
    assert runs["sda"][0][0] == "ok"
    assert result.records["test-hangs"][0]["wall_time"] >= 1.0
    assert time.monotonic() - t0 < DEADLINE
    # a run in the child process has the numbers of the same run in this process
    in_process = compare(_spec("sda", runs=1)).records["sda"][0]
    assert result.records["sda"][0]["cost"] == in_process["cost"]


@pytest.mark.slow
def test_run_timeout_of_the_spec_holds_in_worker_processes(plugins, tmp_path):
    """A hung run's worker is killed and replaced; the limit comes from the spec here."""
    spec = _spec("test-hangs", "sda", run_timeout=1)
    result = compare(spec, workers=2, store=tmp_path / "r.sqlite")
    runs = _by_label(result)
    assert runs["test-hangs"] == [("failed", "time limit of 1 s exceeded")] * 2
    assert [s for s, _ in runs["sda"]] == ["ok", "ok"]
    # the limit is how runs are executed, not what they compute: it stays out of the key
    assert spec.key == replace(spec, run_timeout=None).key


def test_run_timeout_option_of_compare_overrides_the_spec(plugins):
    result = compare(_spec("test-hangs", runs=1, run_timeout=1000), run_timeout=0.5)
    assert _by_label(result)["test-hangs"] == [("failed", "time limit of 0.5 s exceeded")]


def test_run_timeout_is_checked():
    for bad in (0, -1, float("nan"), float("inf"), "10", True):
        with pytest.raises(ConfigError, match="run_timeout"):
            _spec("sda", run_timeout=bad)
        with pytest.raises(ConfigError, match="run_timeout"):
            compare(_spec("sda"), run_timeout=bad)
    assert _spec("sda").run_timeout is None  # no limit unless asked for
    assert _spec("sda", run_timeout=3).run_timeout == 3.0
    with pytest.raises(ConfigError, match="dask"):
        compare(_spec("sda"), scheduler="tcp://127.0.0.1:1", run_timeout=1)


def test_run_timeout_in_the_toml_configuration(tmp_path):
    base = (
        'name = "t"\n[data]\nplant = "twin-rotor"\n[model]\nna = 2\n'
        '[[optimisers]]\nname = "sda"\n'
    )
    path = tmp_path / "c.toml"
    path.write_text(base + "[compare]\nrun_timeout = 2.5\n")
    (spec,) = load_config(path)
    assert spec.run_timeout == 2.5
    plain_path = tmp_path / "plain.toml"
    plain_path.write_text(base)
    (plain,) = load_config(plain_path)
    assert plain.run_timeout is None
    assert plain.key == spec.key  # the limit is not part of what the runs compute
    assert ComparisonSpec.from_dict(spec.to_dict()) == spec
    for text, match in (
        ("[compare]\nrun_timeout = 0\n", "run_timeout"),
        ("[compare]\nrun_timeout = 'long'\n", "run_timeout"),
        ("[compare]\nworkerz = 2\n", "workerz"),
    ):
        path.write_text(base + text)
        with pytest.raises(ConfigError, match=match):
            load_config(path)


def test_run_timeout_on_the_command_line(tmp_path, capsys):
    parser_help = subprocess.run(_flexid("compare --help"), capture_output=True, text=True)
    assert "--run-timeout" in parser_help.stdout
    for bad in ("0", "-2", "nan", "soon"):
        options = f"compare --plant twin-rotor --no-figures --run-timeout {bad} --store"
        status = main([*options.split(), str(tmp_path / "r.sqlite")])
        err = capsys.readouterr().err.strip()
        assert status == 2 and "--run-timeout" in err and len(err.splitlines()) == 1, err
    assert not (tmp_path / "r.sqlite").exists()


def test_run_timeout_and_systemexit_from_the_command_line(plugins, tmp_path):
    """``--run-timeout`` on the command line: a hung run and a quitting one are failed runs,
    the comparison finishes with status 0."""
    store = tmp_path / "r.sqlite"
    cmd = _flexid(
        "compare --plant twin-rotor --na 2 --optimisers test-quits,sda,test-hangs --runs 1 "
        "--budget 200 --run-timeout 1 --no-figures --no-progress --store",
        store,
    )
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=120, env=_env(plugins))
    assert done.returncode == 0, done.stderr
    with sqlite3.connect(store) as con:
        rows = {
            label: (status, error)
            for label, status, error in con.execute("SELECT label, status, error FROM runs")
        }
    assert rows == {
        "ls": ("ok", None),
        "sda": ("ok", None),
        "test-hangs": ("failed", "time limit of 1 s exceeded"),
        "test-quits": ("failed", "SystemExit: 3"),
    }


# ================================================================ 5. nothing left running
_CONFIG = """
name = "stopme"
[data]
plant = "manipulator"
signal = "uniform"
n_samples = 400
seed = 0
outputs = ["tip_acceleration"]
[model]
na = 2
[run]
runs = 3
seed = 1
budget = 300
targets = [1.0]
[[optimisers]]
name = "sda"
[[optimisers]]
name = "test-hangs"
"""


def _members(pgid: int) -> list[int]:
    """Processes of process group ``pgid`` that are not zombies (a zombie runs nothing; who
    reaps an orphan's depends on the machine's init)."""
    if not Path("/proc").is_dir():  # pragma: no cover - not Linux
        try:
            os.killpg(pgid, 0)
        except ProcessLookupError:
            return []
        return [pgid]
    members = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:  # the process ended while the folder was read
            continue
        fields = stat[stat.rindex(")") + 2 :].split()  # after "pid (comm) "
        if int(fields[2]) == pgid and fields[0] != "Z":
            members.append(int(entry.name))
    return members


def _stored(store: Path) -> dict[tuple[str, int], tuple]:
    try:
        with sqlite3.connect(store) as con:
            rows = con.execute("SELECT label, run, created, payload FROM runs").fetchall()
    except sqlite3.OperationalError:  # not created yet
        return {}
    return {(label, run): (created, payload) for label, run, created, payload in rows}


@pytest.mark.slow
@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals and process groups")
@pytest.mark.parametrize(
    ("signum", "status"),
    [(signal.SIGTERM, 143), (signal.SIGINT, 130)],
    ids=["SIGTERM", "SIGINT"],
)
def test_signal_stops_workers_and_keeps_finished_runs(plugins, tmp_path, signum, status):
    """The signal reaches the parent only (as ``kill PID`` sends it); one worker is inside a
    run that never returns, the other does the SDA runs until it reaches one too."""
    config = tmp_path / "c.toml"
    config.write_text(_CONFIG)
    store = tmp_path / "r.sqlite"
    cmd = _flexid("compare --no-figures --no-progress", config, "--store", store)
    # stderr goes to a file: a worker left running would hold a pipe open
    err_path = tmp_path / "stderr.txt"
    with open(err_path, "w") as err_file:
        proc = subprocess.Popen(
            [*cmd, "--workers", "2"],
            stdout=subprocess.DEVNULL,
            stderr=err_file,
            env=_env(plugins),
            start_new_session=True,
            # as a terminal's command gets it: a shell's background job (CI started with '&')
            # inherits SIGINT ignored, and Python then never raises KeyboardInterrupt
            preexec_fn=_default_sigint,
        )
    pgid = proc.pid
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and proc.poll() is None:
            # both finished rows: the two workers' first tasks end in either order
            if {("ls", 0), ("sda", 0)} <= set(_stored(store)):
                break
            time.sleep(0.05)
        assert proc.poll() is None, err_path.read_text()
        before = _stored(store)
        assert ("ls", 0) in before and ("sda", 0) in before
        os.kill(proc.pid, signum)
        proc.wait(timeout=DEADLINE)
        err = err_path.read_text()
        assert proc.returncode == status, err
        assert err.strip().splitlines() == [
            f"flexid: {'terminated' if signum == signal.SIGTERM else 'interrupted'} "
            "(finished runs are in the store; rerun to resume)"
        ]
        deadline = time.monotonic() + DEADLINE
        while _members(pgid) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert _members(pgid) == [], "processes of the comparison are still running"
    finally:
        if _members(pgid):
            os.killpg(pgid, signal.SIGKILL)
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    after = _stored(store)
    assert after.items() >= before.items()  # every run finished before the signal is kept
    assert not any(label == "test-hangs" for label, _ in after)
    # a rerun (serial, without the hung optimiser) runs only the missing SDA runs
    rerun = [*cmd, "--optimisers", "sda"]
    done = subprocess.run(rerun, capture_output=True, text=True, timeout=120, env=_env(plugins))
    assert done.returncode == 0, done.stderr
    final = _stored(store)
    assert {k: final[k] for k in after} == after
    assert sorted(final) == [("ls", 0), ("sda", 0), ("sda", 1), ("sda", 2)]
