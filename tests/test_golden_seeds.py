"""Golden-seed regression: every built-in optimiser gives the recorded result for a seed.

``tests/golden_seeds.json`` records, for each built-in optimiser, the best cost and the FE
count of one seeded run on a 6-D shifted Rosenbrock function.  A change to an algorithm or to
its random-number stream shows up here.  After an intended change, regenerate the file with

    python tests/test_golden_seeds.py --update

and say why in the commit message.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from flexid.optimisers import Problem, available, minimize

GOLDEN = Path(__file__).with_name("golden_seeds.json")
SHIFT = np.linspace(-0.5, 0.5, 6)
BUDGET = 3000
SEED = 11


def rosenbrock(X: np.ndarray) -> np.ndarray:
    Z = X - SHIFT + 1.0  # minimum 0 at X = SHIFT
    return np.sum(100.0 * (Z[:, 1:] - Z[:, :-1] ** 2) ** 2 + (1.0 - Z[:, :-1]) ** 2, axis=1)


def run(name: str) -> dict:
    problem = Problem(rosenbrock, np.full(6, -3.0), np.full(6, 3.0), name="rosenbrock-6")
    result = minimize(name, problem, BUDGET, seed=SEED)
    return {"fun": float(result.fun), "nfev": int(result.nfev), "nit": int(result.nit)}


def builtins() -> list[str]:
    from flexid.optimisers import registry

    return sorted(
        n for n in available() if registry.get(n).__module__.startswith("flexid.optimisers")
    )


def test_golden_file_covers_every_builtin():
    recorded = json.loads(GOLDEN.read_text())
    assert sorted(recorded) == builtins()


@pytest.mark.parametrize("name", builtins())
def test_seeded_run_matches_the_golden_record(name):
    recorded = json.loads(GOLDEN.read_text())[name]
    got = run(name)
    assert got["nfev"] == recorded["nfev"]
    assert got["nit"] == recorded["nit"]
    assert got["fun"] == pytest.approx(recorded["fun"], rel=1e-9, abs=1e-300)


if __name__ == "__main__" and "--update" in sys.argv:
    table = {name: run(name) for name in builtins()}
    GOLDEN.write_text(json.dumps(table, indent=2, sort_keys=True) + "\n")
    print(f"wrote {GOLDEN} ({len(table)} optimisers)")
