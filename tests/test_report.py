"""Tests of flexid.report: Markdown and HTML reports of a result store."""

from __future__ import annotations

import pytest

from flexid import compare
from flexid.errors import ConfigError, StoreError
from flexid.jobs.store import ResultStore
from flexid.report import write_report
from helpers import tiny_spec


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    path = tmp_path_factory.mktemp("rep") / "r.sqlite"
    with ResultStore(path) as s:
        compare(tiny_spec("report test"), store=s, progress=False)
    return path


def test_markdown_report_has_tables_and_figures(store, tmp_path):
    pytest.importorskip("matplotlib")
    path = write_report(store, tmp_path / "out")
    text = path.read_text()
    assert path.name == "report.md"
    assert "report test" in text and "| sda" in text and "| least squares" in text
    images = [line for line in text.splitlines() if line.startswith("![")]
    assert images
    for line in images:
        name = line[line.index("(") + 1 : line.index(")")]
        assert (tmp_path / "out" / name).exists()


def test_html_report_without_figures(store, tmp_path):
    path = write_report(store, tmp_path / "h", fmt="html", figures=False)
    text = path.read_text()
    assert text.lstrip().lower().startswith("<!doctype html") or "<html" in text
    assert "<table" in text and "sda" in text
    assert not list((tmp_path / "h").glob("*.png"))


def test_bad_format_and_missing_store(store, tmp_path):
    with pytest.raises(ConfigError, match="format"):
        write_report(store, tmp_path, fmt="pdf")
    with pytest.raises((StoreError, ConfigError)):
        write_report(tmp_path / "none.sqlite", tmp_path)
