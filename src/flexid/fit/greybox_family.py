"""Grey-box models in the one model interface.

:class:`GreyBoxFamily` poses a grey-box model with
:func:`flexid.fit.greybox_estimation.build_greybox_problem` (its estimated parameters in their
bounds, on the simulation cost) and validates it simulated from its own initial state, its
poles those of the model linearised there.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..costs.greybox import record_for
from ..data.records import IOData
from ..errors import ConfigError, DataError
from ..models.families import Family
from ..models.greybox import GreyBoxModel, ParameterSet
from ..models.greybox_library import greybox_model
from ..models.specs import CostSpec, SearchSpec
from ..models.vocabulary import GREYBOX_REFERENCE_STARTS
from ..validation.diagnostics import _check_max_lag
from ..validation.portmanteau import (
    GRADIENT_STEP,
    ParameterEffect,
    estimation_records,
    estimation_root,
)
from ..validation.verdict import (
    GREYBOX_ESTIMATED_RULE,
    GREYBOX_RULE,
    ValidationReport,
    residual_report,
)
from .greybox_estimation import START_NAME, GreyBoxEstimationProblem, build_greybox_problem
from .greybox_fit import greyest

__all__ = ["GreyBoxFamily", "greybox_of"]


class GreyBoxFamily(Family):
    """Grey-box models: a plant's own equations with named, bounded parameters."""

    name = "greybox"
    structures = (GreyBoxModel,)
    models = (GreyBoxModel,)
    reads_channels = True
    runs_on = True
    start_stop = "given values"
    predictors = ("simulation",)

    def reference(self, data: Any, structure: Any, *, initial: str, starts: int | None,
                  seed: int) -> tuple[Any, float, bool]:
        res = greyest(data, structure, seed=seed,
                      starts=GREYBOX_REFERENCE_STARTS if starts is None else starts)
        return res.model, res.sse, res.local_minimum

    reference.__doc__ = None  # Family.reference's

    def start_name(self, structure: Any) -> str:
        return START_NAME

    start_name.__doc__ = None  # Family.start_name's

    def pose(
        self, data: Any, structure: Any, cost: CostSpec, search: SearchSpec, *, bounds: Any
    ) -> GreyBoxEstimationProblem:
        if isinstance(data, (list, tuple)):
            raise ConfigError(
                f"grey-box model {structure.name!r}: several estimation records are not "
                "supported; estimate on one"
            )
        return build_greybox_problem(data, structure, cost, search, bounds=bounds)

    pose.__doc__ = None  # Family.pose's

    def validate(
        self, model: Any, data: Any, *, max_lag: int, initial: str,
        split: float | int | None, dt: float | None, output: str | None,
        estimated_on: Any = None,
    ) -> ValidationReport:
        return _validate_greybox(model, data, max_lag=max_lag, split=split, dt=dt, output=output,
                                 estimated_on=estimated_on)

    validate.__doc__ = None  # Family.validate's

    def held_out(
        self, model: Any, estimation: Any, validation: Any, *, max_lag: int, initial: str
    ) -> ValidationReport:
        # run on from the record's start into the held-out part; the first output
        return self.validate(
            model, validation, max_lag=max_lag, initial=initial, split=estimation.n_samples,
            dt=None, output=model.outputs[0],
        )

    held_out.__doc__ = None  # Family.held_out's

    def held_out_stable(self, model: Any, report: ValidationReport) -> bool:
        # its linearisation at the initial state, and a finite simulation of the record
        return bool(report.stability.stable and not report.simulation_diverged)

    held_out_stable.__doc__ = None  # Family.held_out_stable's

    def model_numbers(self, model: Any, estimation: Any, records: Any) -> dict[str, Any]:
        # its simulation errors and the poles of its linearisation at the initial state
        cost = estimation.cost
        with np.errstate(all="ignore"):
            y_sim = model.simulate(model.nominal, cost.u, cost.dt)[0, :, 0]
            err = cost.y[:, 0] - y_sim
        finite = bool(np.isfinite(err).all())
        radius = float(np.max(np.abs(_linearised_poles(model, cost.dt)), initial=0.0))
        return {
            "theta": [float(v) for v in model.theta],
            "stable": bool(finite and radius < 1.0),
            "max_pole_radius": radius,
            "estimation_error_min": float(err.min()) if finite else -np.inf,
            "estimation_error_max": float(err.max()) if finite else np.inf,
        }

    model_numbers.__doc__ = None  # Family.model_numbers's


def _linearised_poles(model: Any, dt: float) -> np.ndarray:
    """Discrete poles of a grey-box model linearised at its initial state with zero input.

    Central differences of ``f`` (relative step 1e-6 of each state's scale, at least 1e-6);
    states whose derivative is identically zero there (a locked axis) are left out, since
    they hold their value rather than respond.
    """
    x0 = model.x0.astype(float)
    n = x0.size
    step = 1e-6 * np.maximum(np.abs(x0), 1.0)
    X = np.repeat(x0[None, :], 2 * n, axis=0)
    X[np.arange(n), np.arange(n)] += step
    X[n + np.arange(n), np.arange(n)] -= step
    theta = np.repeat(model.nominal[None, :], 2 * n, axis=0)
    u = np.zeros((2 * n, len(model.inputs)))
    f = np.asarray(model.derivatives(X, u, ParameterSet(model.names, theta)), dtype=float)
    J = ((f[:n] - f[n:]) / (2 * step)[:, None]).T  # J[i, j] = d f_i / d x_j
    moving = np.flatnonzero(np.any(J != 0.0, axis=1))
    return np.exp(np.linalg.eigvals(J[np.ix_(moving, moving)]) * dt)


def _validate_greybox(
    model: Any, data: Any, *, max_lag: int, split: float | int | None, dt: float | None,
    output: str | None = None, estimated_on: Any = None,
) -> ValidationReport:
    """:func:`validate` for a grey-box model: simulated from its own initial state."""
    u_full, y_all, sample_time = record_for(model, data, dt)
    if output is None:
        if y_all.shape[1] != 1:
            raise DataError(
                f"grey-box model {model.name!r} has outputs {list(model.outputs)}: give the "
                "one to validate (output=...)"
            )
        k = 0
    elif output in model.outputs:
        k = list(model.outputs).index(output)
    else:
        raise DataError(
            f"grey-box model {model.name!r} has no output {output!r} (its outputs: "
            f"{list(model.outputs)})"
        )
    y_full = y_all[:, k]
    n = y_full.size
    start = 0
    if split is not None:  # the same split as IOData.split, evaluated after run-in
        record = IOData(u_full, y_full, dt=sample_time)
        parts = record.split(split) if isinstance(split, float) else record.split(index=split)
        start = parts[0].n_samples
    n_eval = n - start
    max_lag = _check_max_lag(max_lag, n_eval, f"the evaluated part (t >= {start})")
    with np.errstate(all="ignore"):
        ysim_full = model.simulate(model.nominal, u_full, sample_time)[0, :, k]
    rule = GREYBOX_ESTIMATED_RULE if model.estimated_initial_states else GREYBOX_RULE
    return residual_report(
        y_full, None, ysim_full, u_full, start=start, dt=sample_time, max_lag=max_lag,
        names=list(model.inputs), output_name=str(model.outputs[k]), initial=rule,
        initial_one_step=rule, poles=_linearised_poles(model, sample_time), zeros=[],
        effect=_parameter_effect(model, u_full, sample_time, k, start, estimated_on),
    )


def _simulation_gradient(model: GreyBoxModel, u: np.ndarray, dt: float) -> np.ndarray:
    """``d e / d theta`` (N, n_y, n_free) of the simulation errors ``e = y - y_sim`` with
    respect to the estimated parameters: central differences, the ``2 n_free`` perturbed
    parameter sets simulated as one population."""
    theta = model.theta
    p = theta.size
    h = GRADIENT_STEP * np.maximum(np.abs(theta), 1e-3)
    free = np.repeat(theta[None, :], 2 * p, axis=0)
    free[np.arange(p), np.arange(p)] += h
    free[p + np.arange(p), np.arange(p)] -= h
    with np.errstate(all="ignore"):
        y = model.simulate(model.full(free), u, dt)
    return -np.moveaxis((y[:p] - y[p:]) / (2.0 * h[:, None, None]), 0, -1)


def _parameter_effect(
    model: GreyBoxModel, u: np.ndarray, dt: float, k: int, start: int, estimated_on: Any
) -> ParameterEffect | None:
    """How the estimate of a grey-box model's parameters enters output ``k``'s residual
    tests (:mod:`flexid.validation.portmanteau`), or None: the parameters taken as known.

    The gradient of output ``k``'s simulation error over the tested samples (``t >= start``)
    and, for a held-out record, the triangular factor of the gradient on the estimation
    record(s), every sample (the simulation cost counts them all). With several outputs the
    estimate weighs each output's errors: their gradients are stacked, each scaled by
    ``sigma_k / sigma_o`` (the estimation records' residual deviations), so that the factor
    gives the estimate's covariance in output ``k``'s noise, exact where the cost's weights
    are proportional to the noise, as for the state-space family. On the estimation record
    itself the estimate is partialled out with one output; with several the joint estimate
    is orthogonal to no single output's gradient, and the parameters are taken as known.
    The initial states a model estimates count like its other parameters (on a validation
    record of their own, where they are refitted, as if estimated with the rest). None where
    the model estimates nothing or its simulation is not finite.
    """
    records = estimation_records(estimated_on)
    if records is None or model.n_free == 0:
        return None
    n_y = len(model.outputs)
    if records == "same" and n_y > 1:
        return None
    here = _simulation_gradient(model, u, dt)[start:, k, :]
    if not np.isfinite(here).all():
        return None
    if records == "same":
        return ParameterEffect(here)
    rows = []
    for r in records:
        u_r, y_r, dt_r = record_for(model, r, None)
        g = _simulation_gradient(model, u_r, dt_r)
        if n_y > 1:
            with np.errstate(all="ignore"):
                sigma = np.std(y_r - model.simulate(model.nominal, u_r, dt_r)[0], axis=0)
            g = g * (sigma[k] / np.where(sigma > 0, sigma, 1.0))[None, :, None]
        rows.append(g.reshape(-1, g.shape[2]))
        if not np.isfinite(rows[-1]).all():
            return None
    return ParameterEffect(here, estimation_root(rows))


def greybox_of(structure: Any, greybox: str | GreyBoxModel | None) -> GreyBoxModel | None:
    """The grey-box model that ``structure`` and ``greybox`` name, or None for a polynomial.

    Parameters
    ----------
    structure : str, structure object, GreyBoxModel or None
    greybox : str, GreyBoxModel or None
        The model of ``structure="greybox"`` (a name of
        :func:`flexid.models.greybox_library.greybox_model`).

    Returns
    -------
    GreyBoxModel or None

    Raises
    ------
    ConfigError
        ``structure="greybox"`` without ``greybox``, or ``greybox`` with another structure.
    UnknownNameError
        An unknown grey-box model name.
    """
    if isinstance(structure, GreyBoxModel):
        if greybox is not None:
            raise ConfigError("give the grey-box model as structure or as greybox, not both")
        return structure
    if isinstance(structure, str) and structure.lower() == "greybox":
        if greybox is None:
            raise ConfigError(
                "structure 'greybox' needs the model: greybox='twin-rotor-pitch' (or "
                "--greybox NAME; 'flexid list greybox' lists them)"
            )
        if isinstance(greybox, GreyBoxModel):
            return greybox
        return greybox_model(greybox)
    if greybox is not None:
        raise ConfigError(
            f"greybox={greybox!r} is the model of structure='greybox', not of "
            f"structure={structure!r}"
        )
    return None
