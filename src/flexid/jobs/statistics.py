"""Statistics of optimiser comparisons: summaries, FE to target, rank-sum tests with Holm.

Everything here works on plain run records (dicts, as stored by :mod:`flexid.jobs.store`), so a
report can be rebuilt from a store file alone.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from scipy import stats

from ..validation.portmanteau import holm

__all__ = [
    "best_at",
    "convergence_band",
    "fe_to_target",
    "headline",
    "holm",
    "rank_sum_against_best",
    "summarise",
]


def best_at(history: Mapping[str, Sequence], fe: np.ndarray) -> np.ndarray:
    """Best cost after ``fe`` evaluations from a stored history (step function).

    Parameters
    ----------
    history : mapping
        ``{"fe": [...], "best": [...]}`` with non-decreasing ``fe``.
    fe : ndarray
        Evaluation counts.

    Returns
    -------
    ndarray
        Best cost so far at each ``fe`` (``inf`` before the first evaluation; the last value
        after the run's end).
    """
    h_fe = np.asarray(history["fe"], dtype=float)
    h_best = np.asarray(history["best"], dtype=float)
    idx = np.searchsorted(h_fe, np.asarray(fe, dtype=float), side="right") - 1
    padded = np.concatenate([[np.inf], h_best])
    return padded[idx + 1]


def fe_to_target(history: Mapping[str, Sequence], target: float) -> float:
    """FE after which the best cost is ``<= target`` (``nan`` if never reached).

    Parameters
    ----------
    history : mapping
        A run's history with sequences ``fe`` and ``best``.
    target : float
        Target cost.

    Returns
    -------
    float
        The FE count, or ``nan``.
    """
    best = np.asarray(history["best"], dtype=float)
    hits = np.flatnonzero(best <= target)
    return float(history["fe"][hits[0]]) if hits.size else float("nan")


def rank_sum_against_best(costs: Mapping[str, Sequence[float]]) -> dict[str, dict[str, Any]]:
    """Two-sided Mann-Whitney rank-sum test of every optimiser against the best one.

    The best optimiser is the one with the lowest median final cost.  p-values are
    Holm-corrected over the comparisons made.  Labels with fewer than two finite runs are
    left out of the tests.

    Parameters
    ----------
    costs : mapping of str to sequence of float
        Final costs of the runs, per optimiser label.

    Returns
    -------
    dict
        ``label -> {"best": bool, "p": raw p, "p_holm": adjusted p, "significant": bool}``
        (significant at 5 % after correction).
    """
    usable = {k: np.asarray(v, float) for k, v in costs.items() if np.isfinite(v).sum() >= 2}
    out: dict[str, dict[str, Any]] = {
        k: {"best": False, "p": math.nan, "p_holm": math.nan, "significant": False} for k in costs
    }
    if not usable:
        return out
    best = min(usable, key=lambda k: (np.median(usable[k]), k))
    out[best]["best"] = True
    others = [k for k in usable if k != best]
    raw = []
    for k in others:
        a, b = usable[best], usable[k]
        if np.array_equal(np.sort(a), np.sort(b)):
            raw.append(1.0)
        else:
            raw.append(float(stats.mannwhitneyu(a, b, alternative="two-sided").pvalue))
    for k, p, q in zip(others, raw, holm(raw)):
        out[k].update(p=p, p_holm=float(q), significant=bool(q < 0.05))
    return out


def summarise(
    records: Sequence[Mapping[str, Any]],
    reference: float,
    targets: Sequence[float],
) -> dict[str, Any]:
    """Summary statistics of one optimiser's runs.

    Parameters
    ----------
    records : sequence of mapping
        Run records with ``status``, ``cost``, ``history``, ``nfev``, ``wall_time`` and the
        validation numbers.
    reference : float
        Reference cost (the least-squares optimum when it is stable).
    targets : sequence of float
        Relative tolerances: target cost ``reference * (1 + t)``.

    Returns
    -------
    dict
        Run counts (``runs``, ``ok``, ``failed``, ``errors``); over the finished runs the final
        cost's ``median``, ``q25``, ``q75``, ``iqr``, ``best``, ``worst``, the median FE and
        wall time (s), the share of stable models; ``reach``, per tolerance the target cost,
        success rate and FE to reach it; the medians of the fits (%) and error bounds, and
        the correlation-test pass rate, the median share of frequencies inside the record's
        band (``frequency_share``, NaN where no run has one).
    """
    ok = [r for r in records if r["status"] == "ok"]
    failed = [r for r in records if r["status"] != "ok"]
    costs = np.array([r["cost"] for r in ok], dtype=float)
    out: dict[str, Any] = {"runs": len(records), "ok": len(ok), "failed": len(failed)}
    if failed:
        out["errors"] = sorted({r.get("error") or "?" for r in failed})
    if not ok:
        return out
    q25, q50, q75 = np.percentile(costs, [25, 50, 75])
    out.update(
        median=float(q50),
        q25=float(q25),
        q75=float(q75),
        iqr=float(q75 - q25),
        best=float(costs.min()),
        worst=float(costs.max()),
        median_fe=float(np.median([r["nfev"] for r in ok])),
        median_time=float(np.median([r["wall_time"] for r in ok])),
        stable_rate=float(np.mean([bool(r.get("stable")) for r in ok])),
    )
    out["reach"] = _reach(ok, reference, targets)
    out.update(_validation_medians(ok))
    return out


def _reach(ok: list[Mapping[str, Any]], reference: float, targets: Sequence[float]) -> dict:
    """Per target ``reference * (1 + t)``: the share of runs that reach it, their median FE
    and every run's FE (inf where a run never does)."""
    reach = {}
    for t in targets:
        fe = np.array([fe_to_target(r["history"], reference * (1 + t)) for r in ok])
        hit = np.isfinite(fe)
        reach[str(t)] = {
            "target": reference * (1 + t),
            "success": float(hit.mean()),
            "median_fe": float(np.median(fe[hit])) if hit.any() else math.nan,
            "fe": fe.tolist(),
        }
    return reach


def headline(validation: Mapping[str, Any]) -> dict[str, Any]:
    """A run's held-out numbers as a comparison's headline tables show them.

    With several outputs the weakest output's: the lowest fits and share inside the
    frequency band over the outputs (a model is as good as its worst sensor), no error range
    (the outputs' units differ), and the joint verdict over every output's tests; with one
    output the numbers as stored.

    Parameters
    ----------
    validation : mapping
        A run's stored ``validation`` record (``fit_one_step``, ``fit_simulation``,
        ``error_min``, ``error_max``, ``correlation_passed``, ``frequency_share``, and
        ``outputs``: each output's numbers, with several).

    Returns
    -------
    dict
        The same keys.
    """
    outputs = list((validation.get("outputs") or {}).values())
    if len(outputs) < 2:
        return dict(validation)
    shares = [o["frequency_share"] for o in outputs if o.get("frequency_share") is not None]
    return {
        **validation,
        "fit_one_step": min(float(o["fit_one_step"]) for o in outputs),
        "fit_simulation": min(float(o["fit_simulation"]) for o in outputs),
        "error_min": math.nan,
        "error_max": math.nan,
        "frequency_share": min(shares) if shares else None,
    }


def _validation_medians(ok: list[Mapping[str, Any]]) -> dict[str, float]:
    """Medians of the runs' validation figures (NaN where no run has one; None, a model
    without a frequency verdict, counts as none) and the share of runs whose correlation
    tests pass."""
    out = {}
    numbers = [headline(r.get("validation", {})) for r in ok]
    for key in ("fit_one_step", "fit_simulation", "error_min", "error_max", "frequency_share"):
        values = np.array([_number(v.get(key)) for v in numbers], dtype=float)
        out[key] = float(np.nanmedian(values)) if np.isfinite(values).any() else math.nan
    passes = [v.get("correlation_passed") for v in numbers]
    passes = [p for p in passes if p is not None]
    out["correlation_pass_rate"] = float(np.mean(passes)) if passes else math.nan
    return out


def _number(value: Any) -> float:
    return math.nan if value is None else float(value)


def convergence_band(
    histories: Sequence[Mapping[str, Sequence]],
    max_fe: int,
    points: int = 200,
    *,
    log: bool = False,
) -> dict[str, np.ndarray]:
    """Median and quartiles of best cost against FE over runs, on a common FE grid.

    Parameters
    ----------
    histories : sequence of mapping
        Run histories with sequences ``fe`` and ``best``.
    max_fe : int
        End of the FE grid.
    points : int
        Number of grid points (fewer where rounding to whole FE merges them).
    log : bool
        Space the grid logarithmically (for a log FE axis) instead of linearly.

    Returns
    -------
    dict of str to ndarray
        ``{"fe", "q25", "median", "q75"}``, arrays on the FE grid (from the first
        evaluation to ``max_fe``); NaN everywhere when there are no histories.
    """
    spaced = np.geomspace if log else np.linspace
    grid = np.unique(spaced(1, max(max_fe, 1), points).round())
    if not histories:
        nan = np.full(grid.size, np.nan)
        return {"fe": grid, "q25": nan, "median": nan, "q75": nan}
    curves = np.array([best_at(h, grid) for h in histories])
    curves = np.where(np.isinf(curves), np.nan, curves)
    q25, q50, q75 = np.full((3, grid.size), np.nan)
    seen = np.isfinite(curves).any(axis=0)
    if seen.any():
        q25[seen], q50[seen], q75[seen] = np.nanpercentile(curves[:, seen], [25, 50, 75], axis=0)
    return {"fe": grid, "q25": q25, "median": q50, "q75": q75}
