"""Subspace identification of a state-space model (PO-MOESP; MATLAB ``n4sid``).

:func:`n4sid` estimates a discrete state-space model with several inputs and outputs from
one record, with no iteration and no start: the order is read from singular values, and
the model is consistent under coloured output noise.  It is the start a prediction-error
refinement (MATLAB ``ssest``) begins from.

Notes
-----
The past-output MOESP scheme of Verhaegen (Verhaegen & Verdult, *Filtering and System
Identification*, 2007, sec. 9.6), in four steps:

1. **Hankel matrices** of ``s`` block rows of future inputs ``U_f`` and outputs ``Y_f`` and
   of past inputs and outputs ``Z_p = [U_p; Y_p]`` (the instrument), ``N - 2 s + 1``
   columns each.
2. **LQ factorisation** of ``[U_f; Z_p; Y_f]`` (a QR of its transpose, never a
   pseudo-inverse): the block ``L32`` is the part of ``Y_f`` the instrument explains
   orthogonally to the future inputs, and its column space is that of the extended
   observability matrix ``O_s = [C; C A; ...; C A^(s-1)]``.
3. **SVD** of ``L32``: the order ``n`` is the number of significant singular values (given,
   or at the largest gap of their logarithms); ``O_s = U_n S_n^(1/2)``, ``C`` its first
   block row and ``A`` from its shift invariance ``O_s[ny:] = O_s[:-ny] A``, by least
   squares.
4. **B, D and x0** by linear least squares on the simulation error: with ``A`` and ``C``
   fixed the output ``y(t) = C A^t x0 + sum_j C W_j(t) B[:, j] + D u(t)``,
   ``W_j(t+1) = A W_j(t) + u_j(t) I``, is linear in all three (Ljung, 2nd ed., sec. 10.6).

The noise-free response of a model of the right order is recovered exactly (up to a change
of state coordinates); the tests compare frequency responses, which do not depend on them.
SLICOT's subspace routines (IB01AD, IB01BD) would serve, but slycot (0.7) does not wrap them,
so the scheme is written here with :mod:`scipy.linalg`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import linalg

from .._validate import checked_keywords, integer
from ..errors import ConfigError, DataError, ModelOrderError
from ..models.statespace import StateSpaceModel, state_sequence

__all__ = ["SubspaceResult", "n4sid"]

# Largest order the automatic choice considers, when no order is given.
_MAX_AUTO_ORDER = 10


@dataclass
class SubspaceResult:
    """Outcome of :func:`n4sid`.

    Attributes
    ----------
    model : StateSpaceModel
        The estimate (``K = 0``: the output-error form; ``x0`` estimated).
    singular_values : ndarray, shape (s ny,)
        Of ``L32``, largest first: the order is where they drop.
    order : int
        The order used.
    order_chosen : bool
        Whether the order was read from the singular values (not given).
    block_rows : int
        ``s``, the Hankel matrices' block rows (past and future each).
    """

    model: StateSpaceModel
    singular_values: np.ndarray
    order: int
    order_chosen: bool
    block_rows: int


def _hankel(w: np.ndarray, first: int, rows: int, cols: int) -> np.ndarray:
    """Block Hankel matrix of ``rows`` block rows of the channels of ``w`` (N, m) from
    sample ``first``: block row ``r`` holds ``w[first + r : first + r + cols].T``."""
    m = w.shape[1]
    idx = first + np.arange(rows)[:, None] + np.arange(cols)[None, :]  # (rows, cols)
    return w[idx].transpose(0, 2, 1).reshape(rows * m, cols)


def _order_from_gap(sv: np.ndarray, cap: int) -> int:
    """The order at the largest drop of ``log(sv)`` among the first ``cap + 1`` values."""
    top = sv[: cap + 1]
    top = np.maximum(top, top[0] * 1e-300 if top[0] > 0 else 1e-300)
    gaps = np.log(top[:-1]) - np.log(top[1:])
    return int(np.argmax(gaps)) + 1


def _input_output_terms(
    A: np.ndarray, C: np.ndarray, u: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Regressors of ``x0`` (N, ny, n) and of ``B`` (N, ny, n nu) for the simulated output.

    One state recursion carries ``[W_1 .. W_nu, A^t]`` side by side: ``W_j(t+1) = A W_j(t)
    + u_j(t) I`` from zero and ``A^t`` from ``I``; ``C`` times them gives both.
    """
    n, N, nu = A.shape[0], u.shape[0], u.shape[1]
    eye = np.eye(n)
    forced = np.zeros((N, n, n * (nu + 1)))
    for j in range(nu):  # one block per input, every sample at once
        forced[:, :, j * n : (j + 1) * n] = u[:, j, None, None] * eye
    start = np.hstack([np.zeros((n, n * nu)), eye])
    out = C @ state_sequence(A, forced, start)  # (N, ny, n (nu + 1))
    # B's regressors in B.reshape(-1)'s order (row i, input j -> i nu + j)
    by_input = out[:, :, : n * nu].reshape(N, -1, nu, n).transpose(0, 1, 3, 2)
    return out[:, :, n * nu :], by_input.reshape(N, -1, n * nu)


@checked_keywords
def n4sid(
    data: Any,
    order: int | None = None,
    *,
    block_rows: int | None = None,
    feedthrough: bool = False,
    max_order: int = _MAX_AUTO_ORDER,
) -> SubspaceResult:
    """A state-space model from a record by subspace identification (MATLAB ``n4sid``).

    Parameters
    ----------
    data : IOData or (u, y) pair
        One record: ``u`` shape (N, nu) or (N,), ``y`` shape (N, ny) or (N,); every output
        of an :class:`~flexid.data.IOData` is used, its ``dt`` goes to the model.
    order : int, optional
        The model order ``n``; default: read from the singular values (their largest drop
        among the first ``max_order + 1``).
    block_rows : int, optional
        ``s``, block rows of the past and future Hankel matrices (default
        ``max(order, max_order) + 1``); it must exceed the order.
    feedthrough : bool, optional
        Estimate ``D`` (default False: ``D = 0``, MATLAB ``ssest``'s default).
    max_order : int, optional
        Largest order the automatic choice considers (default 10).

    Returns
    -------
    SubspaceResult

    Raises
    ------
    ConfigError
        A bad ``order``, ``block_rows`` or ``max_order``.
    ModelOrderError
        An order the record cannot support (``block_rows`` too large for ``N``, or an order
        above ``block_rows * ny - 1``).
    DataError
        Non-finite data, or ``u`` and ``y`` of different lengths.
    """
    u, y, dt, in_names, out_names = _record(data)
    N, nu = u.shape
    ny = y.shape[1]
    max_order = integer(max_order, "max_order", error=ConfigError, minimum=1)
    if order is not None:
        order = integer(order, "order", error=ConfigError, minimum=1)
    s = max(order or 0, max_order) + 1 if block_rows is None else integer(
        block_rows, "block_rows", error=ConfigError, minimum=2)  # fmt: skip
    cols = N - 2 * s + 1
    if cols < (2 * s) * (nu + ny):  # the LQ needs more columns than rows
        raise ModelOrderError(
            f"n4sid: {N} samples are too few for {s} block rows ({nu} input(s), {ny} "
            f"output(s)): need N >= {2 * s * (nu + ny) + 2 * s - 1}; give fewer block_rows "
            "or a lower order"
        )
    if order is not None and order >= s * ny:
        raise ModelOrderError(
            f"n4sid: order {order} needs more than {s} block rows ({ny} output(s)); give "
            f"block_rows >= {order // ny + 1}"
        )
    Uf = _hankel(u, s, s, cols)
    Zp = np.vstack([_hankel(u, 0, s, cols), _hankel(y, 0, s, cols)])
    Yf = _hankel(y, s, s, cols)
    # LQ of the stacked data: the transpose's QR, economic
    R = linalg.qr(np.vstack([Uf, Zp, Yf]).T, mode="r")[0][: Uf.shape[0] + Zp.shape[0] +
                                                         Yf.shape[0]].T  # fmt: skip
    a, b = Uf.shape[0], Uf.shape[0] + Zp.shape[0]
    L32 = R[b:, a:b]
    Un, sv, _ = linalg.svd(L32, full_matrices=False)
    chosen = order is None
    n = _order_from_gap(sv, min(max_order, sv.size - 1)) if chosen else order
    obs = Un[:, :n] * np.sqrt(sv[:n])
    C = obs[:ny]
    A = linalg.lstsq(obs[:-ny], obs[ny:])[0]
    free, forced = _input_output_terms(A, C, u)
    blocks = [free, forced]
    if feedthrough:
        # D[o, j] enters output o alone with regressor u_j(t)
        Dterm = np.zeros((N, ny, ny * nu))
        for o in range(ny):
            Dterm[:, o, o * nu:(o + 1) * nu] = u
        blocks.append(Dterm)
    Phi = np.concatenate(blocks, axis=2).reshape(N * ny, -1)
    theta = linalg.lstsq(Phi, y.reshape(-1))[0]
    x0 = theta[:n]
    B = theta[n : n + n * nu].reshape(n, nu)
    D = theta[n + n * nu :].reshape(ny, nu) if feedthrough else None
    model = StateSpaceModel(A, B, C, D, x0=x0, dt=dt, input_names=in_names,
                            output_names=out_names)  # fmt: skip
    return SubspaceResult(model, sv, n, chosen, s)


def _record(data: Any) -> tuple[np.ndarray, np.ndarray, float, list, list]:
    """``u`` (N, nu), ``y`` (N, ny), ``dt`` and the channel names of a record or a pair."""
    if isinstance(data, (tuple, list)) and len(data) == 2:
        u, y = (np.asarray(v, dtype=float) for v in data)
        dt, in_names, out_names = 1.0, None, None
    else:
        u, y = np.asarray(data.u, dtype=float), np.asarray(data.y, dtype=float)
        dt = float(data.dt)
        in_names, out_names = list(data.input_names), list(data.output_names)
    u = u[:, None] if u.ndim == 1 else u
    y = y[:, None] if y.ndim == 1 else y
    if u.ndim != 2 or y.ndim != 2 or u.shape[0] != y.shape[0]:
        raise DataError(f"n4sid: u and y need the same number of samples, got {u.shape} and "
                        f"{y.shape}")  # fmt: skip
    if not (np.isfinite(u).all() and np.isfinite(y).all()):
        raise DataError("n4sid: the record has non-finite values")
    if not math.isfinite(dt) or dt <= 0:
        raise DataError(f"n4sid: dt must be positive, got {dt}")
    return u, y, dt, in_names, out_names
