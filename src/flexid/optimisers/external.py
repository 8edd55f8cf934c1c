"""Optimisers of other libraries run inside flexid's driver: nevergrad, pycma and pymoo.

Each adapter drives its library through the library's own ask/tell interface, so flexid's
driver evaluates every population and the rules of a fair comparison hold as they do for
flexid's own optimisers:

* **exact FE budgets**: the driver truncates the last population at the budget and never
  tells it back, so the library cannot overrun (a library is never handed the objective);
* **the shared initial population**: the first batch of every adapter is the first
  ``initial_points`` (or ``population``) rows of the run's shared initial population,
  handed to the library in the way it accepts one (see each class);
* **the run's seed**: the library's seed is drawn from the run's ``numpy.random.Generator``
  and no adapter touches NumPy's global random state;
* **errors**: an exception raised by the library becomes an
  :class:`~flexid.errors.OptimiserError` naming the optimiser and the FE count, which a
  comparison records as a failed run.

Every library searches the unit box ``[0, 1]^n`` that flexid's optimisers see, so a length
hyper-parameter (``sigma0``) is a fraction of each side of the problem's box.

Names are ``<library>:<the library's name of the algorithm>``:

* ``ng:<name>`` for any optimiser of ``nevergrad.optimizers.registry`` (``ng:NGOpt``,
  ``ng:TwoPointsDE``, ``ng:CMA``, ...), resolved on first use; ``ng:CMA``, ``ng:TwoPointsDE`` and
  ``ng:OnePlusOne`` are registered (listed by ``flexid list optimisers``) when nevergrad is
  installed;
* ``cma:CMA-ES``, pycma's ``CMAEvolutionStrategy``;
* ``pymoo:GA``, ``pymoo:DE``, ``pymoo:PSO``, ``pymoo:NelderMead``.

The libraries are optional extras (``pip install 'flexid[nevergrad]'``, ``[cma]``,
``[pymoo]``): an adapter is registered only when its library is installed, and the library
is imported only when a run starts, so listing optimisers stays fast.
"""

from __future__ import annotations

import builtins
import contextlib
import difflib
import importlib.util
import warnings
from collections.abc import Callable, Iterator
from importlib.metadata import PackageNotFoundError, version
from typing import Any, ClassVar

import numpy as np

from ..errors import OptimiserError, UnknownOptimiserError
from ._params import Optimiser, Param, SearchGenerator
from ._problem import SearchSpace
from .registry import _REGISTRY, register, register_prefix

__all__ = ["NevergradOptimiser", "PyCMA", "PymooOptimiser", "installed", "library_notes"]

# nevergrad clips larger losses itself (with a warning); +inf costs are told as this value
_NG_MAX_LOSS = 5.0e20
# nevergrad optimisers listed (and checked by the conformance test) when nevergrad is installed
_NG_LISTED = ("CMA", "TwoPointsDE", "OnePlusOne")
# consecutive asks with nothing new to evaluate after which a pymoo algorithm counts as stalled
_PYMOO_STALL = 100

# the import name of the library behind each name prefix (also the name of its flexid extra)
_LIBRARIES = {"ng": "nevergrad", "cma": "cma", "pymoo": "pymoo"}


def installed(library: str) -> bool:
    """Whether an optional optimiser library can be imported (without importing it).

    Parameters
    ----------
    library : {"nevergrad", "cma", "pymoo"}
        The import name.

    Returns
    -------
    bool
    """
    return importlib.util.find_spec(library) is not None


def _source(distribution: str) -> str:
    try:
        return f"{distribution} {version(distribution)}"
    except PackageNotFoundError:
        return distribution


def _library_seed(rng: np.random.Generator) -> int:
    """A seed for the library drawn from the run's generator (< 2**32 for RandomState)."""
    return int(rng.integers(0, 2**32 - 1))


class _External(Optimiser):
    """Base of the adapters: turns a library exception into an OptimiserError."""

    library: ClassVar[str] = ""

    def search(self, space: SearchSpace, rng: np.random.Generator) -> SearchGenerator:
        inner = self._search(space, rng)
        told = 0
        try:
            X = next(inner)
            while True:
                F = yield X
                told += len(F)
                X = inner.send(F)
        except StopIteration:
            return
        except OptimiserError:
            raise
        except Exception as exc:  # the library's, recorded by compare as a failed run
            raise OptimiserError(
                f"{self.name}: {self.library} raised {type(exc).__name__}: {exc} "
                f"(after {told} function evaluations)"
            ) from exc
        finally:
            inner.close()

    def _search(self, space: SearchSpace, rng: np.random.Generator) -> Iterator[np.ndarray]:
        raise NotImplementedError


# ==================================================================================== nevergrad
class NevergradOptimiser(_External):
    """An optimiser of nevergrad's registry, asked and told by flexid's driver.

    Parameters
    ----------
    num_workers : int
        Candidates asked before they are told, evaluated as one batch (default 1, nevergrad's
        default: the sequential setting its optimisers are tuned for).  nevergrad receives it
        as ``num_workers``, and some optimisers (NGOpt) choose their algorithm from it.
    initial_points : int
        Size of the shared initial population evaluated as the first batch (default 50, as
        for flexid's CMA-ES).  The points are passed to ``optimizer.suggest`` and told back,
        so they count in nevergrad's own budget and it learns from them; 0 leaves
        nevergrad's own start (the centre of the box, then its own sampling).

    Notes
    -----
    The parametrisation is ``ng.p.Array`` in ``[0, 1]^n`` seeded with a ``RandomState`` of
    its own (the seed drawn from the run's generator), and nevergrad's ``budget`` is the
    run's FE budget.  Costs of +inf (NaN/inf from the objective) are told as ``5e20``, the
    value nevergrad caps losses at.  One batch is one iteration.
    """

    name = "ng"
    library = "nevergrad"
    reference = "Rapin & Teytaud, Nevergrad - A gradient-free optimization platform, 2018"
    bounds = "library's + clip"
    bounds_note = (
        "nevergrad's bounded parametrisation (ng.p.Array with lower and upper "
        "bounds) handles the box; the points it asks are also clipped to it."
    )
    stays_in_box = True
    ng_name: ClassVar[str] = ""
    num_workers = Param(int, 1, "candidates asked per batch (nevergrad's num_workers)", low=1)
    initial_points = Param(int, 50, "size of the shared initial population (0: nevergrad's own)",
                           low=0)

    def _search(self, space: SearchSpace, rng: np.random.Generator) -> Iterator[np.ndarray]:
        with _global_state_kept():
            ng = _import_nevergrad()
            # nevergrad's own bounded array (sigma 1/6 of the box, uniform sampling); building
            # it seeds a random state from NumPy's global one, replaced by the run's at once
            param = ng.p.Array(shape=(space.dim,), lower=0.0, upper=1.0)
        param.random_state = np.random.RandomState(_library_seed(rng))
        # nevergrad's budget is the run's (NGOpt chooses its algorithm from it)
        opt = ng.optimizers.registry[self.ng_name](
            parametrization=param, budget=space.max_fe, num_workers=self.num_workers
        )
        if self.initial_points:
            X0 = space.initial_population(self.initial_points)
            for x in X0[::-1]:  # nevergrad hands suggestions out last in, first out
                opt.suggest(x)
            yield from _ng_batch(opt, space, len(X0))
        while True:
            yield from _ng_batch(opt, space, self.num_workers)


@contextlib.contextmanager
def _global_state_kept() -> Iterator[None]:
    """Restore NumPy's global random state, which nevergrad draws from on import and when it
    builds a parametrisation, so a run leaves the user's state as it found it."""
    state = np.random.get_state()  # noqa: NPY002 (restored, not used)
    try:
        yield
    finally:
        np.random.set_state(state)  # noqa: NPY002


def _import_nevergrad() -> Any:
    with _global_state_kept():
        import nevergrad
    _mend_metamodel()
    return nevergrad


def _one_element_float(x: Any) -> float:
    """``float(x)`` that also takes a one-element array of any shape, as NumPy < 2.4 did."""
    if isinstance(x, np.ndarray) and x.size == 1:
        return builtins.float(x.reshape(-1)[0])
    return builtins.float(x)


def _mend_metamodel() -> None:
    """Let nevergrad's meta-model (used by ``NGOpt``) run under NumPy >= 2.4.

    nevergrad 1.0.12 scores a point of its meta-model with ``float(model.predict(x))``,
    where ``predict`` returns a one-element array (1,); NumPy 2.4 refuses ``float`` of an
    array with a dimension, so every meta-model step of ``NGOpt`` raises ``TypeError``.
    The metamodel module's name ``float`` is bound to :func:`_one_element_float`, which
    gives what ``float`` gave before; nothing outside that module changes, and nothing is
    done where ``float`` of such an array still works or the module has its own ``float``.
    """
    try:
        builtins.float(np.ones(1))
        return
    except TypeError:
        pass
    from nevergrad.optimization import metamodel

    if "float" not in vars(metamodel):
        metamodel.float = _one_element_float


@contextlib.contextmanager
def _surrogate_warnings_quiet() -> Iterator[None]:
    """Silence the overflow warnings of the surrogate nevergrad's meta-model fits and
    minimises at every step (scipy's Powell and scikit-learn's polynomial features; hundreds
    per NGOpt run): they concern the surrogate, never the problem or the run."""
    with warnings.catch_warnings():
        warnings.filterwarnings(
            "ignore", category=RuntimeWarning, module=r"(scipy\.optimize|sklearn)\b"
        )
        yield


def _ng_batch(opt: Any, space: SearchSpace, size: int) -> Iterator[np.ndarray]:
    with _surrogate_warnings_quiet():
        candidates = [opt.ask() for _ in range(size)]
    X = space.clip(np.array([c.value for c in candidates], dtype=float))
    F = yield X
    with _surrogate_warnings_quiet():
        for candidate, f in zip(candidates, np.minimum(F, _NG_MAX_LOSS)):
            opt.tell(candidate, float(f))


def _nevergrad_class(name: str) -> type[Optimiser]:
    """The adapter of ``ng:<name>``, registered on first use (nevergrad is imported here)."""
    ng_name = name.partition(":")[2]
    if name in _REGISTRY:
        return _REGISTRY[name]
    if not installed("nevergrad"):
        _missing(name, "nevergrad")
    ng = _import_nevergrad()
    known = sorted(ng.optimizers.registry)
    if ng_name not in known:
        _unknown(name, "ng", known, f"{_source('nevergrad')} has no optimiser {ng_name!r}")
    return _register_ng(ng_name)


def _register_ng(ng_name: str) -> type[Optimiser]:
    cls = type(
        f"Nevergrad_{''.join(c if c.isalnum() else '_' for c in ng_name)}",
        (NevergradOptimiser,),
        {
            "name": f"ng:{ng_name}",
            "ng_name": ng_name,
            "__module__": __name__,
            "__doc__": f"nevergrad's {ng_name}, asked and told by flexid's driver.\n\n"
            + (NevergradOptimiser.__doc__ or "").split("\n", 2)[2],
        },
    )
    return register(cls, source=_source("nevergrad"))


# ========================================================================================= pycma
class PyCMA(_External):
    """pycma's CMA-ES (``cma.CMAEvolutionStrategy``), asked and told by flexid's driver.

    Parameters
    ----------
    population : int or None
        ``popsize`` (lambda, FE per generation); None: pycma's default ``4 + floor(3 ln n)``.
    sigma0 : float
        Initial step size as a fraction of the box width (default 0.3, as flexid's CMA-ES).
    initial_points : int
        Size of the shared initial population evaluated as the first batch (default 50).
        pycma accepts a start point, not a population: its mean starts at the best of these
        points, as flexid's CMA-ES does.
    restarts : bool
        When pycma's own termination criteria fire before the budget, start again from a
        uniform point drawn from the run's generator (default True); ``False`` ends the run
        (``stop == "converged"``).

    Notes
    -----
    pycma's options: ``bounds = [0, 1]`` (its ``BoundTransform``: every point it asks is in
    the box), ``randn`` the run's generator, ``seed = nan`` (so pycma never seeds NumPy's
    global random state) and ``verbose = -9``.  One generation is one iteration.
    """

    name = "cma:CMA-ES"
    library = "pycma"
    reference = "Hansen, Akimoto & Baudis, pycma (CMA-ES in Python), doi:10.5281/zenodo.2559634"
    bounds = "periodic transform + clip"
    bounds_note = (
        "pycma's BoundTransform (bounds = [0, 1]) maps its samples into the "
        "box; the points are also clipped to it."
    )
    stays_in_box = True
    population = Param(int, None, "popsize (None: 4 + floor(3 ln n))", low=2, none_ok=True)
    sigma0 = Param(float, 0.3, "initial step as a fraction of the box width", low=0.0,
                   low_open=True)
    initial_points = Param(int, 50, "size of the shared initial population", low=1)
    restarts = Param(bool, True, "restart when pycma stops before the budget")

    def _search(self, space: SearchSpace, rng: np.random.Generator) -> Iterator[np.ndarray]:
        import cma

        X0 = space.initial_population(self.initial_points)
        F0 = yield X0
        x0 = X0[int(np.argmin(F0))]
        options: dict[str, Any] = {
            "bounds": [0.0, 1.0],
            "randn": lambda *shape: rng.standard_normal(shape),
            "seed": float("nan"),
            "verbose": -9,
            "verb_log": 0,
            "verb_disp": 0,
        }
        if self.population is not None:
            options["popsize"] = self.population
        while True:
            es = cma.CMAEvolutionStrategy(x0, self.sigma0, options)
            while not es.stop():
                solutions = es.ask()
                F = yield space.clip(np.array(solutions, dtype=float))
                es.tell(solutions, F.tolist())
            if not self.restarts:
                return
            x0 = space.uniform(1, rng)[0]


# ========================================================================================= pymoo
def _pymoo_algorithm(kind: str, start: np.ndarray, size: int) -> Any:
    """A pymoo algorithm whose initial population (or start sample) is ``start``."""
    if kind == "GA":
        from pymoo.algorithms.soo.nonconvex.ga import GA

        return GA(pop_size=size, sampling=start)
    if kind == "DE":
        from pymoo.algorithms.soo.nonconvex.de import DE

        return DE(pop_size=size, sampling=start)
    if kind == "PSO":
        from pymoo.algorithms.soo.nonconvex.pso import PSO

        return PSO(pop_size=size, sampling=start)
    from pymoo.algorithms.soo.nonconvex.nelder import NelderMead

    return NelderMead(sampling=start, n_sample_points=size)


def _pymoo_problem(n: int) -> Any:
    """A pymoo problem on ``[0, 1]^n`` whose values are the costs flexid's driver sends."""
    from pymoo.core.problem import Problem as PymooProblem

    class Told(PymooProblem):
        def __init__(self) -> None:
            super().__init__(n_var=n, n_obj=1, xl=0.0, xu=1.0)
            self.costs = np.empty(0)

        def _evaluate(self, X: np.ndarray, out: dict, *args: Any, **kwargs: Any) -> None:
            if len(X) != len(self.costs):
                raise OptimiserError(f"pymoo evaluated {len(X)} points, flexid {len(self.costs)}")
            out["F"] = self.costs[:, None]

    return Told()


class PymooOptimiser(_External):
    """A single-objective pymoo algorithm, asked and told by flexid's driver.

    Each registered algorithm has one size parameter: ``population`` (GA, DE, PSO) or
    ``initial_points`` (NelderMead).

    Notes
    -----
    The algorithm is set up on ``[0, 1]^n`` with a termination that never fires (flexid's
    stop rules govern) and a seed drawn from the run's generator (pymoo 0.6 keeps its own
    ``numpy.random.Generator``).  Each ``ask()`` yields the points pymoo has not evaluated
    yet; their costs are set through pymoo's ``Evaluator`` (so its FE count agrees with
    flexid's) and the population is told back.  A population with nothing new to evaluate
    is told at once; 100 of them in a row end the run (``stop == "converged"``).  One
    batch is one iteration.
    """

    name = "pymoo"
    library = "pymoo"
    reference = "Blank & Deb, pymoo: Multi-objective optimization in Python, IEEE Access 8, 2020"
    bounds = "library's + clip"
    bounds_note = (
        "pymoo's operators keep to the bounds of the problem in their own way; "
        "the points it asks are also clipped to the box."
    )
    stays_in_box = True
    algorithm: ClassVar[str] = ""

    def _size(self) -> int:
        params = self.params
        return params["population"] if "population" in params else params["initial_points"]

    def _search(self, space: SearchSpace, rng: np.random.Generator) -> Iterator[np.ndarray]:
        from pymoo.core.individual import Individual
        from pymoo.core.population import Population
        from pymoo.core.termination import NoTermination

        size = self._size()
        algorithm = _pymoo_algorithm(self.algorithm, space.initial_population(size), size)
        problem = _pymoo_problem(space.dim)
        algorithm.setup(problem, termination=NoTermination(), seed=_library_seed(rng),
                        verbose=False)
        stalled = 0
        while stalled < _PYMOO_STALL:
            pop = algorithm.ask()
            if pop is None:
                raise OptimiserError(f"{self.name}: pymoo's algorithm does not use ask/tell")
            # the local search asks single individuals; they are told back as such
            batch = Population.create(pop) if isinstance(pop, Individual) else pop
            todo = [i for i, ind in enumerate(batch) if "F" not in ind.evaluated]
            if todo:
                stalled = 0
                problem.costs = yield space.clip(batch[todo].get("X"))
                algorithm.evaluator.eval(problem, pop)
            else:
                stalled += 1
            algorithm.tell(infills=pop)


# PatternSearch is left out: pymoo 0.6.2 draws its exploration order from fresh OS entropy
# (exploration_move is not given the algorithm's random state), so a seed cannot repeat a run
_PYMOO_DEFAULTS = {"GA": 100, "DE": 100, "PSO": 25, "NelderMead": 20}
_PYMOO_SIZE_DOC = {
    "population": """    population : int
        ``pop_size`` (pymoo's defaults: GA 100, DE 100, PSO 25); the initial population is
        the first ``population`` shared initial points, passed as pymoo's ``sampling``.
""",
    "initial_points": """    initial_points : int
        ``n_sample_points`` (pymoo's default 20): the shared initial points passed as
        ``sampling``, the best of which starts the simplex.
""",
}
_PYMOO_SUMMARY = {
    "GA": "pymoo's genetic algorithm (GA), asked and told by flexid's driver.",
    "DE": "pymoo's differential evolution (DE), asked and told by flexid's driver.",
    "PSO": "pymoo's particle swarm optimisation (PSO), asked and told by flexid's driver.",
    "NelderMead": "pymoo's Nelder-Mead simplex search, asked and told by flexid's driver.",
}


def _register_pymoo(kind: str) -> type[Optimiser]:
    size = _PYMOO_DEFAULTS[kind]
    namespace: dict[str, Any] = {
        "name": f"pymoo:{kind}",
        "algorithm": kind,
        "__module__": __name__,
    }
    size_param = "initial_points" if kind == "NelderMead" else "population"
    notes = (PymooOptimiser.__doc__ or "").split("    Notes\n", 1)[1]
    namespace["__doc__"] = (
        f"{_PYMOO_SUMMARY[kind]}\n\n    Parameters\n    ----------\n"
        f"{_PYMOO_SIZE_DOC[size_param]}\n    Notes\n{notes}"
    )
    if kind == "NelderMead":
        namespace["initial_points"] = Param(int, size, "shared initial points (n_sample_points)",
                                            low=1)
    else:
        # DE's mutation needs distinct members; pymoo's selections need two parents
        low = 4 if kind == "DE" else 2
        namespace["population"] = Param(int, size, "population size (pop_size)", low=low)
    return register(type(f"Pymoo_{kind}", (PymooOptimiser,), namespace), source=_source("pymoo"))


# ==================================================================================== the names
def library_notes() -> list[str]:
    """Lines for ``flexid list optimisers`` on the optimisers of other libraries.

    Returns
    -------
    list of str
        One line per library: the names it gives when installed, or the extra to install.
    """
    lines = []
    for prefix, library in _LIBRARIES.items():
        if prefix == "ng":
            names = "ng:<name>, any optimiser of nevergrad.optimizers.registry"
        elif prefix == "cma":
            names = "cma:CMA-ES"
        else:
            names = ", ".join(f"pymoo:{k}" for k in _PYMOO_DEFAULTS)
        state = _source(library) if installed(library) else (
            f"not installed: pip install 'flexid[{library}]'"
        )
        lines.append(f"{names} ({state})")
    return lines


def _missing(name: str, library: str) -> None:
    error = UnknownOptimiserError(name)
    error.args = (
        f"unknown optimiser {name!r}: it needs {library}, which is not installed "
        f"(pip install 'flexid[{library}]')",
    )
    raise error


def _unknown(name: str, prefix: str, known: list[str], why: str) -> None:
    short = name.partition(":")[2]
    folded = {k.lower(): k for k in known}
    close = [folded[short.lower()]] if short.lower() in folded else []
    close += [k for k in difflib.get_close_matches(short, known, n=5, cutoff=0.6) if k not in close]
    suggestions = [f"{prefix}:{k}" for k in close]
    error = UnknownOptimiserError(name, suggestions)
    hint = f"; did you mean {', '.join(suggestions)}?" if suggestions else ""
    error.args = (f"unknown optimiser {name!r}: {why}{hint}",)
    raise error


def _fixed_resolver(prefix: str, names: list[str]) -> Callable[[str], type[Optimiser]]:
    """The resolver of a prefix whose names are all registered when the library is installed:
    any name it is asked for is unknown."""
    library = _LIBRARIES[prefix]

    def resolve(name: str) -> type[Optimiser]:
        if not installed(library):
            _missing(name, library)
        _unknown(name, prefix, sorted(names), f"flexid adapts {', '.join(sorted(names))} of "
                 f"{library}")
        raise AssertionError("unreachable: _unknown raises")

    return resolve


register_prefix("ng", _nevergrad_class)
if installed("nevergrad"):
    for _name in _NG_LISTED:
        _register_ng(_name)

if installed("cma"):
    register(PyCMA, source=_source("cma"))
register_prefix("cma", _fixed_resolver("cma", ["CMA-ES"]))

if installed("pymoo"):
    for _kind in _PYMOO_DEFAULTS:
        _register_pymoo(_kind)
register_prefix("pymoo", _fixed_resolver("pymoo", list(_PYMOO_DEFAULTS)))
