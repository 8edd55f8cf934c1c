"""Tests of the notebook displays (``_repr_html_``) of IOData, Identification and
ComparisonResult: well-formed HTML, the numbers of the plain-text summaries, escaped names.
"""

from __future__ import annotations

import base64
import re
from html.parser import HTMLParser

import numpy as np
import pytest

import flexid
from flexid import IOData, compare, identify
from flexid._html import escape, table
from flexid._table import labelled
from flexid.config import ModelSpec, OptimiserSpec
from helpers import manipulator_data, small_spec

NASTY = "a<&>b"
_VOID = {"br", "hr", "img", "meta", "input", "col", "wbr"}
_NUMBER = re.compile(r"-?\d+(?:\.\d+)?(?:e[+-]?\d+)?")


class Page(HTMLParser):
    """Parse HTML, check that every tag is closed in order, keep the text and the tables."""

    def __init__(self, text: str) -> None:
        super().__init__(convert_charrefs=True)
        self.stack: list[str] = []
        self.text: list[str] = []
        self.tables: list[list[list[str]]] = []
        self._cell: list[str] | None = None
        self.feed(text)
        self.close()
        assert not self.stack, f"unclosed tags: {self.stack}"

    def handle_starttag(self, tag, attrs):
        if tag in _VOID:
            return
        self.stack.append(tag)
        if tag == "table":
            self.tables.append([])
        elif tag == "tr":
            self.tables[-1].append([])
        elif tag in ("td", "th"):
            self._cell = []

    def handle_endtag(self, tag):
        if tag in _VOID:
            return
        assert self.stack and self.stack[-1] == tag, f"</{tag}> closes {self.stack[-1:]}"
        self.stack.pop()
        if tag in ("td", "th"):
            self.tables[-1][-1].append("".join(self._cell or []))
            self._cell = None

    def handle_data(self, data):
        self.text.append(data)
        if self._cell is not None:
            self._cell.append(data)

    @property
    def all_text(self) -> str:
        return " ".join(self.text)


def numbers(text: str) -> list[str]:
    return _NUMBER.findall(text)


def assert_has_numbers_of(summary: str, page: Page) -> None:
    shown = set(numbers(page.all_text))
    missing = [n for n in numbers(summary) if n not in shown]
    assert not missing, f"numbers of summary() missing from the HTML: {missing[:10]}"


# ---------------------------------------------------------------------- helpers
def test_escape_and_table_cells():
    assert escape("<&>\"'") == "&lt;&amp;&gt;&quot;&#x27;"
    page = Page(table([["a", NASTY], [NASTY, 1.5]]))
    assert page.tables == [[["a", NASTY], [NASTY, "1.5"]]]


# ---------------------------------------------------------------------- IOData
def record(n: int = 300, names=("torque", "volts")) -> IOData:
    rng = np.random.default_rng(3)
    u = rng.standard_normal((n, 2))
    # noise keeps the least-squares problem of the identification test well posed
    y = np.convolve(u[:, 0], [0.0, 0.6, 0.2])[:n] + 0.05 * rng.standard_normal(n)
    return IOData(
        u,
        y,
        0.01,
        input_names=list(names),
        output_names=["tip"],
        input_units=["N m", NASTY],
        output_units=["m/s^2"],
    )


def test_iodata_html_has_the_numbers_of_describe():
    data = record()
    page = Page(data._repr_html_())
    assert_has_numbers_of(data.describe(), page)
    (rows,) = page.tables
    assert [r[0] for r in rows[1:]] == ["torque", "volts", "tip"]
    # each channel row carries the line of describe() for that channel
    for row, line in zip(rows[1:], data.describe().splitlines()[1:]):
        assert numbers(" ".join(row[3:])) == numbers(line.split(":", 1)[1])
        assert row[2] in line  # the unit


def test_iodata_html_escapes_names():
    data = record(names=(NASTY, "ok"))
    raw = data._repr_html_()
    assert NASTY not in raw and "&lt;&amp;&gt;" in raw
    page = Page(raw)
    assert page.tables[0][1][0] == NASTY and page.tables[0][1][2] == "N m"
    assert page.tables[0][2][2] == NASTY  # the unit of the second input


# ---------------------------------------------------------------------- Identification
@pytest.fixture(scope="module")
def identification():
    return identify(record(names=(NASTY, "volts")), na=2, nb=[2, 2], nk=1, optimiser="ls")


def test_identification_html_has_the_numbers_of_summary(identification):
    page = Page(identification._repr_html_())
    summary = identification.summary()
    assert_has_numbers_of(summary, page)
    header, compact = page.tables[0], page.tables[1]
    # the header table is the labelled lines of summary(), value for value
    for label, value in header:
        assert "\n".join(labelled([(label, value)], label_width=12)) in summary
    # every number of the compact table is a number of that record's report, formatted the
    # same; the verdicts are the reports' too
    assert compact[0] == ["", "estimation", "validation (held out)"]
    for column, report in enumerate((identification.estimation, identification.validation), 1):
        printed = set(numbers(report.summary()))
        for row in compact[1:]:
            assert set(numbers(row[column])) <= printed, (row[0], row[column])
        verdict = dict((row[0], row[column]) for row in compact[1:])["correlation tests"]
        assert re.search(rf"overall\s+{verdict}", report.summary())


def test_identification_html_escapes_names(identification):
    raw = identification._repr_html_()
    assert NASTY not in raw and "&lt;&amp;&gt;" in raw
    page = Page(raw)
    assert NASTY in page.tables[0][0][1]  # data: inputs [...]


# ---------------------------------------------------------------------- ComparisonResult
@pytest.fixture(scope="module")
def comparison():
    spec = small_spec(
        name=f"small {NASTY}",
        data=manipulator_data(400, 1),
        model=ModelSpec(na=2, nb=2, nk=1),
        optimisers=(OptimiserSpec("random-search"), OptimiserSpec("de")),
        budget=200,
    )
    return compare(spec)


def _text_rows(table_text: str) -> list[list[str]]:
    return [line.split() for line in table_text.splitlines() if not set(line) <= {"-", " "}]


def test_comparison_html_has_the_tables_of_summary(comparison):
    page = Page(comparison._repr_html_())
    summary = comparison.summary()
    assert_has_numbers_of(summary, page)
    header, costs, validation = page.tables
    for label, value in header:
        assert "\n".join(labelled([(label, value)], label_width=10)) in summary
    # the HTML tables hold the cells of the plain-text tables, in the same order
    for html_rows, text in (
        (costs, comparison.cost_table()),
        (validation, comparison.validation_table()),
    ):
        assert [" ".join(r).split() for r in html_rows] == _text_rows(text)
        assert text in summary
    assert "Lowest median cost" in page.all_text


def test_comparison_html_escapes_the_name(comparison):
    raw = comparison._repr_html_()
    assert NASTY not in raw and "&lt;&amp;&gt;" in raw
    assert NASTY in Page(raw).text[0]


# ------------------------------------------------------------------ the Bode figures
def _images(raw: str) -> list[bytes]:
    found = re.findall(r'<img src="data:image/png;base64,([A-Za-z0-9+/=]+)"', raw)
    return [base64.b64decode(text) for text in found]


def test_the_displays_show_the_held_out_bode_figure(identification, comparison):
    """An identification (one image per output), a comparison and a selection display the
    held-out record's Bode figure inline, as PNG, after their tables."""
    for raw in (identification._repr_html_(), comparison._repr_html_()):
        images = _images(raw)
        assert len(images) == 1 and images[0].startswith(b"\x89PNG\r\n\x1a\n")
        assert raw.index("<img") > raw.index("</table>")  # the numbers first
    choice = flexid.select(record(), structures=("arx",), orders={"arx": [{"na": 1, "nb": 1},
                           {"na": 2, "nb": 2}]}, nk=1)  # fmt: skip
    assert len(_images(choice._repr_html_())) == 1


def test_the_displays_without_matplotlib_show_their_tables_alone(identification, monkeypatch):
    from flexid.report import plots

    def unavailable():
        raise plots.PlottingUnavailable("figures need matplotlib")

    monkeypatch.setattr(plots, "_plt", unavailable)
    raw = identification._repr_html_()
    assert "<img" not in raw and "<table" in raw
