"""Inner loops of the batched ARX costs: compiled when available, NumPy/SciPy otherwise.

flexid ships a small optional C extension, ``flexid._kernels``, built when the package is
installed on a machine with a C compiler.  It runs the Schur-Cohn stability test and the
autoregressive recursion of a whole population in compiled loops, several candidates per
SIMD register.  Without it (or with ``FLEXID_KERNELS=numpy`` in the environment) the same
functions run the NumPy/SciPy reference path, which the tests compare against the compiled
one.  The extension is built from the C files beside this module (``src/flexid/kernels``,
one job each: ``docs/architecture.md`` lists them); they are not needed at run time.

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

The compiled least-squares fits (:func:`arx_fit`, :func:`arx_fit_shifted`,
:func:`initial_state_fit`, :func:`flagged_fit`) run with subnormal numbers flushed to zero
(x86-64's FTZ and DAZ, set for each block and restored after it): the impulse and free
responses of a fast denominator decay through the subnormal range, where every operation
costs some hundred cycles.  Only values below 2.3e-308 in magnitude change; the plain
recursions of the costs (:func:`ar_recursion`, :func:`arx_recursion`) keep IEEE arithmetic.
"""

from __future__ import annotations

import os

import numpy as np
from scipy import signal

from ..errors import FlexidError, plain_number

__all__ = [
    "BACKEND",
    "ar_recursion",
    "ar_recursion_reference",
    "arx_fit",
    "arx_fit_shifted",
    "arx_fit_shifted_reference",
    "arx_recursion",
    "compiled_available",
    "flagged_fit",
    "flagged_fit_compiled",
    "free_fit_compiled",
    "initial_state_fit",
    "initial_state_fit_reference",
    "modal_fit",
    "modal_normal",
    "modal_regressors",
    "modal_regressors_reference",
    "modal_residual",
    "poly_mul_compiled",
    "schur_cohn_compiled",
    "set_threads",
    "shifted_columns",
    "threads",
]

try:  # pragma: no cover - depends on the build
    from .. import _kernels as _c
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
#: Largest ``kappa(Gs) T eps`` :func:`arx_fit_shifted` accepts (``Gs`` the column-scaled
#: Gram matrix of the regressors, ``T`` samples): to first order the relative error of its
#: ``b`` (the normal equations, solved once), so rows above it are flagged for the refined
#: route.  At 1e-2 every row of the benchmark (kappa(F) ~ 5e3: about 1e-5) passes.
FIT_SHIFTED_TOL = 1e-2


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
        raise FlexidError(f"the thread count must be a positive integer, got {plain_number(n)}")
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
    """Compiled Schur-Cohn stability test (no checks; see
    :func:`flexid.models.stability.is_stable`).

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


def poly_mul_compiled(p: np.ndarray, q: np.ndarray) -> np.ndarray | None:
    """Compiled row-wise polynomial products, or None where they do not apply.

    The products of :func:`flexid.costs.polynomial.poly_mul_rows` in one call (a NumPy
    route forms one array per coefficient of the shorter factor, some microseconds each):
    the same sums in the same order, each product rounded before it is added, so on x86-64
    the same numbers bit for bit.

    Parameters
    ----------
    p : ndarray, shape (P, a)
    q : ndarray, shape (P, b)
        Coefficients in powers of ``q^-1``, one polynomial per row, ``a, b >= 1``.

    Returns
    -------
    ndarray, shape (P, a + b - 1), or None
        None when the compiled kernels are not in use or the arguments are not two float64
        populations of the same size.
    """
    if (BACKEND != "c" or not hasattr(_c, "poly_mul") or p.ndim != 2 or q.ndim != 2
            or p.shape[0] != q.shape[0] or min(p.shape[1], q.shape[1]) < 1
            or p.dtype != np.float64 or q.dtype != np.float64):  # fmt: skip
        return None
    out = np.empty((p.shape[0], p.shape[1] + q.shape[1] - 1))
    _c.poly_mul(_rows(p), _rows(q), out)
    return out


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


def modal_regressors_reference(
    poles: np.ndarray, u: np.ndarray, m: int, feedthrough: bool, free_response: bool
) -> np.ndarray:
    """Reference path of :func:`modal_regressors`: one ``scipy.signal.lfilter`` per candidate,
    pole group and input.

    Parameters
    ----------
    poles : ndarray, shape (P, 2 m + r)
    u : ndarray, shape (N, nu)
    m : int
    feedthrough, free_response : bool
        As :func:`modal_regressors`.

    Returns
    -------
    ndarray, shape (P, N, k)
    """
    P, width = poles.shape
    r = width - 2 * m
    N, nu = u.shape
    k = nu * (2 * m + r) + (nu if feedthrough else 0) + (2 * m + r if free_response else 0)
    phi = np.zeros((P, N, k))
    zeros = np.zeros(N)
    for q in range(P):
        col = 0
        for g in range(m):
            den = [1.0, poles[q, 2 * g], poles[q, 2 * g + 1]]
            for j in range(nu):
                x = signal.lfilter([1.0], den, u[:, j])
                phi[q, 1:, col], phi[q, 2:, col + 1] = x[:-1], x[:-2]
                col += 2
        for g in range(r):
            for j in range(nu):
                phi[q, 1:, col] = signal.lfilter([1.0], [1.0, -poles[q, 2 * m + g]], u[:, j])[:-1]
                col += 1
        if feedthrough:
            phi[q, :, col : col + nu] = u
            col += nu
        if not free_response:
            continue
        for g in range(m):
            den = [1.0, poles[q, 2 * g], poles[q, 2 * g + 1]]
            for past in ([1.0, 0.0], [0.0, 1.0]):  # [x(-1), x(-2)]
                zi = signal.lfiltic([1.0], den, past)
                phi[q, 0, col] = past[0]
                phi[q, 1:, col] = signal.lfilter([1.0], den, zeros, zi=zi)[0][:-1]
                col += 1
        for g in range(r):
            phi[q, :, col] = poles[q, 2 * m + g] ** np.arange(N)
            col += 1
    return phi


def modal_regressors(
    poles: np.ndarray, u: np.ndarray, m: int, feedthrough: bool, free_response: bool
) -> np.ndarray:
    """The regressors of the modal state-space cost for every candidate of a population.

    Parameters
    ----------
    poles : ndarray, shape (P, 2 m + r)
        Each candidate's ``a1, a2`` of its ``m`` modes, then its ``r`` real poles.
    u : ndarray, shape (N, nu)
        The inputs.
    m : int
        Modes.
    feedthrough : bool
        Add the inputs themselves as columns.
    free_response : bool
        Add a basis of each pole group's free response.

    Returns
    -------
    ndarray, shape (P, N, k)
        Per candidate: each mode's and input's ``x(t - 1), x(t - 2)`` of ``x(t) = u_j(t) - a1
        x(t - 1) - a2 x(t - 2)`` from rest, each real pole's and input's ``x(t - 1)`` of
        ``x(t) = u_j(t) + p x(t - 1)``; then the inputs (``feedthrough``); then (with
        ``free_response``) each mode's ``x(t - 1)`` of the input-free recursion from
        ``[x(-1), x(-2)] = e1`` and ``e2``, and each real pole's ``p^t``.  ``k = nu (2 m + r)
        + nu + (2 m + r)`` with both options.
    """
    poles = np.ascontiguousarray(poles, dtype=float)
    u = np.ascontiguousarray(u, dtype=float)
    if BACKEND != "c":
        return modal_regressors_reference(poles, u, m, feedthrough, free_response)
    P, width = poles.shape
    N, nu = u.shape
    k = nu * width + (nu if feedthrough else 0) + (width if free_response else 0)
    phi = np.empty((P, N, k))
    _c.modal_regressors(poles, u, phi, m, bool(feedthrough), bool(free_response),
                        _threads_for(P * N * k))  # fmt: skip
    return phi


def modal_normal(
    poles: np.ndarray, u: np.ndarray, target: np.ndarray, m: int, feedthrough: bool,
    free_response: bool,
) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """The normal equations of every candidate's regressors (:func:`modal_regressors`).

    Parameters
    ----------
    poles, u, m, feedthrough, free_response
        As :func:`modal_regressors`.
    target : ndarray, shape (N, ny)

    Returns
    -------
    gram : ndarray, shape (P, k, k)
        ``phi' phi`` of each candidate.
    rhs : ndarray, shape (P, k, ny)
        ``phi' target``.
    """
    poles = np.ascontiguousarray(poles, dtype=float)
    u = np.ascontiguousarray(u, dtype=float)
    target = np.ascontiguousarray(target, dtype=float)
    if BACKEND != "c":
        phi = modal_regressors_reference(poles, u, m, feedthrough, free_response)
        return np.swapaxes(phi, 1, 2) @ phi, np.swapaxes(phi, 1, 2) @ target
    P, width = poles.shape
    N, nu = u.shape
    k = nu * width + (nu if feedthrough else 0) + (width if free_response else 0)
    gram, rhs = np.empty((P, k, k)), np.empty((P, k, target.shape[1]))
    _c.modal_normal(poles, u, target, gram, rhs, m, bool(feedthrough), bool(free_response),
                    _threads_for(P * N * k * k))  # fmt: skip
    return gram, rhs


def modal_fit(
    poles: np.ndarray, u: np.ndarray, target: np.ndarray, m: int, feedthrough: bool,
    estimate: bool, *, ridge: float, rounding: float, tolerance: float,
) -> tuple[np.ndarray, ...]:  # fmt: skip
    """Every candidate's fit from its normal equations, compiled (the C route of the NumPy
    steps of :meth:`flexid.costs.modal.ModalCost.fit`; ``BACKEND == "c"`` only).

    Parameters
    ----------
    poles, u, m, feedthrough
        As :func:`modal_regressors`.
    target : ndarray, shape (N, ny)
    estimate : bool
        Fit the shared initial state (the regressors then hold the free responses).
    ridge : float
        Added to the unit diagonal of each scaled least-squares problem.
    rounding, tolerance : float
        The sum of squares is read from the normal equations where ``rounding (|y_o| +
        sum_i |c_i| sqrt(gram_ii))^2``, summed over the outputs, is at most ``tolerance`` of
        it, and is NaN elsewhere.

    Returns
    -------
    gram : ndarray, shape (P, k, k)
    rhs : ndarray, shape (P, k, ny)
        The normal equations (:func:`modal_normal`).
    fitted : ndarray, shape (P, k, ny)
        The least-squares coefficients.
    used : ndarray, shape (P, k, ny)
        The realised model's: the gains, and the free responses of its initial state.
    x0 : ndarray, shape (P, nu (2 m + r))
        Its initial state (zeros without ``estimate``).
    sse : ndarray, shape (P,)
        Its sum of squared errors, or NaN.
    ok : ndarray of bool, shape (P,)
        False where a Cholesky factor met a non-positive pivot (that row's other outputs are
        then not set).
    """
    if BACKEND != "c":
        raise RuntimeError("modal_fit is the compiled route; the NumPy one is ModalCost's")
    poles = np.ascontiguousarray(poles, dtype=float)
    u = np.ascontiguousarray(u, dtype=float)
    target = np.ascontiguousarray(target, dtype=float)
    P, width = poles.shape
    N, nu = u.shape
    ny = target.shape[1]
    k = nu * width + (nu if feedthrough else 0) + (width if estimate else 0)
    gram, rhs = np.empty((P, k, k)), np.empty((P, k, ny))
    fitted, used = np.empty((P, k, ny)), np.empty((P, k, ny))
    x0, sse, ok = np.empty((P, nu * width)), np.empty(P), np.empty(P, dtype=np.uint8)
    yy = np.einsum("no,no->o", target, target)
    _c.modal_fit(poles, u, target, yy, gram, rhs, fitted, used, x0, sse, ok, m,
                 bool(feedthrough), bool(estimate), float(ridge), float(rounding),
                 float(tolerance), _threads_for(P * N * k * k))  # fmt: skip
    return gram, rhs, fitted, used, x0, sse, ok.astype(bool)


def modal_residual(
    poles: np.ndarray, u: np.ndarray, target: np.ndarray, coef: np.ndarray, m: int,
    feedthrough: bool, free_response: bool, *, want_residual: bool = True,
) -> tuple[np.ndarray | None, np.ndarray]:  # fmt: skip
    """Every candidate's errors ``target - phi coef`` and their sums of squares.

    Parameters
    ----------
    poles, u, m, feedthrough, free_response
        As :func:`modal_regressors`.
    target : ndarray, shape (N, ny)
    coef : ndarray, shape (P, k, ny)
    want_residual : bool, optional
        Return the errors (False: their sums of squares only, without the ``(P, N, ny)``
        array).

    Returns
    -------
    residual : ndarray, shape (P, N, ny), or None
    sse : ndarray, shape (P,)
    """
    poles = np.ascontiguousarray(poles, dtype=float)
    u = np.ascontiguousarray(u, dtype=float)
    target = np.ascontiguousarray(target, dtype=float)
    coef = np.ascontiguousarray(coef, dtype=float)
    if BACKEND != "c":
        phi = modal_regressors_reference(poles, u, m, feedthrough, free_response)
        e = target - phi @ coef
        return (e if want_residual else None), np.einsum("pnq,pnq->p", e, e)
    P = poles.shape[0]
    N, ny = target.shape
    residual = np.empty((P, N, ny)) if want_residual else None
    sse = np.empty(P)
    _c.modal_residual(poles, u, target, coef, residual, sse, m, bool(feedthrough),
                      bool(free_response), _threads_for(P * N * coef.shape[1] * ny))  # fmt: skip
    return residual, sse


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
    first: int = 0,
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
    state, want_output
        As for :func:`ar_recursion`.
    target : ndarray, shape (K - first,), optional
        When given, the sum over ``t >= first`` of ``(target(t - first) - y(t))^2`` is
        returned too.
    first : int
        The first sample the sums of squares count: a recursion from rest at ``t = 0`` whose
        first ``first`` samples are a transient that does not count (``0 <= first <= K``).

    Returns
    -------
    y : ndarray, shape (P, K), or None
    sse : ndarray, shape (P,), or None
    """
    reg = np.ascontiguousarray(reg, dtype=float)
    if BACKEND != "c" or b.shape[1] > _ARX_MAXNB:
        forced = np.asarray(b, float) @ reg.T
        if not first:
            return ar_recursion(a, forced, state, target, want_output=want_output)
        y, _ = ar_recursion(a, forced, state)
        sse = None
        if target is not None:
            e = np.asarray(target, dtype=float) - y[:, first:]
            sse = np.einsum("ij,ij->i", e, e)
        return (y if want_output else None), sse
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
    _c.arx_run(a, b, reg, state, tgt, y, sse, _threads_for(work), int(first))
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
#: Sums of squares only: where the fit of the initial state leaves at least this fraction of
#: the error from rest's ``|e|^2``, the compiled kernel takes the sum of squares as ``|e|^2 -
#: c.r`` (the normal equations' identity) instead of running the fitted free response.  The
#: identity assumes the Gram matrix of the rounded basis, so it is off by the basis's
#: non-orthogonality times ``|e|^2 - sse``: at one half at most that non-orthogonality
#: relative to the sum of squares (``tests/route_bounds.py``, ``free_cancel_bound``), where
#: the explicit sum is second order in it.  Below it the errors are run and summed.
FREE_CANCEL = 0.5


def _basis_window(T: np.ndarray, h: np.ndarray, t0: int, width: int) -> np.ndarray:
    """``(P, n, width)`` values ``g_m(t0 + tau)`` of ``g_m = P_m / den delta``, from ``h``.

    ``h`` (P, >= t0 + width) is the impulse response of ``1 / den`` and ``T`` (P, n, n) the
    coefficients of the numerators ``P_m``: ``g_m(t) = sum_i T[m, i] h(t - i)``.
    """
    n = T.shape[1]
    hp = np.concatenate([np.zeros((h.shape[0], n)), h[:, : t0 + width]], axis=1)
    idx = n + t0 + np.arange(width)[None, :] - np.arange(n)[:, None]  # [i, tau]: h(t0+tau-i)
    return T @ hp[:, idx]


def free_fit_compiled(n: int, nb: int) -> bool:
    """Whether :func:`initial_state_fit` runs the compiled kernel for these sizes.

    The compiled kernel computes the basis and energies itself when not given; the
    reference path needs them.

    Parameters
    ----------
    n : int
        Order of the denominators.
    nb : int
        Terms of the input part.

    Returns
    -------
    bool
    """
    return (BACKEND == "c" and hasattr(_c, "free_fit") and 1 <= n <= FREE_MAXN
            and nb <= _ARX_MAXNB)  # fmt: skip


def initial_state_fit_reference(
    a: np.ndarray,
    num: np.ndarray,
    reg: np.ndarray,
    target: np.ndarray,
    basis: np.ndarray,
    energies: np.ndarray,
    *,
    want_errors: bool = True,
    first: np.ndarray | None = None,
    noise: np.ndarray | None = None,
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
    first : ndarray, shape (P, n), optional
    noise : ndarray, shape (P, 4), optional
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
    if first is None:
        e = target - ar_recursion_reference(a, num @ reg.T, np.zeros(n))
    else:
        v = target - ar_recursion_reference(np.asarray(first, dtype=float), num @ reg.T,
                                            np.zeros(n))  # fmt: skip
        forced = v.copy()
        forced[:, 1:] += noise[:, 2:3] * v[:, :-1]
        forced[:, 2:] += noise[:, 3:4] * v[:, :-2]
        e = ar_recursion_reference(np.ascontiguousarray(noise[:, :2]), forced, np.zeros(2))
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
    basis: np.ndarray | None = None,
    energies: np.ndarray | None = None,
    *,
    want_errors: bool = True,
    first: np.ndarray | None = None,
    noise: np.ndarray | None = None,
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
      more recursion, so that the sum of squares is that of the errors themselves.  With
      ``want_errors`` False the compiled kernel skips that recursion where the fit leaves at
      least :data:`FREE_CANCEL` of ``|e|^2``: the sum of squares is then ``|e|^2 - c.r``
      (``c`` the coefficients, ``r`` the right-hand side), whose cancellation is small.

    Four recursions in all (three for most sums of squares), whatever ``n``, where fitting
    ``n`` free responses computed one by one takes ``n + 1`` and a Gram matrix of ``n^2 K``
    products.  Without ``basis`` and ``energies`` the compiled kernel computes them from the
    step-down of each ``den`` itself (the same operations as
    :func:`~flexid.costs.polynomial.orthogonal_numerators`, rounded alike on x86-64), and a
    row whose step-down breaks down gets a NaN sum of squares.

    With ``first`` and ``noise`` the error from rest is a cascade instead: ``e = (D/C)
    (target - f/F)``, ``F = 1 + first_1 q^-1 + ...`` and ``D/C`` of order two at most, for
    ``den = C F``.  That is the one-step error of Box-Jenkins, ``D/C (y - B/F u)``, in
    fewer multiply-adds than its single filter ``(D F y - D B u)/(C F)`` (the inputs only
    through ``B``, ``y`` once); the two errors from rest differ by a free response of
    ``1/den``, so the fitted errors are the same.

    The compiled kernel takes the rows in blocks of four in the order of a short decay probe
    (the first ``4 n`` samples of each impulse response), slowest first: a block forms the
    tail after the record, or runs the whole impulse response, when any of its rows needs
    it, so alike rows together save that work, and the costliest blocks start first on the
    threads.  The probe fixes which rows share a block, so the results depend neither on the
    order of the rows nor on the thread count.

    Parameters
    ----------
    a : ndarray, shape (P, n)
        ``a_1 .. a_n`` of each candidate's monic ``den``, stable.
    num : ndarray, shape (P, nb)
    reg : ndarray, shape (K, nb)
        The input regressors of every sample (shared by all candidates).
    target : ndarray, shape (K,)
        In output units.
    basis : ndarray, shape (P, n, n), optional
    energies : ndarray, shape (P, n), optional
        Finite and positive.  Both None (the default): computed by the compiled kernel from
        ``a``, which needs :func:`free_fit_compiled` true (the reference path needs them).
    want_errors : bool
        Return the errors too (the ``(P, K)`` array), not only their sums of squares.
    first : ndarray, shape (P, n), optional
        ``F`` of the cascade, ``f_1 ..`` padded with zeros to ``n`` (stable).
    noise : ndarray, shape (P, 4), optional
        ``c_1, c_2, d_1, d_2`` of the cascade's ``D/C`` (zeros past their orders; ``C``
        minimum phase).  Both or neither.

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
    if (first is None) != (noise is None):
        raise FlexidError("initial_state_fit: give both first and noise, or neither")
    if first is not None:
        first = np.ascontiguousarray(first, dtype=float)
        noise = np.ascontiguousarray(noise, dtype=float)
    if free_fit_compiled(n, num.shape[1]):
        p, k = a.shape[0], target.shape[0]
        sse = np.empty(p)
        errors = np.empty((p, k)) if want_errors else None
        coef = np.empty((p, n))
        work = p * k * (4 * n + num.shape[1])
        given = basis is not None and energies is not None
        _c.free_fit(a, _rows(num), np.ascontiguousarray(reg, dtype=float),
                    np.ascontiguousarray(target, dtype=float),
                    np.ascontiguousarray(basis, dtype=float) if given else None,
                    np.ascontiguousarray(energies, dtype=float) if given else None,
                    FREE_WINDOW * n, FREE_CANCEL, errors, sse, coef,
                    _threads_for(work), first, noise)  # fmt: skip
        return sse, errors, coef
    if basis is None or energies is None:
        raise FlexidError(
            "initial_state_fit: the reference path needs basis and energies "
            "(flexid.costs.polynomial.orthogonal_numerators and its energies)"
        )
    return initial_state_fit_reference(
        a, num, reg, target, basis, energies, want_errors=want_errors, first=first, noise=noise
    )


def shifted_columns(reg: np.ndarray) -> bool:
    """Whether every column of ``reg`` is the previous one delayed by a sample.

    ``reg[t, j] = x(t - j)`` for one signal ``x`` (one input's regressors): what
    :func:`arx_fit_shifted` needs.

    Parameters
    ----------
    reg : ndarray, shape (T, nb)

    Returns
    -------
    bool
    """
    reg = np.asarray(reg)
    return reg.ndim == 2 and reg.shape[1] >= 1 and bool(np.array_equal(reg[1:, 1:], reg[:-1, :-1]))


def _boundary_size(reg: np.ndarray, state0: np.ndarray, na: int, free_state: bool = False) -> int:
    """``L``: delays of the impulse response the regressors need (0 with no initial values
    and no initial state to fit)."""
    nb = reg.shape[1]
    if not (free_state or np.any(reg[0, 1:]) or np.any(state0)):
        return 0
    return max(na, nb - 1)


def arx_fit_shifted_reference(
    a: np.ndarray,
    reg: np.ndarray,
    state0: np.ndarray,
    target: np.ndarray,
    offset: int,
    free_state: bool = False,
    num: np.ndarray | None = None,
    targets: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Reference path of :func:`arx_fit_shifted`: ``lfilter`` and NumPy sums of products.

    The same basis, combinations and flag as the compiled kernel; its Gram matrix is formed
    from the delayed signals directly (``einsum`` over the window) rather than by lag sums.

    Parameters
    ----------
    a : ndarray, shape (P, na)
        Stable denominators.
    reg : ndarray, shape (T, nb)
        The input regressors, delays of one signal.
    state0 : ndarray, shape (na,)
        ``[y(-1), ..., y(-na)]`` of the free response.
    target : ndarray, shape (T - offset,)
    offset : int
    free_state : bool
        Fit the initial state with ``b`` (``state0`` unused), as :func:`arx_fit_shifted`.
    num, targets : ndarray, optional
        Per-candidate input numerators and targets, as :func:`arx_fit_shifted`.

    Returns
    -------
    b : ndarray, shape (P, nb)
        Zero in the rows flagged.
    ok : ndarray of bool, shape (P,)
        As :func:`arx_fit_shifted`.
    """
    a = np.atleast_2d(np.asarray(a, dtype=float))
    reg = np.asarray(reg, dtype=float)
    state0 = np.asarray(state0, dtype=float)
    target = np.asarray(target, dtype=float)
    p, na = a.shape
    t_len, m = reg.shape
    big_l = _boundary_size(reg, state0, na, free_state)
    nfree = na if free_state else 0
    n = m + big_l
    pad = n + 1
    x = reg[:, 0]
    pre = reg[0]  # pre[i] = x(-i), 1 <= i < m
    impulse = np.zeros(t_len)
    impulse[0] = 1.0
    sig = np.zeros((2, p, pad + t_len))  # v and h, zeros before t = 0
    x_ext = np.r_[pre[:0:-1], x]  # x(-(m - 1)) .. x(T - 1)
    for i in range(p):
        den = np.r_[1.0, a[i]]
        if num is None:
            sig[0, i, pad:] = signal.lfilter([1.0], den, x)
        else:  # the input sum_k d_k x(t - k), the samples before 0 from reg's first row
            xd = np.convolve(x_ext, num[i])[m - 1 : m - 1 + t_len]
            sig[0, i, pad:] = signal.lfilter([1.0], den, xd)
        sig[1, i, pad:] = signal.lfilter([1.0], den, impulse)

    def seg(k: int, lo: int, hi: int) -> np.ndarray:  # signal k over times [lo, hi)
        return sig[k, :, pad + lo : pad + hi]

    # basis b: S^b v (b < m), S^(b - m) h (b >= m); G_M over the window [offset, T)
    kinds = [(0, j) for j in range(m)] + [(1, j) for j in range(big_l)]
    gm = np.empty((p, n, n))
    for b1 in range(n):
        for b2 in range(b1, n):
            (k1, j1), (k2, j2) = kinds[b1], kinds[b2]
            gm[:, b1, b2] = gm[:, b2, b1] = np.einsum(
                "pt,pt->p", seg(k1, offset - j1, t_len - j1), seg(k2, offset - j2, t_len - j2)
            )
    tgt = np.broadcast_to(target, (p, t_len - offset)) if targets is None else targets
    mt = np.stack(
        [np.einsum("pt,pt->p", seg(k, offset - j, t_len - j), tgt) for k, j in kinds], axis=1
    )
    # unknowns: b, then with free_state the coefficients of S^l h (l < na), which span every
    # free response, so the pre-sample inputs' S^l h with l < na drop out of the b columns
    e = np.zeros((n, m + nfree))
    e[:m, :m] = np.eye(m)
    for j in range(m):
        for l_ in range(nfree, min(j, big_l)):
            e[m + l_, j] = pre[j - l_]
    for l_ in range(nfree):
        e[m + l_, m + l_] = 1.0
    gam = np.zeros((p, n))
    if big_l and not free_state:
        for l_ in range(na):
            gam[:, m + l_] = -np.einsum("pi,i->p", a[:, l_:], state0[: na - l_])
    gram = np.einsum("bj,pbc,ck->pjk", e, gm, e)
    rhs = np.einsum("bj,pb->pj", e, mt - np.einsum("pbc,pc->pb", gm, gam))
    scale = np.sqrt(np.maximum(np.einsum("pjj->pj", gram), 0.0))
    scale[scale == 0] = 1.0
    gs = gram / scale[:, :, None] / scale[:, None, :]
    b = np.zeros((p, m))
    ok = np.zeros(p, dtype=bool)
    for i in range(p):
        try:
            chol = np.linalg.cholesky(gs[i])
        except np.linalg.LinAlgError:
            continue
        inv = np.linalg.inv(chol)
        kappa = np.linalg.norm(gs[i]) * float((inv * inv).sum())
        c = np.linalg.solve(chol.T, np.linalg.solve(chol, rhs[i] / scale[i]))
        b[i] = (c / scale[i])[:m]
        ok[i] = kappa * t_len * np.finfo(float).eps <= FIT_SHIFTED_TOL and np.isfinite(b[i]).all()
    b[~ok] = 0.0
    return b, ok


def arx_fit_shifted(
    a: np.ndarray,
    reg: np.ndarray,
    state0: np.ndarray,
    target: np.ndarray,
    offset: int,
    *,
    want_sse: bool = False,
    free_state: bool = False,
    num: np.ndarray | None = None,
    targets: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """:func:`arx_fit` for regressor columns that are delays of one signal, by lag sums.

    With ``reg[t, j] = x(t - j)`` (:func:`shifted_columns`), ``v`` the response of ``1/A``
    to ``x`` and ``h`` its impulse response (from rest at ``t = 0``), every regressor is a
    fixed combination of the delays ``S^j v`` and ``S^l h``: delaying ``v`` by ``j`` drops
    the pre-sample inputs ``x(-j) .. x(-1)``, whose responses are delayed impulse responses,
    and the free response from ``state0`` is the response to ``na`` inputs at the first
    samples.  Their Gram matrix and products with ``target`` are lag sums of ``v``, ``h``
    and ``target`` (``3 (nb + L) - 1`` multiply-adds per sample, ``L = max(na, nb - 1)``, or
    ``2 nb`` and no ``h`` when ``state0`` and the pre-sample inputs are zero; with
    ``offset = 0`` the ``nb - 1`` sums of ``h`` with delays of ``v`` past it follow from
    ``A h = delta`` instead) plus a few terms at the ends of the window, instead of
    ``nb + 1`` recursions and a Gram matrix.  The normal equations of the
    column-scaled regressors are solved once (Cholesky): ``b`` is within about
    ``kappa(Gs) T eps`` relative of the exact least-squares solution (``tests/route_bounds.py``,
    ``vp_normal_bound``), and rows where that exceeds :data:`FIT_SHIFTED_TOL` come back with
    ``ok`` False.

    Parameters
    ----------
    a : ndarray, shape (P, na)
        Stable denominators.
    reg : ndarray, shape (T, nb)
        The input regressors, delays of one signal.
    state0 : ndarray, shape (na,)
        ``[y(-1), ..., y(-na)]`` of the free response.
    target : ndarray, shape (T - offset,)
    offset : int
    want_sse : bool
        Also return the sum of squared errors of the simulation from ``state0`` at the fitted
        ``b`` (compiled kernels and ``offset`` 0 only): the recursion of :func:`arx_recursion`
        itself, so exactly the sums it returns for the same rows.
    free_state : bool
        Fit the initial state too (MATLAB's estimated initial condition; ``state0`` is not
        used): the coefficients of ``S^l h``, ``l < na``, which span every free response,
        are unknowns beside ``b``, and ``b`` is that of the joint least-squares problem.
        Not with ``want_sse``.
    num : ndarray, shape (P, nd + 1), optional
        Per-candidate FIR numerators ``D`` on the signal (``nd < nb``): the regressors are
        the delays of the response of ``D/A`` to ``x`` (a Box-Jenkins or ARMAX predictor's).
        Only where no pre-sample input enters the basis: all of ``reg[0, 1:]`` and
        ``state0`` zero, or ``free_state`` with ``nb - 1 <= na``.  Not with ``want_sse``.
    targets : ndarray, shape (P, T - offset), optional
        Per-candidate targets in place of ``target`` (which is then ignored).  Not with
        ``want_sse``.

    Returns
    -------
    b : ndarray, shape (P, nb)
    ok : ndarray of bool, shape (P,)
        False where the bound above is too large, the factorisation broke down or ``b`` is
        not finite (solve those rows with :func:`arx_fit`).
    sse : ndarray, shape (P,), or None
        With ``want_sse``.
    """
    reg = np.ascontiguousarray(reg, dtype=float)
    state0 = np.ascontiguousarray(state0, dtype=float)
    target = np.ascontiguousarray(target, dtype=float)
    a = np.atleast_2d(np.asarray(a, dtype=float))
    na, nb = a.shape[1], reg.shape[1]
    if want_sse and (free_state or num is not None or targets is not None):
        raise FlexidError(
            "arx_fit_shifted: no sums of squares with a fitted initial state, per-candidate "
            "numerators or targets"
        )
    if num is not None:
        num = np.ascontiguousarray(np.atleast_2d(num), dtype=float)
        if not (num.shape[1] <= nb and ((free_state and nb - 1 <= na)
                                       or _boundary_size(reg, state0, na) == 0)):  # fmt: skip
            raise FlexidError(
                "arx_fit_shifted: per-candidate numerators need nd < nb and no pre-sample "
                "input in the basis (zero initial values, or free_state with nb - 1 <= na)"
            )
    if targets is not None:
        targets = np.ascontiguousarray(np.atleast_2d(targets), dtype=float)
    if BACKEND != "c" or not (1 <= na <= 24 and 1 <= nb <= 16):
        if want_sse:
            raise FlexidError("arx_fit_shifted: the sums of squares need the compiled kernels")
        b, ok = arx_fit_shifted_reference(a, reg, state0, target, offset, free_state, num,
                                          targets)  # fmt: skip
        return b, ok, None
    a = _rows(a)
    p = a.shape[0]
    big_l = _boundary_size(reg, state0, na, free_state)
    b = np.empty((p, nb))
    ok = np.empty(p, dtype=np.uint8)
    sse = np.empty(p) if want_sse else None
    work = p * reg.shape[0] * (2 * na + 3 * (nb + big_l) + (na + nb + 1 if want_sse else 0))
    # (an upper bound of the multiply-adds: what the thread count needs)
    _c.arx_fit_shifted(a, reg, state0, target, int(offset), big_l, FIT_SHIFTED_TOL, b, ok, sse,
                       _threads_for(work), int(free_state), num, targets)  # fmt: skip
    return b, ok.view(bool), sse


def flagged_fit_compiled(n: int, nb: int, nl: int = 1) -> bool:
    """Whether :func:`flagged_fit` runs compiled for these orders.

    Parameters
    ----------
    n : int
        Order of ``den``.
    nb : int
        Terms of the numerator.
    nl : int
        Terms of the lead numerator (``D``; 1 without one).

    Returns
    -------
    bool
        True when the compiled kernels are in use and ``1 <= n <= 24``, ``1 <= nb <= 16``
        and ``1 <= nl <= 8``.
    """
    return (BACKEND == "c" and hasattr(_c, "flagged_fit") and 1 <= n <= 24 and 1 <= nb <= 16
            and 1 <= nl <= 8)  # fmt: skip


def flagged_fit(
    a: np.ndarray,
    nb: int,
    sig: np.ndarray,
    target: np.ndarray | None,
    targets: np.ndarray | None = None,
    *,
    lead: np.ndarray | None = None,
    free: bool = False,
    restart: bool = False,
    state: np.ndarray | None = None,
    tol: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The least-squares numerator of one input, solved in the orthogonal numerators' basis.

    The problem of :meth:`flexid.costs.polynomial.PolynomialCost.b_regressors` for one
    input, solved as :func:`flexid.costs.polynomial._least_squares_rows` solves it (normal
    equations of the column-scaled regressors, up to two refinement steps with the residual
    formed from the regressors), without ``(P, nb, K)`` arrays.  With ``w = lead sig`` and
    ``start = N - K``, regressor ``m`` over ``t >= start`` is ``P_m(q)/den(q) w`` from rest
    at ``t = 0``, ``P_m`` the orthogonal numerators
    (:func:`~flexid.costs.polynomial.orthogonal_numerators`, from the step-down of ``den``
    in the kernel): one recursion of ``1/den`` and a lattice filter of it, where the route
    of one recursion per coefficient runs ``nb`` recursions (the same signals); or with
    ``restart`` the response of ``1/den`` to ``P_m(q) w`` from rest at ``t = start`` (the
    rule ``"measured"``: each regressor's own recursion, since their transients differ);
    with ``free`` the ``n`` free responses ``Q_k(q)/den(q) delta`` from ``t = start`` are
    unknowns too (the same lattice on one impulse response).  Its rounding errors are those
    of the recursions' route, a few ``eps`` times the gain of ``1/den``
    (``tests/test_flagged_fit.py`` measures them).  The compiled kernels only: the route of
    one recursion per coefficient is the reference.

    Parameters
    ----------
    a : ndarray, shape (P, n)
        ``a_1 .. a_n`` of each ``den``, stable.
    nb : int
        Terms of ``B``.
    sig : ndarray, shape (N,)
        The input delayed by ``nk`` (zeros before it).
    target : ndarray, shape (K,), or None
        Shared target over ``t >= start``.
    targets : ndarray, shape (P, K), optional
        Per-candidate targets in place of ``target`` (give exactly one of them).
    lead : ndarray, shape (P, nl), optional
        A numerator on the input (``D`` of a one-step predictor); None: 1.
    free : bool
        The free responses from ``t = start`` are unknowns too (the rule ``"estimate"``).
    restart : bool
        The regressors from rest at ``t = start`` (the rule ``"measured"``).
    state : ndarray, shape (n,), optional
        Past outputs ``y(start - 1) .. y(start - n)`` (:func:`ar_recursion`'s ``state``),
        with ``target``: each candidate's target is ``target`` less the free response of
        ``1/den`` from them (the rule ``"measured"`` of a predictor with no output
        numerator), formed in the kernel instead of a ``(P, K)`` ``targets``.
    tol : float
        Refinement tolerance (relative step below which a row has converged).

    Returns
    -------
    b : ndarray, shape (P, nb)
        ``B`` in powers of ``q^-1`` (the fitted combination of the ``P_m``).
    sse : ndarray, shape (P,)
        Sums of squares of the residual at ``b`` (and the fitted free responses): that of
        the last residual formed, less the last refinement step's share
        (``|e - R s|^2 = |e|^2 - 2 s.R'e + s'Gs``, a correction far below ``|e|^2``).
    ok : ndarray of bool, shape (P,)
        False where the factorisation broke down, the refinement still moved after two
        steps (where :func:`~flexid.costs.polynomial._least_squares_rows` solves again by
        SVD) or a result is not finite: solve those rows another way.
    """
    a = _rows(np.atleast_2d(np.asarray(a, dtype=float)))
    p, n = a.shape
    nl = 1 if lead is None else np.shape(lead)[-1]
    if not flagged_fit_compiled(n, nb, nl):
        raise FlexidError(
            "flagged_fit: the compiled kernels are not in use or the orders are out of range "
            "(the reference route is PolynomialCost._fitted_b_recursions)"
        )
    if (target is None) == (targets is None):
        raise FlexidError("flagged_fit: give target or targets, not both")
    if state is not None and target is None:
        raise FlexidError("flagged_fit: state is subtracted from a shared target only")
    coef = np.empty((p, nb))
    sse = np.empty(p)
    ok = np.empty(p, dtype=np.uint8)
    k = (target if target is not None else targets).shape[-1]
    nr = nb + (n if free else 0)
    work = p * k * (nr * (nr + 1) // 2 + nb * (nb + 1) // 2 + 4 * nr)
    _c.flagged_fit(a, None if lead is None else _rows(np.asarray(lead, dtype=float)),
                   np.ascontiguousarray(sig, dtype=float),
                   None if target is None else np.ascontiguousarray(target, dtype=float),
                   None if targets is None else np.ascontiguousarray(targets, dtype=float),
                   None if state is None else np.ascontiguousarray(state, dtype=float),
                   bool(free), bool(restart), float(tol), coef, sse, ok,
                   _threads_for(work))  # fmt: skip
    return coef, sse, ok.view(bool)
