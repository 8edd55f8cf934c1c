"""Reports of the comparisons in a result store: Markdown or HTML with their figures, and the
IOHprofiler export for IOHanalyzer.

The report's ECDF is the empirical distribution of the runtimes over (run, target) pairs, as
COCO and IOHanalyzer draw it (:func:`comparison_ecdf`); :func:`export_ioh` writes the runs in
the IOHprofiler format (the module :mod:`flexid._ioh` says which layout and how flexid maps
onto it).
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from ._compare import load_result
from ._comparison_result import ComparisonResult
from ._html import escape, table
from ._ioh import (
    IOH_LAYOUTS,
    TARGETS_PER_DECADE,
    _name,
    check_histories,
    comparison_ecdf,
    ecdf_fraction,
    ecdf_targets,
    export_ioh,
)
from .errors import ConfigError

__all__ = [
    "IOH_LAYOUTS",
    "comparison_ecdf",
    "ecdf_fraction",
    "ecdf_targets",
    "export_ioh",
    "figure_prefix",
    "write_report",
]


def _slug(text: str) -> str:
    """The file-name form of a comparison name: the export's folder name, in lower case."""
    return _name(text).lower()


def figure_prefix(result: ComparisonResult) -> str:
    """The file-name prefix of a comparison's figures: its name and its key.

    Two comparisons with the same name (other data, orders or budgets) have other keys, so
    neither's figures replace the other's.

    Parameters
    ----------
    result : ComparisonResult

    Returns
    -------
    str
        ``"<name>-<first 8 characters of the key>-"``, letters, digits and single hyphens.
    """
    return f"{_slug(result.spec.name)}-{result.key[:8]}-"


def _md_table(header: list[str], rows: list[list[str]]) -> list[str]:
    """The lines of a Markdown table: the header, the separator, one line per row."""
    return [_md_row(header), "|" + "---|" * len(header)] + [_md_row(r) for r in rows]


def _md_row(cells: list[str]) -> str:
    return "| " + " | ".join(cells) + " |"


def _markdown_table(text_table: str) -> str:
    """Turn one of ComparisonResult's plain-text tables into a Markdown table."""
    lines = [ln for ln in text_table.splitlines() if ln.strip()]
    header = re.split(r"\s{2,}", lines[0].strip())
    rows = []
    for line in lines[2:]:
        cells = re.split(r"\s{2,}", line.strip())
        rows.append(cells + [""] * (len(header) - len(cells)))
    return "\n".join(_md_table(header, rows))


def _section(result: ComparisonResult, outdir: Path, figures: bool) -> list[str]:
    spec = result.spec
    slug = figure_prefix(result).rstrip("-")
    lines = [f"## {spec.name}", ""]
    header, _, _ = result.summary().partition("\n\n")
    lines += ["```", header, "```", ""]
    lines += ["### Final cost and FE to target", "", _markdown_table(result.cost_table()), ""]
    lines += [
        "Costs are final best costs at the budget. *FE to t (ok)*: median function evaluations "
        "to reach reference x (1 + t) over the runs that reached it, and the share of runs that "
        "did. *p (Holm)*: two-sided rank-sum test against the optimiser with the lowest median, "
        "Holm-corrected; * marks p < 0.05.",
        "",
    ]
    lines += [
        "### Validation on the held-out record",
        "",
        _markdown_table(result.validation_table()),
        "",
    ]
    conclusion = result.summary().rsplit("\n", 1)[-1]
    if conclusion.startswith("Lowest median cost"):
        lines += [conclusion, ""]
    ecdf = comparison_ecdf(result)
    lines += _ecdf_lines(result, ecdf)
    if figures:
        from .plots import _save, comparison_figures, plot_ecdf

        paths = comparison_figures(result, outdir, prefix=f"{slug}-")
        if len(ecdf["targets"]):
            paths.append(_save(plot_ecdf(ecdf), outdir / f"{slug}-ecdf.png"))
        for path in paths:
            lines += [f"![{path.stem}]({path.name})", ""]
    return lines


def _ecdf_lines(result: ComparisonResult, ecdf: dict) -> list[str]:
    """The ECDF section: what the targets are, and the fraction reached at a few budgets."""
    lines = ["### ECDF of (run, target) pairs", ""]
    targets = ecdf["targets"]
    if not len(targets):
        return [*lines, "No ECDF: the reference cost is not a finite positive number.", ""]
    reference = ecdf["reference"]
    easiest, hardest = targets[0] / reference - 1.0, targets[-1] / reference - 1.0
    budget = result.spec.max_fe
    budgets = sorted({max(1, math.ceil(budget / 100)), max(1, math.ceil(budget / 10)), budget})
    rows = []
    for label, curve in ecdf["curves"].items():
        if not curve["runs"]:
            rows.append([label, "0"] + ["-"] * len(budgets))
            continue
        fe, fraction = curve["fe"], curve["fraction"]
        at = fraction[np.searchsorted(fe, np.asarray(budgets, float), side="right") - 1]
        rows.append([label, str(curve["runs"])] + [f"{v * 100:.0f}%" for v in at])
    out = _md_table(["optimiser", "runs"] + [f"{b} FE" for b in budgets], rows)
    note = (
        f"Fraction of (run, target) pairs reached within the FE shown, over {len(targets)} "
        f"targets reference x (1 + d), d log-spaced from {easiest:.3g} (the worst first "
        f"best cost of any run) down to {hardest:.3g} (the smallest target t), "
        f"{TARGETS_PER_DECADE} to a decade as COCO places its targets; reference "
        f"{reference:.5g}. Finished runs only."
    )
    return lines + out + ["", note, ""]


def write_report(
    store: str | Path,
    outdir: str | Path,
    *,
    fmt: str = "md",
    key: str | None = None,
    figures: bool = True,
) -> Path:
    """Write ``report.md`` (or ``report.html``) and the PNG figures for a store.

    Parameters
    ----------
    store : path
        A result store written by :func:`flexid.compare`.
    outdir : path
        Folder for the report and figures (created).
    fmt : {"md", "html"}
        Report format.
    key : str, optional
        Only this comparison (a unique key prefix).
    figures : bool
        Draw the figures (needs matplotlib).

    Returns
    -------
    Path
        The report file.
    """
    if fmt not in ("md", "html"):
        raise ConfigError(f"report format must be 'md' or 'html', got {fmt!r}")
    check_histories(store, key)  # the statistics read every history
    results = load_result(store, key)
    if not results:
        raise ConfigError(f"{store}: the store holds no comparison")
    outdir = Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    lines = ["# flexid comparison report", "", f"Store: `{store}`", ""]
    for result in results:
        lines += _section(result, outdir, figures)
    markdown = "\n".join(lines) + "\n"
    if fmt == "md":
        path = outdir / "report.md"
        path.write_text(markdown, encoding="utf-8")
        return path
    path = outdir / "report.html"
    path.write_text(_to_html(markdown), encoding="utf-8")
    return path


def _to_html(markdown: str) -> str:
    """A small Markdown subset (headings, code blocks, tables, images, paragraphs) to HTML."""
    out = [
        "<!DOCTYPE html><html><head><meta charset='utf-8'><title>flexid report</title>",
        "<style>body{font-family:sans-serif;max-width:70em;margin:auto}"
        "table{border-collapse:collapse}td,th{border:1px solid #bbb;padding:2px 6px;"
        "text-align:right}td:first-child,th:first-child{text-align:left}"
        "pre{background:#f4f4f4;padding:6px}</style></head><body>",
    ]
    lines = markdown.splitlines()
    i = 0
    while i < len(lines):
        line = lines[i]
        if line.startswith("```"):
            j = i + 1
            block = []
            while j < len(lines) and not lines[j].startswith("```"):
                block.append(escape(lines[j]))
                j += 1
            out.append("<pre>" + "\n".join(block) + "</pre>")
            i = j + 1
            continue
        if line.startswith("|"):
            rows = []
            while i < len(lines) and lines[i].startswith("|"):
                rows.append(lines[i])
                i += 1
            cells = [[c.strip() for c in r.strip("|").split("|")] for r in rows]
            out.append(table([cells[0], *cells[2:]]))  # cells[1] is the separator
            continue
        heading = re.match(r"^(#+) (.*)", line)
        image = re.match(r"^!\[(.*)\]\((.*)\)$", line)
        if heading:
            n = len(heading.group(1))
            out.append(f"<h{n}>{escape(heading.group(2))}</h{n}>")
        elif image:
            out.append(
                f"<p><img src='{escape(image.group(2))}' "
                f"alt='{escape(image.group(1))}'></p>"
            )
        elif line.strip():
            text = escape(line)
            text = re.sub(r"`([^`]*)`", r"<code>\1</code>", text)
            text = re.sub(r"\*([^*]+)\*", r"<em>\1</em>", text)
            out.append(f"<p>{text}</p>")
        i += 1
    out.append("</body></html>")
    return "\n".join(out)
