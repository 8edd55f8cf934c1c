"""The adapters of nevergrad, pycma and pymoo (``flexid.optimisers.external``).

What the conformance test checks for every registered optimiser (determinism, FE-exact
budgets, ask/tell, hyper-parameters, beating random search) covers the registered adapters
when their library is installed; this file checks what is particular to the adapters: names
resolved on first use, the budget at odd sizes for names that are not registered in advance,
the shared initial population reaching the library, the library's seed coming from the run,
a library exception becoming a failed run of a comparison, and the listing.  Each test skips
when its library is missing.
"""

from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np
import pytest

from flexid import compare
from flexid.cli import main
from flexid.config import OptimiserSpec
from flexid.errors import OptimiserError, UnknownOptimiserError
from flexid.optimisers import Problem, available, get, minimize
from flexid.optimisers.external import installed, library_notes
from objectives import Recorder

N = 5
SHIFT = np.linspace(-0.3, 0.4, N)

# pycma's injection warnings (nevergrad's CMA asks one point at a time) and nevergrad's
# advice on bounds are the libraries' business, not what these tests check
pytestmark = pytest.mark.filterwarnings("ignore::UserWarning", "ignore::RuntimeWarning:nevergrad")


def sphere(X):
    return ((X - SHIFT) ** 2).sum(axis=1)


def box(f=sphere) -> Problem:
    return Problem(f, -2.0 * np.ones(N), 2.0 * np.ones(N))


def needs(library: str):
    return pytest.mark.skipif(not installed(library), reason=f"{library} is not installed")


NG, CMA, PYMOO = needs("nevergrad"), needs("cma"), needs("pymoo")
# one name per kind of adapter; ng:DE is resolved on first use, not registered in advance
ADAPTERS = [
    pytest.param("ng:DE", marks=NG),
    pytest.param("ng:TwoPointsDE", marks=NG),
    pytest.param("cma:CMA-ES", marks=CMA),
    pytest.param("pymoo:DE", marks=PYMOO),
    pytest.param("pymoo:NelderMead", marks=PYMOO),
]


# ------------------------------------------------------------------------- the budget
@pytest.mark.parametrize("name", ADAPTERS)
@pytest.mark.parametrize("budget", [1, 7, 333])
def test_exact_budget(name, budget):
    rec = Recorder(sphere)
    r = minimize(name, box(rec), budget, seed=4)
    assert r.nfev == rec.points.shape[0] == budget and r.stop == "budget"
    # every point the library asked for is inside the box
    assert np.all(rec.points >= -2.0) and np.all(rec.points <= 2.0)
    F = sphere(rec.points)  # the same function on the same rows: exact
    assert r.fun == F.min()


@pytest.mark.parametrize("name", ADAPTERS)
def test_deterministic_for_a_seed_whatever_the_global_state(name):
    runs = []
    for seed, global_seed in ((9, 1), (9, 2), (10, 1)):
        np.random.seed(global_seed)  # noqa: NPY002 (the adapters must not read it)
        rec = Recorder(sphere)
        runs.append((minimize(name, box(rec), 300, seed=seed), rec.points))
    (a, rows_a), (b, rows_b), (_, rows_c) = runs
    np.testing.assert_array_equal(rows_a, rows_b)
    assert a.fun == b.fun
    assert not np.array_equal(rows_a, rows_c)  # the run's seed reaches the library


# ------------------------------------------------------------- the shared initial population
@pytest.mark.parametrize(
    ("name", "size"),
    [
        pytest.param("ng:DE", 50, marks=NG),
        pytest.param("cma:CMA-ES", 50, marks=CMA),
        pytest.param("pymoo:DE", 100, marks=PYMOO),
        pytest.param("pymoo:PSO", 25, marks=PYMOO),
        pytest.param("pymoo:NelderMead", 20, marks=PYMOO),
    ],
)
def test_first_batch_is_the_shared_initial_population(name, size):
    rec = Recorder(sphere)
    minimize(name, box(rec), size + 10, seed=6)
    shared = box().initial_population(size, seed=np.random.SeedSequence(6).spawn(2)[0])
    # the library receives the unit-box points and hands them back; mapping them to the box
    # is the same arithmetic flexid's own optimisers go through, so the rows are equal
    np.testing.assert_array_equal(rec.batches[0], shared)


@pytest.mark.parametrize("name", [pytest.param("ng:TwoPointsDE", marks=NG)])
def test_no_initial_points_leaves_the_library_its_own_start(name):
    rec = Recorder(sphere)
    minimize(name, box(rec), 60, seed=6, params={"initial_points": 0})
    shared = box().initial_population(1, seed=np.random.SeedSequence(6).spawn(2)[0])
    assert not np.array_equal(rec.points[0], shared[0])


@CMA
def test_pycma_starts_from_the_best_initial_point():
    import cma

    starts = []
    original = cma.CMAEvolutionStrategy.__init__

    def spy(self, x0, sigma0, options=None):
        starts.append(np.array(x0, copy=True))
        original(self, x0, sigma0, options)

    rec = Recorder(sphere)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(cma.CMAEvolutionStrategy, "__init__", spy)
        minimize("cma:CMA-ES", box(rec), 60, seed=2)
    first = rec.batches[0]
    best = first[np.argmin(sphere(first))]
    np.testing.assert_array_equal(starts[0], (best + 2.0) / 4.0)  # the unit-box point


# ---------------------------------------------------------------------- library errors
def _break(mp, name):
    """Make the library behind ``name`` raise on its first tell."""
    if name.startswith("ng:"):
        import nevergrad as ng

        mp.setattr(ng.optimization.base.Optimizer, "tell", _boom)
    elif name.startswith("cma:"):
        import cma

        mp.setattr(cma.CMAEvolutionStrategy, "tell", _boom)
    else:
        from pymoo.core.algorithm import Algorithm

        mp.setattr(Algorithm, "tell", _boom)


def _boom(*args, **kwargs):
    raise ValueError("library failure")


@pytest.mark.parametrize("name", ADAPTERS)
def test_a_library_exception_is_an_optimiser_error(name):
    with pytest.MonkeyPatch.context() as mp:
        _break(mp, name)
        with pytest.raises(OptimiserError, match=rf"^{name}: .* raised ValueError: library "
                           r"failure \(after \d+ function evaluations\)"):
            minimize(name, box(), 500, seed=1)


@pytest.mark.parametrize("name", [pytest.param("cma:CMA-ES", marks=CMA)])
def test_a_library_exception_is_a_failed_run_of_a_comparison(name):
    from test_compare import small_spec

    spec = replace(
        small_spec(), optimisers=(OptimiserSpec(name), OptimiserSpec("random-search")), runs=2
    )
    with pytest.MonkeyPatch.context() as mp:
        _break(mp, name)
        result = compare(spec)
    assert [r["status"] for r in result.records[name]] == ["failed", "failed"]
    assert all("library failure" in r["error"] for r in result.records[name])
    assert [r["status"] for r in result.records["random-search"]] == ["ok", "ok"]
    assert "failed" in result.summary()


# ---------------------------------------------------------------------------- the names
@NG
def test_any_nevergrad_name_resolves_on_first_use():
    assert "ng:RandomSearch" not in available()
    cls = get("ng:RandomSearch")
    assert cls.name == "ng:RandomSearch" and "ng:RandomSearch" in available()
    assert get("ng:RandomSearch") is cls


@NG
def test_unknown_nevergrad_name_suggests_close_names():
    with pytest.raises(UnknownOptimiserError, match=r"'ng:twopointsde'.*did you mean "
                       r"ng:TwoPointsDE"):
        get("ng:twopointsde")
    with pytest.raises(UnknownOptimiserError, match="no optimiser 'NoSuchThing'"):
        get("ng:NoSuchThing")


@PYMOO
def test_unknown_pymoo_name_lists_the_adapted_algorithms():
    with pytest.raises(UnknownOptimiserError, match="did you mean pymoo:GA"):
        get("pymoo:ga")


def test_a_missing_library_says_which_extra_to_install(monkeypatch):
    import flexid.optimisers.external as external

    monkeypatch.setattr(external, "installed", lambda library: False)
    with pytest.raises(UnknownOptimiserError, match=r"pip install 'flexid\[pymoo\]'"):
        get("pymoo:NoSuchAlgorithm")
    with pytest.raises(UnknownOptimiserError, match=r"pip install 'flexid\[nevergrad\]'"):
        get("ng:NoSuchOptimiser")


def test_list_optimisers_shows_the_libraries(capsys):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["list", "optimisers"]) == 0
        short = capsys.readouterr().out
        assert main(["list", "optimisers", "--long"]) == 0
    out = capsys.readouterr().out
    # the short form: one line per optimiser, its name first
    for name in ("hbcsd", "cmaes", "de"):
        assert sum(line.split(" ")[0] == name for line in short.splitlines()) == 1
    assert len(short.splitlines()) < len(out.splitlines())
    assert "Optimisers of other libraries" in out
    for line in library_notes():
        assert line in out
    for library, names in (("nevergrad", ["ng:CMA", "ng:TwoPointsDE"]), ("cma", ["cma:CMA-ES"]),
                           ("pymoo", ["pymoo:GA", "pymoo:DE", "pymoo:PSO"])):
        for name in names:
            assert (f"\n{name} [{library} " in out) == installed(library), name


# ------------------------------------------------------------------- NGOpt's meta-model
@NG
def test_ngopt_runs_its_meta_model_steps(monkeypatch):
    """NGOpt picks nevergrad's meta-model here (14 steps in 300 FE), whose scoring calls
    ``float`` of a one-element array: under NumPy >= 2.4 that raised in every step."""
    from flexid.optimisers.external import _import_nevergrad

    _import_nevergrad()
    from nevergrad.optimization import optimizerlib

    steps = []
    original = optimizerlib.learn_on_k_best

    def counted(*args, **kwargs):
        steps.append(1)
        return original(*args, **kwargs)

    monkeypatch.setattr(optimizerlib, "learn_on_k_best", counted)
    result = minimize("ng:NGOpt", box(), 300, seed=0)
    assert steps, "NGOpt did not use its meta-model: the test no longer checks it"
    assert result.nfev == 300
    assert result.fun < 1e-8  # the quadratic meta-model finds a sphere's minimum


def test_one_element_float_gives_what_float_gave():
    from flexid.optimisers.external import _one_element_float

    assert _one_element_float(np.array([2.5])) == 2.5
    assert _one_element_float(np.array([[2.5]])) == 2.5
    assert _one_element_float(3) == 3.0 and _one_element_float("1.5") == 1.5
    with pytest.raises(TypeError):
        _one_element_float(np.ones(2))


def test_the_surrogates_overflow_warnings_are_quiet():
    """NGOpt's meta-model minimises an unbounded surrogate at each step, and scipy's Powell
    and scikit-learn's polynomial features warn of overflows by the hundred; those alone are
    silenced around nevergrad's ask and tell."""
    import warnings

    from flexid.optimisers.external import _surrogate_warnings_quiet

    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        with _surrogate_warnings_quiet():
            for module in ("scipy.optimize._optimize", "sklearn.preprocessing._polynomial",
                           "flexid.costs.arx"):  # fmt: skip
                warnings.warn_explicit(module, RuntimeWarning, "f.py", 1, module=module)
            warnings.warn_explicit("scipy", UserWarning, "f.py", 1, module="scipy.optimize")
    assert [str(w.message) for w in seen] == ["flexid.costs.arx", "scipy"]
