"""The input delay of a record: MATLAB's ``delayest``, and the prewhitened cross-correlation.

``method="arx"`` (MATLAB ``delayest``)
    For each delay ``nk`` in a range, ARX(``na``, ``nb``, ``nk``) is fitted by least squares
    and its loss (the mean squared one-step error) computed over the *same* samples for
    every ``nk`` (from the largest ``start``); the delay is the one of the smallest loss.
    With several inputs each input's delay is estimated in turn from a model of all inputs,
    the others at the delays found so far (inputs in order, from ``nk_min``; up to three
    passes, until no delay changes).
    Where ARX(2, 2) cannot describe the plant its losses can rank a long delay first (the
    DaISy flutter record: 14 samples, where its response starts at once).
``method="correlation"`` (Box and Jenkins' prewhitening)
    The input is whitened by its own AR(``p``) model (least squares), the output filtered by
    the same filter, and the delay is the first lag ``>= nk_min`` whose cross-correlation
    lies outside the 99 % band ``+-2.58/sqrt(N)``: the first sample of the impulse response
    the record can tell from zero.  It needs no model of the plant.

On the DaISy dryer both give 3 samples, on the robot arm 0; on flutter 14 (``"arx"``) and
0 (``"correlation"``).  :func:`flexid.select` tries the delays of both.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import signal

from .._validate import checked_keywords, integer
from ..data.records import IOData
from ..errors import ConfigError, DataError, UnknownNameError
from ..models.arx import ARXStructure

__all__ = ["DELAY_METHODS", "DelayEstimate", "estimate_delay"]

#: The delay estimators (see the module docstring).
DELAY_METHODS = {
    "arx": "MATLAB delayest: the smallest one-step loss of ARX(na, nb, nk)",
    "correlation": "the first lag of the prewhitened cross-correlation outside its 99 % band",
}
_BAND_99 = 2.576  # two-sided 99 % quantile of the standard normal
_WHITENING_ORDER = 10


class _UnknownDelayMethod(UnknownNameError, ConfigError):
    pass


@dataclass(frozen=True)
class DelayEstimate:
    """The delays found and the losses they were chosen by.

    Attributes
    ----------
    nk : tuple of int
        The delay of each input in samples.
    scores : tuple of ndarray
        Per input, one value per candidate delay ``nk_min .. nk_max``: the loss (mean
        squared one-step error, output units squared) for ``"arx"``, the cross-correlation
        in units of its 99 % band for ``"correlation"``.
    nk_range : tuple of int
        ``(nk_min, nk_max)``.
    method : str
        ``"arx"`` or ``"correlation"``.
    """

    nk: tuple[int, ...]
    scores: tuple[np.ndarray, ...]
    nk_range: tuple[int, int]
    method: str = "arx"

    def describe(self) -> str:
        """One line: the delays and how they were found.

        Returns
        -------
        str
        """
        lo, hi = self.nk_range
        values = ", ".join(str(k) for k in self.nk)
        return f"nk = {values} ({DELAY_METHODS[self.method]}, over nk = {lo} .. {hi})"


@checked_keywords
def estimate_delay(
    data: IOData,
    *,
    method: str = "arx",
    na: int = 2,
    nb: int = 2,
    nk_min: int = 0,
    nk_max: int | None = None,
) -> DelayEstimate:
    """Estimate the input delay of a single-output record.

    Parameters
    ----------
    data : IOData
        The record (use the estimation part; detrend it first where it has offsets).
    method : {"arx", "correlation"}, optional
        MATLAB ``delayest`` (default) or the prewhitened cross-correlation (module docstring).
    na, nb : int, optional
        Orders of the ARX models compared by ``"arx"`` (MATLAB's defaults, 2 and 2).
    nk_min : int, optional
        Smallest delay tried (default 0).
    nk_max : int, optional
        Largest delay tried (default ``nk_min + 20``, as MATLAB).

    Returns
    -------
    DelayEstimate

    Raises
    ------
    DataError
        A record with several outputs, or too short for the largest delay.
    ConfigError
        Orders or a range out of bounds.
    """
    if method not in DELAY_METHODS:
        raise _UnknownDelayMethod("delay estimation method", str(method), tuple(DELAY_METHODS))
    if not isinstance(data, IOData):
        raise DataError(f"estimate_delay takes an IOData, got {type(data).__name__}")
    if data.n_outputs != 1:
        raise DataError(f"estimate_delay takes a single-output record, got {data.n_outputs} "
                        "outputs; select one first")  # fmt: skip
    na = integer(na, "na", error=ConfigError, minimum=0)
    nb = integer(nb, "nb", error=ConfigError, minimum=1)
    nk_min = integer(nk_min, "nk_min", error=ConfigError, minimum=0)
    nk_max = nk_min + 20 if nk_max is None else integer(
        nk_max, "nk_max", error=ConfigError, minimum=nk_min
    )
    u, y = data.u, data.y[:, 0]
    n_u = u.shape[1]
    first = max(na, nk_max + nb - 1)
    if y.size - first < 4 * (na + n_u * nb):
        raise DataError(
            f"a record of {y.size} samples is too short to compare delays up to {nk_max} with "
            f"ARX({na}, {nb}): it leaves {y.size - first} samples"
        )
    if method == "correlation":
        return _by_correlation(u, y, nk_min, nk_max)
    nk = [nk_min] * n_u
    losses: list[np.ndarray] = [np.empty(0)] * n_u
    candidates = np.arange(nk_min, nk_max + 1)
    for _ in range(3 if n_u > 1 else 1):  # passes until no input's delay changes
        before = list(nk)
        for j in range(n_u):
            losses[j] = _arx_losses(u, y, na, nb, nk, j, candidates, first)
            nk[j] = int(candidates[int(np.argmin(losses[j]))])
        if nk == before:
            break
    return DelayEstimate(nk=tuple(nk), scores=tuple(losses), nk_range=(nk_min, nk_max))


def _arx_losses(
    u: np.ndarray, y: np.ndarray, na: int, nb: int, nk: list[int], j: int,
    candidates: np.ndarray, first: int,
) -> np.ndarray:
    """The one-step loss of each candidate delay of input ``j``, the others at ``nk``."""
    n_u = u.shape[1]
    loss = np.empty(candidates.size)
    for i, k in enumerate(candidates):
        trial = list(nk)
        trial[j] = int(k)
        phi, target = ARXStructure(na, [nb] * n_u, trial).regressors(u, y)
        skip = phi.shape[0] - (y.size - first)  # the same samples for every delay
        phi, target = phi[skip:], target[skip:]
        theta, *_ = np.linalg.lstsq(phi, target, rcond=None)
        e = target - phi @ theta
        loss[i] = float(e @ e) / e.size
    return loss


def _by_correlation(u: np.ndarray, y: np.ndarray, nk_min: int, nk_max: int) -> DelayEstimate:
    p = _WHITENING_ORDER
    nk, scores = [], []
    lags = np.arange(nk_min, nk_max + 1)
    for j in range(u.shape[1]):
        x = u[:, j]
        past = np.column_stack([x[p - i - 1 : x.size - i - 1] for i in range(p)])
        a = np.linalg.lstsq(past, x[p:], rcond=None)[0]
        whitening = np.concatenate([[1.0], -a])
        uw = signal.lfilter(whitening, [1.0], x)[p:]
        yw = signal.lfilter(whitening, [1.0], y)[p:]
        n = uw.size
        su, sy = np.std(uw), np.std(yw)
        if su == 0 or sy == 0:
            raise DataError(f"input {j} or the output is constant: no delay to estimate")
        uw, yw = uw - uw.mean(), yw - yw.mean()
        r = np.array([uw[: n - k] @ yw[k:] for k in lags]) / (n * su * sy)
        score = np.abs(r) / (_BAND_99 / np.sqrt(n))
        outside = np.flatnonzero(score > 1.0)
        nk.append(int(lags[outside[0]]) if outside.size else nk_min)
        scores.append(score)
    return DelayEstimate(nk=tuple(nk), scores=tuple(scores), nk_range=(nk_min, nk_max),
                         method="correlation")  # fmt: skip
