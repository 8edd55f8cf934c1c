"""The batched prediction-error costs of the polynomial family and their search space.

Independent routes: :func:`flexid.models.polynomial.run_predictor` (one model,
``scipy.signal.lfilter`` and ``scipy.linalg.lstsq``) and a cascade of ``lfilter`` calls
written from the model equation.  The batched cost builds the same filter by batched
polynomial products, a GEMM against lagged data and the compiled (or NumPy) recursion, so
the two agree to rounding: filters here have every root within radius 0.9, so the
recursion's rounding error grows by at most ``1/(1-0.9)^order``-bounded factors, and the
bound 1e-9 relative to the SSE is thousands of times the measured differences (1e-15 to
1e-13) yet far below any modelling difference.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from flexid.costs.polynomial import PolynomialCost, poly_mul_rows
from flexid.errors import ConfigError, DataError
from flexid.fit.polynomial_space import PolynomialSpace
from flexid.models.polynomial import PolynomialStructure, run_predictor, structure
from flexid.optimisers import Budget, available, minimize

N = 600
RTOL = 1e-9  # see the module docstring

STRUCTS = {
    "arx": PolynomialStructure.arx(2, 2, 1),
    "armax": PolynomialStructure.armax(2, 2, 2, 1),
    "oe": PolynomialStructure.oe(2, 2, 1),
    "bj": PolynomialStructure.bj(2, 2, 1, 2, 1),
    "oe2": PolynomialStructure.oe([2, 1], [2, 1], [1, 0]),
    "bj2": PolynomialStructure.bj([2, 1], 1, 2, [2, 1], [1, 1]),
    # nd <= nc: the estimated state's error from rest by the cascade D/C (y - B/F u)
    "bj_cascade": PolynomialStructure.bj(3, 2, 2, 2, 1),
    "bj2_cascade": PolynomialStructure.bj([2, 1], 2, 1, [2, 1], [1, 2]),
}


def _record(n_inputs: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    u = rng.standard_normal((N, n_inputs))
    y = signal.lfilter([0.0, 0.5, 0.3], [1.0, -1.2, 0.6], u[:, 0])
    if n_inputs > 1:
        y += signal.lfilter([0.4, 0.1], [1.0, -0.5], u[:, 1])
    y += signal.lfilter([1.0, 0.4], [1.0, -0.7], 0.1 * rng.standard_normal(N))
    return u, y


def _candidates(s: PolynomialStructure, size: int, seed: int, r_max: float = 0.9):
    """Admissible candidates: every polynomial drawn in the pole space of radius ``r_max``."""
    space = PolynomialSpace(s, "poles", "search", b_lower=-1.0, b_upper=1.0, r_max=r_max)
    rng = np.random.default_rng(seed)
    Z = space.lower + (space.upper - space.lower) * rng.random((size, space.n_search))
    return space.to_theta(Z)


def _reference_sse(cost: PolynomialCost, theta: np.ndarray) -> float:
    model = cost.structure.model(theta)
    k = 1 if cost.predictor == "one-step" else np.inf
    den, num_y, nums = model.predictor_polynomials(k)
    yhat, _ = run_predictor(den, num_y, nums, cost.u, cost.y, cost.structure.start, cost.initial)
    e = (cost.y - yhat)[cost.structure.start :]
    return float(e @ e)


CASES = [
    (name, predictor, rule)
    for name, s in STRUCTS.items()
    for predictor in ("one-step", "simulation")
    for rule in ("estimate", "zero", "measured")
    if not (predictor == "simulation" and s.has_noise_model)
]


@pytest.mark.numerics
@pytest.mark.parametrize(("name", "predictor", "rule"), CASES)
def test_cost_equals_the_single_model_reference(name, predictor, rule):
    s = STRUCTS[name]
    cost = PolynomialCost(s, _record(s.n_inputs), metric="sse", predictor=predictor, initial=rule)
    X = _candidates(s, 6, seed=1)
    got = cost(X)
    expected = [_reference_sse(cost, x) for x in X]
    np.testing.assert_allclose(got, expected, rtol=RTOL)


def test_box_jenkins_estimated_state_runs_the_cascade_where_it_fits_the_same():
    # the structures above whose estimated state takes the cascade D/C (y - B/F u), and
    # one it must not (nd > nc: the cascade's rest would differ by more than a free
    # response of 1/(C F)); each is then checked against the single-model route above
    def cascade(name):
        s = STRUCTS[name]
        return PolynomialCost(s, _record(s.n_inputs), initial="estimate")._cascade

    assert cascade("bj") and cascade("bj_cascade") and cascade("bj2_cascade")
    assert not cascade("bj2") and not cascade("oe") and not cascade("armax")


@pytest.mark.numerics
@pytest.mark.parametrize("name", sorted(STRUCTS))
def test_one_step_error_from_rest_equals_the_lfilter_cascade(name):
    s = STRUCTS[name]
    u, y = _record(s.n_inputs)
    cost = PolynomialCost(s, (u, y), metric="sse", initial="zero")
    for theta in _candidates(s, 3, seed=2):
        m = s.model(theta)
        v = signal.lfilter(m.a, [1.0], y)
        for j in range(s.n_inputs):
            v -= signal.lfilter(np.r_[np.zeros(s.nk[j]), m.b[j]], m.f[j], u[:, j])
        e = signal.lfilter(m.d, m.c, v)[s.start :]
        np.testing.assert_allclose(cost.residuals(theta), e, atol=RTOL * np.abs(e).max())


@pytest.mark.numerics
@pytest.mark.parametrize(("name", "predictor", "rule"), CASES)
def test_estimated_initial_state_is_never_worse_than_the_other_rules(name, predictor, rule):
    """``"estimate"`` minimises over every initial state; the others pick one of them."""
    s = STRUCTS[name]
    data = _record(s.n_inputs)
    X = _candidates(s, 6, seed=3)
    best = PolynomialCost(s, data, metric="sse", predictor=predictor, initial="estimate")(X)
    other = PolynomialCost(s, data, metric="sse", predictor=predictor, initial=rule)(X)
    assert np.all(best <= other * (1 + RTOL))


# ================================================================================ numerator
@pytest.mark.numerics
@pytest.mark.parametrize(("name", "predictor", "rule"), CASES)
def test_fitted_numerator_is_the_least_squares_optimum(name, predictor, rule):
    s = STRUCTS[name]
    cost = PolynomialCost(s, _record(s.n_inputs), metric="sse", predictor=predictor, initial=rule)
    X = _candidates(s, 5, seed=4)
    fitted_cost, theta = cost.fitted_costs(X)
    np.testing.assert_allclose(theta, cost.fit_numerator(X), rtol=1e-8, atol=1e-12)
    # the one-pass cost is the cost of the model it returns
    np.testing.assert_allclose(fitted_cost, cost(theta), rtol=RTOL)
    # and no other numerator does better: random moves of b only raise the cost
    rng = np.random.default_rng(5)
    b_cols = np.concatenate([np.arange(s.n_params)[sl] for sl in s.slices()["b"]])
    for _ in range(5):
        moved = theta.copy()
        moved[:, b_cols] += rng.normal(0.0, 1e-3, (len(X), b_cols.size))
        assert np.all(cost(moved) >= fitted_cost * (1 - RTOL))


def test_fitted_numerator_recovers_the_true_b_from_noise_free_data():
    s = STRUCTS["bj2"]
    theta = _candidates(s, 1, seed=6)[0]
    rng = np.random.default_rng(7)
    u = rng.standard_normal((N, 2))
    y = s.model(theta).simulate(u)
    for rule in ("zero", "estimate"):
        cost = PolynomialCost(s, (u, y), metric="sse", initial=rule)
        blank = theta.copy()
        blank[np.concatenate([np.arange(s.n_params)[sl] for sl in s.slices()["b"]])] = 0.0
        # noise-free data from rest: the true b is the exact least-squares solution
        np.testing.assert_allclose(cost.fit_numerator(blank), theta, rtol=1e-8, atol=1e-10)


# ================================================================================ validity
def test_inadmissible_candidates_cost_the_penalty_and_non_finite_ones_infinity():
    s = STRUCTS["bj"]
    cost = PolynomialCost(s, _record(1), metric="rmse", penalty=1e6)
    good = _candidates(s, 1, seed=8)[0]
    c_not_minimum_phase = good.copy()
    c_not_minimum_phase[s.slices()["c"]] = [0.0, -1.5]  # C = 1 - 1.5 q^-2: roots outside
    f_unstable = good.copy()
    f_unstable[s.slices()["f"][0]] = [-2.0, 1.1]
    nan = good.copy()
    nan[0] = np.nan
    out = cost(np.stack([good, c_not_minimum_phase, f_unstable, nan]))
    assert out[0] < 1e6 <= out[1] and out[2] >= 1e6 and out[3] == np.inf
    graded = PolynomialCost(s, _record(1), metric="rmse", penalty=1e6, penalty_kind="graded")
    # C has roots at radius 1.22, F at 1.05: the farther one costs more
    assert graded(f_unstable)[0] < graded(c_not_minimum_phase)[0]


def test_bad_cost_input_gets_a_typed_error():
    with pytest.raises(ConfigError, match="noise model"):
        PolynomialCost(STRUCTS["bj"], _record(1), predictor="simulation")
    with pytest.raises(DataError, match="input"):
        PolynomialCost(STRUCTS["oe2"], _record(1))
    cost = PolynomialCost(STRUCTS["oe"], _record(1))
    with pytest.raises(DataError, match=r"shape \(P, 4\)"):
        cost(np.zeros((2, 3)))


def test_least_squares_start_reads_arx_least_squares_as_the_structure():
    u, y = _record(1)
    cost = PolynomialCost(STRUCTS["oe"], (u, y))
    from flexid.models.arx import ARXStructure

    arx = ARXStructure(2, 2, 1).least_squares(u, y)
    np.testing.assert_allclose(cost.theta_ls, np.r_[arx.theta[2:], arx.theta[:2]])


@pytest.mark.parametrize("widths", [(3, 5), (5, 3), (4, 4), (1, 6), (7, 1), (1, 1)])
def test_row_products_equal_numpy_convolve(widths):
    # each coefficient of a product is a sum of at most min(a, b) products, so the routes
    # agree with np.convolve to a few eps of the sum of their magnitudes (rtol 1e-14 on
    # standard normal factors of at most 7 terms); the compiled route forms the NumPy
    # route's sums in its order, each product rounded: on x86-64 (no fused multiply-add in
    # the baseline) bit for bit, also on rows of a wider array (a column block)
    import platform

    from flexid import kernels
    from flexid.costs.polynomial import poly_mul_rows_reference

    rng = np.random.default_rng(9)
    a, b = widths
    wide = rng.standard_normal((6, a + b + 2))
    p, q = wide[:, 1 : 1 + a], rng.standard_normal((6, b))
    expected = np.stack([np.convolve(x, y) for x, y in zip(p, q)])
    reference = poly_mul_rows_reference(p, q)
    np.testing.assert_allclose(reference, expected, rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose(poly_mul_rows(p, q), expected, rtol=1e-14, atol=1e-14)
    compiled = kernels.poly_mul_compiled(p, q)
    if compiled is None:
        assert kernels.BACKEND != "c" or not kernels.compiled_available()
    elif platform.machine() in ("x86_64", "AMD64"):
        np.testing.assert_array_equal(compiled, reference)
    assert kernels.poly_mul_compiled(p[:, 0], q) is None  # not a population: NumPy route


# ================================================================================ search space
@pytest.mark.parametrize("param", ["poles", "reflection"])
@pytest.mark.parametrize("name", sorted(STRUCTS))
def test_every_point_of_the_stable_boxes_is_a_valid_model(name, param):
    s = STRUCTS[name]
    space = PolynomialSpace(s, param, "fit", r_max=0.999)
    rng = np.random.default_rng(10)
    Z = space.lower + (space.upper - space.lower) * rng.random((200, space.n_search))
    Z[:20] = space.lower  # the corners too
    Z[20:40] = space.upper
    cost = PolynomialCost(s, _record(s.n_inputs))
    assert cost._admissible(space.to_theta(Z)).all()
    theta = space.to_theta(Z[40:])
    np.testing.assert_allclose(space.to_theta(space.from_theta(theta)), theta, atol=1e-9)


# ================================================================================ optimisers
@pytest.mark.parametrize("optimiser", sorted(available()))
def test_every_registered_optimiser_identifies_every_structure_with_valid_candidates(optimiser):
    """Each optimiser searches the OE and BJ spaces; every candidate it asks for is valid."""
    from flexid.config import CostSpec, SearchSpec
    from flexid.data import IOData
    from flexid.fit.estimation import build_problem

    u, y = _record(1)
    data = IOData(u, y[:, None], dt=0.01)
    for s in (structure("oe", nb=2, nf=2), structure("bj", nb=2, nc=1, nd=1, nf=2)):
        est = build_problem(data, s, CostSpec(metric="rmse"), SearchSpec())
        seen: list[np.ndarray] = []

        def spy(Z, f=est.problem.objective, space=est.parametrisation, seen=seen):
            seen.append(space.to_theta(Z))
            return f(Z)

        est.problem.objective = spy
        result = minimize(optimiser, est.problem, Budget(max_fe=300), seed=0)
        assert result.nfev == 300
        assert est.cost._admissible(np.vstack(seen)).all()
        model = s.model(est.theta(result.x))
        assert model.is_stable and model.predictor_stable
        assert result.fun <= est.cost_ls * 1.5  # a search, not a failure


def _lightly_damped(radius: float) -> np.ndarray:
    """Order 16, 8 modes of ``radius`` (the benchmark's plant at 0.99)."""
    poles = radius * np.exp(1j * np.array([0.05, 0.15, 0.3, 0.6, 0.9, 1.4, 2.0, 2.6]))
    return np.poly(np.r_[poles, poles.conj()]).real


@pytest.mark.parametrize(
    "case",
    [
        "order 16 at radius 0.99",
        "order 16 at radius 0.999",
        "order 16 at radius 0.2",  # the impulse response passes through the subnormal range
        "order 2 well damped",
        "order 16 well damped",
    ],
)
def test_estimated_state_by_one_pass_equals_n_recursions(case):
    """The one-pass fit (step-down energies, tail Gram matrix, anti-causal right-hand side)
    equals the fit of the ``n`` free responses computed one by one, within
    ``route_bounds.initial_state_fit_bound``: both solve the same normal equations, which
    differ by the non-orthogonality of the rounded basis (measured here) and the routes'
    rounding of the error from rest.  Where the basis has decayed below ``FREE_TAIL`` by the
    end of the record (the well damped cases) the kernel takes the Gram matrix as ``I``,
    leaving out a tail ``Q Q^T`` that is added to the measured deviation."""
    from route_bounds import ar_route_bound, initial_state_fit_bound

    rng = np.random.default_rng(3)
    if case == "order 2 well damped":
        s = PolynomialStructure.oe(2, 2, 1)
        u, y = _record(1)
        f = np.array([-0.6, 0.25])  # poles at radius 0.5
        X = np.tile(np.r_[0.5, 0.3, f], (4, 1)) + 0.01 * rng.standard_normal((4, 4))
    elif case == "order 16 well damped":
        s = PolynomialStructure.oe(16, 16, 1)
        u = rng.uniform(-0.3, 0.3, (1500, 1))
        y = signal.lfilter(np.r_[0.0, 0.05 * rng.standard_normal(16)], _lightly_damped(0.99),
                           u[:, 0])  # fmt: skip
        y += signal.lfilter([1.0, 0.5], [1.0, -0.9], 0.01 * rng.standard_normal(1500))
        X = _candidates(s, 9, 4, r_max=0.95)
        X[:, :16] *= 0.05
    else:
        s = PolynomialStructure.oe(16, 16, 1)
        a = _lightly_damped(float(case.split()[-1]))
        u = rng.uniform(-0.3, 0.3, (1500, 1))
        y = signal.lfilter(np.r_[0.0, 0.05 * rng.standard_normal(16)], a, u[:, 0])
        y += signal.lfilter([1.0, 0.5], [1.0, -0.9], 0.01 * rng.standard_normal(1500))
        X = np.zeros((4, 32))
        X[:, :16] = 0.05 * rng.standard_normal((4, 16))
        X[:, 16:] = a[1:] + 1e-9 * rng.standard_normal((4, 16))
    cost = PolynomialCost(s, (u, y), metric="sse", initial="estimate")
    X = X[cost._admissible(X)]
    den, num_y, nums = cost._predictor(cost._parts(X))
    n = den.shape[1] - 1
    sse, e_new = cost._estimated(den, num_y, nums, want_errors=True)
    e_old = cost._estimated_by_recursions(den, num_y, nums)
    # the Gram matrices of both routes, in the basis normalised by the step-down energies
    from flexid import kernels
    from flexid.costs.polynomial import _energies, orthogonal_numerators

    T = orthogonal_numerators(den, n)
    E = _energies(den, T)
    free = cost._free_responses(den)
    g_old = free @ free.transpose(0, 2, 1) / np.sqrt(E[:, :, None] * E[:, None, :])
    width = kernels.FREE_WINDOW * n
    impulse = np.zeros((den.shape[0], cost.K + width))
    impulse[:, 0] = 1.0
    h = kernels.ar_recursion_reference(den[:, 1:], impulse, np.zeros(n))
    s0 = kernels._basis_window(T, h, 0, width) / np.sqrt(E)[:, :, None]
    sk = kernels._basis_window(T, h, cost.K, width) / np.sqrt(E)[:, :, None]
    qt = np.linalg.solve(s0 @ s0.transpose(0, 2, 1), s0 @ sk.transpose(0, 2, 1))
    g_new = np.eye(n) - qt.transpose(0, 2, 1) @ qt
    assert np.linalg.cond(g_new).max() < 1.02  # the premise of the bound
    tail = qt.transpose(0, 2, 1) @ qt
    gram_dev = np.linalg.norm(g_old - g_new, ord=2, axis=(1, 2))
    gram_dev += np.linalg.norm(tail, ord=2, axis=(1, 2))  # where the kernel takes I
    skipped = (sk * sk).sum(axis=(1, 2)) < 1e-17  # the kernel's FREE_TAIL
    lam = np.linalg.eigvalsh(s0 @ s0.transpose(0, 2, 1))[:, 0]
    assert (lam[skipped] >= 0.45).all()  # the premise of FREE_TAIL's bound
    assert (np.linalg.norm(tail, ord=2, axis=(1, 2))[skipped] <= 2.3e-17).all()
    forced = cost._forced(num_y, nums)
    y_rest = kernels.ar_recursion_reference(den[:, 1:], forced, np.zeros(n))
    e_rest = cost._target - y_rest
    terms = sum(np.abs(num) @ np.abs(lags[: num.shape[1]]) for num, lags in zip(nums, cost._ulags))
    rest = np.linalg.norm(
        ar_route_bound(den[:, 1:], forced, np.zeros(n), y_rest, terms, nums[0].shape[1]), axis=1
    )
    fitted = np.linalg.norm(e_rest - e_old, axis=1)
    resid = np.linalg.norm(e_old, axis=1)
    d, dsse = initial_state_fit_bound(gram_dev, fitted, resid, rest, cost.K)
    assert (np.linalg.norm(e_new - e_old, axis=1) <= d).all()
    assert (np.abs(sse - resid**2) <= dsse).all()
    # the SSE-only pass: |e|^2 - c.r where the fit leaves enough (route_bounds.
    # free_cancel_bound), else the same sums as the pass with the errors
    from route_bounds import free_cancel_bound

    sse_only = cost.sse(X)
    num = cost._numerator(num_y, nums)
    coef = kernels.initial_state_fit(den[:, 1:], num, cost._reg, cost._target, T, E)[2]
    forcing = np.zeros_like(e_rest)
    forcing[:, :n] = np.einsum("pmi,pm->pi", T, coef)
    y_fit = kernels.ar_recursion_reference(den[:, 1:], forcing, np.zeros(n))
    fitted_dev = np.linalg.norm(ar_route_bound(den[:, 1:], forcing, np.zeros(n), y_fit), axis=1)
    ee = (e_rest * e_rest).sum(axis=1)
    bound = free_cancel_bound(ee, sse, gram_dev, n, cost.K, rest, fitted_dev)
    assert (np.abs(sse_only - sse) <= bound).all()
    left = sse / ee < kernels.FREE_CANCEL / 2  # the kernel runs the fitted response there
    np.testing.assert_array_equal(sse_only[left], sse[left])


@pytest.mark.parametrize("rule", ["zero", "measured"])
@pytest.mark.parametrize("name", ["oe16", "bj16", "armax", "bj2"])
def test_sse_by_the_arx_kernel_equals_the_reference(name, rule):
    """Under ``"zero"`` and ``"measured"`` the SSE-only pass runs the predictor as one ARX
    recursion on the shared regressors (compiled, input part and sum of squares in the
    kernel); the reference forms the forced terms by GEMMs and runs ``lfilter``.  Both are
    the same filter: the routes differ by the recursion's rounding and that of the
    ``nb``-term input part, filtered by ``1/den`` (``route_bounds.ar_route_bound``), and the
    sum of squares by ``sse_route_bound`` over the samples counted (from ``start``)."""
    from flexid import kernels
    from route_bounds import ar_route_bound, sse_route_bound

    if name.endswith("16"):
        s = structure("oe", nb=16, nf=16, nk=1) if name == "oe16" else structure(
            "bj", nb=16, nc=2, nd=2, nf=16, nk=1
        )
        rng = np.random.default_rng(5)
        u = rng.uniform(-0.3, 0.3, (1500, 1))
        y = signal.lfilter(np.r_[0.0, 0.05 * rng.standard_normal(16)], _lightly_damped(0.99),
                           u[:, 0])  # fmt: skip
        y += signal.lfilter([1.0, 0.5], [1.0, -0.9], 0.01 * rng.standard_normal(1500))
        X = _candidates(s, 12, 6, r_max=0.999)
        X[:, s.b_columns] *= 0.1
    else:
        s = STRUCTS[name]
        u, y = _record(s.n_inputs)
        X = _candidates(s, 12, 6)
    cost = PolynomialCost(s, (u, y), metric="sse", initial=rule)
    sse = cost.sse(X)
    den, num_y, nums = cost._predictor(cost._parts(X))
    n = den.shape[1] - 1
    forced = cost._forced(num_y, nums)
    state = cost._state[:n] if rule == "measured" else np.zeros(n)
    ref = kernels.ar_recursion_reference(den[:, 1:], forced, state)
    first = cost.start - cost._t0
    e = cost._target - ref[:, first:]
    num = cost._numerator(num_y, nums)
    terms = np.abs(num) @ np.abs(cost._reg).T
    dy = ar_route_bound(den[:, 1:], forced, state, ref, terms, num.shape[1])
    bound = sse_route_bound(e, dy[:, first:])
    assert (np.abs(sse - (e * e).sum(axis=1)) <= bound).all()
    # the errors themselves (GEMM and ar_recursion) sum to the same within the bound
    e2 = cost.prediction_errors(X)
    assert (np.abs(sse - (e2 * e2).sum(axis=1)) <= 2 * bound).all()
