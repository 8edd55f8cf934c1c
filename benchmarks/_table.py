"""The result table the benchmark scripts print (imported from their own folder)."""

from __future__ import annotations


def print_table(rows: list[tuple[str, str]], note: str) -> None:
    """Print ``note``, then ``rows`` as a two-column table of cases and results.

    Parameters
    ----------
    rows : list of (str, str)
        Case name and formatted result, one pair per row.
    note : str
        The line above the table (how the numbers were taken).
    """
    width = max(len(name) for name, _ in rows)
    print(note)
    print(f"{'case':<{width}}  result")
    print("-" * (width + 2 + max(len(value) for _, value in rows)))
    for name, value in rows:
        print(f"{name:<{width}}  {value}")
