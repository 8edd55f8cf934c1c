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
    "initial_state_fit",
    "initial_state_fit_reference",
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


# ------------------------------------------------------------------ estimated initial state
#: Samples of the start and of the end of the record whose basis values give the tail's Gram
#: matrix, per unit of order: the basis over the first ``FREE_WINDOW * n`` samples is well
#: conditioned (measured at most 2.2 for lightly damped order-16 denominators up to radius
#: 0.999, against ~1e6 over ``n`` samples).
FREE_WINDOW = 3
#: Largest order the compiled kernel of :func:`initial_state_fit` takes (the reference path
#: runs above it).
FREE_MAXN = 24


def _basis_window(T: np.ndarray, h: np.ndarray, t0: int, width: int) -> np.ndarray:
    """``(P, n, width)`` values ``g_m(t0 + tau)`` of ``g_m = P_m / den delta``, from ``h``.

    ``h`` (P, >= t0 + width) is the impulse response of ``1 / den`` and ``T`` (P, n, n) the
    coefficients of the numerators ``P_m``: ``g_m(t) = sum_i T[m, i] h(t - i)``.
    """
    n = T.shape[1]
    hp = np.concatenate([np.zeros((h.shape[0], n)), h[:, : t0 + width]], axis=1)
    idx = n + t0 + np.arange(width)[None, :] - np.arange(n)[:, None]  # [i, tau]: h(t0+tau-i)
    return T @ hp[:, idx]


def initial_state_fit_reference(
    a: np.ndarray,
    num: np.ndarray,
    reg: np.ndarray,
    target: np.ndarray,
    basis: np.ndarray,
    energies: np.ndarray,
    *,
    want_errors: bool = True,
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """Reference path of :func:`initial_state_fit` (NumPy; the same steps and sums).

    Parameters
    ----------
    a : ndarray, shape (P, n)
    num : ndarray, shape (P, nb)
    reg : ndarray, shape (K, nb)
    target : ndarray, shape (K,)
    basis : ndarray, shape (P, n, n)
    energies : ndarray, shape (P, n)
    want_errors : bool
        As for :func:`initial_state_fit`.

    Returns
    -------
    sse : ndarray, shape (P,)
    errors : ndarray, shape (P, K), or None
    coef : ndarray, shape (P, n)
        As for :func:`initial_state_fit`.
    """
    a = np.ascontiguousarray(a, dtype=float)
    p, n = a.shape
    k = target.shape[0]
    e = target - ar_recursion_reference(a, num @ reg.T, np.zeros(n))
    width = FREE_WINDOW * n
    impulse = np.zeros((p, k + width))
    impulse[:, 0] = 1.0
    h = ar_recursion_reference(a, impulse, np.zeros(n))
    scale = 1.0 / np.sqrt(energies)
    s0 = _basis_window(basis, h, 0, width) * scale[:, :, None]
    sk = _basis_window(basis, h, k, width) * scale[:, :, None]
    # the tail's Gram matrix Q Q^T, Q = sk s0^+ (the state map over k steps, normalised)
    qt = _cholesky_solve(s0 @ s0.transpose(0, 2, 1), s0 @ sk.transpose(0, 2, 1))
    gram = np.eye(n) - qt.transpose(0, 2, 1) @ qt
    # right-hand side: sum_t g_m(t) e(t) = sum_i T[m, i] w(i), w the anti-causal 1/den of e
    w = ar_recursion_reference(a, np.ascontiguousarray(e[:, ::-1]), np.zeros(n))[:, ::-1]
    rhs = np.einsum("pmi,pi->pm", basis, w[:, :n]) * scale
    coef = _cholesky_solve(gram, rhs[:, :, None])[:, :, 0] * scale
    forcing = np.zeros((p, k))
    forcing[:, : min(n, k)] = np.einsum("pmi,pm->pi", basis, coef)[:, :k]
    e = e - ar_recursion_reference(a, forcing, np.zeros(n))
    return np.einsum("pk,pk->p", e, e), (e if want_errors else None), coef


def _cholesky_solve(G: np.ndarray, R: np.ndarray) -> np.ndarray:
    """``G^-1 R`` for a stack of symmetric positive definite ``G`` (P, n, n), ``R`` (P, n, m).

    Rows whose factorisation fails come back as NaN (the caller falls back).
    """
    out = np.full(R.shape, np.nan)
    try:
        L = np.linalg.cholesky(G)
        ok = np.ones(G.shape[0], dtype=bool)
    except np.linalg.LinAlgError:
        L = np.zeros_like(G)
        ok = np.zeros(G.shape[0], dtype=bool)
        for i in range(G.shape[0]):
            try:
                L[i] = np.linalg.cholesky(G[i])
                ok[i] = True
            except np.linalg.LinAlgError:
                pass
    if ok.any():
        Lo = L[ok]
        z = np.linalg.solve(Lo, R[ok])
        out[ok] = np.linalg.solve(Lo.transpose(0, 2, 1), z)
    return out


def initial_state_fit(
    a: np.ndarray,
    num: np.ndarray,
    reg: np.ndarray,
    target: np.ndarray,
    basis: np.ndarray,
    energies: np.ndarray,
    *,
    want_errors: bool = True,
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """Errors of ``1/den`` filters with the initial state fitted by least squares.

    For each candidate, ``y = (1/den) f`` from rest with ``f(t) = sum_j num_j reg[t, j]``,
    the error ``e = target - y``, and the least-squares fit of the free responses of
    ``1/den`` to ``e`` (MATLAB ``compare``'s estimated initial state).  The free responses
    are spanned by the impulse responses ``g_m`` of ``P_m(q)/den(q)``, ``basis`` holding
    the ``P_m`` (:func:`flexid.costs.polynomial.orthogonal_numerators`): orthogonal over
    ``t >= 0`` with energies ``energies``.  So the fit needs no ``n`` recursions:

    * the Gram matrix over the record is ``diag(E) - G_tail``, the tail after ``K`` from the
      basis values over windows of ``FREE_WINDOW n`` samples at ``0`` and at ``K`` (the state
      map over ``K`` steps ``Q = S_K S_0^+`` in the basis normalised to unit energy,
      ``G_tail = Q Q^T``), from the impulse response ``h`` of ``1/den``;
    * the right-hand side ``sum_t g_m(t) e(t) = sum_i P_m[i] w(i)``, ``w`` the anti-causal
      recursion of ``1/den`` over ``e`` (one recursion backwards in time);
    * a Cholesky solve of the normalised system (condition near 1: the basis is nearly
      orthonormal over the record), and the fitted free response removed from ``e`` by one
      more recursion, so that the sum of squares is that of the errors themselves.

    Four recursions in all, whatever ``n``, where fitting ``n`` free responses computed one
    by one takes ``n + 1`` and a Gram matrix of ``n^2 K`` products.

    Parameters
    ----------
    a : ndarray, shape (P, n)
        ``a_1 .. a_n`` of each candidate's monic ``den``, stable.
    num : ndarray, shape (P, nb)
    reg : ndarray, shape (K, nb)
        The input regressors of every sample (shared by all candidates).
    target : ndarray, shape (K,)
        In output units.
    basis : ndarray, shape (P, n, n)
    energies : ndarray, shape (P, n)
        Finite and positive.
    want_errors : bool
        Return the errors too (the ``(P, K)`` array), not only their sums of squares.

    Returns
    -------
    sse : ndarray, shape (P,)
        Sums of squared errors, output units squared; NaN where the small solve failed
        (solve those rows another way).
    errors : ndarray, shape (P, K), or None
        In output units.
    coef : ndarray, shape (P, n)
        The fitted combination of the ``g_m``.
    """
    a = np.ascontiguousarray(a, dtype=float)
    n = a.shape[1]
    if BACKEND == "c" and hasattr(_c, "free_fit") and 1 <= n <= FREE_MAXN and \
            num.shape[1] <= _ARX_MAXNB:  # fmt: skip
        p, k = a.shape[0], target.shape[0]
        sse = np.empty(p)
        errors = np.empty((p, k)) if want_errors else None
        coef = np.empty((p, n))
        work = p * k * (4 * n + num.shape[1])
        _c.free_fit(a, _rows(num), np.ascontiguousarray(reg, dtype=float),
                    np.ascontiguousarray(target, dtype=float),
                    np.ascontiguousarray(basis, dtype=float),
                    np.ascontiguousarray(energies, dtype=float), FREE_WINDOW * n,
                    errors, sse, coef, _threads_for(work))  # fmt: skip
        return sse, errors, coef
    return initial_state_fit_reference(
        a, num, reg, target, basis, energies, want_errors=want_errors
    )
