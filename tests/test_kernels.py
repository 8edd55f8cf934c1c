"""The compiled kernels against the NumPy/SciPy reference path (flexid.kernels).

The compiled kernels round differently from the reference path (the AVX2/FMA clone fuses
``acc - c y`` into one rounding; SIMD lanes; another summation order), so values are
compared within the rounding bounds of tests/route_bounds.py and decisions (stable or not)
exactly only where a margin shows that rounding cannot flip them.  These tests carry the
``numerics`` mark.
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
from flexid.models.arx import ARXStructure
from flexid.models.stability import is_stable, is_stable_reference
from numerics import EPS, assert_close_to_terms
from route_bounds import ar_route_bound, sse_route_bound

compiled = pytest.mark.skipif(
    not kernels.compiled_available(), reason="flexid._kernels was not built (no C compiler)"
)


def test_compiled_kernels_run_when_required():
    # .ci/run sets FLEXID_KERNELS=c where a C compiler exists, so that CI cannot silently
    # test the fallback only; the import already fails without the build, this names why
    if os.environ.get("FLEXID_KERNELS", "").strip().lower() == "c":
        assert kernels.compiled_available()
        assert kernels.BACKEND == "c"


def stable_denominators(rng, p, na, radius=(0.2, 0.999)):
    """Random real polynomials with all roots inside the circle (conjugate pairs + reals)."""
    out = np.empty((p, na))
    for i in range(p):
        roots = []
        while len(roots) < na:
            r = rng.uniform(*radius)
            if na - len(roots) >= 2 and rng.random() < 0.7:
                w = rng.uniform(0, np.pi)
                roots += [r * np.exp(1j * w), r * np.exp(-1j * w)]
            else:
                roots.append(r * rng.choice([-1.0, 1.0]))
        out[i] = np.poly(roots).real[1:]
    return out


def flip_margin(row: np.ndarray) -> float:
    """How far the Schur-Cohn decisions of ``row`` are from flipping under rounding (> 0: safe).

    Step ``m`` maps ``c -> (c - k rev(c)) / (1 - k^2)`` with ``k = c[m-1]``: an error ``err``
    already in ``c`` grows by at most ``1/(1-|k|) + (max|c| + 2|k| max|c'|) / (1 - k^2)``
    (first order), and the step adds at most ``4 eps (max|c| (1+|k|) / (1 - k^2) + max|c'|)``
    (two roundings before the division, the division, ``1 - k^2``; twice the unit roundoff
    per rounding for safety), whatever the order or FMA.  Two routes each within ``err`` of the
    exact ``k`` decide alike while ``||k| - 1| > 2 err``.
    """
    c = np.array(row, dtype=float)
    err, margin = 0.0, np.inf
    for m in range(c.size, 0, -1):
        k = c[m - 1]
        margin = min(margin, abs(abs(k) - 1.0) - 2 * err)
        if not abs(k) < 1.0 or m == 1:
            break
        head = c[: m - 1]
        d = 1.0 - k * k
        new = (head - k * head[::-1]) / d
        cmax, nmax = np.abs(head).max(), np.abs(new).max()
        err = err * (1 / (1 - abs(k)) + (cmax + 2 * abs(k) * nmax) / d) + 4 * EPS * (
            cmax * (1 + abs(k)) / d + nmax
        )
        c = new
    return margin


@pytest.mark.numerics
@compiled
def test_schur_cohn_compiled_equals_reference():
    rng = np.random.default_rng(1)
    for n in range(0, 17):
        a = rng.normal(size=(700, n)) * rng.uniform(0.05, 1.5, size=(700, 1))
        a[::50] = np.nan
        a[1::50] = np.inf
        # decisions, compared exactly: every finite row is certified to be further from a
        # flip than the rounding of either route (FMA or not) can move it
        finite = np.isfinite(a).all(axis=1)
        if n:
            assert min(flip_margin(row) for row in a[finite]) > 0
        ref = is_stable_reference(a)
        got = kernels.schur_cohn_compiled(a)
        assert got.dtype == bool and got.shape == (700,)
        np.testing.assert_array_equal(got, ref)
        if n:
            assert not got[::50].any() and not got[1::50].any()


@pytest.mark.numerics
@compiled
def test_schur_cohn_compiled_on_roots_near_the_circle():
    # against the truth: a root 1e-6..1e-7 from the circle, the others at radius <= 0.9, is
    # moved by rounding (of np.polymul and of the recursion, ~10 eps relative per step) by
    # orders of magnitude less than its distance; the FMA clone and the generic one must
    # both decide it
    rng = np.random.default_rng(2)
    for eps in (1e-6, 1e-7):
        for sign in (-1, 1):
            a = stable_denominators(rng, 200, 8, radius=(0.3, 0.9))
            # move one real root to 1 +- eps
            factor = np.r_[1.0, -(1.0 + sign * eps)]
            polys = np.array([np.polymul(factor, np.r_[1.0, row]) for row in a])
            got = kernels.schur_cohn_compiled(polys[:, 1:])
            assert got.all() == (sign < 0) and got.any() == (sign < 0)


@pytest.mark.numerics
@pytest.mark.parametrize("na", [0, 1, 2, 5, 8, 12])
@pytest.mark.parametrize("p", [1, 15, 16, 17, 50])
@pytest.mark.parametrize("shared_state", [True, False])
def test_ar_recursion_equals_lfilter(na, p, shared_state):
    rng = np.random.default_rng(na * 100 + p)
    k = 300
    a = stable_denominators(rng, p, na) if na else np.zeros((p, 0))
    forced = rng.normal(size=(p, k))
    state = rng.normal(size=na) if shared_state else rng.normal(size=(p, na))
    target = rng.normal(size=k)
    y, sse = kernels.ar_recursion(a, forced, state, target)
    ref = np.empty((p, k))
    for i in range(p):
        den = np.r_[1.0, a[i]]
        s = state if shared_state else state[i]
        if na:
            ref[i] = signal.lfilter([1.0], den, forced[i], zi=signal.lfiltic([1.0], den, s))[0]
        else:
            ref[i] = forced[i]
    # both are the exact recursion, rounded differently: na + 1 terms per step, the
    # difference filtered by 1/A(q) (poles up to radius 0.999 amplify it up to ~1e3 x)
    dy = ar_route_bound(a, forced, state, ref)
    assert_close_to_terms(y, ref, dy, 1.0)
    e = target - ref
    assert_close_to_terms(sse, (e * e).sum(axis=1), sse_route_bound(e, dy), 1.0)
    # without outputs: the same kernel and block layout (same P), so exactly the same sums
    y2, sse2 = kernels.ar_recursion(a, forced, state, target, want_output=False)
    assert y2 is None
    np.testing.assert_array_equal(sse2, sse)
    y3, sse3 = kernels.ar_recursion(a, forced, state)
    assert sse3 is None
    np.testing.assert_array_equal(y3, y)


@pytest.mark.numerics
def test_ar_recursion_shorter_record_than_order():
    rng = np.random.default_rng(3)
    a = stable_denominators(rng, 3, 6)
    forced = rng.normal(size=(3, 4))
    state = rng.normal(size=6)
    y, _ = kernels.ar_recursion(a, forced, state)
    ref = kernels.ar_recursion_reference(a, forced, state)
    # the compiled and the reference recursion (the same path with FLEXID_KERNELS=numpy)
    assert_close_to_terms(y, ref, ar_route_bound(a, forced, state, ref), 1.0)


@compiled
def test_compiled_ar_run_rejects_bad_buffers():
    from flexid import _kernels

    a = np.zeros((4, 2))
    f = np.zeros((4, 10))
    with pytest.raises(ValueError, match="differ in P"):
        _kernels.ar_run(a, np.zeros((3, 10)), np.zeros(2), None, None, None)
    with pytest.raises(ValueError, match="state"):
        _kernels.ar_run(a, f, np.zeros(3), None, None, None)
    with pytest.raises(ValueError, match="target"):
        _kernels.ar_run(a, f, np.zeros(2), np.zeros(9), None, None)
    with pytest.raises(ValueError, match="y_out"):
        _kernels.ar_run(a, f, np.zeros(2), None, np.zeros((4, 9)), None)
    with pytest.raises(TypeError, match="format"):
        _kernels.ar_run(a.astype(np.float32), f, np.zeros(2), None, None, None)
    with pytest.raises(TypeError, match="C-contiguous"):
        _kernels.ar_run(np.zeros((2, 4)).T, f, np.zeros(2), None, None, None)
    with pytest.raises(TypeError, match="writable"):
        out = np.zeros(4)
        out.flags.writeable = False
        _kernels.ar_run(a, f, np.zeros(2), None, None, out)
    with pytest.raises(ValueError, match="schur_cohn"):
        _kernels.schur_cohn(a, np.zeros(3, np.uint8))


@compiled
def test_compiled_twin_rotor_run_checks_buffers_and_fills_out():
    # Its numbers are held to the reference route in tests/test_twin_rotor.py; here the glue:
    # the argument checks, and out holding the state after each sample.  The same kernel on
    # the same rotors with and without out does the same arithmetic: equal exactly.
    from flexid import _kernels
    from flexid.envs.twin_rotor_physics import TwinRotorParameters
    from flexid.envs.twin_rotor_steppers import _kernel_params

    k = _kernel_params(TwinRotorParameters())
    rng = np.random.default_rng(5)
    batch, samples = 6, 9
    x0 = rng.normal(0.0, 0.3, (batch, 7))
    u = rng.uniform(-2.5, 2.5, (samples, batch, 2))
    out = np.full((samples, batch, 7), np.nan)
    x = x0.copy()
    _kernels.twin_rotor_run(k, x, u, out, 10, 0.01, False, False)
    np.testing.assert_array_equal(out[-1], x)
    assert np.all(np.isfinite(out)) and np.all(out[0] != x0)
    for s in range(samples):  # sample by sample, without out: the same states
        x1 = (x0 if s == 0 else out[s - 1]).copy()
        _kernels.twin_rotor_run(k, x1, u[s : s + 1], None, 10, 0.01, False, False)
        np.testing.assert_array_equal(x1, out[s])
    with pytest.raises(ValueError, match="params"):
        _kernels.twin_rotor_run(k[:-1], x, u, None, 10, 0.01, False, False)
    with pytest.raises(ValueError, match="x \\(B, 7\\)"):
        _kernels.twin_rotor_run(k, x[:-1], u, None, 10, 0.01, False, False)
    with pytest.raises(ValueError, match="n_sub"):
        _kernels.twin_rotor_run(k, x, u, None, 0, 0.01, False, False)
    with pytest.raises(ValueError, match="out must be"):
        _kernels.twin_rotor_run(k, x, u, out[:, 1:].copy(), 10, 0.01, False, False)
    with pytest.raises(TypeError, match="writable"):
        x.flags.writeable = False
        _kernels.twin_rotor_run(k, x, u, None, 10, 0.01, False, False)


@pytest.mark.numerics
@compiled
@pytest.mark.parametrize("predictor", ["one-step", "simulation"])
@pytest.mark.parametrize("initial", ["measured", "zero"])
def test_cost_is_the_same_on_both_backends(monkeypatch, predictor, initial):
    rng = np.random.default_rng(4)
    u = rng.uniform(-1, 1, 600)
    y = signal.lfilter([0, 0.3, 0.1], [1, -1.5, 0.7], u) + 0.01 * rng.standard_normal(600)
    s = ARXStructure(4, 3, 1)
    cost = ARXCost(s, (u, y), predictor=predictor, initial=initial)
    X = cost.theta_ls + 0.05 * rng.normal(size=(37, s.n_params))
    X[3] *= 40  # unstable rows, penalised on both paths
    X[5, 2] = np.nan
    a = X[np.isfinite(X).all(axis=1), :4]
    monkeypatch.setattr(kernels, "BACKEND", "c")  # also when FLEXID_KERNELS=numpy
    np.testing.assert_array_equal(is_stable(a), is_stable_reference(a))
    c_values = cost(X)
    monkeypatch.setattr(kernels, "BACKEND", "numpy")
    ref = cost(X)
    assert np.isinf(c_values[5]) and c_values[3] > 1e9
    ok = np.isfinite(X).all(axis=1) & is_stable_reference(X[:, :4])
    if predictor == "one-step":
        # the backends share every operation but the stability test, whose decisions agree
        np.testing.assert_array_equal(c_values, ref)
        return
    # unstable rows take the same penalty path on both; stable ones differ by the rounding
    # of the recursion and of the forced term (the compiled route computes it in the kernel,
    # the NumPy one by a GEMM: nb = 3 terms each), then of the SSE
    np.testing.assert_array_equal(c_values[~ok], ref[~ok])
    Xs = X[ok]
    forced = Xs[:, 4:] @ cost._phi_u_t
    state = cost._state if initial == "measured" else np.zeros(4)
    yref = kernels.ar_recursion_reference(Xs[:, :4], forced, state)
    dy = ar_route_bound(Xs[:, :4], forced, state, yref,
                        np.abs(Xs[:, 4:]) @ np.abs(cost._phi_u_t), 3)  # fmt: skip
    if initial == "zero":
        yref, dy = yref[:, s.start :], dy[:, s.start :]
    e = cost._target - yref
    sse = (e * e).sum(axis=1)
    # cost = w sqrt(sse) / K: relative change half that of the SSE, plus 3 roundings each
    rel = sse_route_bound(e, dy) / (2 * sse) + 3 * EPS
    assert_close_to_terms(c_values[ok], ref[ok], rel * ref[ok], 1.0)


def run_python(code: str, value: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, FLEXID_KERNELS=value)
    return subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120
    )


def test_environment_variable_selects_the_backend():
    done = run_python("from flexid import kernels; print(kernels.BACKEND)", "numpy")
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "numpy"
    bad = run_python("import flexid.kernels", "fortran")
    assert bad.returncode != 0
    assert "FLEXID_KERNELS must be" in bad.stderr
    forced = run_python("from flexid import kernels; print(kernels.BACKEND)", "c")
    if kernels.compiled_available():
        assert forced.stdout.strip() == "c", forced.stderr
    else:
        assert forced.returncode != 0 and "were not built" in forced.stderr
