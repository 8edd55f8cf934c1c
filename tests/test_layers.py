"""The layers of ``docs/architecture.md`` hold: nothing imports upward, nothing imports in a circle.

The drawing at the top of the page is the one statement of the layers: each layer is a
label followed by its modules (``name.py``) and packages (``name/``, every module under
it).  This test reads it, places every module of the package in exactly one layer, and
checks every import statement of every module, module-level, inside functions and under
``TYPE_CHECKING`` alike (a lazy import still ties two modules together).
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "src" / "flexid"
DRAWING = ROOT / "docs" / "architecture.md"


def layers() -> list[tuple[str, list[str]]]:
    """``(label, entries)`` of each layer, top first, from the page's ```text block."""
    text = DRAWING.read_text(encoding="utf-8")
    block = re.search(r"```text\n(.*?)```", text, re.S)
    assert block, f"{DRAWING}: no ```text drawing of the layers"
    out: list[tuple[str, list[str]]] = []
    for line in block.group(1).splitlines():
        entries = re.findall(r"(?<![\w/.])(\w+(?:\.py|/))(?=\s|$)", line)
        head = line.strip()
        if head and head[0].isalpha() and not line.startswith(" " * 10):  # a label: a new layer
            label = line[: line.index(entries[0])].strip() if entries else head
            out.append((label, []))
        elif entries and not out:
            pytest.fail(f"{DRAWING}: modules before the first layer's label: {line!r}")
        if entries:
            out[-1][1].extend(entries)
    return out


def module_files() -> dict[str, Path]:
    """Dotted name -> file of every module of the package (``flexid`` for its root)."""
    out = {}
    for path in PACKAGE.rglob("*.py"):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def entry_of(name: str, path: Path) -> list[str]:
    """The drawing's entries that could name module ``name``: its file, its package(s)."""
    rel = path.relative_to(PACKAGE)
    found = ["/".join(rel.parts)] if len(rel.parts) == 1 else []
    found += [f"{rel.parts[0]}/"] if len(rel.parts) > 1 else []
    return found


def imports(name: str, path: Path, known: set[str]) -> set[str]:
    """Modules of the package that module ``name`` imports, anywhere in its file."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            submodules = [f"{target}.{alias.name}" for alias in node.names]
            # ``from . import sensors`` needs the submodule; the package itself only for a
            # name its ``__init__`` defines
            whole = any(m not in known for m in submodules)
            candidates = ([target] if whole else []) + submodules
        elif isinstance(node, ast.Import):
            candidates = [alias.name for alias in node.names]
        else:
            continue
        out |= {c for c in candidates if c in known and c != name}
    return out


LAYERS = layers()
FILES = module_files()


def layer_index() -> dict[str, int]:
    index = {}
    for name, path in FILES.items():
        places = [
            i for i, (_, entries) in enumerate(LAYERS) for e in entry_of(name, path) if e in entries
        ]
        assert len(places) == 1, (
            f"{name} ({path.relative_to(ROOT)}) is in {len(places)} layers of the drawing in "
            f"{DRAWING.relative_to(ROOT)}; give it exactly one"
        )
        index[name] = places[0]
    return index


def test_the_drawing_names_only_modules_that_exist():
    existing = {e for name, path in FILES.items() for e in entry_of(name, path)}
    named = [e for _, entries in LAYERS for e in entries]
    assert len(LAYERS) >= 5
    assert sorted(set(named) - existing) == []
    assert len(named) == len(set(named)), "a module is drawn twice"


def test_every_module_is_in_one_layer():
    assert len(layer_index()) == len(FILES)


def test_no_module_imports_from_a_layer_above_it():
    index = layer_index()
    upward = []
    for name, path in FILES.items():
        for target in imports(name, path, set(FILES)):
            if target == "flexid":  # ``from . import x`` of a module is caught as x itself
                continue
            if index[target] < index[name]:
                upward.append(
                    f"{name} ({LAYERS[index[name]][0]}) imports {target} "
                    f"({LAYERS[index[target]][0]})"
                )
    assert upward == []


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan's algorithm)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        for nxt in graph[node]:
            if nxt not in index:
                visit(nxt)
                low[node] = min(low[node], low[nxt])
            elif nxt in stack:
                low[node] = min(low[node], index[nxt])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                component.append(member)
                if member == node:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return found


def test_the_import_graph_has_no_circle():
    graph = {name: imports(name, path, set(FILES)) - {"flexid"} for name, path in FILES.items()}
    assert circles(graph) == []
    # the search finds one where there is one
    assert circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_the_check_sees_a_lazy_upward_import(tmp_path):
    """The import reader finds an import inside a function, so the checks above can fail."""
    source = tmp_path / "mod.py"
    source.write_text("def f():\n    from .jobs._identify import identify\n    return identify\n")
    assert imports("flexid.mod", source, {"flexid.jobs._identify"}) == {"flexid.jobs._identify"}
