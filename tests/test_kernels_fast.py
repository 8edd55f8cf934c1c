"""The fast compiled recursions (issue 28) against the NumPy/SciPy reference path.

* ``arx_run`` computes the input part ``f(t) = sum_j b_j reg[t, j]`` in the kernel, where the
  reference forms it with one GEMM: the two are ``nb``-term sums in different orders, so each
  step differs by the recursion's ``na + 1``-term rounding plus the ``nb``-term rounding of
  ``f``, both filtered by ``1/A(q)`` (``ar_route_bound`` with ``forced_terms``,
  tests/route_bounds.py).  Those bounds hold on any IEEE-754 machine, with or without FMA,
  whatever the SIMD width, because they are in terms of the magnitudes summed at each step.
* Every instruction set the CPU runs (``_kernels.simd``: the portable 2-lane build, AVX2/FMA,
  AVX-512) is held to the same bounds, so a CI machine with AVX-512 checks all three.
* The thread count only decides which thread computes a block of 4 candidates, never how:
  results are compared exactly across thread counts, and between strided and contiguous
  inputs (the same arithmetic on the same numbers).
"""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest
from scipy import signal

from flexid import kernels
from flexid.costs.arx import ARXCost
from flexid.errors import FlexidError
from flexid.models.arx import ARXStructure
from flexid.models.stability import is_stable_reference
from numerics import EPS, assert_close_to_terms
from route_bounds import ar_route_bound, lstsq_error, normal_equations_error, sse_route_bound
from test_kernels import stable_denominators

compiled = pytest.mark.skipif(
    not kernels.compiled_available(), reason="flexid._kernels was not built (no C compiler)"
)


def simd_levels() -> list[str]:
    """The instruction sets of the recursions this CPU runs (all, not only the best)."""
    if not kernels.compiled_available():
        return []
    from flexid import _kernels

    order = ["generic", "avx2", "avx512"]
    best = _kernels.simd()[1]
    return order[: order.index(best) + 1] if best in order else [best]


@pytest.fixture(params=simd_levels() or ["none"])
def simd(request):
    """Run the test on one instruction set of the compiled recursions, then restore."""
    if request.param == "none":
        pytest.skip("flexid._kernels was not built")
    from flexid import _kernels

    before = _kernels.simd()[0]
    _kernels.simd(request.param)
    yield request.param
    _kernels.simd(before)


def problem(rng, p, na, nb, k, shared_state):
    a = stable_denominators(rng, p, na) if na else np.zeros((p, 0))
    b = rng.normal(size=(p, nb))
    reg = rng.normal(size=(k, nb))
    state = rng.normal(size=na) if shared_state else rng.normal(size=(p, na))
    target = rng.normal(size=k)
    return a, b, reg, state, target


@pytest.mark.numerics
@compiled
@pytest.mark.parametrize("na", [0, 1, 2, 5, 8, 16, 17])
@pytest.mark.parametrize("nb", [0, 1, 3, 8, 9])
@pytest.mark.parametrize("p", [1, 5, 50])
def test_arx_run_equals_the_reference(simd, na, nb, p):
    from flexid import _kernels

    rng = np.random.default_rng(1000 * na + 10 * nb + p)
    k = 300  # not a multiple of the kernel's chunk of 128 steps, nor of 8
    for shared in (True, False):
        a, b, reg, state, target = problem(rng, p, na, nb, k, shared)
        forced = b @ reg.T
        ref = kernels.ar_recursion_reference(a, forced, state)
        y = np.empty((p, k))
        sse = np.empty(p)
        _kernels.arx_run(a, b, reg, state, target, y, sse, 1)
        # the recursion (na + 1 terms a step) and f (nb terms, GEMM against the kernel's
        # order), both filtered by 1/A(q)
        dy = ar_route_bound(a, forced, state, ref, np.abs(b) @ np.abs(reg).T, nb)
        assert_close_to_terms(y, ref, dy, 1.0)
        e = target - ref
        assert_close_to_terms(sse, (e * e).sum(axis=1), sse_route_bound(e, dy), 1.0)
        # the forced terms given: the recursion's rounding only
        y2 = np.empty((p, k))
        _kernels.ar_run(a, forced, state, None, y2, None, 1)
        assert_close_to_terms(y2, ref, ar_route_bound(a, forced, state, ref), 1.0)


@pytest.mark.numerics
@compiled
@pytest.mark.parametrize("na", [2, 16, 18, 24])
@pytest.mark.parametrize("first", [0, 1, 17, 150, 299, 300])
def test_arx_run_counts_the_squares_from_first(simd, na, first):
    # from rest, the samples before first run but are not counted: the outputs are those
    # of first = 0 exactly (the same recursion), the sum that of the errors from first on
    # (orders above 16 too: BJ's C F runs on the block path)
    from flexid import _kernels

    rng = np.random.default_rng(10 * na + first)
    p, nb, k = 9, 37, 300
    a, b, reg, state, target = problem(rng, p, na, nb, k, True)
    forced = b @ reg.T
    ref = kernels.ar_recursion_reference(a, forced, state)
    y0, y, sse = np.empty((p, k)), np.empty((p, k)), np.empty(p)
    _kernels.arx_run(a, b, reg, state, None, y0, None, 2)
    _kernels.arx_run(a, b, reg, state, target[first:], y, sse, 2, first)
    np.testing.assert_array_equal(y, y0)
    dy = ar_route_bound(a, forced, state, ref, np.abs(b) @ np.abs(reg).T, nb)
    assert_close_to_terms(y, ref, dy, 1.0)
    e = target[first:] - ref[:, first:]
    assert_close_to_terms(sse, (e * e).sum(axis=1), sse_route_bound(e, dy[:, first:]), 1.0)
    _, sse2 = kernels.arx_recursion(a, b, reg, state, target[first:], want_output=False,
                                    first=first)  # fmt: skip
    if kernels.BACKEND == "c":  # the wrapper runs the same kernel
        np.testing.assert_array_equal(sse2, sse)
    else:  # the reference path: a GEMM and lfilter, within the same bound
        assert_close_to_terms(sse2, (e * e).sum(axis=1), sse_route_bound(e, dy[:, first:]), 1.0)
    with pytest.raises(ValueError, match="K - first"):
        _kernels.arx_run(a, b, reg, state, target, None, sse, 1, max(first, 1))
    with pytest.raises(ValueError, match="first must be"):
        _kernels.arx_run(a, b, reg, state, None, None, None, 1, k + 1)


@pytest.mark.numerics
@compiled
@pytest.mark.parametrize("k", [1, 3, 7, 128, 129, 136])
def test_arx_run_short_records_and_chunk_edges(simd, k):
    # records shorter than the order (the state alone feeds the first outputs), and lengths
    # around the kernel's chunks of 128 forced terms and blocks of 8
    from flexid import _kernels

    rng = np.random.default_rng(k)
    a, b, reg, state, target = problem(rng, 6, 8, 4, k, False)
    forced = b @ reg.T
    ref = kernels.ar_recursion_reference(a, forced, state)
    y = np.empty((6, k))
    _kernels.arx_run(a, b, reg, state, target, y, None, 1)
    dy = ar_route_bound(a, forced, state, ref, np.abs(b) @ np.abs(reg).T, 4)
    assert_close_to_terms(y, ref, dy, 1.0)


@compiled
@pytest.mark.parametrize("na", [3, 8, 20])
def test_thread_count_and_strides_do_not_change_results(simd, na):
    # a thread computes whole blocks of 4 candidates exactly as one thread would
    from flexid import _kernels

    rng = np.random.default_rng(na)
    p, nb, k = 37, 5, 400
    a, b, reg, state, target = problem(rng, p, na, nb, k, False)
    forced = b @ reg.T
    outs = []
    for n_threads in (1, 2, 3, 8, 100):
        y, sse = np.empty((p, k)), np.empty(p)
        _kernels.arx_run(a, b, reg, state, target, y, sse, n_threads)
        y2, sse2 = np.empty((p, k)), np.empty(p)
        _kernels.ar_run(a, forced, state, target, y2, sse2, n_threads)
        outs.append((y, sse, y2, sse2))
    for other in outs[1:]:
        for x0, x1 in zip(outs[0], other):
            np.testing.assert_array_equal(x1, x0)
    # a and b as column blocks of one population array (strided rows): no copy, same numbers
    X = np.hstack([a, b])
    y, sse = np.empty((p, k)), np.empty(p)
    _kernels.arx_run(X[:, :na], X[:, na:], reg, state, target, y, sse, 2)
    np.testing.assert_array_equal(y, outs[0][0])
    np.testing.assert_array_equal(sse, outs[0][1])
    # without outputs or without a target: the same sums
    sse3 = np.empty(p)
    _kernels.arx_run(a, b, reg, state, target, None, sse3, 3)
    np.testing.assert_array_equal(sse3, outs[0][1])
    y3 = np.empty((p, k))
    _kernels.arx_run(a, b, reg, state, None, y3, None, 3)
    np.testing.assert_array_equal(y3, outs[0][0])


@compiled
def test_arx_run_rejects_bad_buffers():
    from flexid import _kernels

    a, b, reg = np.zeros((4, 2)), np.zeros((4, 3)), np.zeros((10, 3))
    with pytest.raises(ValueError, match="reg \\(K, nb\\)"):
        _kernels.arx_run(a, b, np.zeros((10, 2)), np.zeros(2), None, None, None)
    with pytest.raises(ValueError, match="reg \\(K, nb\\)"):
        _kernels.arx_run(a, np.zeros((3, 3)), reg, np.zeros(2), None, None, None)
    with pytest.raises(ValueError, match="state"):
        _kernels.arx_run(a, b, reg, np.zeros(3), None, None, None)
    with pytest.raises(ValueError, match="y_out"):
        _kernels.arx_run(a, b, reg, np.zeros(2), None, np.zeros((4, 9)), None)
    with pytest.raises(TypeError, match="rows must be contiguous"):
        _kernels.arx_run(np.zeros((2, 4)).T, b, reg, np.zeros(2), None, None, None)
    with pytest.raises(ValueError, match="at most 64"):
        _kernels.arx_run(a, np.zeros((4, 65)), np.zeros((10, 65)), np.zeros(2), None, None, None)
    with pytest.raises(ValueError, match="not one this CPU runs"):
        _kernels.simd("sse9")


@pytest.mark.numerics
def test_arx_recursion_against_gemm_and_lfilter():
    # the public function on either backend (FLEXID_KERNELS=numpy: the reference itself)
    rng = np.random.default_rng(7)
    p, na, nb, k = 19, 6, 4, 500
    a, b, reg, state, target = problem(rng, p, na, nb, k, True)
    X = np.hstack([a, b])
    y, sse = kernels.arx_recursion(X[:, :na], X[:, na:], reg, state, target)
    forced = b @ reg.T
    ref = np.empty((p, k))
    for i in range(p):
        den = np.r_[1.0, a[i]]
        ref[i] = signal.lfilter([1.0], den, forced[i], zi=signal.lfiltic([1.0], den, state))[0]
    dy = ar_route_bound(a, forced, state, ref, np.abs(b) @ np.abs(reg).T, nb)
    assert_close_to_terms(y, ref, dy, 1.0)
    e = target - ref
    assert_close_to_terms(sse, (e * e).sum(axis=1), sse_route_bound(e, dy), 1.0)
    y2, sse2 = kernels.arx_recursion(a, b, reg, state, target, want_output=False)
    assert y2 is None
    np.testing.assert_array_equal(sse2, sse)


@pytest.mark.numerics
@compiled
@pytest.mark.parametrize("initial", ["measured", "zero"])
def test_simulation_cost_compiled_against_numpy(monkeypatch, simd, initial):
    # ARXCost's simulation SSE by the fused kernel (f in the kernel) against the NumPy route
    # (GEMM + lfilter): the recursion and f bounds, then the SSE and the metric's roundings
    rng = np.random.default_rng(11)
    u = rng.uniform(-1, 1, 700)
    yv = signal.lfilter([0, 0.3, 0.1, 0.05], [1, -1.5, 0.7, -0.05], u)
    yv += 0.01 * rng.standard_normal(700)
    s = ARXStructure(5, 4, 1)
    cost = ARXCost(s, (u, yv), predictor="simulation", initial=initial)
    X = cost.theta_ls + 0.02 * rng.normal(size=(45, s.n_params))
    X = X[is_stable_reference(X[:, :5])]
    monkeypatch.setattr(kernels, "BACKEND", "c")
    got = cost(X)
    monkeypatch.setattr(kernels, "BACKEND", "numpy")
    ref = cost(X)
    a, b = X[:, :5], X[:, 5:]
    phi_u = cost._phi_u
    forced = b @ phi_u.T
    state = cost._state if initial == "measured" else np.zeros(5)
    yref = kernels.ar_recursion_reference(a, forced, state)
    dy = ar_route_bound(a, forced, state, yref, np.abs(b) @ np.abs(phi_u).T, 4)
    if initial == "zero":
        yref, dy = yref[:, s.start :], dy[:, s.start :]
    e = cost._target - yref
    sse = (e * e).sum(axis=1)
    # cost = w sqrt(sse) / K: relative change half that of the SSE, plus 3 roundings each
    rel = sse_route_bound(e, dy) / (2 * sse) + 3 * EPS
    assert_close_to_terms(got, ref, rel * ref, 1.0)


def test_thread_setting():
    old = kernels.set_threads(3)
    try:
        assert kernels.threads() == 3
        assert kernels.set_threads(None) == 3
        assert kernels.threads() == len(os.sched_getaffinity(0))
        for bad in (0, -1, 1.5, True, "2"):
            with pytest.raises(FlexidError, match="positive integer"):
                kernels.set_threads(bad)
    finally:
        kernels.set_threads(old)


def test_thread_environment_variable():
    code = "from flexid import kernels; print(kernels.threads())"
    env = dict(os.environ, FLEXID_THREADS="5")
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                          text=True, timeout=120)  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "5"
    env["FLEXID_THREADS"] = "none"
    bad = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                         text=True, timeout=120)  # fmt: skip
    assert bad.returncode != 0 and "FLEXID_THREADS must be" in bad.stderr


def test_compare_worker_processes_use_one_thread(monkeypatch):
    # the worker processes of compare --workers share the cores already: one thread each
    from flexid.jobs import _compare

    sent = []

    class Conn:
        def send(self, msg):
            sent.append(msg)

        def recv(self):
            return None

    monkeypatch.setattr(_compare, "_exit_with_parent", lambda: None)
    old = kernels.set_threads(4)
    try:
        _compare._worker_main(Conn())
        assert kernels.threads() == 1
        assert sent == [("ready", None)]
    finally:
        kernels.set_threads(old)


# ------------------------------------------------------------------ the fitted numerator
def fitted_numerator_problem(na, nb, initial, radius=0.9):
    """A simulation cost and stable denominators near the data's (poles at ``radius``)."""
    rng = np.random.default_rng(na * 10 + nb + (initial == "zero"))
    u = rng.uniform(-1, 1, 600)
    poles = radius * np.exp(1j * np.linspace(0.3, 2.5, na // 2))
    den = np.poly(np.r_[poles, poles.conj(), [0.5 * radius / 0.9] * (na % 2)]).real
    yv = signal.lfilter(np.r_[0.0, rng.normal(size=nb)], den, u) + 0.01 * rng.normal(size=600)
    cost = ARXCost(ARXStructure(na, nb, 1), (u, yv), predictor="simulation", initial=initial)
    a = den[1:] + 0.01 * rng.normal(size=(9, na))
    return cost, a[is_stable_reference(a)]


@pytest.mark.numerics
@compiled
@pytest.mark.parametrize("initial", ["measured", "zero"])
@pytest.mark.parametrize("orders", [(2, 3), (8, 8), (5, 1), (1, 4)])
def test_arx_fit_solves_the_least_squares_problem(simd, initial, orders):
    # kernels.arx_fit (nb + 1 recursions, normal equations of the scaled columns, Cholesky,
    # one refinement step) against the exact least-squares solution (SVD) of the reference
    # route's regressors (lfilter).  Two parts:
    # * the problems differ by the recursions' rounding, bounded element-wise by
    #   ar_route_bound for every column and for the free response; the least-squares
    #   perturbation theorem (Higham Thm 20.1) maps those relative perturbations eps_F, eps_r
    #   to |dx| <= kappa e / (1 - kappa e) (2 |x| + (kappa + 1) |r| / |F|), e = max of them;
    # * each solve's own rounding: lstsq_error (route_bounds.py) for each of the two, the
    #   compiled one under the condition that its refinement converges, kappa^2 eps < 1/2
    #   (asserted): then one refinement step from the normal equations reaches the accuracy of
    #   a backward-stable solve (Higham sec. 20.5).
    na, nb = orders
    cost, a = fitted_numerator_problem(na, nb, initial)
    start = cost.structure.start
    offset = 0 if initial == "measured" else start
    state0 = cost._state if initial == "measured" else np.zeros(na)
    reg = cost._phi_u_rows
    b, ok = kernels.arx_fit(a, reg, state0, cost._target, offset)
    assert ok.all() and b.shape == (a.shape[0], nb)
    forced = np.vstack([np.zeros((1, reg.shape[0])), reg.T])
    for i, row in enumerate(a):
        rows = np.repeat(row[None], nb + 1, 0)
        states = np.zeros((nb + 1, na))
        states[0] = state0
        y = kernels.ar_recursion_reference(rows, forced, states)
        dy = ar_route_bound(rows, forced, states, y)[:, offset:]
        F, r = y[1:, offset:].T, cost._target - y[0, offset:]
        sv = np.linalg.svd(F, compute_uv=False)
        kappa = sv[0] / sv[-1]
        assert kappa**2 * EPS < 0.5
        exact = np.linalg.lstsq(F, r, rcond=None)[0]
        resid = float(np.linalg.norm(r - F @ exact))
        e = max(np.linalg.norm(dy[1:]) / sv[0], np.linalg.norm(dy[0]) / np.linalg.norm(r))
        assert kappa * e < 0.5
        perturbation = kappa * e / (1 - kappa * e) * (
            2 * np.linalg.norm(exact) + (kappa + 1) * resid / sv[0])  # fmt: skip
        bound = perturbation + 2 * lstsq_error(F, exact, resid)
        assert np.linalg.norm(b[i] - exact) <= bound


@compiled
def test_fitted_numerator_compiled_and_numpy_routes_agree(monkeypatch):
    # ARXCost.fit_numerator takes kernels.arx_fit_shifted on both backends (one input): the
    # compiled lag sums and the NumPy ones (lfilter, einsum), each within the stated bound of
    # the exact solution (test_arx_fit_shifted_solves_the_least_squares_problem), so within
    # twice it of each other
    cost, a = fitted_numerator_problem(8, 8, "measured")
    monkeypatch.setattr(kernels, "BACKEND", "c")
    got = cost.fit_numerator(a)
    monkeypatch.setattr(kernels, "BACKEND", "numpy")
    ref = cost.fit_numerator(a)
    np.testing.assert_array_equal(got[:, :8], ref[:, :8])
    for i, (_, bound, _) in enumerate(lag_sum_bounds(cost, a, "measured")):
        assert np.linalg.norm(got[i, 8:] - ref[i, 8:]) <= 2 * bound


@compiled
def test_arx_fit_rejects_bad_arguments_and_flags_singular_rows():
    a = np.array([[-0.5], [0.2]])
    reg = np.zeros((50, 2))  # zero regressors: a singular Gram matrix
    _, ok = kernels.arx_fit(a, reg, np.zeros(1), np.ones(50), 0)
    assert not ok.any()
    with pytest.raises(ValueError, match="arx_fit"):
        kernels.arx_fit(a, reg, np.zeros(2), np.ones(50), 0)
    with pytest.raises(ValueError, match="arx_fit"):
        kernels.arx_fit(a, reg, np.zeros(1), np.ones(49), 0)
    with pytest.raises(ValueError, match="arx_fit"):
        kernels.arx_fit(np.zeros((2, 17)), reg, np.zeros(17), np.ones(50), 0)


@compiled
def test_arx_fit_does_not_depend_on_the_thread_count(simd):
    from flexid import _kernels

    cost, a = fitted_numerator_problem(4, 3, "measured")
    a = np.vstack([a] * 5)
    outs = []
    for n_threads in (1, 2, 3, 16):
        b, ok = np.empty((a.shape[0], 3)), np.empty(a.shape[0], np.uint8)
        _kernels.arx_fit(a, cost._phi_u_rows, cost._state, cost._target, 0, b, ok, n_threads)
        outs.append(b)
    for b in outs[1:]:
        np.testing.assert_array_equal(b, outs[0])


@compiled
def test_rows_the_compiled_fit_cannot_solve_take_the_numpy_route(monkeypatch):
    cost, a = fitted_numerator_problem(3, 2, "measured")
    real = kernels.arx_fit

    def flaky(*args):
        b, ok = real(*args)
        ok[::2] = False
        return b, ok

    monkeypatch.setattr(kernels, "BACKEND", "c")
    cost._shifted = False  # the route of nb + 1 recursions (other structures' route)
    want = cost._simulation_numerators_numpy(a, 0, cost._state)
    monkeypatch.setattr(kernels, "arx_fit", flaky)
    got = cost.fit_numerator(a)[:, 3:]
    np.testing.assert_array_equal(got[::2], want[::2])  # recomputed by the NumPy route
    np.testing.assert_array_equal(got[1::2], real(a, cost._phi_u_rows, cost._state,
                                                   cost._target, 0)[0][1::2])  # fmt: skip


@compiled
@pytest.mark.skipif(not hasattr(os, "fork"), reason="no fork")
def test_threads_after_fork():
    # the helper threads are kept between calls; a child made by fork has none and must
    # start its own (pthread_atfork), not wait for the parent's
    code = """
import os, sys, numpy as np
from flexid import _kernels
rng = np.random.default_rng(3)
a, b, reg = rng.random((64, 4)) * 0.1, rng.random((64, 3)), rng.random((500, 3))
out = np.empty(64)
_kernels.arx_run(a, b, reg, np.zeros(4), None, None, out, 2)  # the parent's helpers start
pid = os.fork()
if pid == 0:
    child = np.empty(64)
    _kernels.arx_run(a, b, reg, np.zeros(4), None, None, child, 2)
    same = np.array_equal(child, out)
    _kernels.arx_run(a, b, reg, np.zeros(4), None, None, child, 3)
    os._exit(0 if same and np.array_equal(child, out) else 1)
_, status = os.waitpid(pid, 0)
sys.exit(os.waitstatus_to_exitcode(status))
"""
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=60)  # fmt: skip
    assert done.returncode == 0, done.stderr


@compiled
def test_threads_from_several_python_threads():
    # the kernels run without the GIL: Python threads may call them at once (one of them
    # owns the helper threads, the others run alone); every result as on one thread
    from concurrent.futures import ThreadPoolExecutor

    from flexid import _kernels

    rng = np.random.default_rng(4)
    a, b, reg, state, target = problem(rng, 40, 6, 4, 800, False)
    want = np.empty(40)
    _kernels.arx_run(a, b, reg, state, target, None, want, 1)

    def run(_):
        got = np.empty(40)
        _kernels.arx_run(a, b, reg, state, target, None, got, 2)
        return got

    with ThreadPoolExecutor(4) as pool:
        for got in pool.map(run, range(32)):
            np.testing.assert_array_equal(got, want)


# ------------------------------------------------------------------ the fit by lag sums
def lag_sum_basis(cost, row, offset, state0):
    """The reference route's basis ``M`` (delays of v and h by lfilter), ``E`` and ``gamma``."""
    reg = cost._phi_u_rows
    t_len, m = reg.shape
    na = row.size
    big_l = kernels._boundary_size(reg, state0, na)
    den = np.r_[1.0, row]
    impulse = np.zeros(t_len)
    impulse[0] = 1.0
    v = signal.lfilter([1.0], den, reg[:, 0])
    h = signal.lfilter([1.0], den, impulse)

    def delay(z, j):
        return np.r_[np.zeros(j), z[: t_len - j]]

    M = np.column_stack([delay(v, j) for j in range(m)] + [delay(h, j) for j in range(big_l)])
    E = np.zeros((m + big_l, m))
    E[:m] = np.eye(m)
    for j in range(m):
        for l_ in range(min(j, big_l)):
            E[m + l_, j] = reg[0, j - l_]
    gamma = np.zeros(m + big_l)
    for l_ in range(na if big_l else 0):
        gamma[m + l_] = -row[l_:] @ state0[: na - l_]
    return M[offset:], E, gamma


@pytest.mark.numerics
@pytest.mark.parametrize("initial", ["measured", "zero"])
@pytest.mark.parametrize("orders", [(2, 3), (8, 8), (5, 1), (1, 4), (3, 12)])
@pytest.mark.parametrize("route", ["compiled", "numpy"])
def test_arx_fit_shifted_solves_the_least_squares_problem(simd, route, initial, orders):
    # the fit by lag sums against the exact least-squares solution (SVD) of the reference
    # route's regressors (nb + 1 lfilter recursions).  Three parts, as for arx_fit:
    # * the regressors of the two routes differ by the recursions' rounding (ar_route_bound
    #   for v, h and each column), mapped by the least-squares perturbation theorem;
    # * the normal equations formed by lag sums and solved once: normal_equations_error
    #   (route_bounds.py), kappa(F)^2 times the rounding of the sums;
    # * the reference solve's own rounding, lstsq_error.
    # The two routes' regressors F = M E are the same matrix in exact arithmetic (checked
    # below to the recursions' rounding), which is what the lag sums rely on.
    if route == "compiled" and not kernels.compiled_available():
        pytest.skip("flexid._kernels was not built")
    cost, a = fitted_numerator_problem(*orders, initial)
    check_lag_sum_fit(cost, a, initial, route)


@pytest.mark.numerics
@pytest.mark.parametrize("route", ["compiled", "numpy"])
def test_arx_fit_shifted_on_lightly_damped_denominators(simd, route):
    # the benchmark's problem (benchmarks/bench_costs.py): poles at radius 0.99, kappa(F) ~ 5e3
    # after column scaling, so the normal equations' kappa^2 reaches 2.5e7; the stated bound
    # still holds (about 1 % of |b| here, the error itself about 1e-9 of it)
    if route == "compiled" and not kernels.compiled_available():
        pytest.skip("flexid._kernels was not built")
    rng = np.random.default_rng(0)
    poles = 0.99 * np.exp(1j * np.array([0.05, 0.3, 0.9, 2.0]))
    den = np.poly(np.r_[poles, poles.conj()]).real
    u = rng.uniform(-0.3, 0.3, 1500)
    y = signal.lfilter(np.r_[0.0, rng.normal(size=8) * 0.1], den, u)
    y += 1e-3 * rng.standard_normal(1500)
    cost = ARXCost(ARXStructure(8, 8, 1), (u, y), predictor="simulation")
    a = cost.theta_ls[:8] + 1e-5 * rng.normal(size=(3, 8))
    assert is_stable_reference(a).all()
    check_lag_sum_fit(cost, a, "measured", route)


def shifted_fit_bound(row, reg, target, offset, free, d=None):
    """The exact ``b`` (SVD) of :func:`kernels.arx_fit_shifted`'s problem for one
    denominator ``row``, and the stated bound on the kernel's ``b``.

    The reference regressors: ``v``, the response from rest at the window's start to the
    signal (``reg[:, 0]``, or ``D`` applied to it with the samples before 0 from ``reg[0]``),
    delayed, and the delayed impulse responses ``h`` that carry the pre-sample inputs and,
    with ``free``, span every free response (lfilter).  The bound has two parts, as
    :func:`lag_sum_bounds`: the route's ``v`` and ``h`` (the kernel's recursion) against
    lfilter's, within ``ar_route_bound``, mapped by the least-squares perturbation theorem
    (Higham Thm 20.1); and the normal equations formed by lag sums and solved once
    (``normal_equations_error``).  Only the cases the kernel serves with ``d``: no
    pre-sample input from rest, or ``free`` with ``nb - 1 <= na``.
    """
    na, (t_len, nb) = row.size, reg.shape
    pre = reg[0]
    assert free or not pre[1:].any()
    big_l = max(na, nb - 1) if free else 0
    nfree = na if free else 0
    x = reg[:, 0]
    if d is not None:
        assert nb - 1 <= nfree or not pre[1:].any()
        x = np.convolve(np.r_[pre[:0:-1], x], d)[nb - 1 : nb - 1 + t_len]
    den = np.r_[1.0, row]
    impulse = np.eye(1, t_len)[0]
    v, h = signal.lfilter([1.0], den, x), signal.lfilter([1.0], den, impulse)

    def delay(z, j):
        return np.r_[np.zeros(j), z[: t_len - j]]

    M = np.column_stack([delay(v, j) for j in range(nb)] + [delay(h, l_) for l_ in range(big_l)])
    M = M[offset:]
    E = np.zeros((nb + big_l, nb + nfree))
    E[:nb, :nb] = np.eye(nb)
    for j in range(nb):
        for l_ in range(nfree, min(j, big_l)):  # pre-sample inputs outside the free span
            E[nb + l_, j] = pre[j - l_]
    E[nb : nb + nfree, nb:] = np.eye(nfree)
    F = M @ E
    exact = np.linalg.lstsq(F, target, rcond=None)[0]
    resid = float(np.linalg.norm(target - F @ exact))
    pair = np.repeat(row[None], 2, 0)
    inputs = np.vstack([x, impulse])
    vh = kernels.ar_recursion_reference(pair, inputs, np.zeros(na))
    dM = ar_route_bound(pair, inputs, np.zeros(na), vh)
    dF = np.abs(E[:nb]).sum(0) * dM[0].max() + np.abs(E[nb:]).sum(0) * dM[1].max()
    sv = np.linalg.svd(F, compute_uv=False)
    kappa = sv[0] / sv[-1]
    e = np.linalg.norm(dF) * np.sqrt(t_len) / sv[0]
    assert kappa * e < 0.5
    perturbation = kappa * e / (1 - kappa * e) * (
        2 * np.linalg.norm(exact) + (kappa + 1) * resid / sv[0])  # fmt: skip
    zero = np.zeros(M.shape[1])
    if offset == 0 and big_l:  # the lag sums of h with later v continued by A h = delta
        h_ext = signal.lfilter([1.0], den, np.eye(1, t_len + 16)[0])
        normal = normal_equations_error(M, E, zero, target, exact, a=row, v=vh[0], h=h_ext,
                                        n_v=nb)  # fmt: skip
    else:
        normal = normal_equations_error(M, E, zero, target, exact, n_v=nb)
    return exact[:nb], perturbation + normal + lstsq_error(F, exact, resid)


def free_state_bounds(cost, a):
    """:func:`shifted_fit_bound` of ARX cost's problem with a free initial state, per row."""
    return [shifted_fit_bound(row, cost._phi_u_rows, cost._target, 0, True) for row in a]


@pytest.mark.numerics
@pytest.mark.parametrize("radius", [0.9, 0.2])
@pytest.mark.parametrize("orders", [(2, 3), (8, 8), (5, 1), (1, 4), (3, 12)])
@pytest.mark.parametrize("route", ["compiled", "numpy"])
def test_arx_fit_shifted_with_a_free_initial_state(simd, route, orders, radius):
    # free_state: b and the initial state at the window's start fitted together (MATLAB's
    # estimated initial condition), against the exact least-squares solution of the
    # reference regressors within the stated bound (free_state_bounds); at radius 0.2 the
    # impulse response decays through the subnormal range (below 2.3e-308 from about the
    # 440th of the 600 samples), which the compiled fit flushes to zero
    if route == "compiled" and not kernels.compiled_available():
        pytest.skip("flexid._kernels was not built")
    cost, a = fitted_numerator_problem(*orders, "measured", radius)
    args = (a, cost._phi_u_rows, np.zeros(orders[0]), cost._target, 0)
    if route == "compiled":
        b, ok, _ = kernels.arx_fit_shifted(*args, free_state=True)
    else:
        b, ok = kernels.arx_fit_shifted_reference(*args, free_state=True)
    assert ok.all() and b.shape == (a.shape[0], orders[1])
    for i, (exact, bound) in enumerate(free_state_bounds(cost, a)):
        assert np.linalg.norm(b[i] - exact) <= bound
    with pytest.raises(FlexidError, match="initial state"):
        kernels.arx_fit_shifted(*args, free_state=True, want_sse=True)


def check_lag_sum_fit(cost, a, initial, route):
    """The fit by lag sums of ``a`` against the exact solution, within the stated bound, and
    against the route of nb + 1 recursions (kernels.arx_fit) within the sum of both bounds."""
    na, nb = cost.structure.na, cost.n_params - cost.structure.na
    offset = 0 if initial == "measured" else cost.structure.start
    state0 = cost._state if initial == "measured" else np.zeros(na)
    reg = cost._phi_u_rows
    assert kernels.shifted_columns(reg)
    if route == "compiled":
        b, ok, _ = kernels.arx_fit_shifted(a, reg, state0, cost._target, offset)
    else:
        b, ok = kernels.arx_fit_shifted_reference(a, reg, state0, cost._target, offset)
    assert ok.all() and b.shape == (a.shape[0], nb)
    old = None
    if kernels.compiled_available():
        old = kernels.arx_fit(a, reg, state0, cost._target, offset)[0]
    for i, (exact, bound, old_bound) in enumerate(lag_sum_bounds(cost, a, initial)):
        assert np.linalg.norm(b[i] - exact) <= bound
        if old is not None:
            assert np.linalg.norm(b[i] - old[i]) <= bound + old_bound


def lag_sum_bounds(cost, a, initial):
    """Per row of ``a``: the exact least-squares ``b`` (SVD of the reference regressors), the
    stated bound of the fit by lag sums, and that of the route of nb + 1 recursions."""
    na, nb = cost.structure.na, cost.n_params - cost.structure.na
    offset = 0 if initial == "measured" else cost.structure.start
    state0 = cost._state if initial == "measured" else np.zeros(na)
    reg = cost._phi_u_rows
    forced = np.vstack([np.zeros((1, reg.shape[0])), reg.T])
    out = []
    for row in a:
        rows = np.repeat(row[None], nb + 1, 0)
        states = np.zeros((nb + 1, na))
        states[0] = state0
        y = kernels.ar_recursion_reference(rows, forced, states)
        dy = ar_route_bound(rows, forced, states, y)[:, offset:]
        F, r = y[1:, offset:].T, cost._target - y[0, offset:]
        M, E, gamma = lag_sum_basis(cost, row, offset, state0)
        # the same regressors and free response by the basis: within the rounding of the
        # recursions of the columns, of v and h (amplified by |E|), and of the combination
        pair = np.repeat(row[None], 2, 0)
        inputs = np.vstack([reg[:, 0], np.eye(1, reg.shape[0])[0]])  # x and an impulse
        vh = kernels.ar_recursion_reference(pair, inputs, np.zeros(na))
        dM = ar_route_bound(pair, inputs, np.zeros(na), vh)
        scale_v, scale_h = dM[0].max(), dM[1].max()
        slack = (np.abs(E[:nb]).sum(0) * scale_v + np.abs(E[nb:]).sum(0) * scale_h
                 + route_tolerance_terms(M, E))  # fmt: skip
        assert np.all(np.abs(M @ E - F) <= dy[1:].max(axis=1)[None, :] + slack[None, :])
        sv = np.linalg.svd(F, compute_uv=False)
        kappa = sv[0] / sv[-1]
        exact = np.linalg.lstsq(F, r, rcond=None)[0]
        resid = float(np.linalg.norm(r - F @ exact))
        e = max(np.linalg.norm(dy[1:]) / sv[0], np.linalg.norm(dy[0]) / np.linalg.norm(r))
        assert kappa * e < 0.5
        perturbation = kappa * e / (1 - kappa * e) * (
            2 * np.linalg.norm(exact) + (kappa + 1) * resid / sv[0])  # fmt: skip
        ext = np.zeros(reg.shape[0] + 16)
        ext[0] = 1.0
        h_ext = signal.lfilter([1.0], np.r_[1.0, row], ext)  # h past the window: end terms
        normal = normal_equations_error(M, E, gamma, cost._target, exact, a=row,
                                        v=vh[0], h=h_ext) if offset == 0 else \
            normal_equations_error(M, E, gamma, cost._target, exact)  # fmt: skip
        own = lstsq_error(F, exact, resid)
        # arx_fit: the recursions' perturbation and its refined solve (first test above)
        out.append((exact, perturbation + normal + own, perturbation + 2 * own))
    return out


def route_tolerance_terms(M, E):
    """Rounding of the combination ``M E`` itself: ``n`` terms per entry, at most."""
    return M.shape[1] * EPS * (np.abs(M) @ np.abs(E)).max(axis=0)


@compiled
def test_fitted_costs_are_the_plain_costs_of_the_fitted_rows():
    # ARXCost.fitted runs the plain recursion at the fitted b inside the fit's kernel
    # (AR_BLOCK_IMPL itself, the same sums in the same order): exactly self(theta), also
    # for unstable and non-finite rows, which take the plain route
    cost, a = fitted_numerator_problem(8, 8, "measured")
    theta, costs = cost.fitted(a)  # every row stable: one call of the kernel
    np.testing.assert_array_equal(theta, cost.fit_numerator(a))
    np.testing.assert_array_equal(costs, cost(theta))
    a = np.vstack([a, np.full(8, 0.9), a[:1] * np.nan, a])
    theta, costs = cost.fitted(a)
    np.testing.assert_array_equal(theta, cost.fit_numerator(a))
    np.testing.assert_array_equal(costs, cost(theta))


@compiled
def test_arx_fit_shifted_does_not_depend_on_the_thread_count(simd):
    from flexid import _kernels

    cost, a = fitted_numerator_problem(4, 3, "measured")
    a = np.vstack([a] * 5)
    outs = []
    for n_threads in (1, 2, 3, 16):
        b, ok, sse = np.empty((a.shape[0], 3)), np.empty(a.shape[0], np.uint8), np.empty(a.shape[0])
        _kernels.arx_fit_shifted(a, cost._phi_u_rows, cost._state, cost._target, 0, 4,
                                 kernels.FIT_SHIFTED_TOL, b, ok, sse, n_threads)  # fmt: skip
        outs.append((b, sse))
    for b, sse in outs[1:]:
        np.testing.assert_array_equal(b, outs[0][0])
        np.testing.assert_array_equal(sse, outs[0][1])


@compiled
def test_rows_the_fit_by_lag_sums_flags_take_the_refined_route(monkeypatch):
    cost, a = fitted_numerator_problem(3, 2, "measured")
    real = kernels.arx_fit_shifted

    def flaky(*args, **kwargs):
        b, ok, sse = real(*args, **kwargs)
        ok[::2] = False
        return b, ok, sse

    monkeypatch.setattr(kernels, "arx_fit_shifted", flaky)
    want = cost._simulation_numerators_refined(a, 0, cost._state)
    got = cost.fit_numerator(a)[:, 3:]
    np.testing.assert_array_equal(got[::2], want[::2])
    np.testing.assert_array_equal(got[1::2], real(a, cost._phi_u_rows, cost._state,
                                                   cost._target, 0)[0][1::2])  # fmt: skip
    theta, costs = cost.fitted(a)
    np.testing.assert_array_equal(costs, cost(theta))


@compiled
def test_arx_fit_shifted_rejects_bad_arguments():
    from flexid import _kernels

    a = np.array([[-0.5], [0.2]])
    reg = np.ones((50, 2))
    b, ok = np.empty((2, 2)), np.empty(2, np.uint8)
    with pytest.raises(ValueError, match="arx_fit_shifted"):
        _kernels.arx_fit_shifted(a, reg, np.zeros(1), np.ones(50), 0, 3, 1e-2, b, ok, None)
    with pytest.raises(ValueError, match="arx_fit_shifted"):
        _kernels.arx_fit_shifted(a, reg, np.zeros(1), np.ones(49), 0, 1, 1e-2, b, ok, None)
    with pytest.raises(ValueError, match="arx_fit_shifted"):
        _kernels.arx_fit_shifted(a, reg, np.zeros(1), np.ones(49), 1, 1, 1e-2, b, ok,
                                 np.empty(2))  # fmt: skip
    # zero regressors: a singular Gram matrix, flagged
    _, ok2, _ = kernels.arx_fit_shifted(a, np.zeros((50, 2)), np.zeros(1), np.ones(50), 0)
    assert not ok2.any()


@compiled
@pytest.mark.parametrize("n", [2, 16, 18])
def test_initial_state_fit_computes_the_step_down_itself(simd, n):
    # without basis and energies the kernel runs the step-down of orthogonal_numerators and
    # _energies itself, compiled without contracted multiply-adds: the same basis, bit for
    # bit, on x86-64 (elsewhere within the rounding the fit tolerates); whole blocks of 4 per
    # thread, so the thread count changes nothing
    import platform

    from flexid.costs.polynomial import _energies, orthogonal_numerators

    if kernels.BACKEND != "c":
        pytest.skip("the reference path takes the basis as given")
    rng = np.random.default_rng(n)
    p, nb, k = 11, 5, 400
    a = stable_denominators(rng, p, n, (0.2, 0.95))
    b, reg, target = rng.normal(size=(p, nb)), rng.normal(size=(k, nb)), rng.normal(size=k)
    den = np.hstack([np.ones((p, 1)), a])
    T = orthogonal_numerators(den, n)
    E = _energies(den, T)
    given = kernels.initial_state_fit(a, b, reg, target, T, E)
    old = kernels.set_threads(1)
    try:
        own = kernels.initial_state_fit(a, b, reg, target)
        kernels.set_threads(3)
        own3 = kernels.initial_state_fit(a, b, reg, target)
    finally:
        kernels.set_threads(old)
    for x, y in zip(own, own3):
        np.testing.assert_array_equal(x, y)
    if platform.machine() in ("x86_64", "AMD64"):
        for x, y in zip(own, given):
            np.testing.assert_array_equal(x, y)
    else:
        np.testing.assert_allclose(own[0], given[0], rtol=1e-9)
    # a denominator whose step-down breaks down (not stable): NaN, the caller's fallback
    bad = a.copy()
    bad[3] = 0.0
    bad[3, -1] = 1.0
    sse = kernels.initial_state_fit(bad, b, reg, target, want_errors=False)[0]
    assert np.isnan(sse[3]) and np.isfinite(np.delete(sse, 3)).all()


@compiled
@pytest.mark.parametrize("n", [2, 15, 18, 24])
def test_initial_state_fit_equals_the_reference_where_the_impulse_response_stops(
    monkeypatch, simd, n
):
    # blocks of 4 that mix fast poles (radius 0.2-0.5: the impulse response stops early,
    # its tail after the record bounded below FREE_TAIL, and the Gram matrix is I) with a
    # lightly damped one (0.97-0.995: the whole response and the tail's Gram matrix), and
    # blocks of fast ones only; 11 rows, so the last block is partial.  The NumPy reference
    # forms the tail in every row.  In the fast rows both solve the same normalised system
    # (condition near 1) from errors that no pole amplifies, so they agree to a few
    # roundings (measured 2e-15 relative); the tail left out is below FREE_TAIL = 1e-17 of
    # the unit basis energy.  In the lightly damped rows the routes' errors from rest (a
    # compiled recursion against lfilter, sums in different orders) differ by their
    # roundings amplified by poles near the circle (measured up to 1.1e-9 relative): they
    # are here to make their blocks form the tail, so they are checked loosely
    from flexid.costs.polynomial import _energies, orthogonal_numerators

    monkeypatch.setattr(kernels, "BACKEND", "c")  # the compiled kernel, whatever the default
    rng = np.random.default_rng(100 + n)
    p, nb, k = 11, 6, 700
    slow = [1, 5]
    radius = [(0.97, 0.995) if i in slow else (0.2, 0.5) for i in range(p)]
    a = np.vstack([stable_denominators(rng, 1, n, r) for r in radius])
    b, reg, target = rng.normal(size=(p, nb)), rng.normal(size=(k, nb)), rng.normal(size=k)
    den = np.hstack([np.ones((p, 1)), a])
    T = orthogonal_numerators(den, n)
    E = _energies(den, T)
    sse, e, _ = kernels.initial_state_fit(a, b, reg, target)
    sse_only = kernels.initial_state_fit(a, b, reg, target, want_errors=False)[0]
    sse_r, e_r, _ = kernels.initial_state_fit_reference(a, b, reg, target, T, E)
    fast = np.setdiff1d(np.arange(p), slow)
    for got in (sse, sse_only):
        np.testing.assert_allclose(got[fast], sse_r[fast], rtol=1e-13)
        np.testing.assert_allclose(got[slow], sse_r[slow], rtol=1e-7)
    scale = np.sqrt(sse_r[fast])[:, None]
    assert (np.abs(e[fast] - e_r[fast]) <= 1e-13 * scale).all()

@compiled
@pytest.mark.parametrize(
    ("nf", "nc", "nd"), [(1, 1, 0), (8, 2, 2), (12, 2, 1), (16, 2, 2), (22, 2, 2)]
)
def test_initial_state_fit_cascade_equals_the_reference(monkeypatch, simd, nf, nc, nd):
    # the error from rest by the cascade e = (D/C)(target - f/F) (Box-Jenkins' one-step
    # error, kernels.initial_state_fit's first and noise), on every instruction set: orders
    # C F = 2 .. 24 (fused with the impulse response at 14 and below with 32 registers), 10
    # rows (a partial block).  Poles within radius 0.9, so no rounding is amplified much:
    # the compiled and NumPy routes (sums in different orders) agree to a few hundred
    # roundings
    from flexid.costs.polynomial import _energies, orthogonal_numerators, poly_mul_rows

    monkeypatch.setattr(kernels, "BACKEND", "c")  # the compiled kernel, whatever the default
    rng = np.random.default_rng(7 * nf + nc)
    p, nb, k = 10, 5, 500
    f = stable_denominators(rng, p, nf, (0.2, 0.9))
    c = stable_denominators(rng, p, nc, (0.2, 0.9))
    d = stable_denominators(rng, p, nd, (0.2, 0.9)) if nd else np.zeros((p, 0))
    ones = np.ones((p, 1))
    den = poly_mul_rows(np.hstack([ones, c]), np.hstack([ones, f]))
    n = nf + nc
    first = np.zeros((p, n))
    first[:, :nf] = f
    noise = np.zeros((p, 4))
    noise[:, :nc], noise[:, 2 : 2 + nd] = c, d
    b, reg, target = rng.normal(size=(p, nb)), rng.normal(size=(k, nb)), rng.normal(size=k)
    T = orthogonal_numerators(den, n)
    E = _energies(den, T)
    sse, e, _ = kernels.initial_state_fit(den[:, 1:], b, reg, target, first=first, noise=noise)
    sse_r, e_r, _ = kernels.initial_state_fit_reference(
        den[:, 1:], b, reg, target, T, E, first=first, noise=noise
    )
    np.testing.assert_allclose(sse, sse_r, rtol=1e-12)
    assert (np.abs(e - e_r) <= 1e-12 * np.sqrt(sse_r)[:, None]).all()
    # that the cascade's fitted errors are the single filter's: on the costs, against the
    # single-model lfilter route (tests/test_polynomial_cost.py, the bj_cascade structures)


@compiled
def test_initial_state_fit_does_not_depend_on_the_order_of_the_rows(monkeypatch, simd):
    # the kernel forms its blocks of 4 from the rows in the order of a decay probe (slowest
    # first), not in the population's: a permuted population gives each row the same block
    # companions, so the same numbers bit for bit (the probe's keys differ between rows)
    monkeypatch.setattr(kernels, "BACKEND", "c")  # the compiled kernel, whatever the default
    rng = np.random.default_rng(11)
    p, n, nb, k = 23, 12, 4, 600
    a = np.vstack([stable_denominators(rng, 1, n, (0.3, r)) for r in rng.uniform(0.5, 0.99, p)])
    b, reg, target = rng.normal(size=(p, nb)), rng.normal(size=(k, nb)), rng.normal(size=k)
    perm = rng.permutation(p)
    sse, e, coef = kernels.initial_state_fit(a, b, reg, target)
    sse_p, e_p, coef_p = kernels.initial_state_fit(a[perm], b[perm], reg, target)
    np.testing.assert_array_equal(sse_p, sse[perm])
    np.testing.assert_array_equal(e_p, e[perm])
    np.testing.assert_array_equal(coef_p, coef[perm])


@compiled
def test_fits_leave_the_floating_point_environment_as_found(monkeypatch):
    # the least-squares fits flush subnormal numbers to zero while they run,
    # on whichever thread runs a block, and restore the caller's setting after it: subnormal
    # arithmetic afterwards, in NumPy on this thread and in the plain recursion on the
    # helpers, is exact (0.5^t down to 2^-1074: every product by 0.5 is exact)
    monkeypatch.setattr(kernels, "BACKEND", "c")
    rng = np.random.default_rng(5)
    k, n = 1200, 4
    a = stable_denominators(rng, 64, n, (0.1, 0.3))
    reg = rng.normal(size=(k, n))
    target = rng.normal(size=k)
    old = kernels.set_threads(2)
    try:
        for _ in range(2):
            kernels.initial_state_fit(a, rng.normal(size=(64, n)), reg, target)
            shifted = np.column_stack([np.r_[np.zeros(j), target[: k - j]] for j in range(n)])
            kernels.arx_fit_shifted(a, shifted, np.zeros(n), target, 0, free_state=True)
            kernels.arx_fit(a, shifted, target[:n], target, 0)
        tiny = np.float64(2.0**-1022)
        assert tiny / 4 == 2.0**-1024 and tiny / 4 > 0
        impulse = np.zeros((1000, k))
        impulse[:, 0] = 1.0
        y = kernels.ar_recursion(np.full((1000, 1), -0.5), impulse, np.zeros(1))[0]
        np.testing.assert_array_equal(y, np.broadcast_to(0.5 ** np.arange(k), y.shape))
        assert y[0, 1073] == 2.0**-1073
    finally:
        kernels.set_threads(old)


@pytest.mark.numerics
@compiled
def test_output_error_numerator_with_the_estimated_state_by_lag_sums(monkeypatch):
    # OE under "estimate" (the default): B and the initial state at start fitted by lag sums
    # in one pass (free_state), within the stated bound of the exact solution, as is the
    # route of one recursion per coefficient of B and per free response
    from flexid.costs.polynomial import PolynomialCost
    from flexid.models.polynomial import PolynomialStructure

    monkeypatch.setattr(kernels, "BACKEND", "c")  # also under FLEXID_KERNELS=numpy
    nf, nb = 8, 8
    arx_cost, f = fitted_numerator_problem(nf, nb, "measured")
    oe = PolynomialStructure.oe(nb, nf, 1)
    cost = PolynomialCost(oe, (arx_cost.u, arx_cost.y), metric="sse", initial="estimate")
    X = np.zeros((len(f), oe.n_params))
    X[:, oe.slices()["f"][0]] = f
    fitted, theta = cost.fitted_costs(X)
    np.testing.assert_array_equal(fitted, cost(theta))  # the cost of the model returned
    got = theta[:, oe.b_columns]
    monkeypatch.setattr(kernels, "BACKEND", "numpy")
    by_recursions = cost.fit_numerator(X)[:, oe.b_columns]
    for i, (exact, bound) in enumerate(free_state_bounds(arx_cost, f)):
        assert np.linalg.norm(got[i] - exact) <= bound
        assert np.linalg.norm(by_recursions[i] - exact) <= bound


@pytest.mark.numerics
@compiled
@pytest.mark.parametrize("initial", ["measured", "zero"])
def test_output_error_numerator_is_arx_simulation_numerator(monkeypatch, initial):
    # OE(nb, nf, 1) under "zero" or "measured" predicts B/F u, ARX(nf, nb, 1)'s simulation
    # with A = F: its fitted B takes the same kernel on the same regressors, target, window
    # and initial state, so the same bits; and that fit is within the stated bound of the
    # exact least-squares solution (lag_sum_bounds); the route of one recursion per
    # coefficient, which the other structures (and the NumPy kernels) take, is within that of
    # its own kind
    from flexid.costs.polynomial import PolynomialCost
    from flexid.models.polynomial import PolynomialStructure

    monkeypatch.setattr(kernels, "BACKEND", "c")  # also under FLEXID_KERNELS=numpy
    nf, nb = 8, 8
    arx_cost, f = fitted_numerator_problem(nf, nb, initial)
    oe = PolynomialStructure.oe(nb, nf, 1)
    assert oe.start == arx_cost.structure.start
    cost = PolynomialCost(oe, (arx_cost.u, arx_cost.y), metric="sse", initial=initial)
    X = np.zeros((len(f), oe.n_params))
    X[:, oe.slices()["f"][0]] = f
    got = cost.fit_numerator(X)[:, oe.b_columns]
    np.testing.assert_array_equal(got, arx_cost.fit_numerator(f)[:, nf:])
    monkeypatch.setattr(kernels, "BACKEND", "numpy")
    by_recursions = cost.fit_numerator(X)[:, oe.b_columns]
    for i, (exact, bound, bound_recursions) in enumerate(lag_sum_bounds(arx_cost, f, initial)):
        assert np.linalg.norm(got[i] - exact) <= bound
        # recursions of the same rounding, then a refined least-squares solve: arx_fit's bound
        assert np.linalg.norm(by_recursions[i] - exact) <= bound_recursions


@pytest.mark.numerics
@compiled
@pytest.mark.parametrize("initial", ["zero", "estimate"])
@pytest.mark.parametrize("name", ["bj", "armax"])
def test_noise_model_numerator_by_lag_sums(monkeypatch, name, initial):
    # one-step predictors with C or D: the regressors are delays of (D / (C F)) u and the
    # target (D A / C) y, per candidate; B fitted by the lag sums with D on the input and
    # each candidate's target (from rest, or with the state at start fitted where the inputs
    # before start enter only through it), within the stated bound of the exact
    # least-squares solution (shifted_fit_bound), as is the route of one recursion per
    # coefficient; the fitted costs are the plain costs of the rows returned
    from flexid.costs.polynomial import PolynomialCost, _monic
    from flexid.models.polynomial import PolynomialStructure

    monkeypatch.setattr(kernels, "BACKEND", "c")  # also under FLEXID_KERNELS=numpy
    s = {"bj": PolynomialStructure.bj(4, 1, 2, 4, 1),
         "armax": PolynomialStructure.armax(3, 3, 2, 1)}[name]  # fmt: skip
    rng = np.random.default_rng(11)
    u = rng.uniform(-1, 1, 500)
    true = np.zeros(s.n_params)
    sl = s.slices()
    for part, poles in (("f", [0.9, 0.8]), ("a", [0.85, 0.7]), ("c", [0.5]), ("d", [0.6])):
        for key in ([sl["f"][0]] if part == "f" else [sl[part]]):
            width = key.stop - key.start
            if width:
                r = np.r_[[p * np.exp(1j * 0.7) for p in poles]][: width // 2]
                roots = np.r_[r, r.conj(), [0.3] * (width % 2)]
                true[key] = np.poly(roots).real[1:]
    true[s.b_columns] = rng.normal(size=s.nb[0])
    m = s.model(true)
    y = m.simulate(u) + 0.05 * signal.lfilter(m.c, np.convolve(m.d, m.a), rng.normal(size=500))
    cost = PolynomialCost(s, (u, y), metric="sse", initial=initial)
    assert cost._lag_sum_fit_filtered
    X = np.repeat(true[None], 5, 0)
    noisy = np.setdiff1d(np.arange(s.n_params), s.b_columns)
    X[:, noisy] += 0.01 * rng.normal(size=(5, noisy.size))
    assert cost._admissible(X).all()
    fitted, theta = cost.fitted_costs(X)
    np.testing.assert_array_equal(fitted, cost(theta))
    got = theta[:, s.b_columns]
    p = cost._parts(X)
    den = cost._predictor(p)[0]
    z = cost._filtered_target(p)
    free = initial == "estimate"
    offset = 0 if free else s.start
    b, ok, _ = kernels.arx_fit_shifted(den[:, 1:], cost._u_reg, np.zeros(den.shape[1] - 1),
                                       cost._target, offset, free_state=free, num=p["d"],
                                       targets=z)  # fmt: skip
    assert ok.all()  # every row by the lag sums, none by the recursions
    np.testing.assert_array_equal(b, got)
    monkeypatch.setattr(kernels, "BACKEND", "numpy")
    by_recursions = cost.fit_numerator(X)[:, s.b_columns]
    for i in range(len(X)):
        exact, bound = shifted_fit_bound(den[i, 1:], cost._u_reg, z[i], offset, free,
                                         d=_monic(X[i : i + 1, sl["d"]])[0])  # fmt: skip
        assert np.linalg.norm(got[i] - exact) <= bound
        assert np.linalg.norm(by_recursions[i] - exact) <= bound
