"""Reports of the comparisons in a result store: Markdown or HTML with their figures, and the
IOHprofiler export for IOHanalyzer.

The report's ECDF is the empirical distribution of the runtimes over (run, target) pairs, as
COCO and IOHanalyzer draw it (:func:`comparison_ecdf`); :func:`export_ioh` writes the runs in
the IOHprofiler format (the module :mod:`flexid.jobs._ioh` says which layout and how flexid maps
onto it).
"""

from __future__ import annotations

import hashlib
import json
import math
import re
import warnings
from pathlib import Path

import numpy as np

from .._html import escape, table
from ..data._files import write_files
from ..errors import ConfigError, StoreError, StoreWarning
from ..jobs._compare import load_result
from ..jobs._comparison_result import ComparisonResult
from ..jobs._ioh import (
    IOH_LAYOUTS,
    TARGETS_PER_DECADE,
    _name,
    check_histories,
    comparison_ecdf,
    ecdf_fraction,
    ecdf_targets,
    export_ioh,
)
from ..jobs.store import ResultStore
from ..models.vocabulary import LEAST_SQUARES

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
    """The file-name prefix of a comparison's figures: its name, its key and its digest.

    The key names the problem (record, model, cost, budget), which comparisons of other
    optimisers or run counts share (they share its runs in the store); the digest names the
    comparison itself (:func:`_comparison_digest`).  So no comparison's figures replace
    another's, and the same comparison run again writes the same names.

    Parameters
    ----------
    result : ComparisonResult

    Returns
    -------
    str
        ``"<name>-<first 8 characters of the key>-<6-character digest>-"``, letters, digits
        and single hyphens.
    """
    spec = result.spec
    return f"{_slug(spec.name)}-{result.key[:8]}-{_comparison_digest(spec)}-"


def _comparison_digest(spec) -> str:
    """A short hash of what a comparison's figures show beyond its problem: the optimisers
    in their order with their labels and hyper-parameters, the runs, budget and targets."""
    shown = {
        "optimisers": [[o.display, o.name, o.params] for o in spec.optimisers],
        "runs": spec.runs,
        "budget": spec.budget,
        "max_fe": spec.max_fe,
        "targets": list(spec.targets),
    }
    text = json.dumps(shown, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:6]


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


def _section(result: ComparisonResult, figures: bool) -> tuple[list[str], list]:
    """The Markdown lines of a comparison and its figures' (file name, PNG bytes)."""
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
    files: list[tuple[str, bytes]] = []
    if figures:
        from .plots import _comparison_images, _drawn, plot_ecdf

        files = _comparison_images(result, f"{slug}-")
        if len(ecdf["targets"]):
            files.append(_drawn(plot_ecdf(ecdf), f"{slug}-ecdf.png"))
        for name, _ in files:
            lines += [f"![{Path(name).stem}]({name})", ""]
    return lines, files


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

    A comparison that cannot be read (its least-squares row damaged, or not written yet
    while its reference is computing) is left out, named in one line in the report and in
    a :class:`~flexid.errors.StoreWarning`; the others are reported.  The report and its
    figures are written together or not at all.

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

    Raises
    ------
    StoreError
        If no comparison of the store can be read (each is named, with why).
    DataFileError
        If the report cannot be written to ``outdir`` (a full disk, no permission, a file
        of that name such as the store itself); no file of it is left then.
    """
    if fmt not in ("md", "html"):
        raise ConfigError(f"report format must be 'md' or 'html', got {fmt!r}")
    results, left_out = _readable_results(store, key)
    lines = ["# flexid comparison report", "", f"Store: `{store}`", ""]
    lines += [f"Left out: {line}." for line in left_out] + ([""] if left_out else [])
    files: list[tuple[str, bytes]] = []
    for result in results:
        section, images = _section(result, figures)
        lines += section
        files += images
    markdown = "\n".join(lines) + "\n"
    name, text = ("report.md", markdown) if fmt == "md" else ("report.html", _to_html(markdown))
    # the report and its figures together, or nothing: never a report without its figures
    return write_files(Path(outdir), [*files, (name, text.encode("utf-8"))], "the report")[-1]


def _readable_results(
    store: str | Path, key: str | None
) -> tuple[list[ComparisonResult], list[str]]:
    """The comparisons of a store that can be reported, and a line for each left out.

    A comparison whose least-squares row is damaged, or not written yet (its reference is
    still computing), or whose histories are unusable, is left out with a
    :class:`~flexid.errors.StoreWarning` of one line (instead of the store's own warning
    about its rows); the others are reported.  With none left, a :class:`StoreError`.
    """
    results, left_out, shown = [], [], []
    with ResultStore(store, readonly=True) as db:
        entries = [db.comparison(key)] if key else db.comparisons()
        if not entries:
            raise ConfigError(f"{store}: the store holds no comparison")
        for entry in entries:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                try:
                    check_histories(store, entry["key"])  # the statistics read every history
                    (result,) = load_result(db, entry["key"])
                except StoreError as exc:
                    why = _why_unreadable(db, entry["key"], exc)
                    left_out.append((entry["name"], entry["key"][:8], *why))
                    caught = [w for w in caught if not issubclass(w.category, StoreWarning)]
                else:
                    results.append(result)
            shown += caught
    seen = set()
    for w in shown:  # each warning once, though the rows were read twice
        if (w.category, str(w.message)) not in seen:
            seen.add((w.category, str(w.message)))
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    if not results:
        by_reason: dict[str, list[str]] = {}
        for name, _, why, _ in left_out:
            by_reason.setdefault(why, []).append(repr(name))
        reasons = "; ".join(f"{', '.join(names)}: {why}" for why, names in by_reason.items())
        raise StoreError(f"{store}: nothing to report: {reasons}")
    lines = [
        f"{name!r} [{short}]: {why}" + (f" ({hint})" if hint else "")
        for name, short, why, hint in left_out
    ]
    for line in lines:
        warnings.warn(f"report: left out {line}", StoreWarning, stacklevel=3)
    return results, lines


def _why_unreadable(db: ResultStore, key: str, exc: StoreError) -> tuple[str, str]:
    """Why a comparison cannot be reported, in a few words, and what to do (or "")."""
    if "least-squares reference row is missing" not in str(exc):
        return str(exc).rsplit("]: ", 1)[-1], ""  # the message less the comparison it names
    if db.has_run(key, LEAST_SQUARES, 0):
        return "least-squares row damaged", "rerun it"
    return "not finished", "no reference row yet"


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
