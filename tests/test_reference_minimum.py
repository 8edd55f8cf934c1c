"""The polynomial reference ends at a minimum, also where the SSE falls towards the cap.

A Levenberg-Marquardt run that rejects steps outside the stable set stops on the cap short
of the minimum along it; the reference then continues with the capped roots held on the cap
(:func:`flexid.fit.reference.along_the_cap`).  Each case checks the reference against LM
restarts from its end (as it is, and with its poles pulled inside), accepted only when their
end is stable: none may be lower by more than 0.1 %.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy import signal
from scipy.optimize import least_squares

from flexid.errors import DataError
from flexid.fit.prediction_error import pem, prediction_jacobian
from flexid.models.polynomial import PolynomialModel, structure
from flexid.models.stability import is_stable, pull_inside
from flexid.validation import validate

REAL = Path(__file__).resolve().parents[2] / "shared" / "data" / "real"
# a restart's stable end lower than the reference by more than this fraction fails the case
AT_MINIMUM = 1e-3
# the radii the restarts pull the reference's poles in to: a hair inside the circle, and
# down to the 0.99 of the reference's own restarts (a check, not a copy: these run plain LM
# without refitting B)
PULLED_TO = (0.9999, 0.999, 0.998, 0.995, 0.99)


def _restart(s, theta0, u, y, initial: str) -> float:
    """SSE at the end of plain LM from ``theta0``; inf when that end is not stable.

    A step to an unstable predictor gets a residual far above any stable point's, so LM
    rejects it (the prediction errors of an unstable predictor are refused).
    """
    k = y.size - s.start
    fsl = s.slices()["f"][0]

    def errors(x):
        try:
            return prediction_jacobian(s, x, u, y, initial)
        except DataError:
            return np.full(k, 1e6), np.zeros((k, x.size))

    sol = least_squares(lambda x: errors(x)[0], theta0, jac=lambda x: errors(x)[1],
                        method="lm", x_scale="jac", ftol=1e-12, xtol=1e-12, gtol=1e-12,
                        max_nfev=5000)  # fmt: skip
    if not is_stable(sol.x[fsl])[0]:
        return np.inf
    return float(sol.fun @ sol.fun)


def _lowest_restart(res, s, u, y, initial: str) -> float:
    fsl = s.slices()["f"][0]
    theta = res.theta
    found = [_restart(s, theta, u, y, initial)]
    for r in PULLED_TO:
        pulled = theta.copy()
        pulled[fsl] = pull_inside(theta[fsl], r)
        found.append(_restart(s, pulled, u, y, initial))
    return min(found)


def _check_at_minimum(u, y, s, initial: str):
    res = pem((u, y), s, initial=initial)
    lowest = _lowest_restart(res, s, u, y, initial)
    assert res.stable
    assert res.sse <= lowest * (1.0 + AT_MINIMUM), (res.sse, lowest, res.message)
    # a reference on the cap says so, and why
    assert res.local_minimum or (res.on_cap and res.status == 2 and res.cap_reason)
    return res


def _generated(n: int, seed: int, w0: float):
    """OE(4,4,1) plant with a pole pair at radius 0.9985, a sinusoidal output disturbance
    (which an output-error model can only follow with an undamped mode) and noise."""
    rng = np.random.default_rng(seed)
    poles = np.array([0.9985 * np.exp(0.3j), 0.9 * np.exp(1.8j)])
    f = np.real(np.poly(np.concatenate([poles, poles.conj()])))
    b = np.array([0.0, 0.1, -0.05, 0.02, 0.01])
    u = rng.standard_normal(n)
    y = signal.lfilter(b, f, u) + np.sin(w0 * np.arange(n)) + 0.02 * rng.standard_normal(n)
    return u, y


@pytest.mark.parametrize(
    ("n", "seed", "w0", "initial"),
    # without the continuation along the cap the reference stops on the circle 19 % and
    # 1.0 % above the restarts' lowest stable end on these two records
    [(400, 3, 1.3, "estimate"), (1000, 2, 1.0, "measured")],
)
def test_generated_reference_at_minimum(n, seed, w0, initial):
    u, y = _generated(n, seed, w0)
    res = _check_at_minimum(u, y, structure("oe", nb=6, nf=6, nk=1), initial)
    assert res.on_cap and res.max_radius > 1.0 - 1e-6


@pytest.mark.parametrize("initial", ["measured", "estimate"])
@pytest.mark.parametrize(("file", "orders"), [("robot_arm.csv", (8, 8, 1)),
                                              ("dryer.csv", (6, 6, 3))])  # fmt: skip
def test_real_record_reference_at_minimum(file, orders, initial):
    # without the restarts on the cap: the robot arm's reference 2.1 % (measured) and 1.8 %
    # (estimate) above the restarts' lowest stable end, the dryer's 5.0 % and 0.02 %
    if not (REAL / file).exists():
        pytest.skip(f"no record {REAL / file}")
    record = np.genfromtxt(REAL / file, delimiter=",", names=True)
    n = 2 * record.size // 3 + 1  # the first two thirds, as the suite's split
    u, y = record["u"][:n], record["y"][:n]
    nb, nf, nk = orders
    _check_at_minimum(u, y, structure("oe", nb=nb, nf=nf, nk=nk), initial)


def test_undamped_mode_is_not_called_stable():
    s = structure("oe", nb=2, nf=4, nk=1)
    pair = (1.0 - 1e-9) * np.exp(0.5j)
    f = np.real(np.poly([pair, pair.conjugate(), 0.5, -0.3]))[1:]
    model = PolynomialModel(s, np.concatenate([[0.5, 0.2], f]))
    assert model.is_stable  # strictly inside, by a hair
    summary = model.summary()
    assert "MARGINALLY STABLE: an undamped mode (pole radius 1.000000)" in summary
    assert "stable, largest pole radius" not in summary
    rng = np.random.default_rng(0)
    u = rng.standard_normal(300)
    y = model.simulate(u) + 0.01 * rng.standard_normal(300)
    report = validate(model, (u, y)).summary()
    block = report.split("Stability", 1)[1].splitlines()[1]
    assert block.strip() == "MARGINALLY STABLE: an undamped mode (pole radius 1.00000)"
    assert all(len(line) < 100 for line in summary.splitlines() + report.splitlines())
