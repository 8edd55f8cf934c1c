"""A package's names imported from its submodules on first use (:pep:`562`).

The front door, :mod:`flexid.models` and :mod:`flexid.costs` export their names this way, so
importing one submodule does not import the others.
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Mapping
from typing import Any

__all__: list[str] = []


def lazy_exports(
    package: str, table: Mapping[str, str | None]
) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The module ``__getattr__`` and ``__dir__`` of ``package`` for the names of ``table``.

    ``__getattr__`` imports a name from its submodule (``table``: public name -> submodule
    of ``package``, or None where the name is a submodule itself) and keeps it in the
    package's namespace, so it is imported once.
    """
    namespace = sys.modules[package].__dict__

    def __getattr__(name: str) -> Any:
        if name not in table:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        module = table[name]
        if module is None:
            value = importlib.import_module(f".{name}", package)
        else:
            value = getattr(importlib.import_module(f".{module}", package), name)
        namespace[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted(set(namespace) | set(table))

    return __getattr__, __dir__
