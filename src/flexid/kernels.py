"""Inner loops of the batched ARX costs: compiled when available, NumPy/SciPy otherwise.

flexid ships a small optional C extension, ``flexid._kernels``, built when the package is
installed on a machine with a C compiler.  It runs the Schur-Cohn stability test and the
autoregressive recursion of a whole population in compiled loops, several candidates per
SIMD register.  Without it (or with ``FLEXID_KERNELS=numpy`` in the environment) the same
functions run the NumPy/SciPy reference path, which the tests compare against the compiled
one.

Environment variable ``FLEXID_KERNELS``:

``auto`` (default)
    the compiled kernels when they were built, the reference path otherwise;
``numpy``
    always the reference path;
``c``
    the compiled kernels, and :class:`~flexid.errors.FlexidError` at import if they were
    not built (for CI and benchmarks that must not fall back silently).

Environment variable ``FLEXID_THREADS``: how many threads the compiled recursions split a
population between (a positive integer; default: the cores this process may run on,
``os.sched_getaffinity``).  :func:`set_threads` changes it at run time; the worker processes
of ``compare --workers`` set it to 1 (they already share the cores).  A thread takes whole
blocks of 4 candidates and computes them exactly as one thread would, so the results do not
depend on the thread count.
"""

from __future__ import annotations

import os

import numpy as np
from scipy import signal

from .errors import FlexidError

__all__ = [
    "BACKEND",
    "ar_recursion",
    "ar_recursion_reference",
    "arx_fit",
    "arx_recursion",
    "compiled_available",
    "schur_cohn_compiled",
    "set_threads",
    "threads",
]

try:  # pragma: no cover - depends on the build
    from . import _kernels as _c
except ImportError:  # pragma: no cover - depends on the build
    _c = None

_CHOICE = os.environ.get("FLEXID_KERNELS", "auto").strip().lower() or "auto"
if _CHOICE not in ("auto", "numpy", "c"):
    raise FlexidError(
        f"FLEXID_KERNELS must be 'auto', 'numpy' or 'c', got {os.environ['FLEXID_KERNELS']!r}"
    )
if _CHOICE == "c" and _c is None:
    raise FlexidError(
        "FLEXID_KERNELS=c but the compiled kernels flexid._kernels were not built "
        "(reinstall flexid on a machine with a C compiler)"
    )

#: ``"c"`` when the compiled kernels run, ``"numpy"`` for the reference path.
BACKEND: str = "c" if (_c is not None and _CHOICE != "numpy") else "numpy"

#: Multiply-adds below which a recursion runs on one thread: starting a helper thread costs
#: some 10-50 microseconds, the time of about 1e5-1e6 of them.
_THREAD_MIN_WORK = 1 << 20
#: Largest ``nb`` whose input part the compiled kernel computes itself (``AR_MAXNB``).
_ARX_MAXNB = 64


def _cores() -> int:
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def _threads_from_env() -> int:
    text = os.environ.get("FLEXID_THREADS", "").strip()
    if not text:
        return _cores()
    try:
        n = int(text)
    except ValueError:
        n = 0
    if n < 1:
        raise FlexidError(f"FLEXID_THREADS must be a positive integer, got {text!r}")
    return n


_THREADS = _threads_from_env()


def threads() -> int:
    """Threads the compiled recursions split a population between (see the module).

    Returns
    -------
    int
    """
    return _THREADS


def set_threads(n: int | None) -> int:
    """Set the thread count of the compiled recursions; ``None``: the cores available.

    Parameters
    ----------
    n : int or None
        A positive integer, or None for the default (``os.sched_getaffinity``).

    Returns
    -------
    int
        The previous setting.
    """
    global _THREADS
    if n is not None and (isinstance(n, bool) or not isinstance(n, int) or n < 1):
        raise FlexidError(f"the thread count must be a positive integer, got {n!r}")
    old, _THREADS = _THREADS, (_cores() if n is None else n)
    return old


def _threads_for(work: int) -> int:
    """Threads worth starting for ``work`` multiply-adds."""
    return max(1, min(_THREADS, work // _THREAD_MIN_WORK + 1))


def compiled_available() -> bool:
    """True when the optional compiled kernels were built (whatever ``BACKEND`` says).

    Returns
    -------
    bool
        Whether ``flexid._kernels`` imports.
    """
    return _c is not None


def schur_cohn_compiled(a: np.ndarray) -> np.ndarray:
    """Compiled Schur-Cohn stability test (no checks; see :func:`flexid.stability.is_stable`).

    Parameters
    ----------
    a : ndarray, shape (P, n), float64
        ``a_1 .. a_n`` of monic denominators.

    Returns
    -------
    ndarray of bool, shape (P,)
    """
    a = _rows(a)  # column blocks of a population array need no copy
    out = np.empty(a.shape[0], dtype=np.uint8)
    _c.schur_cohn(a, out)
    return out.view(bool)


def ar_recursion_reference(a: np.ndarray, forced: np.ndarray, state: np.ndarray) -> np.ndarray:
    """Reference path of :func:`ar_recursion`: one ``scipy.signal.lfilter`` per candidate.

    The initial state enters as an extra input on the first ``na`` samples (what
    ``scipy.signal.lfiltic`` would compute, for every row at once), which is cheaper than
    passing ``zi``.

    Parameters
    ----------
    a : ndarray, shape (P, na)
        Denominator coefficients ``a1..a_na`` of every candidate.
    forced : ndarray, shape (P, K)
        The input part ``f(t) = B(q) u(t)`` of every candidate.
    state : ndarray, shape (na,) or (P, na)
        ``[y(-1), ..., y(-na)]`` before the first sample (shared or per candidate).

    Returns
    -------
    ndarray, shape (P, K)
        The simulated outputs.
    """
    p, na = a.shape
    out = np.array(forced, dtype=float)
    if na == 0:
        return out
    state = np.broadcast_to(np.asarray(state, float), (p, na))
    den = np.hstack([np.ones((p, 1)), a])
    # transposed direct form II state for b = [1] and past outputs s:
    # zi[i] = -sum_{j >= 1} a_{i+j} s_j
    zi = np.zeros((p, na))
    for i in range(na):
        zi[:, i] = -np.einsum("pj,pj->p", a[:, i:], state[:, : na - i])
    out[:, : min(na, out.shape[1])] += zi[:, : out.shape[1]]
    one = np.ones(1)
    for i in range(p):
        out[i] = signal.lfilter(one, den[i], out[i])
    return out


def ar_recursion(
    a: np.ndarray,
    forced: np.ndarray,
    state: np.ndarray,
    target: np.ndarray | None = None,
    *,
    want_output: bool = True,
) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Run ``y(t) = f(t) - sum_i a_i y(t - i)`` for every candidate of a population.

    Parameters
    ----------
    a : ndarray, shape (P, na)
        ``a_1 .. a_na`` of each candidate.  Callers pass stable candidates only: an
        unstable recursion overflows.
    forced : ndarray, shape (P, K)
        The input part ``f(t) = B(q) u(t)`` of each candidate.
    state : ndarray, shape (na,) or (P, na)
        ``[y(-1), ..., y(-na)]`` before the first sample (shared or per candidate).
    target : ndarray, shape (K,), optional
        When given, the sum over ``t`` of ``(target(t) - y(t))^2`` is returned too.
    want_output : bool
        Return the simulated outputs (``False`` saves the ``(P, K)`` array when only the
        sums of squares are needed).

    Returns
    -------
    y : ndarray, shape (P, K), or None
        Simulated outputs (None when ``want_output`` is False).
    sse : ndarray, shape (P,), or None
        Sums of squared errors against ``target`` (None without ``target``).
    """
    a = np.ascontiguousarray(a, dtype=float)
    forced = np.ascontiguousarray(forced, dtype=float)
    p = a.shape[0]
    k = forced.shape[1]
    state = np.ascontiguousarray(state, dtype=float)
    if BACKEND == "c":
        y = np.empty((p, k)) if want_output else None
        sse = np.empty(p) if target is not None else None
        tgt = None if target is None else np.ascontiguousarray(target, dtype=float)
        _c.ar_run(a, forced, state, tgt, y, sse, _threads_for(p * k * (a.shape[1] + 1)))
        return y, sse
    y = ar_recursion_reference(a, forced, state)
    sse = None
    if target is not None:
        e = np.asarray(target, dtype=float) - y
        sse = np.einsum("ij,ij->i", e, e)
    return (y if want_output else None), sse


def _rows(x: np.ndarray) -> np.ndarray:
    """``x`` as float64 (P, n) whose rows are contiguous (a copy only when they are not)."""
    x = np.asarray(x, dtype=float)
    if x.ndim == 2 and (x.shape[1] <= 1 or x.strides[1] == 8) and x.strides[0] >= 0:
        return x
    return np.ascontiguousarray(x)


def arx_recursion(
    a: np.ndarray,
    b: np.ndarray,
    reg: np.ndarray,
    state: np.ndarray,
    target: np.ndarray | None = None,
    *,
    want_output: bool = True,
) -> tuple[np.ndarray | None, np.ndarray | None]:
    """:func:`ar_recursion` with the input part ``f(t) = sum_j b_j reg[t, j]`` of each row.

    The compiled kernel computes ``f`` itself, a few steps ahead of the recursion, so that
    the ``(P, K)`` array of forced terms is never formed; the reference path forms it with one
    matrix product (``b @ reg.T``) and runs :func:`ar_recursion_reference`.  The two round
    ``f`` differently (an ``nb``-term sum in another order), which
    ``tests/route_bounds.py`` bounds.

    Parameters
    ----------
    a : ndarray, shape (P, na)
    b : ndarray, shape (P, nb)
    reg : ndarray, shape (K, nb)
        The input regressors of every step, shared by all candidates.
    state, target, want_output
        As for :func:`ar_recursion`.

    Returns
    -------
    y : ndarray, shape (P, K), or None
    sse : ndarray, shape (P,), or None
    """
    reg = np.ascontiguousarray(reg, dtype=float)
    if BACKEND != "c" or b.shape[1] > _ARX_MAXNB:
        return ar_recursion(a, np.asarray(b, float) @ reg.T, state, target,
                            want_output=want_output)  # fmt: skip
    # the kernel takes rows of contiguous values at any (positive) stride: column blocks of a
    # population array need no copy
    a = _rows(a)
    b = _rows(b)
    p, k = a.shape[0], reg.shape[0]
    state = np.ascontiguousarray(state, dtype=float)
    y = np.empty((p, k)) if want_output else None
    sse = np.empty(p) if target is not None else None
    tgt = None if target is None else np.ascontiguousarray(target, dtype=float)
    work = p * k * (a.shape[1] + b.shape[1] + 1)
    _c.arx_run(a, b, reg, state, tgt, y, sse, _threads_for(work))
    return y, sse


def arx_fit(
    a: np.ndarray, reg: np.ndarray, state0: np.ndarray, target: np.ndarray, offset: int
) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares numerators of the simulation cost, compiled (variable projection).

    For each denominator ``a[p]``, the ``b`` minimising ``sum_t (target(t) - y(offset +
    t))^2`` with ``y = g_0 + sum_j b_j g_j``: ``g_0`` the free response from ``state0``,
    ``g_j`` the response to ``reg[:, j - 1]`` from rest.  The ``nb + 1`` recursions (each
    summed as :func:`ar_recursion` sums), the normal equations of the column-scaled
    regressors, a Cholesky solve and one step of iterative refinement run in one pass of the
    compiled kernel, without the ``(P, nb + 1, T)`` array of regressors.  Compiled kernels
    only (``BACKEND == "c"``), ``1 <= na, nb <= 16``.

    Parameters
    ----------
    a : ndarray, shape (P, na)
    reg : ndarray, shape (T, nb)
        The input regressors of every step.
    state0 : ndarray, shape (na,)
        ``[y(-1), ..., y(-na)]`` of the free response.
    target : ndarray, shape (T - offset,)
    offset : int

    Returns
    -------
    b : ndarray, shape (P, nb)
    ok : ndarray of bool, shape (P,)
        False where the factorisation broke down or ``b`` is not finite (solve those rows
        another way).
    """
    a = _rows(a)
    reg = np.ascontiguousarray(reg, dtype=float)
    p, nb = a.shape[0], reg.shape[1]
    b = np.empty((p, nb))
    ok = np.empty(p, dtype=np.uint8)
    work = p * reg.shape[0] * (nb + 1) * (a.shape[1] + nb)
    _c.arx_fit(a, reg, np.ascontiguousarray(state0, dtype=float),
               np.ascontiguousarray(target, dtype=float), int(offset), b, ok,
               _threads_for(work))  # fmt: skip
    return b, ok.view(bool)
