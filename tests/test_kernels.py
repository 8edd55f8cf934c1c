"""The compiled kernels against the NumPy/SciPy reference path (flexid.kernels)."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest
from scipy import signal

from flexid import kernels
from flexid.arx import ARXStructure
from flexid.objective import ARXCost
from flexid.stability import is_stable, is_stable_reference

compiled = pytest.mark.skipif(
    not kernels.compiled_available(), reason="flexid._kernels was not built (no C compiler)"
)


def test_compiled_kernels_built_when_required():
    # .ci/run sets FLEXID_REQUIRE_KERNELS=1 where a C compiler exists, so that CI cannot
    # silently test the fallback only
    if os.environ.get("FLEXID_REQUIRE_KERNELS") == "1":
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


@compiled
def test_schur_cohn_compiled_equals_reference():
    rng = np.random.default_rng(1)
    for n in range(0, 17):
        a = rng.normal(size=(700, n)) * rng.uniform(0.05, 1.5, size=(700, 1))
        a[::50] = np.nan
        a[1::50] = np.inf
        ref = is_stable_reference(a)
        got = kernels.schur_cohn_compiled(a)
        assert got.dtype == bool and got.shape == (700,)
        np.testing.assert_array_equal(got, ref)
        if n:
            assert not got[::50].any() and not got[1::50].any()


@compiled
def test_schur_cohn_compiled_on_roots_near_the_circle():
    rng = np.random.default_rng(2)
    for eps in (1e-6, 1e-7):
        for sign in (-1, 1):
            a = stable_denominators(rng, 200, 8, radius=(0.3, 0.9))
            # move one real root to 1 +- eps
            factor = np.r_[1.0, -(1.0 + sign * eps)]
            polys = np.array([np.polymul(factor, np.r_[1.0, row]) for row in a])
            got = kernels.schur_cohn_compiled(polys[:, 1:])
            assert got.all() == (sign < 0) and got.any() == (sign < 0)


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
    scale = np.abs(ref).max(axis=1, keepdims=True)
    # both are the exact recursion, rounded differently; poles up to radius 0.999 at
    # order 12 amplify that to ~1e-13 of the output scale
    assert np.all(np.abs(y - ref) <= 1e-10 * scale)
    np.testing.assert_allclose(sse, ((target - ref) ** 2).sum(axis=1), rtol=1e-10)
    y2, sse2 = kernels.ar_recursion(a, forced, state, target, want_output=False)
    assert y2 is None
    np.testing.assert_array_equal(sse2, sse)
    y3, sse3 = kernels.ar_recursion(a, forced, state)
    assert sse3 is None
    np.testing.assert_array_equal(y3, y)


def test_ar_recursion_shorter_record_than_order():
    rng = np.random.default_rng(3)
    a = stable_denominators(rng, 3, 6)
    forced = rng.normal(size=(3, 4))
    state = rng.normal(size=6)
    y, _ = kernels.ar_recursion(a, forced, state)
    ref = kernels.ar_recursion_reference(a, forced, state)
    np.testing.assert_allclose(y, ref, rtol=1e-12, atol=1e-14)


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
    np.testing.assert_array_equal(is_stable(a), is_stable_reference(a))
    c_values = cost(X)
    monkeypatch.setattr(kernels, "BACKEND", "numpy")
    ref = cost(X)
    np.testing.assert_allclose(c_values, ref, rtol=1e-11)
    assert np.isinf(c_values[5]) and c_values[3] > 1e9


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
