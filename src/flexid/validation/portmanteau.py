"""The statistics of the residual tests: one portmanteau statistic and p-value per test, and
Holm's correction over a battery of tests.

A residual test asks whether the one-step residual ``e`` is correlated with lagged values of
a signal ``x`` (``e`` itself for whiteness, an input for independence, ``u^2`` or ``e u``
for the Billings-Voon tests).  Its statistic is the Lagrange-multiplier (Breusch-Godfrey)
form: regress ``e`` on the lag matrix ``Phi`` of ``x``,

``Q = e' Phi (Phi' Phi)^-1 Phi' e / sigma^2 = N R^2``,  ``sigma^2 = e'e / N``,

with ``Phi[t, i] = x(t - lag_i)`` (zero where ``t - lag_i`` is outside the record) and every
signal's mean removed.  For a white residual independent of ``x`` it is ``chi^2(m)`` with
``m`` the lags' count, whatever the colour of ``x``: the plain sum of squared correlations
(Box-Pierce) is that only for a white ``x``, and for an input of narrow band it counts the
same information many times over.  The p-value is that of the small-sample F form
``F = (Q / m) / ((N - Q) / (N - m - k - 1))`` on ``(m, N - m - k - 1)`` degrees of
freedom
(statsmodels' ``acorr_breusch_godfrey`` ``fvalue``), which holds the level better than the
chi-square form on a few hundred samples.

The model's parameters were estimated, which changes the statistic's distribution; a
:class:`ParameterEffect` says how, from the gradient ``J = de/dtheta`` of the residual:

- on the estimation record the estimate makes ``e`` orthogonal to ``J``, which shrinks the
  correlations (by about the number of parameters, shared among the tests where they act).
  ``Phi`` is then replaced by its part orthogonal to ``J`` (the Breusch-Godfrey regression
  on ``[J, Phi]``), and ``k`` is the rank of ``J``: the statistic is again ``chi^2(m')``,
  ``m'`` the rank of that part (fewer than ``m`` where a lag is itself a parameter's
  regressor, a finite impulse response's input lags, say);
- on a record held out from the estimation the estimation error ``delta`` is independent of
  the record's noise and adds ``J delta`` to the residual, which inflates the correlations
  (by about ``N_validation / N_estimation`` times the number of parameters).  Its covariance
  ``sigma^2 P``, ``P = (J_e' J_e)^-1`` from the estimation record, is added to the
  statistic's: ``Q = g' (Phi'Phi + Phi'J P J'Phi)^-1 g / sigma^2``, ``g = Phi' e``.

Both are computed from triangular factors (``J = Q R`` by Householder QR), never from the
normal equations ``J'J``: the gradient of a high-order model of a lightly damped plant is
ill-conditioned (OE(16,16,1) of the manipulator: ``cond(J)`` about ``4e9``, so ``J'J`` would
lose every digit in its weakest directions), and each direction of ``theta`` adds about
``N_validation / N_estimation`` to the statistic however weakly it is determined.

Without a :class:`ParameterEffect` the parameters are taken as known (true values).

A battery of tests is judged at a family-wise level ``alpha`` by :func:`holm`: valid for
tests of any dependence, and as powerful as Bonferroni's rule at the first rejection.

References
----------
T. S. Breusch, "Testing for autocorrelation in dynamic linear models", Australian Economic
Papers 17, 334-355, 1978; L. G. Godfrey, Econometrica 46, 1293-1301, 1978.
L. Ljung, System Identification: Theory for the User, 2nd ed., sec. 16.6, 1999.
S. Holm, "A simple sequentially rejective multiple test procedure", Scand. J. Statist. 6,
65-70, 1979.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import linalg, stats

from ..data.records import IOData
from ..errors import DataError

__all__ = [
    "GRADIENT_STEP",
    "KNOWN",
    "ParameterEffect",
    "Portmanteau",
    "describe",
    "estimation_records",
    "estimation_root",
    "holm",
    "portmanteau",
]

#: Relative step of the central differences by which the families without an analytic
#: gradient differentiate their simulated outputs (of each parameter's magnitude, at least
#: 1e-3 of it): a simulation's rounding (a few eps times the gain of a lightly damped mode,
#: about 1e-13 relative) over the step stays near 1e-7 of the derivative, the truncation
#: error (the step squared) below 1e-11.
GRADIENT_STEP = 1e-6

#: How a report words tests whose parameters were taken as known (no :class:`ParameterEffect`).
KNOWN = "the parameters taken as known"

#: Rows of the lag matrix built at a time: the Gram sums stay exact while the memory of a
#: test on a record of millions of samples stays a few megabytes.
_CHUNK = 16384

#: Relative size below which a direction of a Gram matrix counts as absent (its rank): far
#: above the rounding of sums of ``N`` products (``N eps``), far below any real excitation.
_RANK_TOL = 1e-9


@dataclass(frozen=True)
class ParameterEffect:
    """How the estimation of a model's parameters enters its residual tests.

    Attributes
    ----------
    gradient : ndarray, shape (N, p)
        ``d e / d theta``, the derivative of the one-step residual with respect to the
        parameters, over the tested samples (output units per parameter unit).
    root : ndarray, shape (p, p), or None
        When the tested record was held out from the estimation: the upper-triangular
        ``R`` of the estimation records' stacked gradient, ``J_e = Q R`` (the estimate's
        covariance is ``sigma^2 (R'R)^-1``; :func:`estimation_root` computes it).  None when
        the tested record is the estimation record.
    """

    gradient: np.ndarray
    root: np.ndarray | None = None

    @property
    def held_out(self) -> bool:
        """The tested record was not the estimation record."""
        return self.root is not None

    def describe(self) -> str:
        """The rule in words, for a report.

        Returns
        -------
        str
            E.g. ``"the estimate of 12 parameters partialled out of the tests"``.
        """
        p = self.gradient.shape[1]
        if self.held_out:
            return f"the estimation error of {p} parameters added to the tests' null"
        return f"the estimate of {p} parameters partialled out of the tests"


def estimation_records(estimated_on: Any) -> str | list | None:
    """``estimated_on`` of :func:`flexid.validate`, checked: None, ``"same"`` or a list.

    Parameters
    ----------
    estimated_on : None, "same", IOData or sequence of IOData

    Returns
    -------
    None, "same" or list of IOData

    Raises
    ------
    DataError
        A string other than ``"same"``.
    """
    if estimated_on is None:
        return None
    if isinstance(estimated_on, str):
        if estimated_on != "same":
            raise DataError(
                f"estimated_on must be 'same', a record or records, got {estimated_on!r}"
            )
        return "same"
    return [estimated_on] if isinstance(estimated_on, IOData) else list(estimated_on)


def estimation_root(gradients: Any) -> np.ndarray:
    """The triangular factor of the estimation records' gradients, for a held-out test.

    Parameters
    ----------
    gradients : sequence of ndarray, shape (N_k, p)
        ``d e / d theta`` on each estimation record.

    Returns
    -------
    ndarray, shape (p, p)
        Upper-triangular ``R`` with ``J_e = Q R``, ``J_e`` the records' gradients stacked.
    """
    stacked = np.vstack([np.asarray(j, dtype=float) for j in gradients])
    return linalg.qr(stacked, mode="r")[0][: stacked.shape[1]]


def _orthonormal_range(j: np.ndarray) -> np.ndarray:
    """An orthonormal basis of the column space of ``j`` (pivoted Householder QR; columns
    whose pivot is below ``N eps`` of the largest are dependent and left out)."""
    q, r, _ = linalg.qr(j, mode="economic", pivoting=True)
    d = np.abs(np.diag(r))
    keep = d > j.shape[0] * np.finfo(float).eps * (d[0] if d.size else 0.0)
    return q[:, keep]


def describe(effect: ParameterEffect | None) -> str:
    """How the estimated parameters entered the tests, in words.

    Parameters
    ----------
    effect : ParameterEffect or None
        The effect, or None for parameters taken as known.

    Returns
    -------
    str
        :meth:`ParameterEffect.describe`, or :data:`KNOWN`.
    """
    return KNOWN if effect is None else effect.describe()


@dataclass(frozen=True)
class Portmanteau:
    """One test's statistic.

    Attributes
    ----------
    statistic : float
        ``Q = N R^2``, approximately ``chi^2(dof)`` for a valid model.
    dof : int
        Degrees of freedom ``m'``: the rank of the tested lags' (partialled) matrix.
    p_value : float
        From the F form on ``(dof, N - dof - k - 1)`` degrees of freedom (1.0 when ``dof`` is 0).
    """

    statistic: float
    dof: int
    p_value: float


def _lag_rows(x: np.ndarray, lags: np.ndarray, rows: slice) -> np.ndarray:
    """Rows ``rows`` of the lag matrix ``Phi[t, i] = x(t - lags[i])``, zero outside."""
    t = np.arange(rows.start, rows.stop)[:, None] - lags[None, :]
    inside = (t >= 0) & (t < x.size)
    return np.where(inside, x[np.clip(t, 0, x.size - 1)], 0.0)


def _sums(
    e: np.ndarray, x: np.ndarray, lags: np.ndarray, gradient: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """``Phi'Phi``, ``Phi'e`` and ``Phi'J`` by chunks of rows, ``Phi``'s columns centred
    (``e`` and ``J`` are: their products need no correction)."""
    m = lags.size
    gram, cross, total = np.zeros((m, m)), np.zeros(m), np.zeros(m)
    pj = None if gradient is None else np.zeros((m, gradient.shape[1]))
    for start in range(0, e.size, _CHUNK):
        rows = slice(start, min(start + _CHUNK, e.size))
        phi = _lag_rows(x, lags, rows)
        gram += phi.T @ phi
        total += phi.sum(axis=0)
        cross += phi.T @ e[rows]
        if pj is not None:
            pj += phi.T @ gradient[rows]
    return gram - np.outer(total, total) / e.size, cross, pj


def _inverse_on_range(a: np.ndarray) -> tuple[np.ndarray, int]:
    """The pseudo-inverse of a symmetric positive semi-definite matrix and its rank."""
    w, v = np.linalg.eigh(a)
    keep = w > _RANK_TOL * max(float(w[-1]), 0.0) if w.size else np.zeros(0, bool)
    if not np.any(keep):
        return np.zeros_like(a), 0
    vk = v[:, keep]
    return (vk / w[keep]) @ vk.T, int(keep.sum())


def _unit(v: np.ndarray) -> np.ndarray:
    """``v`` scaled by a power of two to a peak in [0.5, 1), its mean removed: correlations
    do not depend on the scale, and a diverging residual (1e200, say) then cannot overflow
    their sums; the power of two is exact, since a rounding here would be amplified by the
    centring that follows."""
    peak = float(np.max(np.abs(v))) if v.size else 0.0
    v = np.ldexp(v, -math.frexp(peak)[1]) if peak > 0.0 else v
    return v - v.mean()


def portmanteau(
    e: Any, x: Any, lags: Any, effect: ParameterEffect | None = None
) -> Portmanteau:
    """The portmanteau statistic of a residual against the lags of a signal.

    Parameters
    ----------
    e : array_like, shape (N,)
        Residual (its mean is removed).
    x : array_like, shape (N,)
        The signal whose lags are tested (its mean is removed); ``e`` itself for a
        whiteness test.
    lags : array_like of int, shape (m,)
        Lags in samples: ``Phi[t, i] = x(t - lags[i])``.
    effect : ParameterEffect, optional
        The estimated parameters' effect (module docstring); default: parameters known.

    Returns
    -------
    Portmanteau
        Statistic, degrees of freedom and p-value.
    """
    e, x = (_unit(np.asarray(v, dtype=float)) for v in (e, x))
    lags = np.asarray(lags, dtype=int)
    n = e.size
    energy = float(e @ e)
    if energy == 0.0 or lags.size == 0:
        return Portmanteau(0.0, 0, 1.0)
    basis = None  # what the sums are taken against: the residual's gradient, orthonormal
    if effect is not None:
        gradient = np.asarray(effect.gradient, dtype=float)
        gradient = gradient - gradient.mean(axis=0)  # as e is: a shift of e is not tested
        basis = gradient if effect.held_out else _orthonormal_range(gradient)
    gram, g, pj = _sums(e, x, lags, basis)
    k = 0
    if effect is not None and not effect.held_out:
        # the part of Phi orthogonal to J: its Gram and its product with e (whose own
        # product with J the estimate has made zero, up to the search's tolerance)
        k = basis.shape[1]
        gram = gram - pj @ pj.T
        g = g - pj @ (basis.T @ e)
    elif effect is not None:
        # Phi'J P J'Phi with P = (R'R)^-1: X = Phi'J R^-1 by a triangular solve
        spread = linalg.solve_triangular(np.asarray(effect.root, dtype=float), pj.T,
                                         trans="T").T  # fmt: skip
        gram = gram + spread @ spread.T
    inv, dof = _inverse_on_range(gram)
    q = float(g @ inv @ g) / (energy / n)
    if dof == 0:
        return Portmanteau(0.0, 0, 1.0)
    den = n - dof - k - 1  # the lags, the partialled parameters, the mean
    if den <= 0:
        return Portmanteau(q, dof, float(stats.chi2.sf(q, dof)))
    r2 = min(q / n, 1.0)
    f = (r2 / dof) / max((1.0 - r2) / den, 1e-300)
    return Portmanteau(q, dof, float(stats.f.sf(f, dof, den)))


def holm(p_values: Any) -> np.ndarray:
    """Holm's step-down adjusted p-values (Holm 1979).

    A test is rejected at family-wise level ``alpha`` when its adjusted p-value is below
    ``alpha``; the probability of rejecting any true hypothesis is then at most ``alpha``,
    whatever the tests' dependence.

    Parameters
    ----------
    p_values : array_like, shape (m,)
        The tests' own p-values.

    Returns
    -------
    ndarray, shape (m,)
        Adjusted p-values in [0, 1], in the input's order.
    """
    p = np.asarray(p_values, dtype=float).reshape(-1)
    m = p.size
    order = np.argsort(p, kind="stable")
    stepped = np.maximum.accumulate((m - np.arange(m)) * p[order])
    out = np.empty(m)
    out[order] = np.minimum(stepped, 1.0)
    return out
