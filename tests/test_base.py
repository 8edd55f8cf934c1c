"""Tests of the optimiser framework (driver, budgets, params, ask/tell) on test optimisers.

The framework's private modules (flexid.optimisers._budget, _problem, _params, _history,
_driver) are reached through flexid.optimisers.  What every registered optimiser must do
(FE-exact, deterministic, ask/tell equals minimize, hyper-parameter validation) is checked
on each of them in test_conformance.py.

Costs are compared exactly: the best cost is one of the evaluated ones, and re-evaluating a
row (a 3-term row sum, elementwise IEEE operations) gives the same number on any machine.
"""

from __future__ import annotations

import ast
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import OptimizeResult

from flexid.errors import BudgetError, HyperParameterError, OptimiserError
from flexid.optimisers import (
    AskTell,
    Budget,
    IterationInfo,
    Optimiser,
    Param,
    Problem,
    available,
    create,
    get,
    minimize,
    register_variant,
    unregister,
)

BUILTIN_BASELINES = ["random-search", "pso", "de", "ga", "cmaes", "nelder-mead", "powell",
                     "l-bfgs-b"]


def sphere(X):
    return ((X - 0.3) ** 2).sum(axis=1)


class Counter:
    """Objective wrapper counting evaluated rows and recording every batch."""

    def __init__(self, f=sphere):
        self.f = f
        self.fe = 0
        self.batches = []

    def __call__(self, X):
        self.fe += X.shape[0]
        self.batches.append(X.copy())
        return self.f(X)


class Fixed(Optimiser):
    """Test optimiser: yields batches of fixed size ``points`` of uniform points."""

    name = "test-fixed"
    points = Param(int, 7, "batch size", low=1)
    ratio = Param(float, 0.5, "a float in (0, 1]", low=0.0, high=1.0, low_open=True)
    flag = Param(bool, False, "a flag")
    mode = Param(str, "a", "a choice", choices=("a", "b"))
    extra = Param(int, None, "optional", low=0, none_ok=True)

    def search(self, space, rng):
        yield space.initial_population(self.points)
        while True:
            yield space.uniform(self.points, rng)


class Finite(Optimiser):
    """Test optimiser that ends its own schedule after three batches."""

    name = "test-finite"

    def search(self, space, rng):
        for _ in range(3):
            yield space.uniform(4, rng)


def box(n=3, f=sphere):
    return Problem(f, -np.ones(n), np.ones(n))


# ------------------------------------------------------------------------ FE accounting
@pytest.mark.parametrize("budget", [1, 6, 7, 8, 50, 51])
def test_fe_exact_with_truncated_last_batch(budget):
    obj = Counter()
    r = minimize(Fixed(), box(f=obj), budget=budget, seed=0)
    assert obj.fe == r.nfev == budget
    sizes = [len(b) for b in obj.batches]
    assert sizes[:-1] == [7] * (len(sizes) - 1) and 1 <= sizes[-1] <= 7
    assert r.stop == "budget"
    # the truncated batch is the prefix of the full one the optimiser asked for
    full = minimize(Fixed(), box(f=Counter()), budget=7 * len(sizes), seed=0)
    assert full.nfev == 7 * len(sizes)


# -------------------------------------------------------------------------- bad costs
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_bad_costs_are_plus_inf_and_never_best(bad):
    def f(X):
        F = sphere(X)
        F[X[:, 0] < 0] = bad  # half of the box is invalid
        return F

    seen = []

    def g(X):
        seen.append(X.copy())
        return f(X)

    r = minimize(Fixed(), box(f=g), budget=200, seed=0)
    assert np.isfinite(r.fun) and r.x[0] >= 0
    X = np.concatenate(seen)
    F = f(X)
    ok = np.isfinite(F)
    assert r.fun == F[ok].min()
    assert np.all(np.isfinite(r.history.best[1:]) | (r.history.best[1:] == np.inf))


def test_all_bad_costs_gives_inf_and_no_success():
    r = minimize(Fixed(), box(f=lambda X: np.full(len(X), np.nan)), budget=30, seed=0)
    assert r.fun == math.inf and not r.success


def test_costs_received_by_optimiser_are_cleaned():
    got = []

    class Spy(Optimiser):
        name = "test-spy"

        def search(self, space, rng):
            F = yield space.initial_population(3)
            got.append(F)

    minimize(Spy(), box(f=lambda X: np.array([np.nan, -np.inf, 1.0])), budget=10, seed=0)
    np.testing.assert_array_equal(got[0], [np.inf, np.inf, 1.0])


# ---------------------------------------------------------------------------- history
def test_history_consistent_and_best_non_increasing():
    obj = Counter()
    r = minimize(Fixed(), box(f=obj), budget=100, seed=3)
    h = r.history
    assert np.all(np.diff(h.best) <= 0)
    assert np.all(np.diff(h.fe) > 0)
    assert h.fe[-1] == r.nfev
    assert h.iteration[0] == 0 and h.phase[0] == "init"
    np.testing.assert_array_equal(h.iteration, np.arange(len(h)))
    assert h.iteration[-1] == r.nit
    # best recorded at each row equals the running minimum of the costs evaluated so far
    F = np.concatenate([sphere(b) for b in obj.batches])
    np.testing.assert_array_equal(h.best, np.minimum.accumulate(F)[h.fe - 1])


def test_result_fields():
    r = minimize("random-search", box(), budget=120, seed=9, params={"points": 40})
    assert isinstance(r, OptimizeResult)
    assert r.x.shape == (3,) and r.fun == sphere(r.x[None])[0]
    assert (r.nfev, r.nit, r.seed, r.optimiser) == (120, 2, 9, "random-search")
    assert r.params == {"population": 40}  # the canonical name of the alias "points"
    assert r.success and r.stop == "budget" and "budget" in r.message
    assert r.wall_time >= 0


def test_converged_when_the_optimiser_ends():
    r = minimize(Finite(), box(), budget=1000, seed=0)
    assert r.stop == "converged" and r.nfev == 12 and r.nit == 2


# -------------------------------------------------------------------------- stop rules
def test_max_iter_stop():
    r = minimize(Fixed(), box(), budget={"max_iter": 4}, seed=0)
    assert r.stop == "iterations" and r.nit == 4 and r.nfev == 5 * 7


def test_target_stop():
    obj = Counter()
    r = minimize(Fixed(), box(f=obj), budget=Budget(max_fe=10_000, target=0.5), seed=0)
    assert r.stop == "target" and r.fun <= 0.5
    # it stopped at the first batch reaching the target
    bests = [sphere(b).min() for b in obj.batches]
    assert min(bests[:-1]) > 0.5 >= bests[-1]


def test_max_time_stop():
    r = minimize(Fixed(), box(), budget={"max_time": 0.05}, seed=0)
    assert r.stop == "time" and r.wall_time >= 0.05


def test_callbacks_receive_info_and_can_stop():
    infos = []

    def cb(info):
        infos.append(info)
        return info.iteration >= 3

    r = minimize(Fixed(), box(), budget=1000, seed=0, callback=[cb, lambda i: None])
    assert r.stop == "callback" and r.nit == 3
    assert all(isinstance(i, IterationInfo) for i in infos)
    assert [i.fe for i in infos] == [14, 21, 28]
    assert infos[-1].max_fe == 1000 and infos[-1].best == r.fun
    np.testing.assert_array_equal(infos[-1].x_best, r.x)


# -------------------------------------------------------------------- reproducibility
def test_ask_tell_errors():
    at = AskTell(Fixed(), box(), budget=10, seed=0)
    with pytest.raises(OptimiserError, match="without a pending ask"):
        at.tell([1.0])
    X = at.ask()
    np.testing.assert_array_equal(at.ask(), X)  # asking again returns the same batch
    with pytest.raises(OptimiserError, match="7 costs"):
        at.tell(np.ones(3))
    at.tell(sphere(X))
    at.tell(sphere(at.ask()))
    assert at.done and at.nfev == 10
    with pytest.raises(OptimiserError, match="finished"):
        at.ask()


def test_initial_population_shared_and_prefix():
    firsts = {}
    for name in ["random-search", "pso", "de", "ga", "cmaes"]:
        obj = Counter()
        minimize(name, box(n=5, f=obj), budget=60, seed=21, params=None)
        firsts[name] = obj.batches[0]
    ref = firsts["pso"]
    for X in firsts.values():
        k = min(len(X), len(ref))
        np.testing.assert_array_equal(X[:k], ref[:k])
    small, large = Counter(), Counter()
    minimize(Fixed(points=5), box(f=small), budget=5, seed=2)
    minimize(Fixed(points=30), box(f=large), budget=30, seed=2)
    np.testing.assert_array_equal(small.batches[0], large.batches[0][:5])
    other = Counter()
    minimize(Fixed(points=5), box(f=other), budget=5, seed=3)
    assert not np.array_equal(other.batches[0], small.batches[0])


def test_seed_none_is_recorded_and_replayable():
    r = minimize("pso", box(), budget=200)
    again = minimize("pso", box(), budget=200, seed=r.seed)
    assert r.fun == again.fun


@pytest.mark.parametrize("seed", [-1, 1.5, "a", True])
def test_bad_seed(seed):
    with pytest.raises(OptimiserError, match="seed"):
        minimize(Fixed(), box(), budget=10, seed=seed)


# ------------------------------------------------------------------------ validation
@pytest.mark.parametrize("ret", [lambda X: np.zeros((len(X), 2)), lambda X: np.zeros(len(X) + 1),
                                 lambda X: 0.0])
def test_objective_wrong_shape(ret):
    with pytest.raises(OptimiserError, match="one cost per row"):
        minimize(Fixed(), box(f=ret), budget=20, seed=0)


def test_optimiser_yielding_wrong_shape():
    class Bad(Optimiser):
        name = "test-bad"

        def search(self, space, rng):
            yield np.zeros((3, space.dim + 1))

    with pytest.raises(OptimiserError, match=r"test-bad.*\(P, 3\)"):
        minimize(Bad(), box(), budget=20, seed=0)


@pytest.mark.parametrize(
    "budget",
    [0, -5, 2.5, True, {"max_fe": 0}, {"max_iter": -1}, {"max_time": 0}, {"max_time": -1.0},
     {"target": "low", "max_fe": 10}, {"target": 1.0}, {"bogus": 1}, "100", None],
)
def test_budget_validation(budget):
    with pytest.raises(BudgetError):
        minimize(Fixed(), box(), budget=budget, seed=0)


def test_budget_coerce():
    assert Budget.coerce(100) == Budget(max_fe=100)
    assert Budget.coerce({"max_iter": 3}) == Budget(max_iter=3)


@pytest.mark.parametrize(
    "lower, upper, match",
    [([0, 0], [1], "same non-zero length"), ([], [], "same non-zero length"),
     ([0, np.inf], [1, np.inf], "finite"), ([0, 2], [1, 2], "coordinate 1"),
     ([0, np.nan], [1, 1], "finite")],
)
def test_problem_bounds_validation(lower, upper, match):
    with pytest.raises(OptimiserError, match=match):
        Problem(sphere, lower, upper)


def test_problem_other_validation():
    with pytest.raises(OptimiserError, match="callable"):
        Problem("not callable", [0], [1])
    with pytest.raises(OptimiserError, match="x0"):
        Problem(sphere, [0, 0], [1, 1], x0=[0.5])
    p = Problem(sphere, [0, 0], [1, 1], x0=[0.2, 0.4])
    assert p.dim == 2
    with pytest.raises(ValueError):
        p.lower[0] = 5  # bounds are read-only


@pytest.mark.parametrize(
    "params, match",
    [({"nope": 1}, "unknown hyper-parameter.*'nope'"),
     ({"points": 2.0}, "'points' must be an integer"),
     ({"points": True}, "'points' must be int, got the boolean"),
     ({"points": 0}, r"'points' must lie in \[1"),
     ({"points": None}, "'points' must not be None"),
     ({"ratio": 0.0}, r"'ratio' must lie in \(0"),
     ({"ratio": 1.5}, "'ratio' must lie in"),
     ({"ratio": np.nan}, "'ratio' must be finite"),
     ({"ratio": "x"}, "'ratio' must be a number"),
     ({"flag": 1}, "'flag' must be true or false"),
     ({"mode": "c"}, "'mode' must be one of"),
     ({"mode": 1}, "'mode' must be a string"),
     ({"extra": -1}, "'extra' must lie in")],
)
def test_param_validation(params, match):
    with pytest.raises(HyperParameterError, match=match) as info:
        Fixed(**params)
    assert "test-fixed" in str(info.value)


def test_param_conversion_and_defaults():
    opt = Fixed(points=np.int64(3), ratio=1, extra=None, flag=np.bool_(True))
    assert opt.params == {"points": 3, "ratio": 1.0, "flag": True, "mode": "a", "extra": None}
    assert isinstance(opt.ratio, float) and isinstance(opt.points, int)
    with pytest.raises(AttributeError, match="fixed at construction"):
        opt.points = 4
    assert list(Fixed.hyperparameters()) == ["points", "ratio", "flag", "mode", "extra"]


def test_invalid_default_rejected_at_class_definition():
    # Python < 3.12 wraps errors raised in __set_name__ in a RuntimeError
    with pytest.raises((HyperParameterError, RuntimeError)) as info:
        class Broken(Optimiser):
            name = "test-broken"
            size = Param(int, 0, "bad default", low=1)
    err = info.value if isinstance(info.value, HyperParameterError) else info.value.__cause__
    assert isinstance(err, HyperParameterError) and "'size'" in str(err)


def test_variant_error_names_the_variant():
    with pytest.raises(HyperParameterError, match="nelder-mead"):
        create("nelder-mead", fd_step=-1.0)


def test_params_with_instance_rejected():
    with pytest.raises(OptimiserError, match="hyper-parameters go with an optimiser name"):
        minimize(Fixed(), box(), budget=10, params={"points": 3})
    with pytest.raises(OptimiserError, match="not an optimiser"):
        minimize(42, box(), budget=10)
    r = minimize(Fixed, box(), budget=10, seed=0)  # a class is instantiated with defaults
    assert r.nfev == 10


def test_builtins_are_available():
    names = available()
    for name in BUILTIN_BASELINES:
        assert name in names


# ------------------------------------------------------------------------------ aliases
class Aliased(Optimiser):
    """Test optimiser whose population size has two older names."""

    name = "test-aliased"
    population = Param(int, 4, "batch size", low=1, aliases=("points", "size"))
    ratio = Param(float, 0.5, "a float", low=0.0)

    def search(self, space, rng):
        while True:
            yield space.uniform(self.population, rng)


def test_an_alias_stands_for_its_parameter():
    assert Aliased(points=3).population == 3
    assert Aliased(size=2).params == {"population": 2, "ratio": 0.5}
    assert Aliased.aliases() == {"points": "population", "size": "population"}
    assert Aliased.canonical_params({"points": 3, "ratio": 1}) == {"population": 3, "ratio": 1}
    assert list(Aliased.hyperparameters()) == ["population", "ratio"]
    assert Aliased.hyperparameters()["population"].describe()["aliases"] == ["points", "size"]
    assert "aliases" not in Aliased.hyperparameters()["ratio"].describe()
    r = minimize(Aliased(points=5), box(), budget=12, seed=0)
    assert r.params == {"population": 5, "ratio": 0.5}
    assert not hasattr(Aliased(), "points")  # only the canonical name is an attribute


@pytest.mark.parametrize(
    "params, match",
    [({"points": 1, "population": 1}, "'population' given twice, as 'points' and 'population'"),
     ({"points": 1, "size": 1}, "'population' given twice"),
     ({"points": 0}, r"'population' \(given as 'points'\) must lie in \[1"),
     ({"size": 1.5}, r"'population' \(given as 'size'\) must be an integer"),
     ({"pop": 3}, "unknown hyper-parameter.*'pop'; valid: population, ratio")],
)
def test_alias_errors(params, match):
    with pytest.raises(HyperParameterError, match=match) as info:
        Aliased(**params)
    assert str(info.value).startswith("test-aliased: ")


def test_alias_clash_is_a_declaration_error():
    class Clash(Optimiser):
        name = "test-clash"
        population = Param(int, 4, "size", low=1, aliases=("ratio",))
        ratio = Param(float, 0.5, "a float")

    class Twice(Optimiser):
        name = "test-twice"
        population = Param(int, 4, "size", low=1, aliases=("n",))
        chains = Param(int, 4, "size", low=1, aliases=("n",))

    for cls in (Clash, Twice):
        with pytest.raises(TypeError, match="clashes"):
            cls()
    with pytest.raises(TypeError, match="aliases"):
        Param(int, 1, "x", aliases="points")  # a string, not a sequence of names


def test_variant_defaults_may_use_an_alias():
    register_variant("test-aliased-variant", Aliased, "by the old name", points=9)
    try:
        assert get("test-aliased-variant")().population == 9
        assert create("test-aliased-variant", size=3).population == 3
        with pytest.raises(HyperParameterError, match="given twice"):
            register_variant("test-aliased-variant-2", Aliased, points=9, population=9)
        assert "test-aliased-variant-2" not in available()
    finally:
        unregister("test-aliased-variant")


# ------------------------------------------------------------------------ module layout
FRAMEWORK = ["_budget", "_problem", "_params", "_history", "registry", "_driver"]


def _package_imports(path: Path) -> set[str]:
    """Modules of flexid.optimisers that ``path`` imports at run time (anywhere in it, but not
    under ``if TYPE_CHECKING:``)."""
    found: set[str] = set()

    def visit(node: ast.AST) -> None:
        if isinstance(node, ast.If) and getattr(node.test, "id", None) == "TYPE_CHECKING":
            return
        if isinstance(node, ast.ImportFrom) and node.level == 1:
            if node.module:
                found.add(node.module.split(".")[0])
            else:
                found.update(alias.name for alias in node.names)
        for child in ast.iter_child_nodes(node):
            visit(child)

    visit(ast.parse(path.read_text()))
    return found


def test_framework_modules_depend_one_way():
    """Each framework module imports only those before it: no cycle, and the registry (which
    the driver uses to resolve names) does not import the driver."""
    import flexid.optimisers as package

    folder = Path(package.__file__).parent
    assert not (folder / "base.py").exists()
    for i, module in enumerate(FRAMEWORK):
        imported = _package_imports(folder / f"{module}.py") & set(FRAMEWORK)
        assert imported <= set(FRAMEWORK[:i]), (module, imported)


def test_result_status_and_message_say_why_a_run_stopped():
    """``status`` as scipy.optimize's: 0 done or target, 1 a limit, 2 time, 3 callback, 4
    no finite cost."""
    from flexid.optimisers import Budget, Problem, minimize

    sphere = Problem(lambda X: (X**2).sum(axis=1), -np.ones(3), np.ones(3))
    run = minimize("random-search", sphere, 50, seed=0)
    assert (run.status, run.stop) == (1, "budget") and "budget reached (50)" in run.message
    hit = minimize("random-search", sphere, Budget(max_fe=5000, target=0.5), seed=0)
    assert (hit.status, hit.stop) == (0, "target")
    stopped = minimize("random-search", sphere, 500, seed=0, callback=lambda info: True)
    assert (stopped.status, stopped.stop) == (3, "callback")
    nowhere = Problem(lambda X: np.full(X.shape[0], np.inf), -np.ones(2), np.ones(2))
    lost = minimize("random-search", nowhere, 40, seed=0)
    assert lost.status == 4 and not lost.success
