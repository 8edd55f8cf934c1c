"""Plain-text tables of the summaries (comparisons, structure selection)."""

from __future__ import annotations

from collections.abc import Sequence

__all__ = ["text_table"]


def text_table(rows: Sequence[Sequence[object]], left: Sequence[int] = (0,)) -> str:
    """Rows as aligned text: the first row a header underlined by dashes.

    Parameters
    ----------
    rows : sequence of sequences
        Header, then one row per line; cells are converted with ``str``.
    left : sequence of int, optional
        Columns aligned left (negative indices count from the end); the others align right.

    Returns
    -------
    str
    """
    n = len(rows[0])
    widths = [max(len(str(r[i])) for r in rows) for i in range(n)]
    lefts = {i % n for i in left}
    lines = []
    for k, row in enumerate(rows):
        cells = [
            str(c).ljust(w) if i in lefts else str(c).rjust(w)
            for i, (c, w) in enumerate(zip(row, widths))
        ]
        lines.append("  ".join(cells).rstrip())
        if k == 0:
            lines.append("  ".join("-" * w for w in widths).rstrip())
    return "\n".join(lines)
