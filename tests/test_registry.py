"""Tests of flexid.optimisers.registry (names, variants, describe, entry-point plugins)."""

from __future__ import annotations

import sys
import textwrap
import warnings

import numpy as np
import pytest

from flexid.errors import HyperParameterError, RegistryError, UnknownOptimiserError
from flexid.optimisers import (
    ENTRY_POINT_GROUP,
    Optimiser,
    Param,
    PluginWarning,
    Problem,
    available,
    create,
    describe,
    get,
    minimize,
    register,
    register_variant,
    reload_plugins,
    unregister,
)


def sphere(X):
    return ((X - 0.25) ** 2).sum(axis=1)


@pytest.fixture
def names():
    """Names registered by a test; unregistered afterwards."""
    taken: list[str] = []
    yield taken
    for name in taken:
        unregister(name)


def make_class(name, default_points=5):
    class Toy(Optimiser):
        """Toy optimiser for the registry tests."""

        points = Param(int, default_points, "batch size", low=1)
        scale = Param(float, 1.0, "a scale", low=0.0, low_open=True)

        def search(self, space, rng):
            yield space.initial_population(self.points)
            while True:
                yield space.uniform(self.points, rng)

    Toy.name = name
    return Toy


def test_register_get_create_and_run(names):
    cls = register(make_class("test-toy"))
    names.append("test-toy")
    assert get("test-toy") is cls
    assert "test-toy" in available()
    opt = create("test-toy", points=3)
    assert opt.points == 3
    r = minimize("test-toy", Problem(sphere, -np.ones(2), np.ones(2)), budget=10, seed=0)
    assert r.nfev == 10 and r.optimiser == "test-toy"


def test_register_under_another_name_keeps_original(names):
    cls = make_class("test-orig")
    alias = register(cls, name="test-alias")
    names.append("test-alias")
    assert alias.name == "test-alias" and cls.name == "test-orig"
    assert "test-orig" not in available()


def test_duplicate_name_rejected(names):
    register(make_class("test-dup"))
    names.append("test-dup")
    with pytest.raises(RegistryError, match="'test-dup' is already registered"):
        register(make_class("test-dup"))
    with pytest.raises(RegistryError, match="already registered"):
        register(make_class("pso"))  # a built-in name


def test_register_rejects_non_optimisers_and_nameless():
    with pytest.raises(RegistryError, match="only Optimiser subclasses"):
        register(dict)
    with pytest.raises(RegistryError, match="no name"):
        register(make_class(""))


def test_variant_with_own_defaults(names):
    register(make_class("test-base"))
    names.append("test-base")
    variant = register_variant("test-variant", "test-base", "from a paper", points=9, scale=2.5)
    names.append("test-variant")
    assert issubclass(variant, get("test-base"))
    opt = create("test-variant")
    assert (opt.points, opt.scale) == (9, 2.5)
    assert create("test-base").points == 5  # the base keeps its defaults
    assert create("test-variant", points=2).points == 2
    d = describe("test-variant")
    assert d["variant_of"] == "test-base"
    assert d["hyperparameters"]["points"]["default"] == 9
    assert d["summary"] == "from a paper"


def test_variant_unknown_parameter_rejected(names):
    register(make_class("test-base2"))
    names.append("test-base2")
    with pytest.raises(HyperParameterError, match=r"unknown hyper-parameter.*'swarm'"):
        register_variant("test-v2", "test-base2", swarm=3)
    assert "test-v2" not in available()


def test_variant_invalid_default_is_rejected(names):
    register(make_class("test-base3"))
    names.append("test-base3")
    with pytest.raises((HyperParameterError, RuntimeError)):
        register_variant("test-v3", "test-base3", points=0)
    assert "test-v3" not in available()


def test_variant_invalid_default_raises_hyper_parameter_error(names):
    register(make_class("test-base4"))
    names.append("test-base4")
    with pytest.raises(HyperParameterError, match="points"):
        register_variant("test-v4", "test-base4", points=0)


def test_variant_of_a_builtin_by_an_old_name(names):
    register_variant("test-pso-old-name", "pso", "swarm of 12", particles=12)
    names.append("test-pso-old-name")
    assert create("test-pso-old-name").population == 12
    assert describe("test-pso-old-name")["hyperparameters"]["population"]["default"] == 12


def test_variant_cross_parameter_check_applied():
    with pytest.raises(HyperParameterError, match="elites"):
        register_variant("test-ga-bad", "ga", elites=60)
    assert "test-ga-bad" not in available()


def test_unknown_name_lists_names():
    with pytest.raises(UnknownOptimiserError) as info:
        get("no-such-optimiser")
    msg = str(info.value)
    assert "no-such-optimiser" in msg and "pso" in msg and "cmaes" in msg
    assert "pso" in info.value.known
    with pytest.raises(LookupError):
        create("no-such-optimiser")


def test_describe_builtin():
    d = describe("pso")
    assert d["name"] == "pso" and d["source"] == "flexid" and d["reference"]
    hp = d["hyperparameters"]
    assert hp["population"]["default"] == 50 and hp["population"]["type"] == "int"
    assert hp["population"]["aliases"] == ["particles"] and "particles" not in hp
    assert hp["inertia"]["default"] == pytest.approx(0.7298)
    assert set(hp["inertia"]) == {"type", "default", "range", "doc"}
    assert describe("ga")["hyperparameters"]["p_mutation"]["type"] == "float or None"


def test_every_builtin_has_summary_reference_and_valid_defaults():
    for name in available():
        if name.startswith("test-"):
            continue
        d = describe(name)
        assert d["summary"], name
        create(name)  # defaults pass validation and cross checks


# ------------------------------------------------------------------------------- plugins
def write_plugin(root, dist, module, body, entries):
    (root / f"{module}.py").write_text(textwrap.dedent(body))
    info = root / f"{dist}-1.0.dist-info"
    info.mkdir()
    info.joinpath("METADATA").write_text(f"Metadata-Version: 2.1\nName: {dist}\nVersion: 1.0\n")
    lines = "\n".join(f"{k} = {v}" for k, v in entries.items())
    info.joinpath("entry_points.txt").write_text(f"[{ENTRY_POINT_GROUP}]\n{lines}\n")


GOOD = """
    import numpy as np
    from flexid.optimisers import Optimiser, Param

    class CoordinateWalk(Optimiser):
        '''Plugin test optimiser: random coordinate steps from the best point.'''

        name = "coordinate-walk"
        step = Param(float, 0.1, "step", low=0.0, low_open=True)

        def search(self, space, rng):
            X = space.initial_population(4)
            F = yield X
            x, f = X[np.argmin(F)], F.min()
            while True:
                cand = space.clip(x + self.step * rng.standard_normal((4, space.dim)))
                Fc = yield cand
                if Fc.min() < f:
                    x, f = cand[np.argmin(Fc)], Fc.min()

    NotAnOptimiser = dict
"""


@pytest.fixture
def plugin_dir(tmp_path, monkeypatch):
    monkeypatch.syspath_prepend(str(tmp_path))
    added = ["test-plugin-walk", "test-plugin-broken", "test-plugin-dict"]
    yield tmp_path
    for name in added:
        unregister(name)
    for mod in ("flexid_test_plugin_good", "flexid_test_plugin_broken"):
        sys.modules.pop(mod, None)
    monkeypatch.undo()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        reload_plugins()


def test_plugin_found_and_run(plugin_dir):
    write_plugin(plugin_dir, "flexid_test_plugin_good", "flexid_test_plugin_good", GOOD,
                 {"test-plugin-walk": "flexid_test_plugin_good:CoordinateWalk"})
    with warnings.catch_warnings():
        warnings.simplefilter("error", PluginWarning)
        reload_plugins()
    assert "test-plugin-walk" in available()
    assert describe("test-plugin-walk")["source"].startswith("plugin")
    p = Problem(sphere, -np.ones(3), np.ones(3))
    r = minimize("test-plugin-walk", p, budget=400, seed=1, params={"step": 0.05})
    assert r.nfev == 400 and r.optimiser == "test-plugin-walk" and r.fun < 0.05
    # loading again does not clash with itself
    with warnings.catch_warnings():
        warnings.simplefilter("error", PluginWarning)
        reload_plugins()


def test_broken_plugins_warn_and_are_skipped(plugin_dir):
    write_plugin(plugin_dir, "flexid_test_plugin_good", "flexid_test_plugin_good", GOOD,
                 {"test-plugin-walk": "flexid_test_plugin_good:CoordinateWalk",
                  "test-plugin-dict": "flexid_test_plugin_good:NotAnOptimiser",
                  "pso": "flexid_test_plugin_good:CoordinateWalk"})
    write_plugin(plugin_dir, "flexid_test_plugin_broken", "flexid_test_plugin_broken",
                 "import flexid_no_such_dependency\n",
                 {"test-plugin-broken": "flexid_test_plugin_broken:Thing"})
    with pytest.warns(PluginWarning) as record:
        reload_plugins()
    messages = " | ".join(str(w.message) for w in record)
    assert "test-plugin-broken" in messages and "failed to load" in messages
    assert "ModuleNotFoundError" in messages
    assert "test-plugin-dict" in messages and "not an" in messages
    assert "'pso'" in messages and "clashes" in messages
    names = available()
    assert "test-plugin-walk" in names
    assert "test-plugin-broken" not in names and "test-plugin-dict" not in names
    assert get("pso").__module__ == "flexid.optimisers.pso"  # the built-in wins
    p = Problem(sphere, -np.ones(2), np.ones(2))
    assert minimize("test-plugin-walk", p, budget=50, seed=0).nfev == 50
    assert minimize("pso", p, budget=50, seed=0).nfev == 50


def test_a_misspelled_builtin_module_is_an_error(monkeypatch):
    from flexid.optimisers import registry

    monkeypatch.setattr(registry, "_BUILTIN_MODULES", (*registry._BUILTIN_MODULES, "psoo"))
    monkeypatch.setitem(registry._state, "builtins", False)
    with pytest.raises(RegistryError, match=r"'flexid\.optimisers\.psoo'.*does not exist"):
        registry.available()
