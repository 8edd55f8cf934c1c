"""Plain-text tables of the summaries (comparisons, structure selection)."""

from __future__ import annotations

import textwrap
from collections.abc import Iterable, Sequence

__all__ = ["LINE_WIDTH", "labelled", "text_table", "wrapped"]

#: The longest line a summary prints: a terminal's or a log viewer's width, with margin.
LINE_WIDTH = 100


def wrapped(text: str, indent: str = "", hang: str = "    ", width: int = LINE_WIDTH) -> str:
    """One paragraph of prose in lines of at most ``width`` characters.

    Parameters
    ----------
    text : str
        The paragraph (one line; words longer than the line, an address say, are kept whole).
    indent : str
        The first line's indent.
    hang : str
        Added to ``indent`` for the lines after the first.
    width : int

    Returns
    -------
    str
    """
    return textwrap.fill(text, width, initial_indent=indent, subsequent_indent=indent + hang,
                         break_long_words=False, break_on_hyphens=False)  # fmt: skip


def labelled(items: Iterable[tuple[str, str]], *, label_width: int, indent: str = "  ",
             width: int = LINE_WIDTH) -> list[str]:  # fmt: skip
    """Header lines ``label : value``, a long value continued under its first word.

    Parameters
    ----------
    items : iterable of (str, str)
        Labels and values.
    label_width : int
        The labels' column width.
    indent : str
        Before each label.
    width : int
        The longest line.

    Returns
    -------
    list of str
    """
    lines = []
    for label, value in items:
        head = f"{indent}{label:<{label_width}}: "
        body = textwrap.wrap(str(value), width - len(head), break_long_words=False,
                             break_on_hyphens=False) or [""]  # fmt: skip
        lines.append(head + body[0])
        lines += [" " * len(head) + part for part in body[1:]]
    return lines


def text_table(rows: Sequence[Sequence[object]], left: Sequence[int] = (0,), *,
               width: int | None = None, keys: int = 1) -> str:  # fmt: skip
    """Rows as aligned text: the first row a header underlined by dashes.

    Parameters
    ----------
    rows : sequence of sequences
        Header, then one row per line; cells are converted with ``str``.
    left : sequence of int, optional
        Columns aligned left (negative indices count from the end); the others align right.
    width : int, optional
        The longest line.  A wider table is printed in blocks of columns, one under the
        other, each repeating the first ``keys`` columns (as pandas and R print a wide
        frame); default: one block whatever its width.
    keys : int
        The columns that name a row (repeated in every block).

    Returns
    -------
    str
    """
    n = len(rows[0])
    widths = [max(len(str(r[i])) for r in rows) for i in range(n)]
    lefts = {i % n for i in left}

    def render(columns: Sequence[int]) -> str:
        lines = []
        for k, row in enumerate(rows):
            cells = [str(row[i]).ljust(widths[i]) if i in lefts else str(row[i]).rjust(widths[i])
                     for i in columns]  # fmt: skip
            lines.append("  ".join(cells).rstrip())
            if k == 0:
                lines.append("  ".join("-" * widths[i] for i in columns).rstrip())
        return "\n".join(lines)

    if width is None or sum(widths) + 2 * (n - 1) <= width:
        return render(range(n))
    named = list(range(min(keys, n)))
    base = sum(widths[i] for i in named) + 2 * (len(named) - 1)
    blocks: list[list[int]] = [[]]
    used = base
    for i in range(len(named), n):
        if blocks[-1] and used + 2 + widths[i] > width:
            blocks.append([])
            used = base
        blocks[-1].append(i)
        used += 2 + widths[i]
    return "\n\n".join(render(named + block) for block in blocks)
