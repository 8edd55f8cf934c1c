"""Tests of flexid.compare: identical problems, statistics, resumable store, parallel runs.

Results of the same runs (resumed, in worker processes, on a dask cluster) are compared
exactly: the same code on the same numbers on one machine.
"""

from __future__ import annotations

import os
import signal
import sqlite3
import subprocess
import sys
import time

import numpy as np
import pytest

from flexid import ComparisonResult, compare, load_result
from flexid.config import OptimiserSpec
from flexid.errors import ConfigError, HyperParameterError, UnknownOptimiserError
from flexid.jobs._compare import run_seed
from flexid.jobs.store import ResultStore
from flexid.optimisers import Optimiser, Param, register, unregister
from helpers import small_spec


def test_run_seed_is_stable_and_independent_of_run_count():
    seeds = [run_seed(5, r) for r in range(4)]
    assert len(set(seeds)) == 4
    assert seeds == [run_seed(5, r) for r in range(4)]
    assert run_seed(6, 0) != seeds[0]
    assert all(0 <= s < 2**63 for s in seeds)


def test_compare_in_memory():
    result = compare(small_spec())
    assert isinstance(result, ComparisonResult)
    assert set(result.records) == {"sda", "random-search"}
    for _label, records in result.records.items():
        assert [r["run"] for r in records] == [0, 1, 2]
        for r in records:
            assert r["status"] == "ok" and r["nfev"] == 600
            assert r["history"]["fe"][-1] == 600
            # one-step cost w sqrt(sse_ls + |R d|^2) / K, |R d|^2 >= 0, rounding monotone,
            # the same data and code for every run: least squares is a lower bound, exactly
            assert r["cost"] >= result.reference["cost"]
    # the same run index has the same seed for every optimiser
    seeds = {label: [r["seed"] for r in rs] for label, rs in result.records.items()}
    assert seeds["sda"] == seeds["random-search"]
    text = result.summary()
    assert "least squares" in text and "sda" in text and "p (Holm)" in text
    assert result.reference["optimiser"] == "ls"


def test_same_initial_population_for_every_optimiser():
    """Run 0 of two optimisers evaluates the same first population (same best after init)."""
    spec = small_spec(
        budget=10,
        optimisers=(
            OptimiserSpec("sda", {"points": 10}),
            OptimiserSpec("random-search", {"points": 10}),
        ),
    )
    result = compare(spec)
    for r in range(3):
        a = result.records["sda"][r]["history"]
        b = result.records["random-search"][r]["history"]
        assert a["best"][0] == b["best"][0]


def test_store_resume_skips_finished_runs(tmp_path):
    store = tmp_path / "r.sqlite"
    first = compare(small_spec(runs=2), store=store)
    seen = []
    second = compare(small_spec(runs=3), store=store, progress=lambda rec: seen.append(rec))
    assert sorted((r["label"], r["run"]) for r in seen) == [("random-search", 2), ("sda", 2)]
    for label in first.records:
        for a, b in zip(first.records[label], second.records[label]):
            assert a["cost"] == b["cost"]
    with ResultStore(store) as db:
        assert db.count(first.key) == {"ok": 7, "failed": 0}  # 2 x 3 runs + least squares
    (again,) = load_result(store)
    assert again.stats["sda"]["median"] == second.stats["sda"]["median"]


class _Boom(Optimiser):
    name = "test-boom"
    points = Param(int, 5, "points", low=1)

    def search(self, space, rng):
        yield space.initial_population(self.points)
        raise RuntimeError("deliberate failure")


@pytest.fixture
def boom():
    register(_Boom)
    yield "test-boom"
    unregister("test-boom")


def test_failing_optimiser_is_recorded_and_others_go_on(tmp_path, boom):
    spec = small_spec(optimisers=(OptimiserSpec(boom), OptimiserSpec("sda", {"points": 10})))
    result = compare(spec, store=tmp_path / "r.sqlite")
    assert all(r["status"] == "failed" for r in result.records[boom])
    assert "RuntimeError: deliberate failure" in result.records[boom][0]["error"]
    assert all(r["status"] == "ok" for r in result.records["sda"])
    assert "failed" in result.summary()
    # an optimiser without two finished runs is not ranked, nor said to be worse
    assert "Lowest median cost: sda (of the optimisers with two or more finished runs; not " \
        f"tested: {boom})." in result.summary()
    assert "significantly worse" not in result.summary()
    # a rerun does not repeat failed runs unless asked to
    seen = []
    compare(spec, store=tmp_path / "r.sqlite", progress=lambda rec: seen.append(rec))
    assert seen == []
    compare(
        spec, store=tmp_path / "r.sqlite", progress=lambda rec: seen.append(rec), retry_failed=True
    )
    assert len(seen) == 3


def test_invalid_specs_fail_before_running(tmp_path):
    with pytest.raises(UnknownOptimiserError):
        compare(small_spec(optimisers=(OptimiserSpec("no-such-optimiser"),)))
    with pytest.raises(HyperParameterError):
        compare(small_spec(optimisers=(OptimiserSpec("sda", {"points": -3}),)))
    with pytest.raises(ConfigError):
        compare(small_spec(), workers=0)
    store = tmp_path / "r.sqlite"
    compare(small_spec(runs=1), store=store)
    changed = small_spec(
        runs=1, optimisers=(OptimiserSpec("sda", {"points": 12}), OptimiserSpec("random-search"))
    )
    with pytest.raises(ConfigError, match="other settings"):
        compare(changed, store=store)


@pytest.mark.slow
def test_workers_give_identical_results():
    spec = small_spec(runs=2)
    serial = compare(spec)
    parallel = compare(spec, workers=2)
    for label in serial.records:
        a = [(r["run"], r["cost"], r["nfev"], r["theta"]) for r in serial.records[label]]
        b = [(r["run"], r["cost"], r["nfev"], r["theta"]) for r in parallel.records[label]]
        assert a == b


def _blas_threads(queue) -> None:
    queue.put({k: os.environ.get(k) for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS",
                                              "MKL_NUM_THREADS")})  # fmt: skip


def test_worker_processes_run_blas_on_one_thread(monkeypatch):
    """A worker process is one core, as a dask worker is: its BLAS gets one thread (a BLAS
    thread per core in every worker oversubscribed the cores), a count the user set is kept,
    and the parent's own environment is as before."""
    from multiprocessing import get_context

    from flexid.jobs._compare import _worker_environment

    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    monkeypatch.delenv("OPENBLAS_NUM_THREADS", raising=False)
    monkeypatch.setenv("MKL_NUM_THREADS", "3")
    mp = get_context("spawn")
    queue = mp.Queue()
    with _worker_environment():
        child = mp.Process(target=_blas_threads, args=(queue,))
        child.start()
    seen = queue.get(timeout=60)
    child.join(60)
    assert seen == {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "3"}
    assert "OMP_NUM_THREADS" not in os.environ and "OPENBLAS_NUM_THREADS" not in os.environ
    assert os.environ["MKL_NUM_THREADS"] == "3"


@pytest.mark.slow
def test_dask_local_cluster_gives_identical_results():
    distributed = pytest.importorskip("distributed")
    spec = small_spec(runs=2)
    serial = compare(spec)
    with (
        distributed.LocalCluster(
            n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None
        ) as cluster,
        distributed.Client(cluster) as client,
    ):
        remote = compare(spec, scheduler=client)
        by_address = compare(spec, scheduler=cluster.scheduler_address)
    for label in serial.records:
        a = [r["cost"] for r in serial.records[label]]
        assert a == [r["cost"] for r in remote.records[label]]
        assert a == [r["cost"] for r in by_address.records[label]]


@pytest.mark.slow
def test_kill_minus_nine_then_resume(tmp_path):
    config = tmp_path / "c.toml"
    config.write_text(
        """
name = "killme"
[data]
plant = "manipulator"
signal = "uniform"
n_samples = 800
seed = 2
outputs = ["tip_acceleration"]
[model]
na = 4
[cost]
predictor = "simulation"
[run]
runs = 4
seed = 3
budget = 3000
[[optimisers]]
name = "sda"
params = { points = 10 }
[[optimisers]]
name = "random-search"
params = { points = 10 }
"""
    )
    store = tmp_path / "r.sqlite"
    cmd = [
        sys.executable,
        "-m",
        "flexid",
        "compare",
        str(config),
        "--store",
        str(store),
        "--no-figures",
        "--no-progress",
    ]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    deadline = time.time() + 120
    rows = 0
    while time.time() < deadline and proc.poll() is None:
        if store.exists():
            try:
                with sqlite3.connect(store) as con:
                    rows = con.execute("SELECT COUNT(*) FROM runs").fetchone()[0]
            except sqlite3.OperationalError:
                rows = 0
            if rows >= 3:  # least squares + at least two optimiser runs
                break
        time.sleep(0.02)
    assert proc.poll() is None, "the comparison finished before it could be killed"
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    with sqlite3.connect(store) as con:
        partial = con.execute("SELECT COUNT(*) FROM runs").fetchone()[0]
    assert 3 <= partial < 9
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    with sqlite3.connect(store) as con:
        rows = con.execute("SELECT label, run FROM runs").fetchall()
    assert len(rows) == 9 == len(set(rows))
    # the resumed store equals an uninterrupted comparison
    fresh = tmp_path / "fresh.sqlite"
    subprocess.run(
        [*cmd[:-4], "--store", str(fresh), "--no-figures", "--no-progress"],
        check=True,
        capture_output=True,
        timeout=300,
    )
    (a,) = load_result(store)
    (b,) = load_result(fresh)
    for label in a.records:
        assert [r["cost"] for r in a.records[label]] == [r["cost"] for r in b.records[label]]
    assert np.isfinite(a.stats["sda"]["median"])
