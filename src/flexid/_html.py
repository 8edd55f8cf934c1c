"""Small HTML building blocks for the notebook displays (``_repr_html_``) of flexid's results.

Every piece of text goes through :func:`escape`, so a channel, optimiser or comparison name
such as ``"<&>"`` is shown as typed and never read as markup.  The displays show the numbers
of the objects' plain-text ``summary()`` formatted the same way, in tables; the long parts
(model coefficients, full validation reports) sit in collapsed ``<details>`` blocks.
"""

from __future__ import annotations

import base64
import html
from collections.abc import Callable, Iterable, Sequence
from typing import Any

__all__ = [
    "block",
    "details",
    "escape",
    "figures",
    "key_values",
    "paragraph",
    "register_figures",
    "table",
]

#: Kind of result -> the function that draws its figures for a display, as PNG bytes (an
#: empty list: none).  The figures' module sits above the results' in the layers, so the
#: front door registers them; with none registered a display shows its tables alone.
_FIGURES: dict[str, Callable[[Any], list[bytes]]] = {}

_TABLE = '<table class="flexid">'
_LEFT = 'style="text-align: left"'
_RIGHT = 'style="text-align: right"'


def escape(value: Any) -> str:
    """``str(value)`` with ``&``, ``<``, ``>`` and both quotes escaped for HTML."""
    return html.escape(str(value), quote=True)


def table(rows: Sequence[Sequence[Any]], caption: str | None = None, left: int = 1) -> str:
    """An HTML table whose first row is the header.

    Parameters
    ----------
    rows : sequence of sequences
        The header row, then the body rows; cells are converted with ``str`` and escaped.
    caption : str, optional
        A caption above the table.
    left : int, optional
        How many leading columns are left-aligned (labels, default 1); the others are
        right-aligned (numbers), as in flexid's plain-text tables.

    Returns
    -------
    str
        The ``<table>`` element.
    """
    parts = [_TABLE]
    if caption:
        parts.append(f"<caption {_LEFT}>{escape(caption)}</caption>")
    head, *body = rows
    parts.append(f"<thead>{_row('th', head, left)}</thead><tbody>")
    parts += [_row("td", row, left) for row in body]
    parts.append("</tbody></table>")
    return "".join(parts)


def _row(tag: str, cells: Sequence[Any], left: int) -> str:
    """One ``<tr>`` of ``tag`` cells, the first ``left`` left-aligned, the others right."""
    return (
        "<tr>"
        + "".join(
            f"<{tag} {_LEFT if i < left else _RIGHT}>{escape(c)}</{tag}>"
            for i, c in enumerate(cells)
        )
        + "</tr>"
    )


def key_values(items: Iterable[tuple[str, Any]]) -> str:
    """A two-column table of labels and values, e.g. the header lines of a ``summary()``."""
    rows = "".join(
        f"<tr><th {_LEFT}>{escape(k)}</th><td {_LEFT}>{escape(v)}</td></tr>" for k, v in items
    )
    return f"{_TABLE}<tbody>{rows}</tbody></table>"


def details(title: str, text: str) -> str:
    """A collapsed block holding preformatted ``text`` (a plain-text report)."""
    return f"<details><summary>{escape(title)}</summary><pre>{escape(text)}</pre></details>"


def paragraph(text: str) -> str:
    """One escaped paragraph."""
    return f"<p>{escape(text)}</p>"


def block(title: str, *parts: str) -> str:
    """The whole display: a bold title over already-built ``parts`` (escaped HTML)."""
    return (
        '<div class="flexid-summary">'
        f"<p><strong>{escape(title)}</strong></p>" + "".join(parts) + "</div>"
    )


def register_figures(kind: str, draw: Callable[[Any], list[bytes]]) -> None:
    """Register the function that draws the figures of a kind of result for its display.

    Parameters
    ----------
    kind : str
        ``"identification"``, ``"comparison"`` or ``"selection"``.
    draw : callable
        ``draw(result)`` -> list of PNG images (bytes); empty when there is no figure (or
        no matplotlib).
    """
    _FIGURES[kind] = draw


def figures(kind: str, result: Any, alt: str) -> str:
    """The registered figures of ``result`` as inline PNG images ("" for none).

    Parameters
    ----------
    kind : str
        The kind of result, as registered.
    result : object
        The result displayed.
    alt : str
        The images' alternative text.

    Returns
    -------
    str
    """
    draw = _FIGURES.get(kind)
    images = [] if draw is None else draw(result)
    return "".join(
        f'<img src="data:image/png;base64,{base64.b64encode(png).decode("ascii")}" '
        f'alt="{escape(alt)}" style="max-width: 100%">'
        for png in images
    )
