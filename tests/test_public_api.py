"""The public API: ``from flexid import *``, each public module's ``__all__``, names that do not
depend on import order, a light ``import flexid`` and the Gymnasium environments' registration.

Import-order and import-cost claims are checked in fresh interpreters (``subprocess``): in
this process other tests have imported everything already.
"""

from __future__ import annotations

import importlib
import importlib.util
import inspect
import pkgutil
import subprocess
import sys
import textwrap
import types

import pytest

import flexid
from flexid._moved import MOVED
from helpers import public_modules

IDS = ("flexid/FlexibleManipulator-v0", "flexid/TwinRotor-v0")


def run_python(*blocks: str) -> subprocess.CompletedProcess:
    """Run the code blocks (each dedented) in a fresh interpreter; fail with its stderr."""
    code = "\n".join(textwrap.dedent(block) for block in blocks)
    run = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert run.returncode == 0, run.stderr
    return run


PUBLIC_MODULES = public_modules()
PUBLIC_PACKAGES = public_modules(packages_only=True)


# ------------------------------------------------------------------ __all__ is the contract
def test_the_walk_finds_the_public_modules():
    for name in ("flexid", "flexid.config", "flexid.envs", "flexid.optimisers", "flexid.data"):
        assert name in PUBLIC_MODULES
    assert PUBLIC_PACKAGES == [
        "flexid", "flexid.costs", "flexid.data", "flexid.envs", "flexid.fit", "flexid.jobs",
        "flexid.kernels", "flexid.models", "flexid.optimisers", "flexid.report",
        "flexid.validation",
    ]
    assert not any(part.startswith("_") for m in PUBLIC_MODULES for part in m.split("."))


@pytest.mark.parametrize("old", sorted(MOVED))
def test_a_public_module_imports_under_its_name_before_the_layers(old):
    """``flexid.<old>`` is the module at its layer's home itself, with the home's own spec."""
    home = importlib.import_module(f"flexid.{MOVED[old]}")
    assert importlib.import_module(f"flexid.{old}") is home
    assert home.__spec__.name == home.__name__ == f"flexid.{MOVED[old]}"
    assert f"flexid.{MOVED[old]}" in PUBLIC_MODULES  # the old name of a public module only


def test_the_old_import_paths_work_in_a_fresh_interpreter():
    run = run_python(
        """
        import flexid.selection, flexid.plots
        from flexid.datasets import generate
        from flexid.stability import is_stable
        import flexid.jobs.selection, flexid.report.plots
        assert flexid.selection is flexid.jobs.selection
        assert flexid.plots is flexid.report.plots
        assert generate.__module__ == "flexid.data.datasets"
        print(is_stable.__module__)
        """
    )
    assert run.stdout.strip() == "flexid.models.stability"


@pytest.mark.parametrize("name", PUBLIC_MODULES)
def test_every_name_in_all_resolves(name):
    module = importlib.import_module(name)
    exported = getattr(module, "__all__", None)
    assert exported is not None, f"{name} has no __all__"
    assert len(set(exported)) == len(exported), f"{name}.__all__ repeats a name"
    missing = [n for n in exported if not hasattr(module, n)]
    assert not missing, f"{name}.__all__ names what it lacks: {missing}"


@pytest.mark.parametrize("name", PUBLIC_MODULES)
def test_all_lists_the_public_functions_and_classes_defined_there(name):
    module = importlib.import_module(name)
    defined = [
        n
        for n, obj in vars(module).items()
        if not n.startswith("_")
        and (inspect.isfunction(obj) or inspect.isclass(obj))
        and obj.__module__ == name
    ]
    unlisted = sorted(set(defined) - set(module.__all__))
    assert not unlisted, f"{name} defines public names outside __all__ (or prefix _): {unlisted}"


def test_star_import_gives_every_name_in_all():
    run = run_python(
        """
        from flexid import *
        import flexid
        missing = [n for n in flexid.__all__ if n not in globals()]
        assert not missing, missing
        print(len(flexid.__all__))
        """
    )
    assert int(run.stdout) == len(flexid.__all__)


def test_top_level_has_the_front_door_and_no_aliases():
    from flexid.config import ComparisonSpec, CostSpec, SearchSpec
    from flexid.optimisers import AskTell, Optimiser, Param

    assert flexid.Optimiser is Optimiser and flexid.Param is Param and flexid.AskTell is AskTell
    assert flexid.ComparisonSpec is ComparisonSpec
    assert flexid.CostSpec is CostSpec and flexid.SearchSpec is SearchSpec
    assert inspect.isclass(flexid.SearchBox) and inspect.isclass(flexid.ComparisonResult)
    assert "make_cost" not in flexid.__all__ and not hasattr(flexid, "make_cost")
    with pytest.raises(AttributeError, match="no attribute 'nonexistent'"):
        flexid.nonexistent  # noqa: B018


# ------------------------------------------------------------------ no function/module clash
@pytest.mark.parametrize("name", PUBLIC_PACKAGES)
def test_no_exported_name_is_also_a_submodule(name):
    """A package attribute that shares its name with a submodule becomes whichever was bound
    last (``import pkg.name`` rebinds it to the module)."""
    package = importlib.import_module(name)
    submodules = {info.name for info in pkgutil.iter_modules(package.__path__)}
    for exported in set(package.__all__) & submodules:
        assert isinstance(getattr(package, exported), types.ModuleType), (
            f"{name}.{exported} is both a submodule and another object"
        )


@pytest.mark.parametrize("old", ["flexid.identify", "flexid.compare"])
def test_no_module_shares_the_name_of_a_function(old):
    assert importlib.util.find_spec(old) is None


FIRST_IMPORTS = [
    "flexid.jobs._identify",
    "flexid.jobs._compare",
    "flexid.cli",
    "flexid.report",
    "flexid.fit.estimation",
    "flexid.report.plots",
]


@pytest.mark.parametrize("first", FIRST_IMPORTS)
def test_identify_and_compare_are_functions_whatever_was_imported_first(first):
    run_python(
        f"""
        import inspect
        import {first}
        import flexid
        from flexid import compare, identify

        for f in (flexid.identify, flexid.compare, identify, compare):
            assert callable(f) and inspect.isfunction(f), f
        assert flexid.identify.__name__ == "identify" and flexid.compare.__name__ == "compare"
        import {first}  # importing again changes nothing
        assert inspect.isfunction(flexid.identify) and inspect.isfunction(flexid.compare)
        """
    )


def test_identify_and_compare_stay_functions_when_their_modules_are_imported_after():
    run_python(
        """
        import inspect
        import flexid
        assert inspect.isfunction(flexid.identify) and inspect.isfunction(flexid.compare)
        import flexid.jobs._compare, flexid.jobs._identify, flexid.cli
        assert inspect.isfunction(flexid.identify) and inspect.isfunction(flexid.compare)
        """
    )


# ------------------------------------------------------------------ a light import
def test_import_flexid_imports_neither_gymnasium_nor_numpy_nor_matplotlib():
    run = run_python(
        """
        import sys
        import flexid
        print(sorted(m for m in ("gymnasium", "matplotlib", "numpy", "scipy") if m in sys.modules))
        """
    )
    assert run.stdout.strip() == "[]"


# ------------------------------------------------------------------ environment registration
CHECK_REGISTERED = f"""
        import gymnasium
        ids = {IDS!r}
        assert all(i in gymnasium.registry for i in ids), sorted(gymnasium.registry)[-5:]
        env = gymnasium.make(ids[0])
        env.reset(seed=0)
        env.close()
"""


def test_envs_registered_when_flexid_envs_is_imported():
    run_python("import flexid.envs", CHECK_REGISTERED)


def test_envs_registered_when_gymnasium_is_imported_after_flexid():
    run_python(
        """
        import sys
        import flexid
        assert "gymnasium" not in sys.modules
        """,
        CHECK_REGISTERED,
        """
        import importlib.machinery
        # the hook is gone and Gymnasium keeps its own loader
        assert not any(type(f).__module__ == "flexid._gymnasium_hook" for f in sys.meta_path)
        assert isinstance(gymnasium.__loader__, importlib.machinery.SourceFileLoader)
        assert gymnasium.__spec__.loader is gymnasium.__loader__
        """,
    )


def test_envs_registered_when_gymnasium_is_imported_before_flexid():
    run_python(
        """
        import sys
        import gymnasium
        import flexid
        assert not any(type(f).__module__ == "flexid._gymnasium_hook" for f in sys.meta_path)
        """,
        CHECK_REGISTERED,
    )


def test_gymnasium_alone_makes_the_envs_by_module_and_id():
    """Gymnasium 1.x reads no plugin entry points: without flexid imported, the
    ``module:id`` form imports the registering module first."""
    run_python(
        f"""
        import sys
        import gymnasium
        assert "flexid" not in sys.modules
        for env_id in {IDS!r}:
            env = gymnasium.make("flexid.envs:" + env_id)
            assert env.spec.id == env_id
            env.close()
        """
    )


def test_a_registration_error_does_not_break_importing_gymnasium():
    run = run_python(
        """
        import sys, warnings
        import flexid
        from flexid import _gymnasium_hook
        _gymnasium_hook._ENVS = "flexid.no_such_module"
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            import gymnasium
        print([str(w.message) for w in caught])
        """
    )
    assert "could not register its Gymnasium environments" in run.stdout


def test_every_public_function_and_method_states_its_return_type():
    """Type hints on the public API: every function and public method of a public module's
    ``__all__`` says what it returns (generators their ``Generator``, figures ``Figure``)."""
    import importlib
    import inspect
    import pkgutil

    import flexid

    missing = []
    for info in pkgutil.walk_packages(flexid.__path__, "flexid."):
        if any(part.startswith("_") for part in info.name.split(".")[1:]):
            continue
        module = importlib.import_module(info.name)
        for attr in getattr(module, "__all__", []):
            obj = getattr(module, attr)
            found = []
            if inspect.isfunction(obj):
                found = [(f"{info.name}.{attr}", obj)]
            elif inspect.isclass(obj) and obj.__module__ == info.name:
                found = [
                    (f"{info.name}.{attr}.{k}", v)
                    for k, v in vars(obj).items()
                    if inspect.isfunction(v) and (not k.startswith("_") or k == "__call__")
                ]
            for qualname, fn in found:
                fn = inspect.unwrap(fn)
                if "return" not in fn.__annotations__:
                    missing.append(qualname)
    assert not missing, sorted(set(missing))
