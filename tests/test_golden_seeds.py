"""Golden-seed regression: every built-in optimiser gives the recorded run for a seed.

The file guards against unintended changes of an algorithm or of its random-number stream,
not against BLAS, LAPACK or the CPU's SIMD kernels.  So it records, for each built-in
optimiser, two things that do not depend on the last bits of a floating-point result:

* **trace**: the first :data:`TRACE_BATCHES` populations it asks for on a 6-D shifted
  Rosenbrock function, fingerprinted by (sum of |x|, sum of x^2, best cost)
  per batch.  These are a few arithmetic operations away from the shared initial population:
  rounding differences between BLAS kernels and FMA enter at about ``n eps = 1e-15`` of the
  values and have no iterations to grow in, except through a finite-difference gradient
  (step ``h = 1e-8`` of the value, gain ``1/h``).  :data:`TRACE_RTOL` = 1e-6 is that worst case
  (``1e-15 / 1e-8 = 1e-7``) with a factor 10 to spare, and still catches any change of an
  algorithm's arithmetic or random stream (which moves these numbers by 1e-3 or more).
* **staircase**: the whole :data:`BUDGET`-FE run on ``floor(16 * rosenbrock)``, an
  integer-valued objective.  Every comparison an optimiser makes is then between exact
  integers, so rounding cannot change a decision and the FE count, iteration count and best
  cost are compared exactly.  Only optimisers whose decisions break ties by a stable rule
  are held to this (all of flexid's own); scipy's Nelder-Mead and Powell order points with
  numpy's default sort, whose order of equal keys depends on the CPU's SIMD sort kernel.

A new built-in optimiser gets its entry with

    python tests/test_golden_seeds.py --add

which records the optimisers that have none and leaves every other entry as it is.  After an
intended change of an algorithm, rewrite its entry (and only its) with

    python tests/test_golden_seeds.py --update NAME [NAME ...]

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
TRACE_BATCHES = 12
TRACE_RTOL = 1e-6
# scipy adapters: their tie order is numpy's (CPU-dependent) default sort; see the docstring
NO_STAIRCASE = {"nelder-mead", "powell", "scipy", "l-bfgs-b"}


def rosenbrock(X: np.ndarray) -> np.ndarray:
    Z = X - SHIFT + 1.0  # minimum 0 at X = SHIFT
    return np.sum(100.0 * (Z[:, 1:] - Z[:, :-1] ** 2) ** 2 + (1.0 - Z[:, :-1]) ** 2, axis=1)


def staircase(X: np.ndarray) -> np.ndarray:
    return np.floor(16.0 * rosenbrock(X))


def _box(objective) -> Problem:
    return Problem(objective, np.full(6, -3.0), np.full(6, 3.0), name="rosenbrock-6")


def run(name: str) -> dict:
    trace: list[list[float]] = []

    def traced(X: np.ndarray) -> np.ndarray:
        F = rosenbrock(X)
        trace.append([float(np.abs(X).sum()), float((X * X).sum()), float(F.min())])
        if len(trace) == TRACE_BATCHES:
            raise _Enough
        return F

    try:
        minimize(name, _box(traced), BUDGET, seed=SEED)
    except _Enough:
        pass
    record: dict = {"trace": trace}
    if name not in NO_STAIRCASE:
        result = minimize(name, _box(staircase), BUDGET, seed=SEED)
        record["staircase"] = {
            "fun": float(result.fun),
            "nfev": int(result.nfev),
            "nit": int(result.nit),
        }
    return record


class _Enough(Exception):
    """Stops a traced run after its first batches."""


def builtins() -> list[str]:
    """flexid's own algorithms (the adapters' numbers belong to their libraries' versions)."""
    from flexid.optimisers import registry

    return sorted(
        n
        for n in available()
        if registry.get(n).__module__.startswith("flexid.optimisers")
        and registry.get(n).__module__ != "flexid.optimisers.external"
    )


def test_golden_file_covers_every_builtin():
    recorded = json.loads(GOLDEN.read_text())
    assert sorted(recorded) == builtins()


@pytest.mark.numerics
@pytest.mark.parametrize("name", builtins())
def test_seeded_run_matches_the_golden_record(name):
    recorded = json.loads(GOLDEN.read_text())[name]
    got = run(name)
    assert len(got["trace"]) == len(recorded["trace"])
    np.testing.assert_allclose(got["trace"], recorded["trace"], rtol=TRACE_RTOL, atol=0)
    assert got.get("staircase") == recorded.get("staircase")


def record(argv: list[str]) -> str:
    """``--add``: record the built-ins without an entry; ``--update NAME ...``: those names.

    Every other entry is written back as it was read.
    """
    table = json.loads(GOLDEN.read_text()) if GOLDEN.exists() else {}
    if argv[:1] == ["--add"] and len(argv) == 1:
        names = [n for n in builtins() if n not in table]
    elif argv[:1] == ["--update"] and len(argv) > 1:
        names = argv[1:]
        unknown = sorted(set(names) - set(builtins()))
        if unknown:
            raise SystemExit(f"not built-in optimisers: {', '.join(unknown)}")
    else:
        raise SystemExit("usage: test_golden_seeds.py --add | --update NAME [NAME ...]")
    table.update({name: run(name) for name in names})
    GOLDEN.write_text(json.dumps(table, indent=2, sort_keys=True) + "\n")
    return f"wrote {GOLDEN}: {', '.join(names) or 'nothing new'}"


if __name__ == "__main__":
    print(record(sys.argv[1:]))


def test_add_records_the_missing_entries_and_rewrites_no_other(tmp_path, monkeypatch):
    table = json.loads(GOLDEN.read_text())
    table.pop("random-search")
    table["pso"] = {"trace": [[0.0, 0.0, 0.0]], "marker": "left as it was"}
    copy = tmp_path / "golden.json"
    copy.write_text(json.dumps(table))
    monkeypatch.setattr(sys.modules[__name__], "GOLDEN", copy)
    assert record(["--add"]).endswith(": random-search")
    after = json.loads(copy.read_text())
    assert after["pso"]["marker"] == "left as it was"
    assert after["random-search"]["trace"]  # recorded afresh
    assert set(after) == set(json.loads(GOLDEN.read_text()))
    with pytest.raises(SystemExit, match="not built-in optimisers: nope"):
        record(["--update", "nope"])
