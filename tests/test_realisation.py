"""Every reported fit holds against the exact model: the well-conditioned realisation
(:mod:`flexid.models.realisation`) against the direct-form recursion computed with 100
significant digits (``mpmath``).

A model *is* its coefficients (exact doubles).  The reference forms that model's direct form,
``den(q) yhat = num_y(q) y + sum_j num_j(q) u_j`` (the products of its polynomials exactly),
runs it and fits its ``n`` free responses by least
squares, all in 100-digit arithmetic: no root, no section, nothing shared with the route under
test.  The models are lightly damped (damping ratios 0.001-0.05, modes clustered in
frequency) up to order 24, the case where the float64 direct form is off by up to ``1e6``
percentage points.

The stated bound, :data:`FIT_BOUND`: every fit within ``1e-8`` percentage points of the exact
one.  It holds because the realisation's only errors are the roots' last bit (the Aberth
iteration on a double-double polynomial lands within an ulp of each root, whatever
:func:`numpy.roots` started from) and the sections' own rounding, which lightly damped
second-order sections amplify by about ``1/(1 - r)``; measured on these models: at most
``1e-12`` points, so the bound leaves four orders of magnitude for other LAPACK and BLAS
builds.
"""

from __future__ import annotations

import numpy as np
import pytest

from flexid.models.polynomial import PolynomialStructure, run_predictor
from flexid.models.realisation import accurate_roots
from flexid.validation.diagnostics import fit_percent

mp = pytest.importorskip("mpmath")

pytestmark = pytest.mark.numerics

FIT_BOUND = 1e-8  # percentage points (module docstring)
DIGITS = 100

# OE(16, 16, 1) of the home-built twin rotor's pitch (DE, 10,000 FE): F has two real poles
# next to z = 1 that numpy.roots returns as a complex pair 1e-2 away
TWIN_ROTOR_F = np.array([
    1.0, -9.1257232956320227, 37.334373996706610, -90.037820587308317,
    141.41124674564054, -150.50499752110122, 109.06807130474887, -52.245549375617728,
    15.129701022511789, -1.9830677473382199, -0.075237311565754042, 0.025003662307131212,
    0.0037885289205048345, 2.2016240053867486e-04, -9.1363648823421519e-06,
    -4.8791970492145488e-07, 3.9611866532642509e-08,
])
TWIN_ROTOR_B = np.array([
    -4.6874967757977445e-05, 0.008820901999545596, -0.05893530290156612, 0.17127845126716404,
    -0.28141567695781305, 0.2966643992365109, -0.24163899725310342, 0.22008659794949048,
    -0.2711336210988409, 0.3665435295119803, -0.45057287293030074, 0.4426627215043779,
    -0.3146737578891611, 0.14876583380693148, -0.04160807979792104, 0.0052027485205696404,
])


def exact_polynomials(model, k):
    """``den``, ``num_y`` and ``num_j`` of the predictor, the products formed exactly."""

    def mul(*polys):
        out = [mp.mpf(1)]
        for p in polys:
            q = [mp.mpf(0)] * (len(out) + len(p) - 1)
            for i, x in enumerate(out):
                for j, c in enumerate(p):
                    q[i + j] += x * c
            out = q
        return out

    def exact(p):
        return [mp.mpf(float(v)) for v in p]

    with mp.workdps(DIGITS):
        s = model.structure
        f = [exact(fj) for fj in model.f]
        b = [[mp.mpf(0)] * s.nk[j] + exact(bj) for j, bj in enumerate(model.b)]
        lead = exact(model.d) if k == 1 else [mp.mpf(1)]
        nums = [mul(lead, b[j], *[fi for i, fi in enumerate(f) if i != j])
                for j in range(s.n_inputs)]  # fmt: skip
        if k != 1:
            return mul(exact(model.a), *f), [mp.mpf(0)], nums
        den = mul(exact(model.c), *f)
        daf = mul(exact(model.d), exact(model.a), *f)
        width = max(len(den), len(daf))
        num_y = [(den[i] if i < len(den) else 0) - (daf[i] if i < len(daf) else 0)
                 for i in range(width)]  # fmt: skip
        return den, num_y, nums


def exact_predictor(den, num_y, nums, u, y, start, initial):
    """The direct form of one model at ``DIGITS`` significant digits (see the docstring).

    ``initial``: ``"zero"`` (from rest at ``t = 0``), ``"estimate"`` (MATLAB's: the state at
    ``t = 0`` of the observer canonical form of order ``max(deg den, deg num)``, fitted to
    every sample) or ``"estimate-start"`` (the costs': the direct form's ``n`` past outputs at
    ``t = start``, fitted to ``t >= start``, the samples before it the measured outputs).
    """
    with mp.workdps(DIGITS):
        n = len(den) - 1
        a = den
        N = len(y)
        Y = [mp.mpf(float(v)) for v in y]
        f = [mp.mpf(0)] * N
        signals = [(num_y, Y)] + [
            (nums[j], [mp.mpf(float(v)) for v in u[:, j]]) for j in range(u.shape[1])
        ]
        for num, x in signals:
            b = [(i, v) for i, v in enumerate(num) if v != 0]
            for t in range(N):
                f[t] += mp.fsum(bi * x[t - i] for i, bi in b if t >= i)

        def recursion(forcing, past):
            out = list(past)
            for ft in forcing:
                out.append(ft - mp.fsum(a[i] * out[-i] for i in range(1, n + 1)))
            return out[n:]

        if initial == "zero":
            return recursion(f, [mp.mpf(0)] * n)
        if initial == "estimate":
            first, base = 0, recursion(f, [mp.mpf(0)] * n)
            order = max(n, *(len(num) - 1 for num, _ in signals))
            padded = list(a) + [mp.mpf(0)] * (order + 1 - len(a))
            cols = []
            for i in range(order):  # y(t) = x_1(t), x_k(t+1) = -a_k x_1(t) + x_(k+1)(t)
                x = [mp.mpf(0)] * order
                x[i] = mp.mpf(1)
                col = []
                for _ in range(N):
                    col.append(x[0])
                    x = [-padded[k + 1] * x[0] + (x[k + 1] if k + 1 < order else 0)
                         for k in range(order)]  # fmt: skip
                cols.append(col)
        else:
            first, base = start, recursion(f[start:], [mp.mpf(0)] * n)
            cols = []
            for i in range(n):
                past = [mp.mpf(0)] * n
                past[n - 1 - i] = mp.mpf(1)
                cols.append(recursion([mp.mpf(0)] * (N - start), past))
        K, m = N - first, len(cols)
        r = [Y[first + t] - base[t] for t in range(K)]
        # normal equations: with 100 digits the direct form's conditioning (squared) still
        # leaves tens of correct digits
        G = mp.matrix(m, m)
        h = mp.matrix(m, 1)
        for i in range(m):
            h[i] = mp.fsum(cols[i][t] * r[t] for t in range(K))
            for j in range(i, m):
                G[i, j] = G[j, i] = mp.fsum(cols[i][t] * cols[j][t] for t in range(K))
        x = mp.lu_solve(G, h) if m else []
        return Y[:first] + [
            base[t] + mp.fsum(cols[i][t] * x[i] for i in range(m)) for t in range(K)
        ]


def exact_fit(y, yhat, start):
    with mp.workdps(50):
        ys = [mp.mpf(float(v)) for v in y[start:]]
        mean = mp.fsum(ys) / len(ys)
        err = mp.sqrt(mp.fsum((ys[t] - yhat[start + t]) ** 2 for t in range(len(ys))))
        scale = mp.sqrt(mp.fsum((v - mean) ** 2 for v in ys))
        return float(100 * (1 - err / scale))


def lightly_damped(rng, n):
    """Monic ``[1, a_1 .. a_n]`` of clustered modes, damping 0.001-0.05 (and a real pole)."""
    poles = []
    w0 = rng.uniform(0.01, 0.2)
    for i in range(n // 2):
        w = w0 * (1 + 0.15 * i) if rng.random() < 0.6 else rng.uniform(0.01, 2.5)
        zeta = 10 ** rng.uniform(-3, -1.3)
        p = np.exp(-zeta * w) * np.exp(1j * w * np.sqrt(1 - zeta**2))
        poles += [p, np.conj(p)]
    if n % 2:
        poles.append(rng.uniform(0.99, 0.9995))
    return np.poly(poles).real


def record(rng, model, n_samples=400):
    u = np.sign(rng.normal(size=(n_samples, model.structure.n_inputs)))
    clean = model.simulate(u)
    y = clean + 0.5 * np.std(clean) * rng.normal(size=n_samples)
    return u, y + np.cumsum(rng.normal(size=n_samples)) * 0.01 * np.std(y)  # a slow drift


def check(model, u, y, k, initial):
    """The reported fit (every sample, MATLAB's rule) against the exact model's; returns the
    exact fit and the float64 direct form's of the costs' rule (``t >= start``)."""
    s = model.structure
    den, num_y, nums = model.predictor_polynomials(k)
    exact_polys = exact_polynomials(model, k)
    exact = exact_fit(y, exact_predictor(*exact_polys, u, y, 0, initial), 0)
    ours = model.simulate(u, y, initial=initial) if k == np.inf else model.predict(
        u, y, initial=initial
    )
    assert abs(fit_percent(y, ours) - exact) <= FIT_BOUND, (fit_percent(y, ours), exact)
    # the costs' rule, from the direct form's state at start
    start = max(s.start, den.size - 1, num_y.size - 1, *[p.size - 1 for p in nums])
    rule = "estimate-start" if initial == "estimate" else initial
    exact_start = exact_fit(y, exact_predictor(*exact_polys, u, y, start, rule), s.start)
    ours = model.simulate(u, y, initial=initial, from_start=True) if k == np.inf else (
        model.predict(u, y, initial=initial, from_start=True)
    )
    assert abs(fit_percent(y[s.start :], ours[s.start :]) - exact_start) <= FIT_BOUND
    direct = run_predictor(den, num_y, nums, u, y, s.start, initial)[0]
    return exact_start, fit_percent(y[s.start :], direct[s.start :])


@pytest.mark.parametrize("order", [4, 8, 12, 16, 20, 24])
def test_output_error_fits_equal_the_exact_model(order):
    rng = np.random.default_rng(order)
    f = lightly_damped(rng, order)
    model = PolynomialStructure.oe(order, order, 1).model(
        np.concatenate([1e-3 * rng.normal(size=order), f[1:]])
    )
    u, y = record(rng, model)
    errors = [abs(direct - exact) for exact, direct in
              (check(model, u, y, np.inf, rule) for rule in ("estimate", "zero"))]  # fmt: skip
    if order >= 12:  # the point of the route: the float64 direct form is wrong here
        assert max(errors) > 1e-3


def test_arx_simulation_and_box_jenkins_prediction_equal_the_exact_model():
    rng = np.random.default_rng(7)
    a = lightly_damped(rng, 16)
    arx = PolynomialStructure.arx(16, 16, 1).model(
        np.concatenate([a[1:], 1e-3 * rng.normal(size=16)])
    )
    u, y = record(rng, arx)
    for rule in ("estimate", "zero"):
        check(arx, u, y, np.inf, rule)
        check(arx, u, y, 1, rule)
    f = lightly_damped(rng, 10)
    c, d = np.poly([0.6, -0.3]), np.poly([0.9 * np.exp(0.4j), 0.9 * np.exp(-0.4j)]).real
    bj = PolynomialStructure.bj(10, 2, 2, 10, 1).model(
        np.concatenate([1e-3 * rng.normal(size=10), c[1:], d[1:], f[1:]])
    )
    u, y = record(rng, bj)
    for rule in ("estimate", "zero"):
        check(bj, u, y, 1, rule)


def test_accurate_roots_equal_100_digit_roots_where_numpy_roots_are_off():
    # the two real poles next to z = 1 of a measured twin rotor OE(16,16,1) denominator:
    # numpy.roots returns them as a complex pair 1e-2 away
    den = TWIN_ROTOR_F
    with mp.workdps(DIGITS):
        ascending = [mp.mpf(float(v)) for v in den[::-1]]
        exact = mp.polyroots(ascending, maxsteps=3000, extraprec=3000, asc=True)
        exact = np.array([complex(r) for r in exact])
    ours = accurate_roots(den)
    assert ours.size == exact.size
    for r in exact:  # each within a few ulps (rounding the exact root is half an ulp)
        assert np.min(np.abs(ours - r)) <= 8 * np.finfo(float).eps * max(abs(r), 1.0)
    assert np.max([np.min(np.abs(np.roots(den) - r)) for r in exact]) > 1e-3
    assert np.sum(ours.imag == 0) == np.sum(np.abs(exact.imag) < 1e-30)
    pairs = ours[ours.imag != 0]
    assert set(pairs) == set(np.conj(pairs))  # exact conjugate pairs


def test_accurate_roots_of_simple_and_degenerate_polynomials():
    assert accurate_roots([0.0, 0.0]).size == 0
    np.testing.assert_array_equal(accurate_roots([2.0, -1.0]), [0.5])
    np.testing.assert_array_equal(np.sort_complex(accurate_roots([1.0, -1.5, 0.5, 0.0])),
                                  [0.0, 0.5, 1.0])  # fmt: skip
    np.testing.assert_array_equal(accurate_roots([0.0, 1.0, 0.25]), [-0.25])  # leading zero
    r = accurate_roots([1.0, 0.0, 1.0])
    np.testing.assert_array_equal(np.sort_complex(r), [-1j, 1j])


# ------------------------------------------------------------------ the costs the searches use
WELL_CONDITIONED = [
    PolynomialStructure.arx(3, 2, 1),
    PolynomialStructure.armax(2, 2, 2, 0),
    PolynomialStructure.oe(3, 3, 1),
    PolynomialStructure.bj(2, 2, 2, 3, 1),
    PolynomialStructure.bj([2, 1], 2, 1, [2, 3], [1, 2]),
    PolynomialStructure(na=2, nb=[2], nc=1, nd=2, nf=[2], nk=[1]),
]


def stable_monic(rng, n, radius=0.8):
    poles = [radius * rng.uniform(0.4, 1) * np.exp(1j * s * a)
             for a in rng.uniform(0.1, 3, size=n // 2) for s in (1, -1)]  # fmt: skip
    poles += list(rng.uniform(-radius, radius, size=n % 2))
    return np.poly(poles).real[1:] if n else np.zeros(0)


@pytest.mark.parametrize("s", WELL_CONDITIONED, ids=repr)
def test_realised_cost_equals_the_batched_cost_where_the_direct_form_is_well_conditioned(s):
    """The two routes compute one cost (same samples, same rules): on well-conditioned models
    they agree to rounding (1e-12 relative; measured at most 2e-15)."""
    from flexid.costs.polynomial import PolynomialCost

    rng = np.random.default_rng(11)
    theta = np.zeros(s.n_params)
    sl = s.slices()
    for part in [sl["a"], sl["c"], sl["d"], *sl["f"]]:
        theta[part] = stable_monic(rng, part.stop - part.start)
    for part in sl["b"]:
        theta[part] = rng.normal(size=part.stop - part.start)
    u, y = rng.normal(size=(300, s.n_inputs)), rng.normal(size=300)
    for predictor in ("one-step", "simulation")[: 1 if s.has_noise_model else 2]:
        for rule in ("zero", "estimate"):
            cost = PolynomialCost(s, (u, y), predictor=predictor, initial=rule, metric="sse")
            batched = float(cost(theta)[0])
            assert cost.realised_cost(theta) == pytest.approx(batched, rel=1e-12, abs=0)


def test_a_final_model_is_rescored_where_the_search_direct_form_is_off():
    """The twin rotor's OE(16, 16, 1): the batched (direct-form) cost is off by orders of
    magnitude on this record, the realised one equals the exact model's to 1e-9, and
    ``rescored`` reports both."""
    from flexid.costs.polynomial import PolynomialCost
    from flexid.jobs._identify import RESCORE_BOUND, rescored

    model = PolynomialStructure.oe(16, 16, 1).model(np.concatenate([TWIN_ROTOR_B,
                                                                    TWIN_ROTOR_F[1:]]))
    rng = np.random.default_rng(0)
    u = np.sign(rng.normal(size=(500, 1)))
    y = model.simulate(u) + 0.5 * rng.normal(size=500) + 0.05 * np.cumsum(rng.normal(size=500))
    cost = PolynomialCost(model.structure, (u, y), initial="estimate", metric="sse")
    batched, realised = float(cost(model.theta)[0]), cost.realised_cost(model.theta)
    s = model.structure
    exact = exact_predictor(*exact_polynomials(model, np.inf), u, y, s.start, "estimate-start")
    with mp.workdps(50):
        exact_sse = float(mp.fsum((mp.mpf(float(y[t])) - exact[t]) ** 2
                                  for t in range(s.start, y.size)))  # fmt: skip
    assert realised == pytest.approx(exact_sse, rel=1e-9)
    assert abs(batched - realised) > 1e3 * realised > RESCORE_BOUND * realised
    assert rescored(cost, model, batched) == (realised, batched)
    assert rescored(cost, model, realised) == (realised, None)


def test_arx_simulation_cost_is_realised_and_rescored_like_the_polynomial_family():
    """ARX's simulation cost from rest: the realised cost is the exact model's to 1e-8 on a
    lightly damped ARX(16, 16, 1) and the batched one's to rounding on a well-conditioned
    ARX(2, 2, 1); the one-step cost has no recursion and is its own."""
    from flexid.costs.arx import ARXCost
    from flexid.models.arx import ARXStructure

    rng = np.random.default_rng(21)
    u = np.sign(rng.normal(size=(400, 1)))
    a = None
    while a is None or not PolynomialStructure.arx(16, 16, 1).model(
        np.concatenate([a[1:], np.zeros(16)])
    ).is_stable:
        a = lightly_damped(rng, 16)
    theta = np.concatenate([a[1:], 1e-3 * rng.normal(size=16)])
    model = PolynomialStructure.arx(16, 16, 1).model(theta)
    y = model.simulate(u) + 0.3 * rng.normal(size=400)
    cost = ARXCost(ARXStructure(16, 16, 1), (u[:, 0], y), predictor="simulation",
                   initial="zero", metric="sse")  # fmt: skip
    exact = exact_predictor(*exact_polynomials(model, np.inf), u, y, 0, "zero")
    start = model.structure.start
    with mp.workdps(50):
        exact_sse = float(mp.fsum((mp.mpf(float(y[t])) - exact[t]) ** 2
                                  for t in range(start, y.size)))  # fmt: skip
    # the sections' rounding, amplified by modes at radius 0.999: measured 2e-9 relative
    assert cost.realised_cost(theta) == pytest.approx(exact_sse, rel=1e-8)
    assert float(cost(theta)[0]) != pytest.approx(exact_sse, rel=1e-6)  # the direct form
    small = ARXCost(ARXStructure(2, 2, 1), (u[:, 0], y), predictor="simulation",
                    initial="zero", metric="sse")  # fmt: skip
    theta2 = np.array([-1.5, 0.7, 1.0, 0.5])
    assert small.realised_cost(theta2) == pytest.approx(float(small(theta2)[0]), rel=1e-12)
    one_step = ARXCost(ARXStructure(2, 2, 1), (u[:, 0], y), metric="sse")
    assert one_step.realised_cost(theta2) == float(one_step(theta2)[0])
