"""Recipe: a new cost, as ``docs/architecture.md`` ("A new cost") says.

Run:  python examples/recipe_cost.py

Any batched function is a cost: ``(P, n)`` in, ``(P,)`` out, wrapped in a ``Problem`` with
its box; every registered optimiser then minimises it with the same shared initial
population and exact budget.  Here: the sum of absolute errors of a first-order model's
simulation (an L1 output-error cost, robust to the record's outliers), written over a whole
population at once, checked against an independent computation (``scipy.signal.lfilter``
per candidate) and minimised by two optimisers.  A new *named* metric of the built-in costs
(used by ``identify``, ``compare`` and the command line) is one row of
``flexid.costs.metrics.METRIC_TABLE`` instead.
"""

from __future__ import annotations

import numpy as np
from scipy import signal

from flexid.kernels import ar_recursion
from flexid.optimisers import Problem, minimize

A_TRUE, B_TRUE = 0.9, 0.5


def simulate(theta: np.ndarray, u: np.ndarray) -> np.ndarray:
    """``y(t) = a y(t-1) + b u(t-1)`` from rest, for every row ``(a, b)`` of ``theta`` at once.

    Parameters
    ----------
    theta : ndarray, shape (P, 2)
    u : ndarray, shape (N,)

    Returns
    -------
    ndarray, shape (P, N)
    """
    u_past = np.concatenate([[0.0], u[:-1]])  # u(t - 1), at rest before the record
    forced = theta[:, 1:2] * u_past[None, :]
    # the whole population's recursion in flexid's batched kernel (compiled when built)
    y, _ = ar_recursion(-theta[:, :1], forced, np.zeros(1))
    return y


def main() -> None:
    """Run the checks the docstring at the top of the file describes, one line each."""
    rng = np.random.default_rng(0)
    u = rng.uniform(-1.0, 1.0, 400)
    y = simulate(np.array([[A_TRUE, B_TRUE]]), u)[0]
    y[rng.choice(y.size, 8, replace=False)] += 5.0  # outliers a squared cost would chase

    def l1_cost(X: np.ndarray) -> np.ndarray:
        return np.abs(y[None, :] - simulate(X, u)).sum(axis=1)

    X = rng.uniform([-0.99, -2.0], [0.99, 2.0], (6, 2))
    independent = [np.abs(y - signal.lfilter([0.0, b], [1.0, -a], u)).sum() for a, b in X]
    print(f"batched cost equals lfilter per candidate: "
          f"{np.allclose(l1_cost(X), independent, rtol=1e-12)}")
    problem = Problem(l1_cost, [-0.99, -2.0], [0.99, 2.0])
    for name in ("de", "cmaes-bipop"):
        run = minimize(name, problem, 3000, seed=1)
        close = np.allclose(run.x, [A_TRUE, B_TRUE], atol=1e-3)
        print(f"{name}: a, b = {run.x.round(4)} despite the outliers: {close}")


if __name__ == "__main__":
    main()
