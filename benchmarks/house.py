"""The package's structure in numbers: its rooms, layers, import arrows and family checks.

Run: ``.venv/bin/python benchmarks/house.py`` (a second or two).  Read from the source, not
run: the rooms are the top-level entries of ``src/flexid`` (a folder or a root module), an
arrow is a pair of rooms one imports from (module-level, lazy and type-only imports alike),
an upward arrow is one from a lower layer of ``docs/architecture.md``'s drawing to a higher
one (``tests/test_layers.py`` refuses any), a family check is an ``isinstance`` on a model
family's class outside the families' own modules (``models/``, ``costs/``, ``*_family.py``),
and a branchy function is one of cyclomatic complexity above 20 (radon's grade D and worse),
as ``lizard`` counts it when it is installed (``pip install lizard``).
"""

from __future__ import annotations

import ast
import re
import subprocess
import sys
from pathlib import Path

from _table import print_table

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "src" / "flexid"
FAMILY_CHECK = re.compile(
    r"isinstance\(.*(PolynomialStructure|ARXStructure|GreyBox|PolynomialModel|ARX\))"
)
FAMILIES_OWN = re.compile(r"^(models|costs)/|_family\.py$")


def room_of(path: Path) -> str:
    """The room a module lies in: its top-level folder, or the root module itself."""
    rel = path.relative_to(PACKAGE)
    return f"{rel.parts[0]}/" if len(rel.parts) > 1 else rel.name


def layers() -> dict[str, int]:
    """Room -> layer number (0 = the foundation), read by the layers test's own reader."""
    sys.path.insert(0, str(ROOT / "tests"))
    from test_layers import layers as drawing

    found = [entries for _, entries in drawing()]
    return {room: len(found) - 1 - i for i, rooms in enumerate(found) for room in rooms}


def arrows() -> set[tuple[str, str]]:
    """Every (importing room, imported room) pair between two different rooms."""
    out = set()
    for path in PACKAGE.rglob("*.py"):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        package = parts[:-1]  # a module's package; an __init__'s is its own folder
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and node.level:
                base = list(package[: len(package) - node.level + 1])
                names = [*(node.module.split(".") if node.module else [])]
                target = base + names
            elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("flexid."):
                target = node.module.split(".")
            else:
                continue
            if len(target) < 2:  # the package root itself (``from .. import kernels``)
                target = [*target, node.names[0].name]
            entry = PACKAGE / target[1]
            room = f"{target[1]}/" if entry.is_dir() else f"{target[1]}.py"
            if room != room_of(path):
                out.add((room_of(path), room))
    return out


def branchy_functions() -> str:
    """Functions of cyclomatic complexity above 20, or why they were not counted."""
    run = subprocess.run([sys.executable, "-m", "lizard", "-l", "python", "-C", "20", "-w",
                          str(PACKAGE)], capture_output=True, text=True)  # fmt: skip
    if "No module named lizard" in run.stderr:
        return "not counted (lizard is not installed)"
    found = [line.split(": warning: ")[1].split(" has ")[0]
             for line in run.stdout.splitlines() if ": warning: " in line]  # fmt: skip
    return f"{len(found)}" + (f" ({', '.join(found)})" if found else "")


def _where(checks: list[str]) -> str:
    """``(file n, ...)``: how many checks each file holds."""
    files: dict[str, int] = {}
    for c in checks:
        files[c.split(":")[0]] = files.get(c.split(":")[0], 0) + 1
    return f"({', '.join(f'{f} {n}' for f, n in sorted(files.items()))})" if files else ""


def main() -> None:
    rooms = sorted({room_of(p) for p in PACKAGE.rglob("*.py")})
    floor = layers()
    pairs = arrows()
    upward = sorted((a, b) for a, b in pairs if floor.get(a, 0) < floor.get(b, 0))
    checks = []
    for path in PACKAGE.rglob("*.py"):
        rel = path.relative_to(PACKAGE).as_posix()
        if FAMILIES_OWN.search(rel):
            continue
        text = path.read_text(encoding="utf-8")
        checks += [f"{rel}:{i}" for i, line in enumerate(text.splitlines(), 1)
                   if FAMILY_CHECK.search(line)]  # fmt: skip
    readme = len((ROOT / "README.md").read_text(encoding="utf-8").splitlines())
    print_table([
        ("modules", str(sum(1 for _ in PACKAGE.rglob("*.py")))),
        ("rooms (top-level folders and root modules)", str(len(rooms))),
        ("modules in the root folder", str(sum(1 for _ in PACKAGE.glob("*.py")))),
        ("layers of the drawing", str(max(floor.values()) + 1)),
        ("arrows between rooms", str(len(pairs))),
        ("upward arrows", str(len(upward)) + (f" {upward}" if upward else "")),
        ("family checks outside the families' modules", f"{len(checks)} {_where(checks)}"),
        ("functions of complexity above 20", branchy_functions()),
        ("README lines", str(readme)),
    ], "the structure of src/flexid, read from its source")  # fmt: skip


if __name__ == "__main__":
    main()
