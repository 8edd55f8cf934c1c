"""Tests of flexid.progress: counts and output with and without tqdm."""

from __future__ import annotations

import builtins

from flexid.progress import ProgressBar


def test_plain_progress_line_without_tqdm(monkeypatch, capsys):
    real_import = builtins.__import__

    def no_tqdm(name, *args, **kwargs):
        if name == "tqdm":
            raise ImportError("no tqdm")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_tqdm)
    bar = ProgressBar(3, "runs")
    for _ in range(3):
        bar.update(status="sda #0")
    bar.close()
    err = capsys.readouterr().err
    assert bar.count == 3
    assert "runs: 3/3" in err
    assert err.count("\n") <= 3


def test_tqdm_progress_counts(capsys):
    bar = ProgressBar(5, "work")
    bar.update(2)
    bar.update(3, status="done")
    bar.close()
    assert bar.count == 5
    assert "work" in capsys.readouterr().err
