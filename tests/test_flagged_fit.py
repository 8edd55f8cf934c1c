"""The compiled orthogonal route of the fitted numerator (issue 44), against exact arithmetic.

``PolynomialCost._fitted_b_compiled`` (:func:`flexid.kernels.flagged_fit`) solves the least-
squares problem of ``PolynomialCost.b_regressors`` for one input, as
``_fitted_b_recursions`` does, with the regressors formed otherwise: one recursion of
``1/den`` and a lattice filter of it (the rules ``"zero"`` and ``"estimate"``), each
regressor's own recursion from ``start`` (``"measured"``), the free responses as lattice
filters of one impulse response. Both routes' regressors carry rounding errors of a few
``eps`` times the gain of ``1/den`` (the recursion's error, amplified by the poles next to
the circle: about 1e-10 relative at radius 0.99 and order 16), and both solve the normal
equations of the column-scaled regressors with refinement from the residual. So the bound
here: against the solution of the same problem with the regressors formed in long double
(80-bit, 11 more bits) and solved by SVD, the compiled route's error is at most ``RATIO``
times that of the recursions, plus a floor of ``FLOOR_EPS eps kappa^2`` (kappa the condition
number of the scaled regressors: the normal equations' own error, below which neither route
is meaningfully ranked). A wrong regressor, transient or free response would be off by many
orders of magnitude more.

The rows the lag-sum kernel accepts must not change at all: their ``B`` and sums of squares
are compared exactly with that kernel's own results.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import linalg, signal

from flexid import kernels
from flexid.costs import polynomial as pc
from flexid.costs.polynomial import PolynomialCost, orthogonal_numerators, poly_mul_rows
from flexid.errors import FlexidError
from flexid.models.polynomial import structure

EPS = np.finfo(float).eps
#: The compiled route's error may be this many times the recursions' (measured: at most 6,
#: next to the benchmark's poles; the two routes' regressors differ only in how they round).
RATIO = 20.0
#: The floor of the bound, in units of ``eps kappa^2``.
FLOOR_EPS = 1e3

compiled = pytest.mark.skipif(
    not kernels.flagged_fit_compiled(1, 1), reason="the compiled kernels are not in use"
)

LD = np.longdouble


def rec_ld(a: np.ndarray, f: np.ndarray) -> np.ndarray:
    """``y(t) = f(t) - sum_i a_i y(t - i)`` from rest, rows of ``a`` (R, n), in long double."""
    a, f = np.asarray(a, LD), np.asarray(f, LD)
    n = a.shape[1]
    y = np.zeros((a.shape[0], n + f.shape[1]), LD)
    rev = a[:, ::-1]
    for t in range(f.shape[1]):
        y[:, n + t] = f[:, t] - (rev * y[:, t : n + t]).sum(axis=1)
    return y[:, n:]


def fir_ld(c: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Rows ``sum_i c[r, i] x[r, t - i]`` (zeros before ``t = 0``), in long double."""
    c, x = np.asarray(c, LD), np.asarray(x, LD)
    out = np.zeros_like(x)
    for i in range(c.shape[1]):
        out[:, i:] += c[:, i : i + 1] * x[:, : x.shape[1] - i]
    return out


def exact_fit(cost: PolynomialCost, X: np.ndarray):
    """``b``, SSE and kappa of ``b_regressors``' problem, its regressors in long double.

    The target is the cost's own (float64, from ``b_regressors``): both routes share it, so
    its rounding is no difference between them.
    """
    s = cost.structure
    p = cost._parts(X)
    one_step = cost.predictor == "one-step"
    den = poly_mul_rows(p["c"] if one_step else p["a"], p["f"][0])
    n_pop, n, nb, nk = X.shape[0], den.shape[1] - 1, s.nb[0], s.nk[0]
    T = orthogonal_numerators(den, nb)
    sig = np.r_[np.zeros(nk), cost.u[: cost.N - nk, 0]]
    w = fir_ld(p["d"], np.broadcast_to(sig, (n_pop, cost.N)))
    a = den[:, 1:]
    if cost.initial == "measured":  # each regressor from rest at start
        regs = [rec_ld(a, fir_ld(T[:, m], w)[:, cost.start :]) for m in range(nb)]
    else:
        x = rec_ld(a, w)
        regs = [fir_ld(T[:, m], x)[:, cost.start :] for m in range(nb)]
    if cost.initial == "estimate":
        impulse = np.zeros((n_pop, cost.K))
        impulse[:, 0] = 1.0
        h = rec_ld(a, impulse)
        Tf = orthogonal_numerators(den, n)
        regs += [fir_ld(Tf[:, k], h) for k in range(n)]
    G = np.stack(regs, axis=1).astype(float)
    z = np.asarray(cost.b_regressors(X)[1], dtype=float)
    b, sse, kappa = np.empty((n_pop, nb)), np.empty(n_pop), np.empty(n_pop)
    for i in range(n_pop):
        A = G[i].T
        scale = np.sqrt((A * A).sum(axis=0))
        scale[scale == 0] = 1.0
        c = linalg.lstsq(A / scale, z[i])[0] / scale
        r = z[i] - A @ c
        sse[i] = r @ r
        b[i] = c[:nb] @ T[i]
        kappa[i] = np.linalg.cond(A / scale)
    return b, sse, kappa


def near_circle(n: int, count: int, rng: np.random.Generator, r_max: float) -> np.ndarray:
    """``count`` monic denominators' ``a_1..a_n`` (n even) of conjugate pole pairs, radii
    uniform in [0.9, r_max], angles uniform in (0.02, 3)."""
    out = np.empty((count, n))
    for i in range(count):
        poles = rng.uniform(0.9, r_max, n // 2) * np.exp(1j * rng.uniform(0.02, 3.0, n // 2))
        out[i] = np.poly(np.r_[poles, poles.conj()]).real[1:]
    return out


def record(rng: np.random.Generator, a: np.ndarray, n_samples: int = 600):
    u = rng.uniform(-0.3, 0.3, n_samples)
    b = rng.normal(size=a.size) * 0.05
    noise = signal.lfilter([1.0, 0.5], [1.0, -0.9], 0.01 * rng.standard_normal(n_samples))
    return u, signal.lfilter(np.r_[0.0, b], np.r_[1.0, a], u) + noise


def population(name: str, rng: np.random.Generator):
    """A structure, its record and candidates: random, and next to the circle (to 0.9985)."""
    if name in ("oe", "oe-wide"):
        # nb < nf, and nb > nf (numerators past the step-up: delays of the last one)
        nb, nf = (6, 8) if name == "oe" else (9, 4)
        s = structure("oe", nb=nb, nf=nf, nk=1)
        plant = near_circle(nf, 1, rng, 0.99)[0]
        f = np.r_[near_circle(nf, 4, rng, 0.9985),
                  plant + 1e-7 * rng.standard_normal((2, nf)),
                  near_circle(nf, 2, rng, 0.95)]  # fmt: skip
        X = np.c_[np.zeros((f.shape[0], nb)), f]
    else:  # Box-Jenkins: D on the input, a target per candidate
        s = structure("bj", nb=5, nc=2, nd=2, nf=6, nk=1)
        plant = near_circle(6, 1, rng, 0.99)[0]
        f = np.r_[near_circle(6, 4, rng, 0.9985), plant + 1e-7 * rng.standard_normal((2, 6))]
        cd = np.tile([-0.5, 0.1, 0.3, 0.05], (f.shape[0], 1))
        X = np.c_[np.zeros((f.shape[0], 5)), cd, f]
    return s, record(rng, plant), X


def _simd_levels() -> list[str]:
    """The compiled kernels' instruction sets this CPU runs (all, not only the best)."""
    if not kernels.flagged_fit_compiled(1, 1):
        return ["none"]
    from flexid import _kernels

    order = ["generic", "avx2", "avx512"]
    best = _kernels.simd()[1]
    return order[: order.index(best) + 1] if best in order else [best]


@pytest.fixture(params=_simd_levels())
def simd(request):
    """Run the kernels on one instruction set, then restore the one in use."""
    if request.param == "none":
        yield request.param
        return
    from flexid import _kernels

    before = _kernels.simd()[0]
    _kernels.simd(request.param)
    try:
        yield request.param
    finally:
        _kernels.simd(before)


@compiled
@pytest.mark.parametrize("initial", ["zero", "estimate", "measured"])
@pytest.mark.parametrize("name", ["oe", "oe-wide", "bj", "oe16"])
def test_compiled_route_is_as_exact_as_the_recursions(name, initial, simd):
    """Random and near-circle candidates (orders 6 and 8, where both routes are near eps), and
    the benchmark's OE(16,16,1) next to the plant's poles (both near 1e-9 to 1e-6), on every
    instruction set the CPU runs (their copies round differently: with or without fused
    multiply-adds).  The bound is over the population: the recursions' own error moves by
    orders of magnitude from row to row with the luck of their rounding (4.6e-11 on one row
    and 3.4e-9 on the next, next to the poles), so a row's error is held to RATIO times the
    largest of theirs, plus the floor."""
    if name == "oe16":
        s, data, X = benchmark_case()
    else:
        s, data, X = population(name, np.random.default_rng(44))
    cost = PolynomialCost(s, data, initial=initial)
    X = X[cost._admissible(X)]
    assert X.shape[0] >= 6
    b_ex, sse_ex, kappa = exact_fit(cost, X)
    b_c, sse_c, ok = cost._fitted_b_compiled(X)
    b_r, sse_r = cost._fitted_b_recursions(X)
    assert ok.all()
    floor = FLOOR_EPS * EPS * kappa**2
    scale = np.abs(b_ex).max(axis=1)
    err_c = np.abs(b_c - b_ex).max(axis=1) / scale
    err_r = np.abs(b_r - b_ex).max(axis=1) / scale
    assert (err_c <= RATIO * err_r.max() + floor).all(), (err_c, err_r, floor)
    serr_c, serr_r = np.abs(sse_c - sse_ex) / sse_ex, np.abs(sse_r - sse_ex) / sse_ex
    assert (serr_c <= RATIO * serr_r.max() + floor).all(), (serr_c, serr_r, floor)


def benchmark_case():
    """OE(16,16,1) on the record of benchmarks/bench_structures.py (8 modes at radius 0.99),
    candidates drawn at random and next to the plant's poles (the rows the lag sums flag)."""
    rng = np.random.default_rng(0)
    poles = 0.99 * np.exp(1j * np.array([0.05, 0.15, 0.3, 0.6, 0.9, 1.4, 2.0, 2.6]))
    plant = np.poly(np.r_[poles, poles.conj()]).real[1:]
    s = structure("oe", nb=16, nf=16, nk=1)
    f = np.r_[near_circle(16, 6, rng, 0.9), plant + 1e-7 * rng.standard_normal((6, 16))]
    f[:6] *= 0.85 ** np.arange(1, 17)  # poles at radius 0.77: accepted
    X = np.c_[np.zeros((12, 16)), f]
    return s, record(rng, plant, 1500), X


@compiled
@pytest.mark.parametrize("initial", ["zero", "estimate", "measured"])
def test_unflagged_rows_are_the_lag_sum_kernels_own(initial, monkeypatch):
    """A population of rows the lag-sum kernel accepts and rows it flags: the accepted rows'
    ``B`` and sums of squares are exactly the kernel's (and ``sse`` at that ``B``), the
    flagged rows' those of the compiled orthogonal route."""
    s, data, X = benchmark_case()
    cost = PolynomialCost(s, data, initial=initial)
    X = X[cost._admissible(X)]
    seen = {}
    real = kernels.arx_fit_shifted

    def spy(*args, **kwargs):
        seen["out"] = out = real(*args, **kwargs)
        return out

    monkeypatch.setattr(kernels, "arx_fit_shifted", spy)
    b, sse = cost._fitted_b(X)
    b_k, ok, sse_k = (x.copy() if x is not None else None for x in seen["out"])
    assert ok.any() and not ok.all()  # both kinds of row
    assert np.array_equal(b[ok], b_k[ok])
    theta = X[ok].copy()
    theta[:, s.b_columns] = b_k[ok]
    assert np.array_equal(sse[ok], sse_k[ok] if sse_k is not None else cost.sse(theta))
    b_c, sse_c, fine = cost._fitted_b_compiled(X[~ok])
    assert fine.all()
    assert np.array_equal(b[~ok], b_c) and np.array_equal(sse[~ok], sse_c)


@compiled
def test_rows_the_compiled_route_flags_take_the_recursions(monkeypatch):
    rng = np.random.default_rng(3)
    s, data, X = population("bj", rng)
    cost = PolynomialCost(s, data, initial="measured")
    X = X[cost._admissible(X)]
    real = kernels.flagged_fit

    def flaky(*args, **kwargs):
        coef, sse, ok = real(*args, **kwargs)
        ok[::2] = False
        return coef, sse, ok

    monkeypatch.setattr(kernels, "flagged_fit", flaky)
    b, sse = cost._fitted_b(X)
    b_r, sse_r = cost._fitted_b_recursions(X[::2])
    assert np.array_equal(b[::2], b_r) and np.array_equal(sse[::2], sse_r)


@compiled
def test_flagged_fit_does_not_depend_on_the_thread_count():
    rng = np.random.default_rng(5)
    s, data, X = population("oe", rng)
    cost = PolynomialCost(s, data, initial="estimate")
    X = np.repeat(X[cost._admissible(X)], 3, axis=0)  # several blocks of 4
    before = kernels.set_threads(1)
    try:
        one = cost._fitted_b_compiled(X)
        kernels.set_threads(2)
        kernels._THREAD_MIN_WORK, keep = 1, kernels._THREAD_MIN_WORK
        try:
            two = cost._fitted_b_compiled(X)
        finally:
            kernels._THREAD_MIN_WORK = keep
    finally:
        kernels.set_threads(before)
    for x, y in zip(one, two):
        assert np.array_equal(x, y)


@compiled
def test_flagged_fit_rejects_bad_arguments():
    a = np.full((2, 2), 0.1)
    sig, target = np.ones(20), np.ones(15)
    with pytest.raises(FlexidError, match="target or targets"):
        kernels.flagged_fit(a, 3, sig, target, np.ones((2, 15)), tol=1e-9)
    with pytest.raises(FlexidError, match="out of range"):
        kernels.flagged_fit(a, 17, sig, target, tol=1e-9)
    with pytest.raises(ValueError, match="flagged_fit"):
        kernels.flagged_fit(a, 3, sig, np.ones(21), tol=1e-9)
    with pytest.raises(FlexidError, match="shared target"):
        kernels.flagged_fit(a, 3, sig, None, np.ones((2, 15)), state=np.ones(2), tol=1e-9)
    with pytest.raises(ValueError, match="flagged_fit"):
        kernels.flagged_fit(a, 3, sig, target, state=np.ones(3), restart=True, tol=1e-9)
    # zero regressors: a singular Gram matrix, flagged
    _, _, ok = kernels.flagged_fit(a, 3, np.zeros(20), target, tol=1e-9)
    assert not ok.any()


def test_the_numpy_route_is_the_recursions(monkeypatch):
    """Without the compiled kernels every row takes the recursions (the reference route)."""
    monkeypatch.setattr(kernels, "BACKEND", "numpy")
    rng = np.random.default_rng(1)
    s, data, X = population("oe", rng)
    cost = PolynomialCost(s, data, initial="zero")
    X = X[cost._admissible(X)]
    assert not cost._compiled_fit
    with pytest.raises(FlexidError, match="not in use"):
        kernels.flagged_fit(np.full((1, 2), 0.1), 2, np.ones(9), np.ones(5), tol=1e-9)
    called = []
    monkeypatch.setattr(pc.PolynomialCost, "_fitted_b_compiled",
                        lambda self, X: called.append(1))  # fmt: skip
    b, sse = cost._fitted_b(X)
    b_r, sse_r = cost._fitted_b_recursions(X)
    assert not called and np.array_equal(b, b_r) and np.array_equal(sse, sse_r)


@compiled
def test_the_measured_free_response_formed_in_the_kernel_is_the_recursions():
    """Under "measured" with no output numerator the kernel subtracts the free response from
    the past outputs itself: the same fit as with the targets formed by ar_recursion (to the
    refinement's tolerance: the two targets differ in rounding only)."""
    s, data, X = benchmark_case()
    cost = PolynomialCost(s, data, initial="measured")
    X = X[cost._admissible(X)]
    p = cost._parts(X)
    den = poly_mul_rows(p["a"], p["f"][0])
    n = den.shape[1] - 1
    y0, _ = kernels.ar_recursion(den[:, 1:], np.zeros((X.shape[0], cost.K)), cost._state[:n])
    sig = np.r_[0.0, cost.u[: cost.N - 1, 0]]
    common = dict(restart=True, tol=pc._REFINE_TOL)
    b_s, sse_s, ok_s = kernels.flagged_fit(den[:, 1:], s.nb[0], sig, cost._target,
                                           state=cost._state[:n], **common)  # fmt: skip
    b_t, sse_t, ok_t = kernels.flagged_fit(den[:, 1:], s.nb[0], sig, None, cost._target - y0,
                                           **common)  # fmt: skip
    assert ok_s.all() and ok_t.all()
    # 1e-6: the coefficients of the P_m move by the targets' rounding times the problem's
    # conditioning (kappa about 3, gains about 1e5 next to these poles)
    np.testing.assert_allclose(b_s, b_t, rtol=1e-6, atol=1e-6 * np.abs(b_t).max())
    np.testing.assert_allclose(sse_s, sse_t, rtol=1e-9)
    # and a wrong state is seen
    b_w, _, _ = kernels.flagged_fit(den[:, 1:], s.nb[0], sig, cost._target,
                                    state=cost._state[:n] + 1.0, **common)  # fmt: skip
    assert np.abs(b_w - b_t).max() > 1e-3 * np.abs(b_t).max()
