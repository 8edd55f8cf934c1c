"""Recipe: a new model family in one file, as ``docs/architecture.md`` ("A new model family")
says.

Run:  python examples/recipe_family.py

A Laguerre model writes the response as a sum of ``n`` orthonormal Laguerre filters of one
real pole ``a``::

    y(t) = sum_k c_k L_k(q) u(t - nk) + e(t),
    L_k(q) = sqrt(1 - a^2) (q^-1 - a)^(k-1) / (1 - a q^-1)^k  (in q^-1, one delay in L_1)

With ``a`` near the plant's dominant pole a few functions describe a slow or lightly damped
response that an FIR model needs hundreds of taps for.  It is linear in ``c``, so its batched
cost is one matrix product and least squares is its exact optimum.

This file writes the structure, the model, the batched cost, the posed problem and the
family, registers the family, and then uses it through flexid's own jobs: ``identify`` (by
least squares and by a metaheuristic), ``validate`` and ``select`` (against an OE model).
Each printed claim is checked against an independent route: the model against its rational
transfer function run by ``scipy.signal.lfilter``, the fitted coefficients against the true
ones, the metaheuristic's cost against the exact optimum.
"""

from __future__ import annotations

import math
import os
import tempfile
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import signal

import flexid
from flexid.config import ComparisonSpec, CostSpec, DataSpec, ModelSpec, OptimiserSpec
from flexid.costs.metrics import metric_from_sse
from flexid.errors import ModelOrderError
from flexid.jobs.suite import Suite, SuiteProblem, run_suite
from flexid.models.families import Family, ReferenceFit, register_family
from flexid.optimisers import Problem
from flexid.validation import ValidationReport, residual_report


@dataclass(frozen=True)
class LaguerreStructure:
    """The orders of a Laguerre model: ``n`` functions of the pole ``pole``, input delay ``nk``.

    Parameters
    ----------
    n : int
        Number of Laguerre functions (parameters), >= 1.
    pole : float
        Their common real pole, ``-1 < pole < 1``.
    nk : int, optional
        Input delay in samples, >= 1 (default 1).
    """

    n: int
    pole: float
    nk: int = 1
    kind = "laguerre"  # what the jobs read: the structure's name
    n_inputs = 1
    start = 0  # the filters start from rest: every sample is scored

    def __post_init__(self) -> None:
        if self.n < 1 or self.nk < 1 or not -1.0 < self.pole < 1.0:
            raise ModelOrderError(f"a Laguerre structure needs n >= 1, nk >= 1, |pole| < 1: {self}")

    def __repr__(self) -> str:
        return f"Laguerre(n={self.n}, pole={self.pole:g}, nk={self.nk})"

    @property
    def n_params(self) -> int:
        """Number of coefficients, ``n``."""
        return self.n

    @property
    def orders(self) -> dict[str, Any]:
        """The orders by name."""
        return {"n": self.n, "pole": self.pole, "nk": self.nk}

    def check_samples(self, n_samples: int) -> None:
        """Refuse a record too short to determine the coefficients.

        Parameters
        ----------
        n_samples : int

        Raises
        ------
        ModelOrderError
            Fewer than ``2 n`` samples.
        """
        if n_samples < 2 * self.n:
            raise ModelOrderError(f"{self!r} needs at least {2 * self.n} samples, got {n_samples}")

    def regressors(self, u: np.ndarray) -> np.ndarray:
        """The input through every Laguerre filter, from rest.

        Parameters
        ----------
        u : ndarray, shape (K,)

        Returns
        -------
        ndarray, shape (K, n)
        """
        a = self.pole
        x = np.empty((u.size, self.n))
        delayed = np.concatenate([np.zeros(self.nk - 1), u[: u.size - self.nk + 1]])
        x[:, 0] = signal.lfilter([0.0, math.sqrt(1.0 - a * a)], [1.0, -a], delayed)
        for k in range(1, self.n):  # one all-pass section per function: n filters, not K steps
            x[:, k] = signal.lfilter([-a, 1.0], [1.0, -a], x[:, k - 1])
        return x

    def model(self, theta: Any, dt: float = 1.0) -> LaguerreModel:
        """The model of coefficients ``theta``.

        Parameters
        ----------
        theta : array_like, shape (n,)
        dt : float, optional
            Sample time (s).

        Returns
        -------
        LaguerreModel
        """
        return LaguerreModel(self, np.asarray(theta, dtype=float).reshape(self.n), dt)

    def to_dict(self) -> dict[str, Any]:
        """The structure as a result stores it.

        Returns
        -------
        dict
        """
        return {"structure": self.kind, **self.orders}


@dataclass
class LaguerreModel:
    """A Laguerre model: a structure and its coefficients.

    Parameters
    ----------
    structure : LaguerreStructure
    theta : ndarray, shape (n,)
        The coefficients ``c_1 .. c_n``.
    dt : float
        Sample time (s).
    input_names : tuple of str
    output_name : str
    """

    structure: LaguerreStructure
    theta: np.ndarray
    dt: float = 1.0
    input_names: tuple = ("u",)
    output_name: str = "y"
    is_stable: bool = field(default=True, init=False)  # its only pole is inside the circle

    def named(self, inputs: Any, output: str) -> LaguerreModel:
        """The same model with the record's channel names.

        Parameters
        ----------
        inputs : sequence of str
        output : str

        Returns
        -------
        LaguerreModel
        """
        return LaguerreModel(self.structure, self.theta, self.dt, tuple(inputs), str(output))

    def simulate(self, u: np.ndarray) -> np.ndarray:
        """The model's output for an input, from rest.

        Parameters
        ----------
        u : ndarray, shape (K,)

        Returns
        -------
        ndarray, shape (K,)
        """
        return self.structure.regressors(np.asarray(u, dtype=float)) @ self.theta

    def transfer_function(self) -> tuple[np.ndarray, np.ndarray]:
        """Numerator and denominator in powers of ``q^-1`` (over ``(1 - a q^-1)^n``).

        Returns
        -------
        num, den : ndarray
        """
        s = self.structure
        a, n = s.pole, s.n
        num = np.zeros(n + s.nk)
        for k, c in enumerate(self.theta, start=1):
            term = np.ones(1)  # coefficients of q^0, q^-1, ...
            for _ in range(k - 1):
                term = np.convolve(term, [-a, 1.0])  # (q^-1 - a)
            for _ in range(n - k):
                term = np.convolve(term, [1.0, -a])  # (1 - a q^-1)
            num[s.nk : s.nk + term.size] += c * math.sqrt(1.0 - a * a) * term
        den = np.poly(np.full(n, a))
        return num, den

    def poles(self) -> np.ndarray:
        """The discrete poles: ``a``, ``n`` times.

        Returns
        -------
        ndarray, shape (n,)
        """
        return np.full(self.structure.n, self.structure.pole)

    def zeros(self) -> np.ndarray:
        """The finite discrete zeros.

        Returns
        -------
        ndarray
        """
        num = np.trim_zeros(self.transfer_function()[0], "f")
        return np.roots(num) if num.size > 1 else np.array([])

    def summary(self) -> str:
        """The structure and its coefficients, one line each.

        Returns
        -------
        str
        """
        rows = [f"{self.structure!r}"]
        rows += [f"  c{k} = {c:.6g}" for k, c in enumerate(self.theta, start=1)]
        return "\n".join(rows)

    def to_dict(self) -> dict[str, Any]:
        """The model as a result stores it.

        Returns
        -------
        dict
        """
        return {**self.structure.to_dict(), "theta": self.theta.tolist(), "dt": self.dt}


class LaguerreCost:
    """The batched simulation cost of a Laguerre structure on a record: ``(P, n) -> (P,)``.

    Parameters
    ----------
    data : IOData
        A single-input, single-output estimation record.
    structure : LaguerreStructure
    spec : CostSpec
        Its metric and weight (a Laguerre model's one-step prediction is its simulation).
    """

    predictor = "simulation"

    def __init__(self, data: Any, structure: LaguerreStructure, spec: Any) -> None:
        self.y = data.y[:, 0]
        self.phi = structure.regressors(data.u[:, 0])
        self.spec = spec
        self.theta_ls = np.linalg.lstsq(self.phi, self.y, rcond=None)[0]
        self.cost_ls = float(self(self.theta_ls[None, :])[0])

    def __call__(self, X: Any) -> np.ndarray:
        errors = self.y[None, :] - np.atleast_2d(X) @ self.phi.T  # (P, K), one product
        sse = np.einsum("pk,pk->p", errors, errors)
        return metric_from_sse(self.spec.metric, sse, self.y.size, self.spec.weight,
                               float(np.std(self.y)))  # fmt: skip

    def describe(self) -> str:
        """One line: the metric and the predictor.

        Returns
        -------
        str
        """
        return f"{self.spec.metric} of the simulation error of a Laguerre model"


@dataclass
class Box:
    """The coefficient box: least squares plus or minus a margin.

    Parameters
    ----------
    lower, upper : ndarray, shape (n,)
        The box.
    rule : str, optional
        How it was chosen, as the summary says.
    """

    lower: np.ndarray
    upper: np.ndarray
    rule: str = "least squares +/- max(3 |c_ls|, 0.1 max |c_ls|)"

    def to_dict(self) -> dict[str, Any]:
        """The box as a result stores it.

        Returns
        -------
        dict
        """
        return {"lower": self.lower.tolist(), "upper": self.upper.tolist(), "rule": self.rule}


@dataclass
class LaguerreProblem:
    """A record and a Laguerre structure posed for the optimisers (what ``pose`` gives).

    Parameters
    ----------
    structure : LaguerreStructure
    cost : LaguerreCost
        The batched cost.
    box : Box
        The coefficient box.
    problem : Problem
        What the optimisers minimise: the cost over the box.
    """

    structure: LaguerreStructure
    cost: LaguerreCost
    box: Box
    problem: Problem

    @property
    def cost_ls(self) -> float:
        """The exact optimum's cost."""
        return self.cost.cost_ls

    @property
    def theta_ls(self) -> np.ndarray:
        """The exact optimum: a comparison's start row."""
        return self.cost.theta_ls

    def output_error_reference(self) -> None:
        """No gradient reference: least squares is already the exact optimum.

        Returns
        -------
        None
        """
        return None

    def theta(self, z: Any) -> np.ndarray:
        """Coefficients of search points (the search space is the coefficients).

        Parameters
        ----------
        z : array_like, shape (P, n) or (n,)

        Returns
        -------
        ndarray
        """
        return np.asarray(z, dtype=float)

    def describe(self) -> str:
        """One line: the search space.

        Returns
        -------
        str
        """
        return f"the {self.structure.n} coefficients in the box {self.box.rule}"

    def to_dict(self) -> dict[str, Any]:
        """The search space as a result stores it.

        Returns
        -------
        dict
        """
        return {"parametrisation": "coefficients", "box_rule": self.box.rule}


class LaguerreFamily(Family):
    """Laguerre models in flexid's one model interface."""

    name = "laguerre"
    names = ("laguerre",)  # structure="laguerre" in identify, and in a comparison's [model]
    structures = (LaguerreStructure,)
    models = (LaguerreModel,)

    def structure(self, spec: Any, n_inputs: int, **orders: Any) -> LaguerreStructure:
        """A Laguerre structure from its name and orders ``n``, ``pole`` and ``nk``.

        Parameters
        ----------
        spec : str or LaguerreStructure
        n_inputs : int
            Must be 1.
        **orders
            ``n`` and ``pole`` (required), ``nk`` (default 1).

        Returns
        -------
        LaguerreStructure

        Raises
        ------
        ModelOrderError
            Missing or unknown orders, or a record with several inputs.
        """
        if not isinstance(spec, str):
            return super().structure(spec, n_inputs, **orders)
        given = {k: v for k, v in orders.items() if v is not None}
        unknown = sorted(set(given) - {"n", "pole", "nk"})
        if unknown or not {"n", "pole"} <= set(given):
            raise ModelOrderError(f"a Laguerre structure takes n, pole and nk; got {given}")
        if n_inputs != 1:
            raise ModelOrderError(f"a Laguerre model has one input; the record has {n_inputs}")
        return LaguerreStructure(int(given["n"]), float(given["pole"]), int(given.get("nk", 1)))

    def pose(self, data: Any, structure: Any, cost: Any, search: Any, *,
             bounds: Any) -> LaguerreProblem:
        """The coefficients' search problem (see :meth:`flexid.models.families.Family.pose`).

        Parameters
        ----------
        data : IOData
        structure : LaguerreStructure
        cost : CostSpec
        search : SearchSpec
            Not used: the search space is the coefficients.
        bounds : object
            Not used: the box is set around least squares.

        Returns
        -------
        LaguerreProblem
        """
        objective = LaguerreCost(data, structure, cost)
        c = objective.theta_ls
        margin = np.maximum(3.0 * np.abs(c), 0.1 * np.max(np.abs(c)))
        box = Box(c - margin, c + margin)
        return LaguerreProblem(structure, objective, box,
                               Problem(objective, box.lower, box.upper, name=repr(structure)))

    def fit(self, estimation: Any, structure: Any, method: str, *, data: Any,
            seed: int | None) -> ReferenceFit:
        """Least squares, the exact optimum (also for ``"pem"``: the cost is quadratic).

        Parameters
        ----------
        estimation : LaguerreProblem
        structure : LaguerreStructure
        method : str
        data : IOData
        seed : int or None

        Returns
        -------
        ReferenceFit
        """
        cost = estimation.cost
        return ReferenceFit(structure.model(cost.theta_ls, dt=data.dt), cost.cost_ls)

    def reference(self, data: Any, structure: Any, *, initial: str, starts: int | None,
                  seed: int) -> tuple[Any, float, bool]:
        """Least squares on a record, as :func:`flexid.select` fits a candidate.

        Parameters
        ----------
        data : IOData
        structure : LaguerreStructure
        initial : str
        starts : int or None
        seed : int

        Returns
        -------
        model : LaguerreModel
        sse : float
        local_minimum : bool
            True: least squares is the global minimum.
        """
        cost = LaguerreCost(data, structure, CostSpec(metric="sse"))
        return structure.model(cost.theta_ls, dt=data.dt), cost.cost_ls, True

    def reference_hint(self, structure: Any, predictor: str) -> str:
        """The exact optimum a search compares with.

        Parameters
        ----------
        structure : LaguerreStructure
        predictor : str

        Returns
        -------
        str
        """
        return "optimiser='ls'"

    def validate(self, model: Any, data: Any, *, max_lag: int, initial: str,
                 split: float | int | None, dt: float | None,
                 output: str | None, estimated_on: Any = None) -> ValidationReport:
        """Simulate the model from rest over the record and report on it.

        Parameters
        ----------
        model : LaguerreModel
        data : IOData
        max_lag : int
        initial : str
            ``"estimate"``: the free response of the filters' state at the record's start is
            fitted by least squares (as MATLAB ``compare`` does); otherwise they start from
            rest.
        split : float, int or None
            Validate on the part after this split only.
        dt : float or None
            Not used: the record has its own.
        output : str or None
            Not used: one output.
        estimated_on : object
            Not used: the residual tests take the parameters as known.

        Returns
        -------
        ValidationReport
        """
        record = data if split is None else (
            data.split(split)[1] if isinstance(split, float) else data.split(index=split)[1]
        )
        u, y = record.u, record.y[:, 0]
        ysim = model.simulate(u[:, 0])
        rule = "estimate" if initial == "estimate" else "zero"
        if rule == "estimate":
            # the free responses of n states at the pole a: impulse responses of
            # 1 / (1 - a q^-1)^j, j = 1 .. n, span them
            impulse = np.zeros(y.size)
            impulse[0] = 1.0
            a, n = model.structure.pole, model.structure.n
            free = np.column_stack([signal.lfilter([1.0], np.poly(np.full(j, a)), impulse)
                                    for j in range(1, n + 1)])  # fmt: skip
            ysim = ysim + free @ np.linalg.lstsq(free, y - ysim, rcond=None)[0]
        return residual_report(
            y, None, ysim, u, start=0, dt=float(record.dt), max_lag=max_lag,
            names=list(record.input_names), output_name=str(record.output_names[0]),
            initial=rule, initial_one_step=rule, poles=model.poles(), zeros=[model.zeros()],
        )


def main() -> None:
    """Run the checks the docstring at the top of the file describes, one line each."""
    register_family(LaguerreFamily())

    # a lightly damped plant near 0.9: what a few Laguerre functions of pole 0.9 describe
    rng = np.random.default_rng(0)
    truth = LaguerreStructure(4, 0.9).model([1.0, -0.6, 0.3, 0.1], dt=0.1)
    u = rng.standard_normal(1500)
    y = truth.simulate(u) + 0.02 * rng.standard_normal(u.size)
    data = flexid.IOData(u, y, dt=0.1)

    num, den = truth.transfer_function()
    print("model equals its transfer function run by lfilter: "
          f"{np.allclose(truth.simulate(u), signal.lfilter(num, den, u), rtol=0, atol=1e-10)}")

    structure = LaguerreStructure(4, 0.9)
    ls = flexid.identify(data, structure=structure, optimiser="ls")
    est = data.split(2 / 3)[0]  # identify's estimation part
    phi = structure.regressors(est.u[:, 0])
    residual = est.y[:, 0] - phi @ ls.model.theta
    sigma2 = residual @ residual / (est.n_samples - structure.n_params)
    std = np.sqrt(np.diag(sigma2 * np.linalg.inv(phi.T @ phi)))
    worst = float(np.max(np.abs(ls.model.theta - truth.theta) / std))
    print(f"least squares recovers the coefficients within 4 standard errors "
          f"({worst:.2f}): {worst < 4}")
    print(f"held-out simulation fit {ls.validation.fit_simulation:.2f} % above 95 %: "
          f"{ls.validation.fit_simulation > 95}")

    de = flexid.identify(data, structure=structure, optimiser="de", budget=4000, seed=1)
    print(f"DE at 4000 evaluations within 0.1 % of the exact optimum's cost: "
          f"{de.cost_value <= 1.001 * ls.cost_value}")
    print(f"the result names the family's structure: {de.to_dict()['structure']['structure']}")

    report = flexid.validate(ls.model, data, split=2 / 3)
    print(f"validate() asks the family: {report.fit_simulation == ls.validation.fit_simulation}")

    chosen = flexid.select(
        data, structures=[LaguerreStructure(2, 0.9), structure, LaguerreStructure(8, 0.9),
                          flexid.structure("oe", nb=2, nf=2)],
    )
    print(f"select ranks Laguerre and OE candidates together, best {chosen.best.label}: "
          f"{chosen.best.structure == structure}")

    # a comparison names the structure in its [model] table; the record is a file
    with tempfile.TemporaryDirectory() as folder:
        record = os.path.join(folder, "laguerre.csv")
        flexid.save(data, record)
        spec = ComparisonSpec(
            name="laguerre", data=DataSpec(file=record),
            model=ModelSpec(structure="laguerre", options={"n": 4, "pole": 0.9}),
            optimisers=(OptimiserSpec("de"), OptimiserSpec("pso")), runs=2, budget=2000,
        )
        result = flexid.compare(spec, store=os.path.join(folder, "runs.db"))
        best = {label: min(r["cost"] for r in result.records[label]) for label in ("de", "pso")}
        exact = result.reference_cost
        print(f"compare runs DE and PSO on it, each best within 1 % of the exact optimum "
              f"{exact:.6g} and none below it: "
              f"{all(exact * (1 - 1e-9) <= c <= 1.01 * exact for c in best.values())}")
        suite = Suite("laguerre", (SuiteProblem("record/laguerre/simulation/0", "record",
                                                "laguerre", "simulation", "0", spec),),
                      budget_per_dim=200, runs=2)  # fmt: skip
        ran = run_suite(suite, ["de"], store=os.path.join(folder, "suite.db"))
        names = [p.name for p in suite.problems]
        print(f"the suite runs it as one of its problems: {list(ran.results) == names}")


if __name__ == "__main__":
    main()
