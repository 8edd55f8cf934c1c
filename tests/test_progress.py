"""Tests of flexid.jobs.progress: a bar on a terminal, one plain line per step in a file or pipe."""

from __future__ import annotations

import builtins
import io
import subprocess
import sys

import pytest

from flexid.jobs.progress import ProgressBar


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


@pytest.fixture
def no_tqdm(monkeypatch):
    real_import = builtins.__import__

    def block(name, *args, **kwargs):
        if name == "tqdm":
            raise ImportError("no tqdm")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", block)


def test_a_file_or_pipe_gets_one_line_per_step_and_no_carriage_return():
    stream = io.StringIO()  # not a terminal
    bar = ProgressBar(3, "runs", stream=stream)
    for k in range(3):
        bar.update(status=f"sda run {k}")
    bar.close()
    lines = stream.getvalue().splitlines()
    assert "\r" not in stream.getvalue()
    assert [line.split(" (")[0] for line in lines] == ["runs: 1/3 run", "runs: 2/3 run",
                                                       "runs: 3/3 run"]
    assert lines[-1].endswith("sda run 2")


def test_a_terminal_without_tqdm_gets_a_status_line_at_most_once_a_second(no_tqdm):
    stream = _Terminal()
    bar = ProgressBar(50, "runs", stream=stream)
    for _ in range(50):  # far faster than a second apart
        bar.update()
    bar.close()
    lines = stream.getvalue().splitlines()
    assert bar.count == 50 and lines[-1].startswith("runs: 50/50 run")
    assert len(lines) <= 3  # the first, at most one more within the test, the last


def test_a_terminal_with_tqdm_draws_a_bar():
    pytest.importorskip("tqdm")
    stream = _Terminal()
    bar = ProgressBar(5, "work", unit="FE", stream=stream)
    bar.update(2)
    bar.update(3, status="done")
    bar.close()
    assert bar.count == 5 and "work" in stream.getvalue() and "FE" in stream.getvalue()


def test_a_delayed_terminal_bar_shows_nothing_for_short_work():
    pytest.importorskip("tqdm")
    stream = _Terminal()
    bar = ProgressBar(5, "quick", unit="FE", delay=60.0, stream=stream)
    bar.update(5)
    bar.close()
    assert "quick" not in stream.getvalue()


def test_compare_writes_no_carriage_return_into_a_pipe(tmp_path):
    run = subprocess.run(
        [sys.executable, "-m", "flexid", "compare", "--optimisers", "random-search", "--runs", "2",
         "--budget", "50", "--store", str(tmp_path / "s.sqlite"), "--no-figures"],
        capture_output=True, text=True, timeout=600,
    )
    assert run.returncode == 0, run.stderr
    assert "\r" not in run.stderr
    assert [line.split(":")[1].split(" (")[0] for line in run.stderr.splitlines()] == [
        " 1/2 run", " 2/2 run"
    ]
