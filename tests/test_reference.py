"""The one gradient reference (:mod:`flexid.fit.reference`): its run, its result type, and every
reference returning that type with the same keys."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal
from scipy.optimize import OptimizeResult, least_squares

from flexid.costs.arx import ARXCost
from flexid.fit.greybox_fit import greyest
from flexid.fit.output_error import output_error
from flexid.fit.prediction_error import pem
from flexid.fit.reference import (
    STATUS,
    ReferenceResult,
    ReferenceRun,
    levenberg_marquardt,
    optimality,
    standard_errors,
)
from flexid.models.arx import ARXStructure
from flexid.models.greybox_library import greybox_model
from flexid.models.polynomial import structure

COMMON = ("x", "fun", "status", "success", "message", "nfev", "njev", "nfev_equivalent", "std",
          "optimality", "local_minimum", "runs", "best_start", "wall_time", "cost", "stable",
          "on_cap")  # fmt: skip


def _rosenbrock(x: np.ndarray) -> np.ndarray:
    return np.array([10.0 * (x[1] - x[0] ** 2), 1.0 - x[0]])


def _rosenbrock_jac(x: np.ndarray) -> np.ndarray:
    return np.array([[-20.0 * x[0], 10.0], [-1.0, 0.0]])


def test_a_run_is_minpack_when_every_point_is_admissible() -> None:
    # without a constraint the run is scipy's own call: the same end, bit for bit
    x0 = np.array([-1.2, 1.0])
    run = levenberg_marquardt(_rosenbrock, _rosenbrock_jac, x0, "x0", tol=1e-12)
    sol = least_squares(_rosenbrock, x0, jac=_rosenbrock_jac, method="lm", x_scale="jac",
                        ftol=1e-12, xtol=1e-12, gtol=1e-12, max_nfev=200)  # fmt: skip
    assert isinstance(run, ReferenceRun)
    np.testing.assert_array_equal(run.x, sol.x)
    assert run.fun == float(sol.fun @ sol.fun) and run.fun0 == pytest.approx(24.2)
    assert run.nfev == sol.nfev + 1  # and the start's own evaluation
    np.testing.assert_allclose(run.x, [1.0, 1.0], atol=1e-10)


def test_inadmissible_steps_are_rejected() -> None:
    # the minimum (1, 1) lies outside x0 <= 0.5: every accepted point stays inside, and the
    # run ends against the constraint, better than its start
    seen: list[np.ndarray] = []

    def jac(x: np.ndarray) -> np.ndarray:
        seen.append(x.copy())
        return _rosenbrock_jac(x)

    x0 = np.array([-1.2, 1.0])
    run = levenberg_marquardt(_rosenbrock, jac, x0, "x0", admissible=lambda x: x[0] <= 0.5)
    assert seen and all(x[0] <= 0.5 for x in seen)
    assert run.x[0] <= 0.5 and run.fun < run.fun0
    assert run.x[0] > 0.3  # it moved up to the constraint, not stopped at the start


def test_bounded_runs_use_the_trust_region() -> None:
    x0 = np.array([0.2, 0.2])
    run = levenberg_marquardt(_rosenbrock, _rosenbrock_jac, x0, "x0", bounds=(0.0, 0.8))
    sol = least_squares(_rosenbrock, x0, jac=_rosenbrock_jac, method="trf", bounds=(0.0, 0.8),
                        ftol=1e-10, xtol=1e-10, gtol=1e-10, max_nfev=200)  # fmt: skip
    np.testing.assert_array_equal(run.x, sol.x)
    assert np.all((run.x >= 0.0) & (run.x <= 0.8))


def test_optimality_and_standard_errors_against_plain_linear_algebra() -> None:
    # a linear least-squares problem: J'e = 0 at the solution, and the standard errors are
    # the textbook sqrt(diag(sigma^2 (J'J)^-1))
    rng = np.random.default_rng(0)
    jac = rng.standard_normal((50, 3))
    y = jac @ [1.0, -2.0, 0.5] + 0.1 * rng.standard_normal(50)
    x = np.linalg.lstsq(jac, y, rcond=None)[0]
    e = y - jac @ x
    assert optimality(e, jac) < 1e-13  # rounding of lstsq (cond(J) ~ 2)
    assert optimality(y, jac) > 0.5  # at x = 0 the residual is nearly in J's span
    sigma2, std = standard_errors(e, jac)
    assert sigma2 == pytest.approx(float(e @ e) / 47, rel=1e-14)
    np.testing.assert_allclose(std, np.sqrt(np.diag(sigma2 * np.linalg.inv(jac.T @ jac))),
                               rtol=1e-10)  # fmt: skip


def _references() -> dict[str, ReferenceResult]:
    rng = np.random.default_rng(1)
    u = rng.standard_normal(300)
    y = signal.lfilter([0.0, 1.0, 0.5], [1.0, -1.5, 0.7], u) + 0.1 * rng.standard_normal(300)
    arx_sim = ARXCost(ARXStructure(2, 2, 1), (u, y), predictor="simulation")
    oe = structure("oe", nb=2, nf=2, nk=1)
    pitch = greybox_model("twin-rotor-pitch")
    from flexid import generate

    data = generate("twin-rotor", seed=0, n_samples=400).select(outputs=["pitch"])
    return {
        "pem": pem((u, y), oe, starts=1),
        "output_error": output_error(arx_sim, starts=2),
        "greyest": greyest(data, pitch, starts=0),
    }


def test_every_reference_returns_the_one_result_type() -> None:
    for name, res in _references().items():
        assert isinstance(res, ReferenceResult) and isinstance(res, OptimizeResult), name
        missing = [k for k in COMMON if k not in res]
        assert not missing, f"{name} lacks {missing}"
        assert res.status in STATUS and res.success == (res.status == 0), name
        assert res.local_minimum == res.success, name
        assert np.shape(res.std) == np.shape(res.x), name
        assert all(isinstance(r, ReferenceRun) for r in res.runs), name
        best = res.runs[res.best_start]
        assert best.fun == pytest.approx(res.fun, rel=1e-9), name  # the winner is the result
        assert res.nfev >= sum(r.nfev for r in res.runs) > 0, name
        assert res.nfev_equivalent >= res.nfev, name
        assert "runs" in repr(res) and "x" in repr(res), name
