"""The public docstrings are numpydoc: ``numpydoc.validate`` passes on every public name.

Every name in ``flexid.__all__`` and in each public module's ``__all__`` (modules whose dotted
name has no ``_``-prefixed part), every registered optimiser class (variants included) and the
public methods and properties those classes define themselves are validated, and the test fails
on the error codes in :data:`CHECKED`, listing each failure as ``name: code message``.

Two readings differ from plain numpydoc, because the signature is not where the parameters are:

* an :class:`~flexid.optimisers.Optimiser` subclass takes ``**params``; its parameters are its
  declared hyper-parameters (:meth:`~flexid.optimisers.Optimiser.hyperparameters`), and the
  class docstring's ``Parameters`` section must list exactly those;
* a dataclass's fields are both constructor parameters and attributes, so a field documented
  under ``Attributes`` counts as documented.

Signature parameters whose name starts with ``_`` are private and need no entry, and a method
that overrides a documented one without a docstring of its own keeps the base's (as
:func:`inspect.getdoc` and ``help`` do).

:data:`PENDING` lists the failures not fixed yet, per name and code.  It may only shrink: an
entry that passes fails :func:`test_pending_entries_still_fail` until it is removed.
"""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import json
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

numpydoc_validate = pytest.importorskip("numpydoc.validate")
numpydoc_docscrape = pytest.importorskip("numpydoc.docscrape")

from flexid.optimisers import Optimiser, available, get  # noqa: E402
from helpers import public_modules  # noqa: E402

# The codes the test holds; the others (no Examples, no See Also, summary wording, ...) are
# style the project does not require of every name.
CHECKED = frozenset(
    {
        "GL06",  # unknown section (only numpydoc's standard sections)
        "GL07",  # sections in the wrong order
        "GL08",  # no docstring
        "PR01",  # a parameter is not documented
        "PR02",  # a documented parameter does not exist
        "PR10",  # "name: type" without the space before the colon (parsed as garbage)
        "SS01",  # no one-line summary
        "SS03",  # summary does not end with a period
        "RT01",  # a function that returns a value has no Returns section
        "YD01",  # a generator has no Yields section
    }
)

# name -> codes that still fail there (see the module docstring: this list only shrinks)
PENDING: dict[str, frozenset[str]] = {}


class FlexidValidator(numpydoc_validate.Validator):
    """numpydoc's validator with flexid's reading of optimiser and dataclass parameters."""

    def __init__(self, obj_name: str, obj: object) -> None:
        super().__init__(numpydoc_docscrape.get_doc_object(obj))
        self.public_name = obj_name

    @property
    def signature_parameters(self) -> tuple[str, ...]:
        if inspect.isclass(self.obj) and issubclass(self.obj, Optimiser):
            return tuple(self.obj.hyperparameters())
        params = super().signature_parameters
        if inspect.isfunction(self.obj) and "." not in self.obj.__qualname__:
            # numpydoc drops a first parameter named cls, right only for methods
            first = next(iter(inspect.signature(self.obj).parameters), None)
            if first == "cls":
                params = ("cls", *params)
        return tuple(p for p in params if not p.startswith("_"))

    @property
    def source_file_def_line(self) -> int | None:
        # numpydoc looks for the first ``def`` of the source: a module of names it imports
        # (a layer's package front) has none, and its docstring starts at its first line
        if inspect.ismodule(self.obj):
            return 1
        return super().source_file_def_line

    @property
    def doc_all_parameters(self) -> dict[str, tuple[str, list[str]]]:
        documented = dict(super().doc_all_parameters)
        if inspect.isclass(self.obj) and dataclasses.is_dataclass(self.obj):
            fields = set(self.signature_parameters)
            for name, entry in self._doc_parameters(["Attributes"]).items():
                if name in fields:
                    documented.setdefault(name, entry)
        return documented


def public_objects() -> dict[str, object]:
    """``{public dotted name: object}``, each object once (under the first name found)."""
    found: dict[str, object] = {}
    seen: set[int] = set()

    def add(name: str, obj: object) -> None:
        if id(obj) not in seen:
            seen.add(id(obj))
            found[name] = obj

    for module_name in public_modules():
        module = importlib.import_module(module_name)
        add(module_name, module)
        for name in module.__all__:
            obj = getattr(module, name)
            if inspect.isclass(obj) or inspect.isfunction(obj):
                add(f"{module_name}.{name}", obj)
    for name in available():
        cls = get(name)
        add(f"{cls.__module__}.{cls.__qualname__}", cls)
    for owner_name, owner in list(found.items()):
        if not inspect.isclass(owner):
            continue
        for name, member in vars(owner).items():
            if name.startswith("_"):
                continue
            if isinstance(member, (staticmethod, classmethod)):
                member = member.__func__
            if inspect.isfunction(member) or isinstance(member, property):
                if member.__doc__ is None and documented_in_base(owner, name):
                    continue  # an override keeps its base's documentation (inspect.getdoc)
                add(f"{owner_name}.{name}", member)
    return found


def documented_in_base(cls: type, name: str) -> bool:
    """Whether a base class of ``cls`` defines ``name`` with a docstring."""
    for base in cls.__mro__[1:]:
        if name in vars(base):
            return getattr(vars(base)[name], "__doc__", None) is not None
    return False


def failures(name: str, obj: object) -> list[tuple[str, str]]:
    """The ``(code, message)`` pairs of :data:`CHECKED` that numpydoc reports for ``obj``."""
    if inspect.isfunction(obj):
        obj = inspect.unwrap(obj)  # the function a checking decorator wraps, as written
    with warnings.catch_warnings():
        # numpydoc also warns about an unknown section; GL06 reports it
        warnings.simplefilter("ignore", UserWarning)
        result = numpydoc_validate.validate(name, validator_cls=FlexidValidator, obj=obj)
    return [(code, message) for code, message in result["errors"] if code in CHECKED]


OBJECTS = public_objects()


def test_the_walk_reaches_the_public_names():
    for name in (
        "flexid.identify",
        "flexid.IOData",
        "flexid.IOData.select",
        "flexid.minimize",
        "flexid.envs.register_environments",
        "flexid.optimisers.hbcsd.HBCSD",
        "flexid.optimisers.bfa.BacterialForaging",
        "flexid.data.signals.make_signal",
    ):
        assert name in OBJECTS, name
    variants = [n for n, o in OBJECTS.items() if getattr(o, "variant_of", None)]
    assert variants, "no registered optimiser variant was walked"


def test_the_validator_catches_what_it_holds():
    """The check can fail: a function with an undocumented parameter and no Returns, and a
    class with a made-up section, are reported under the codes the test holds."""

    def undocumented(x, y):
        """Add two numbers."""
        return x + y

    class Sections:
        """A class.

        Hyper-parameters
        ----------------
        a : int
            A number.
        """

    codes = {code for code, _ in failures("undocumented", undocumented)}
    assert {"PR01", "RT01"} <= codes
    assert "GL06" in {code for code, _ in failures("Sections", Sections)}


def test_optimiser_parameters_are_the_hyperparameters():
    """An optimiser that documents a parameter it lacks (or misses one) is reported."""
    hbcsd = get("hbcsd")
    validator = FlexidValidator("hbcsd", hbcsd)
    assert validator.signature_parameters == tuple(hbcsd.hyperparameters())


def test_public_docstrings_are_numpydoc():
    report = []
    for name, obj in OBJECTS.items():
        pending = PENDING.get(name, frozenset())
        report += [f"{name}: {c} {m}" for c, m in failures(name, obj) if c not in pending]
    assert not report, f"{len(report)} numpydoc failure(s) in public docstrings:\n" + "\n".join(
        report
    )


def test_pending_entries_still_fail():
    fixed = []
    for name, codes in PENDING.items():
        assert name in OBJECTS, f"PENDING names {name}, which the walk does not reach"
        found = {code for code, _ in failures(name, OBJECTS[name])}
        fixed += [f"{name}: {code}" for code in sorted(codes - found)]
    assert not fixed, "fixed, remove from PENDING:\n" + "\n".join(fixed)


RECIPES = sorted((Path(__file__).resolve().parents[1] / "examples").glob("recipe_*.py"))


@pytest.mark.parametrize("path", RECIPES, ids=[p.stem for p in RECIPES])
def test_the_recipes_pass_the_docstring_check(path):
    """The recipes of docs/architecture.md are files that follow the rules they teach: their
    classes and functions pass the same numpydoc check as flexid's own.  Each is imported in
    a fresh interpreter, so what it registers stays out of this one."""
    script = f"""
import importlib.util, inspect, json, sys
sys.path.insert(0, {str(Path(__file__).resolve().parent)!r})
from test_docstrings import failures
spec = importlib.util.spec_from_file_location("recipe", {str(path)!r})
module = importlib.util.module_from_spec(spec)
sys.modules["recipe"] = module
spec.loader.exec_module(module)
found = []
for name, obj in vars(module).items():
    if name.startswith("_") or getattr(obj, "__module__", None) != "recipe":
        continue
    if inspect.isclass(obj) or inspect.isfunction(obj):
        found += [f"{{name}}: {{c}} {{m}}" for c, m in failures(f"recipe.{{name}}", obj)]
print(json.dumps(found))
"""
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         timeout=300)
    assert run.returncode == 0, run.stderr
    assert json.loads(run.stdout.splitlines()[-1]) == []
