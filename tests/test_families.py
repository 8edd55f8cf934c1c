"""The one model interface: every structure and model finds its family, and the jobs ask it.

One test runs over every built-in structure kind and model; the others register a family of
their own and check that :func:`flexid.fit.estimation.build_problem` and :func:`flexid.validate`
dispatch to it, as they do to the built-in ones.
"""

from __future__ import annotations

import numpy as np
import pytest

import flexid
from flexid.config import CostSpec, SearchSpec
from flexid.errors import ConfigError
from flexid.fit.estimation import build_problem
from flexid.fit.greybox_family import GreyBoxFamily
from flexid.fit.polynomial_family import PolynomialFamily
from flexid.models import families
from flexid.models.arx import ARXStructure
from flexid.models.families import Family, family_of, register_family
from flexid.models.greybox_library import greybox_model


@pytest.fixture
def record():
    rng = np.random.default_rng(3)
    u = rng.standard_normal(400)
    from scipy import signal

    y = signal.lfilter([0.0, 0.5, 0.2], [1.0, -1.2, 0.5], u) + 0.01 * rng.standard_normal(400)
    return flexid.IOData(u, y, dt=0.1)


@pytest.fixture
def restore_registry():
    from flexid.models import vocabulary

    families._load_builtins()  # else a first lookup during the test loads them, and the
    # restore below would empty the registry for every later test of this process
    before, names = list(families._FAMILIES), set(vocabulary._REGISTERED_NAMES)
    yield
    families._FAMILIES[:] = before
    vocabulary._REGISTERED_NAMES.clear()
    vocabulary._REGISTERED_NAMES.update(names)


def builtin_objects():
    """One structure and one model of every built-in kind, with the family that owns it."""
    out = [(ARXStructure(2, 2), "polynomial"), (ARXStructure(2, 2).model([0.1, 0.2, 1, 2]),
                                                 "polynomial")]
    for name, orders in (
        ("arx", {"na": 2, "nb": 2}),
        ("armax", {"na": 2, "nb": 2, "nc": 1}),
        ("oe", {"nb": 2, "nf": 2}),
        ("bj", {"nb": 2, "nc": 1, "nd": 1, "nf": 2}),
    ):
        s = flexid.structure(name, **orders)
        out += [(s, "polynomial"), (s.model(np.zeros(s.n_params)), "polynomial")]
    out.append((greybox_model("twin-rotor-pitch"), "greybox"))
    return out


@pytest.mark.parametrize("obj,name", builtin_objects(), ids=lambda v: getattr(v, "name", None)
                         or type(v).__name__)
def test_every_builtin_structure_and_model_finds_its_family(obj, name):
    family = family_of(obj)
    assert family.name == name
    assert isinstance(family, PolynomialFamily if name == "polynomial" else GreyBoxFamily)


def test_an_object_of_no_family_is_a_clear_error():
    with pytest.raises(ConfigError, match=r"dict is not a structure or model.*polynomial"):
        family_of({"na": 2})
    assert family_of({"na": 2}, default="polynomial").name == "polynomial"


def test_register_family_takes_only_families(restore_registry):
    with pytest.raises(ConfigError, match="takes a Family"):
        register_family(PolynomialFamily)  # the class, not an instance


class Tagged:
    """A structure of a family of the test's own: an OE structure under another type."""

    def __init__(self, inner):
        self.inner = inner

    def __getattr__(self, name):  # what the jobs read of a structure: the inner one's
        return getattr(self.__dict__["inner"], name)


class TaggedFamily(Family):
    """Poses and validates a :class:`Tagged` structure as the polynomial family does, and
    records each call, so that the test sees the jobs ask it."""

    name = "tagged"
    structures = (Tagged,)
    models = (Tagged,)

    def __init__(self):
        self.calls: list[str] = []

    def pose(self, data, structure, cost, search, *, bounds):
        self.calls.append("pose")
        return family_of(structure.inner).pose(data, structure.inner, cost, search,
                                               bounds=bounds)

    def validate(self, model, data, *, max_lag, initial, split, dt, output, estimated_on=None):
        self.calls.append("validate")
        return family_of(model.inner).validate(
            model.inner, data, max_lag=max_lag, initial=initial, split=split, dt=dt,
            output=output, estimated_on=estimated_on,
        )


def test_build_problem_and_validate_ask_a_registered_family(record, restore_registry):
    family = register_family(TaggedFamily())
    oe = flexid.structure("oe", nb=2, nf=2)
    cost = CostSpec(predictor="simulation")
    tagged = build_problem(record, Tagged(oe), cost, SearchSpec())
    direct = build_problem(record, oe, cost, SearchSpec())
    assert family.calls == ["pose"]
    Z = direct.problem.initial_population(6, seed=0)
    np.testing.assert_array_equal(tagged.problem.objective(Z), direct.problem.objective(Z))

    model = oe.model([0.5, 0.2, -1.2, 0.5], dt=0.1)
    report = flexid.validate(Tagged(model), record)
    assert family.calls == ["pose", "validate"]
    assert report.fit_simulation == flexid.validate(model, record).fit_simulation


def test_a_later_registration_of_a_name_replaces_it(restore_registry):
    class Other(TaggedFamily):
        pass

    register_family(TaggedFamily())
    register_family(Other())
    assert [f.name for f in families.families()].count("tagged") == 1
    assert type(family_of(Tagged(None))) is Other


def test_structure_names_find_their_family_and_an_unknown_name_lists_them(restore_registry):
    from flexid.errors import UnknownNameError
    from flexid.fit.estimation import structure_of
    from flexid.models.families import family_named, structure_names

    assert set(structure_names()) == {"arx", "armax", "oe", "bj", "ss"}
    assert family_named("OE").name == "polynomial"
    assert structure_of("oe", 1, nb=2, nf=2) == flexid.structure("oe", nb=2, nf=2)

    class Named(TaggedFamily):
        names = ("tagged-oe",)

        def structure(self, spec, n_inputs, **orders):
            if isinstance(spec, str):
                return Tagged(flexid.structure("oe", **{k: v for k, v in orders.items()
                                                        if v is not None}))
            return super().structure(spec, n_inputs, **orders)

    register_family(Named())
    made = structure_of("Tagged-OE", 1, nb=2, nf=2, nk=None)
    assert isinstance(made, Tagged) and made.inner == flexid.structure("oe", nb=2, nf=2)
    with pytest.raises(UnknownNameError, match=r"'narx'; known: armax, arx, bj, oe, ss, tagged-oe"):
        structure_of("narx", 1)
    # a structure object goes to its family whole; orders with it are an error
    assert structure_of(made, 1) is made
    with pytest.raises(flexid.errors.ModelOrderError, match="not both"):
        structure_of(made, 1, nb=3)


def test_a_family_without_its_own_estimate_says_to_name_an_optimiser(record, restore_registry):
    register_family(TaggedFamily())
    oe = flexid.structure("oe", nb=2, nf=2)
    with pytest.raises(ConfigError, match=r"tagged model family has no estimate 'pem'.*optimiser"):
        flexid.identify(record, structure=Tagged(oe), optimiser="pem")
    with pytest.raises(ConfigError, match=r"tagged model family has no reference"):
        TaggedFamily().reference(record, Tagged(oe), initial="estimate", starts=None, seed=0)


def test_identify_and_select_take_the_polynomial_family_estimates(record):
    """The jobs' references come from the family: identify's ``pem`` and select's fit of a
    candidate equal the family's own, called directly."""
    oe = flexid.structure("oe", nb=2, nf=2)
    family = family_of(oe)
    est = record.split(2 / 3)[0]
    model, sse, local = family.reference(est, oe, initial="estimate", starts=None, seed=0)
    chosen = flexid.select(record, structures=[oe])
    assert local and chosen.candidates[0].sse == sse
    np.testing.assert_array_equal(chosen.candidates[0].model.theta, model.theta)
    assert family.reference_hint(oe, "simulation") == "optimiser='pem'"
    arx = ARXStructure(2, 2)
    assert family.reference_hint(arx, "one-step") == "optimiser='ls'"
    assert family.reference_hint(arx, "simulation") == "optimiser='pem'"


class TaggedOE(Tagged):
    """A tagged structure whose models are tagged too, as a family's own would be."""

    def model(self, theta, dt=1.0):
        return Tagged(self.inner.model(theta, dt=dt))


class TaggedOEFamily(TaggedFamily):
    """Builds ``"tagged-oe"`` structures from orders, for a comparison's ``[model]`` table."""

    name = "tagged-oe"
    names = ("tagged-oe",)
    structures = (TaggedOE,)
    models = (Tagged,)

    def structure(self, spec, n_inputs, **orders):
        if isinstance(spec, str):
            return TaggedOE(flexid.structure("oe", **{k: v for k, v in orders.items()
                                                      if v is not None}))  # fmt: skip
        return super().structure(spec, n_inputs, **orders)


def test_a_comparison_runs_a_registered_family_as_the_built_in_one(record, tmp_path,
                                                                   restore_registry):
    # the family poses and validates through the polynomial family's modules, so every run
    # of a comparison of "tagged-oe" must equal the same run of the plain OE comparison
    from flexid.config import ComparisonSpec, DataSpec, ModelSpec, OptimiserSpec

    path = tmp_path / "record.csv"
    flexid.save(record, path)
    family = register_family(TaggedOEFamily())

    def spec(model):
        return ComparisonSpec(name="tagged", data=DataSpec(file=str(path)), model=model,
                              optimisers=(OptimiserSpec("de"),), runs=2, budget=300)  # fmt: skip

    tagged = flexid.compare(spec(ModelSpec(structure="tagged-oe", options={"nb": 2, "nf": 2})),
                            store=tmp_path / "tagged.db")  # fmt: skip
    plain = flexid.compare(spec(ModelSpec(structure="oe", nb=2, nf=2)),
                           store=tmp_path / "plain.db")  # fmt: skip
    assert "pose" in family.calls and "validate" in family.calls
    assert tagged.key != plain.key  # different structures, different stores' keys
    for a, b in zip(tagged.records["de"], plain.records["de"], strict=True):
        assert a["cost"] == b["cost"] and a["theta"] == b["theta"]
        assert a["validation"]["fit_simulation"] == b["validation"]["fit_simulation"]
    assert tagged.reference_cost == plain.reference_cost
    assert "tagged-oe(nb=2, nf=2)" in tagged.summary()


def test_a_model_spec_names_registered_structures_and_takes_their_orders_as_options(
    restore_registry,
):
    from flexid.config import ModelSpec
    from flexid.errors import UnknownNameError

    known = r"'tagged-oe'; known: armax, arx, bj, greybox, oe, ss$"
    with pytest.raises(UnknownNameError, match=known):
        ModelSpec(structure="tagged-oe")
    register_family(TaggedOEFamily())
    spec = ModelSpec(structure="tagged-oe", options={"nb": 2, "nf": 2}, nk=2)
    assert spec.orders() == {"nb": 2, "nf": 2, "nk": 2}
    assert spec.key_material() == {"structure": "tagged-oe", "nb": 2, "nf": 2, "nk": 2}
    with pytest.raises(ConfigError, match="takes its orders in options"):
        ModelSpec(structure="tagged-oe", nb=2)
    with pytest.raises(ConfigError, match="options belong to a registered family"):
        ModelSpec(structure="oe", nb=2, nf=2, options={"nb": 2})


def test_the_built_in_specs_keep_their_keys_and_the_suite_its_versions():
    # the keys and versions stores hold: a change here orphans every stored run (the keys'
    # last, when the verdict became one at a stated level, alpha, a part of every key; the
    # suite's, when its state-space problems joined)
    from dataclasses import replace

    from flexid.config import ModelSpec, default_spec
    from flexid.jobs.suite import get_suite

    m, t = default_spec(plant="manipulator"), default_spec(plant="twin-rotor")
    keys = [m.key, t.key, replace(m, model=ModelSpec(na=4, nb=4)).key,
            replace(m, model=ModelSpec(structure="bj", nb=2, nc=1, nd=1, nf=2)).key]  # fmt: skip
    assert keys == ["5ab16e5394268091", "ef189b1e1e606f86", "14ca496ab5f6a0ba",
                    "09b1389d6a5c1b32"]  # fmt: skip
    assert "options" not in m.to_dict()["model"]
    assert (get_suite("small").version, get_suite("full").version) == (
        "0f98205fb058", "1bf61e4bf3d5"
    )
