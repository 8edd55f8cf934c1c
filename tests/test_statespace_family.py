"""The state-space family: the modal structure, its batched cost, ssest and identify's route."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

import flexid
from flexid import kernels
from flexid.costs.modal import ModalCost
from flexid.data import IOData
from flexid.errors import ConfigError, DataError, ModelOrderError
from flexid.fit.estimation import build_problem
from flexid.fit.statespace_fit import ModalBox, modal_start, ssest
from flexid.models.statespace import StateSpaceModel, StateSpaceStructure
from flexid.validation.diagnostics import format_fit

DT = 0.01


def _modal(structure, rng):
    """A random modal vector: modes 1-40 Hz, damping 0.01-0.9, corners 0.5-30 Hz."""
    out = []
    for _ in range(structure.n_modes):
        out += [rng.uniform(1.0, 40.0), rng.uniform(0.01, 0.9)]
    out += list(rng.uniform(0.5, 30.0, structure.n_real))
    return np.array(out)


def _true_model(rng, *, n_outputs=2):
    """Two modes (3 Hz at 2 %, 11 Hz at 5 %), one input, its gains and initial state drawn."""
    s = StateSpaceStructure(4, 1, n_outputs)
    theta = np.r_[3.0, 0.02, 11.0, 0.05, rng.standard_normal(4 * n_outputs),
                  0.3 * rng.standard_normal(4)]  # fmt: skip
    return s.model(theta, DT)


def _two_sensor(seed):
    rng = np.random.default_rng(seed)
    true = _true_model(rng)
    u = rng.standard_normal((1500, 1))
    y = true.simulate(u)
    y += 0.02 * np.std(y, axis=0) * rng.standard_normal(y.shape)  # 2 % noise per sensor
    return true, IOData(u, y, dt=DT, output_names=["hub", "tip"])


@pytest.fixture(scope="module")
def two_sensor_record():
    return _two_sensor(1)


@pytest.mark.parametrize(
    "nu, ny, order, feedthrough, initial",
    [(1, 1, 4, False, "estimate"), (1, 2, 5, True, "estimate"), (2, 2, 4, False, "estimate"),
     (2, 3, 3, True, "zero")],
)  # fmt: skip
def test_the_modal_cost_is_a_dlsim_of_its_own_model(nu, ny, order, feedthrough, initial):
    # the cost's errors and scipy's simulation of the realised model: the same numbers, by
    # two routes (batched second-order recursions and least squares; a state recursion),
    # equal to rounding: each output's sum of squares to 1e-10 relative over 800 samples
    rng = np.random.default_rng(order + 10 * ny)
    s = StateSpaceStructure(order, nu, ny, feedthrough=feedthrough)
    record = IOData(rng.standard_normal((800, nu)), rng.standard_normal((800, ny)), dt=DT)
    cost = ModalCost(record, s, metric="sse", initial=initial)
    modal = np.vstack([_modal(s, rng) for _ in range(3)])
    theta, sse = cost.fit(modal)
    for i in range(3):
        m = s.model(theta[i], DT)
        _, y_sim, _ = signal.dlsim((m.A, m.B, m.C, m.D, DT), record.u, x0=m.x0)
        e = (record.y - y_sim.reshape(800, ny)) / cost.scale
        assert sse[i] == pytest.approx(np.sum(e * e), rel=1e-10)
        assert m.is_stable
    np.testing.assert_allclose(cost(modal), sse, rtol=1e-12)  # metric "sse"
    if initial == "zero":
        assert np.all(theta[:, -s.n_states :] == 0.0)


def test_with_one_output_the_shared_initial_state_reaches_the_joint_fit():
    # with one output the realisation's x0 spans the free responses, so step 2 loses
    # nothing: the same sum of squares as one least-squares fit of gains and free response
    rng = np.random.default_rng(3)
    s = StateSpaceStructure(5, 1, 1)
    record = IOData(rng.standard_normal((600, 1)), rng.standard_normal((600, 1)), dt=DT)
    cost = ModalCost(record, s, metric="sse")
    modal = _modal(s, rng)[None]
    a, p = s.denominators(modal, DT)
    poles = np.concatenate([a.reshape(1, -1), p], axis=1)
    phi = kernels.modal_regressors(poles, record.u, s.n_modes, False, True)[0]
    joint = np.linalg.lstsq(phi, record.y[:, 0], rcond=None)[1][0]
    assert cost.fit(modal)[1][0] == pytest.approx(joint, rel=1e-8)


@pytest.mark.parametrize("feedthrough, free", [(False, False), (True, True)])
def test_the_compiled_regressors_equal_the_reference_path(feedthrough, free):
    # the compiled loops and one scipy.signal.lfilter per column: the same recursions, in
    # another order of operations; they agree to 1e-12 of the largest regressor (a lightly
    # damped mode's gain, about 1 / (2 zeta), amplifies rounding alike in both)
    if kernels.BACKEND != "c":
        pytest.skip("the compiled kernels are not in use")
    rng = np.random.default_rng(5)
    s = StateSpaceStructure(7, 2, 1)  # three modes, one real pole, two inputs
    a, p = s.denominators(np.vstack([_modal(s, rng) for _ in range(6)]), DT)
    poles = np.concatenate([a.reshape(6, -1), p], axis=1)
    u = rng.standard_normal((500, 2))
    got = kernels.modal_regressors(poles, u, 3, feedthrough, free)
    want = kernels.modal_regressors_reference(poles, u, 3, feedthrough, free)
    assert got.shape == want.shape == (6, 500, 14 + 2 * feedthrough + 7 * free)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12 * np.max(np.abs(want)))
    # the normal equations and errors, made row by row and never stored: against the
    # products of the reference regressors (sums of 500 terms: 1e-12 of the largest entry)
    y = rng.standard_normal((500, 2))
    gram, rhs = kernels.modal_normal(poles, u, y, 3, feedthrough, free)
    G, R = np.swapaxes(want, 1, 2) @ want, np.swapaxes(want, 1, 2) @ y
    np.testing.assert_allclose(gram, G, rtol=0, atol=1e-12 * np.max(np.abs(G)))
    np.testing.assert_allclose(rhs, R, rtol=0, atol=1e-12 * np.max(np.abs(R)))
    coef = rng.standard_normal((6, got.shape[2], 2)) / np.max(np.abs(want))
    residual, sse = kernels.modal_residual(poles, u, y, coef, 3, feedthrough, free)
    e = y - want @ coef
    np.testing.assert_allclose(residual, e, rtol=0, atol=1e-10)
    np.testing.assert_allclose(sse, np.einsum("pnq,pnq->p", e, e), rtol=1e-10)
    assert kernels.modal_residual(poles, u, y, coef, 3, feedthrough, free,
                                  want_residual=False)[0] is None  # fmt: skip


def _simd_levels():
    """The compiled kernels' instruction sets this CPU runs (all, not only the best)."""
    from flexid import _kernels

    order = ["generic", "avx2", "avx512"]
    best = _kernels.simd()[1]
    return order[: order.index(best) + 1] if best in order else [best]


def test_every_instruction_set_sums_the_same_normal_equations():
    # each copy (baseline, AVX2/FMA, AVX-512) against the products of the reference
    # regressors, with feedthrough, two inputs, a real pole and free responses: sums of 700
    # terms in other orders (blocks, interleaved partial sums, fused multiply-adds), within
    # 1e-12 of the largest entry
    if kernels.BACKEND != "c":
        pytest.skip("the compiled kernels are not in use")
    from flexid import _kernels

    rng = np.random.default_rng(8)
    s = StateSpaceStructure(7, 2, 3, feedthrough=True)
    a, p = s.denominators(np.vstack([_modal(s, rng) for _ in range(5)]), DT)
    poles = np.concatenate([a.reshape(5, -1), p], axis=1)
    u, y = rng.standard_normal((700, 2)), rng.standard_normal((700, 3))
    phi = kernels.modal_regressors_reference(poles, u, 3, True, True)
    G, R = np.swapaxes(phi, 1, 2) @ phi, np.swapaxes(phi, 1, 2) @ y
    before = _kernels.simd()[0]
    try:
        for level in _simd_levels():
            _kernels.simd(level)
            gram, rhs = kernels.modal_normal(poles, u, y, 3, True, True)
            np.testing.assert_allclose(gram, G, rtol=0, atol=1e-12 * np.max(np.abs(G)))
            np.testing.assert_allclose(rhs, R, rtol=0, atol=1e-12 * np.max(np.abs(R)))
    finally:
        _kernels.simd(before)


@pytest.mark.parametrize(
    "nu, ny, order, feedthrough, initial",
    [(1, 2, 8, False, "estimate"), (1, 1, 5, True, "estimate"), (2, 3, 5, False, "estimate"),
     (2, 2, 4, True, "zero")],
)  # fmt: skip
def test_the_compiled_fit_is_the_numpy_steps(nu, ny, order, feedthrough, initial):
    # modal_fit's Cholesky factors and the NumPy steps' LU solves of the same scaled, ridged
    # normal equations: on candidates damped 1-90 % (scaled condition below about 1e6) the
    # same coefficients to 1e-9 of the largest; on lightly damped ones (0.01-1 %) the same
    # fitted outputs (the directions the rounding moves the gains in are the ones the data
    # do not see) and sums of squares within the expansion's own tolerance
    if kernels.BACKEND != "c":
        pytest.skip("the compiled kernels are not in use")
    rng = np.random.default_rng(order + 7 * nu + ny)
    s = StateSpaceStructure(order, nu, ny, feedthrough=feedthrough)
    N = 900
    record = IOData(rng.standard_normal((N, nu)), rng.standard_normal((N, ny)), dt=DT)
    cost = ModalCost(record, s, initial=initial)
    damped = np.vstack([_modal(s, rng) for _ in range(6)])
    light = damped.copy()
    light[:, 1 : 2 * s.n_modes : 2] = rng.uniform(1e-4, 1e-2, (6, s.n_modes))
    estimate = initial == "estimate"
    for modal, exact in ((damped, True), (light, False)):
        a, p = s.denominators(modal, DT)
        poles = np.concatenate([a.reshape(len(modal), -1), p], axis=1)
        gram, rhs, coef, used, x0, sse, ok = kernels.modal_fit(
            poles, cost.u, cost._target, s.n_modes, feedthrough, estimate,
            ridge=flexid.costs.modal.RIDGE, rounding=flexid.costs.modal.SUM_ROUNDING,
            tolerance=flexid.costs.modal.EXPANSION_TOLERANCE,
        )  # fmt: skip
        assert ok.all()
        k_in = s.n_states + (nu if feedthrough else 0)
        want_coef, want_used, want_x0 = cost._steps(a, k_in, gram, rhs)
        phi = kernels.modal_regressors_reference(poles, cost.u, s.n_modes, feedthrough, estimate)
        if exact:
            for got, want in ((coef, want_coef), (used, want_used), (x0, want_x0)):
                np.testing.assert_allclose(got, want, rtol=0, atol=1e-9 * np.max(np.abs(want)))
        fitted, want_fitted = phi @ used, phi @ want_used
        assert np.max(np.abs(fitted - want_fitted)) < 1e-7 * np.max(np.abs(want_fitted))
        errors = cost._target - phi @ used
        direct = np.einsum("pno,pno->p", errors, errors)
        here = ~np.isnan(sse)
        assert here.any()
        np.testing.assert_allclose(sse[here], direct[here],
                                   rtol=flexid.costs.modal.EXPANSION_TOLERANCE)  # fmt: skip
        if not estimate:
            assert np.all(x0 == 0.0)


def test_a_near_perfect_fit_is_summed_from_its_errors():
    # noise-free outputs of a model in the structure: at its own modes the errors are about
    # 1e-19 of the outputs' energy (the ridge and the normal equations' rounding of the
    # gains), below what the expansion y'y - 2 c'b + c'Gc can resolve (rounding of about
    # 1e-14 of the energy), so the cost sums the errors themselves there; a population
    # around the modes is read from the expansion within its tolerance
    rng = np.random.default_rng(4)
    true = _true_model(rng)
    u = rng.standard_normal((1500, 1))
    record = IOData(u, true.simulate(u), dt=DT)
    cost = ModalCost(record, true_structure := StateSpaceStructure(4, 1, 2), metric="sse")
    modal = np.array([[3.0, 0.02, 11.0, 0.05]])
    theta, sse = cost.fit(modal)
    energy = float(np.sum(cost._target**2))
    assert sse[0] < 1e-16 * energy
    m = true_structure.model(theta[0], DT)
    _, y_sim, _ = signal.dlsim((m.A, m.B, m.C, m.D, DT), u, x0=m.x0)
    e = (record.y - y_sim.reshape(-1, 2)) / cost.scale
    assert np.sum(e * e) < 1e-16 * energy  # the realised model is the true one
    near = modal * (1 + 0.05 * rng.standard_normal((20, 4)))
    _, sse = cost.fit(near)
    _, residual = cost.residuals(near)
    direct = np.einsum("pno,pno->p", residual, residual)
    np.testing.assert_allclose(sse, direct, rtol=flexid.costs.modal.EXPANSION_TOLERANCE)


def test_the_residual_gradient_of_a_gain_is_its_state():
    # from rest every output is linear in its own gains: the central difference of the
    # residual in gain C[o, i] is minus state i's response from rest on output o and zero on
    # the other, to the difference's rounding (1e-7 of the state, GRADIENT_STEP's reason)
    from flexid.fit.statespace_family import _output_gradient
    from flexid.models.statespace import state_sequence

    rng = np.random.default_rng(6)
    true = _true_model(rng)
    record = IOData(rng.standard_normal((400, 1)), rng.standard_normal((400, 2)), dt=DT)
    gradient = _output_gradient(true, record, "zero")
    s = true.structure
    assert gradient.shape == (400, 2, true.theta.size - s.n_states)
    states = state_sequence(true.A, record.u @ true.B.T, np.zeros(s.n_states))  # (N, n)
    first = s.n_search  # the gains of output 0 follow the modal parameters, then output 1's
    for o in range(2):
        for i in range(s.n_states):
            column = gradient[:, :, first + o * s.n_states + i]
            scale = np.max(np.abs(states[:, i]))
            assert np.max(np.abs(column[:, o] + states[:, i])) < 1e-7 * scale
            assert np.max(np.abs(column[:, 1 - o])) < 1e-7 * scale


def test_a_held_out_state_space_report_carries_the_estimation_error(two_sensor_record):
    # the held-out tests of a realised state-space model add its estimate's error to their
    # null, as a polynomial model's do (every test but the squared residuals' u2'-e2', which
    # the estimate moves at second order only); the estimation record's are partialled with
    # one output, taken as known with several (the joint estimate is orthogonal to no single
    # output's gradient); a model given by its matrices has no parameter vector: known
    _, record = two_sensor_record
    ident = flexid.identify(record, structure="ss", order=4, optimiser="pem")
    p = ident.model.theta.size - ident.model.structure.n_states  # modes and gains: 12

    def rules(report):
        return {t.parameters for t in report.all_tests if "2'-e2'" not in t.name}

    for estimation, held_out in ident.outputs:
        assert rules(held_out) == {f"the estimation error of {p} parameters added to the "
                                   "tests' null"}  # fmt: skip
        assert rules(estimation) == {"the parameters taken as known"}
    one = flexid.identify(record, structure="ss", order=4, optimiser="pem", output="tip")
    assert rules(one.estimation) == {"the estimate of 8 parameters partialled out of the tests"}
    assert rules(one.validation) == {"the estimation error of 8 parameters added to the tests' "
                                     "null"}  # fmt: skip
    m = ident.model
    matrices = StateSpaceModel(m.A, m.B, m.C, dt=m.dt, output_names=m.output_names)
    est, val = record.split(2 / 3)
    report = flexid.validate(matrices, val, output="tip", estimated_on=est)
    assert {t.parameters for t in report.all_tests} == {"the parameters taken as known"}


def test_the_structure_refuses_what_it_cannot_hold():
    with pytest.raises(ModelOrderError, match="3 modes need order >= 6"):
        StateSpaceStructure(4, n_modes=3)
    with pytest.raises(ConfigError, match=r"damping bounds must lie in \(0, 1\]"):
        StateSpaceStructure(4, damping=(0.01, 2.0))
    with pytest.raises(ConfigError, match="0 < low < high"):
        StateSpaceStructure(4, frequency=(0.0, 10.0))
    with pytest.raises(ConfigError, match="above Nyquist"):
        StateSpaceStructure(4, frequency=(1.0, 80.0)).bounds(DT, 1000)
    with pytest.raises(ModelOrderError, match="needs at least"):
        StateSpaceStructure(40).check_samples(100)


def test_a_start_is_read_from_any_poles_in_the_structure_s_counts():
    s = StateSpaceStructure(4, 1, 1)  # two modes
    box = ModalBox.on(s, DT, 1000)
    z = np.exp(2 * np.pi * 5.0 * DT * (-0.05 + 1j * np.sqrt(1 - 0.05**2)))
    # one pair and two real poles (1.68 and 3.55 Hz): the reals become one critically damped
    # mode at their geometric mean, below the pair in frequency
    start = modal_start([z, np.conj(z), 0.9, 0.8], box, DT)
    corner = -np.log([0.9, 0.8]) / (2 * np.pi * DT)
    np.testing.assert_allclose(start, [np.sqrt(np.prod(corner)), 1.0, 5.0, 0.05], rtol=1e-9)
    # a negative real pole has no stable equivalent: read at Nyquist, clipped to the box
    s1 = StateSpaceStructure(1, 1, 1)
    assert modal_start([-0.5], ModalBox.on(s1, DT, 1000), DT)[0] == pytest.approx(50.0)
    # an unstable pair keeps its frequency and both its poles (the counts still match)
    s3 = StateSpaceStructure(3, 1, 1)
    box3 = ModalBox.on(s3, DT, 1000)
    grow = 1.01 * np.exp(2j * np.pi * 5.0 * DT)
    start = modal_start([grow, np.conj(grow), 1.2], box3, DT)
    assert start.shape == (3,) and start[0] == pytest.approx(5.0, rel=1e-3)
    np.testing.assert_allclose(start[1:], 10.0 ** box3.lower[1:])


def test_ssest_recovers_a_known_two_sensor_system_within_its_standard_errors(
    two_sensor_record,
):
    _, record = two_sensor_record
    res = ssest(record, 4)
    assert res.success and res.optimality < 1e-6
    truth = np.array([3.0, 0.02, 11.0, 0.05])
    # each modal parameter within 4 standard errors of the truth (the noise is 2 %)
    assert np.all(np.abs(res.x - truth) < 4 * res.std), (res.x, res.std)
    assert res.model.output_names == ("hub", "tip")
    # every random start ends at the same minimum as the subspace start (a benign problem)
    assert max(r.fun for r in res.runs) == pytest.approx(res.fun, rel=1e-6)


def test_a_two_input_two_output_system_from_scipy_is_recovered_by_ssest():
    # a 2x2 system with two shared modes, made with scipy.signal, noise free: the modal
    # realisation (each mode once per input) holds it exactly, so its frequency response
    # matches to the fit's tolerance, far inside 1e-4 of the peak gain
    rng = np.random.default_rng(7)
    poles = []
    for f, zeta in ((2.0, 0.03), (9.0, 0.1)):
        w = 2 * np.pi * f
        poles += [complex(-zeta * w, w * np.sqrt(1 - zeta * zeta))]
    A = np.zeros((4, 4))
    for k, s in enumerate(poles):
        A[2 * k : 2 * k + 2, 2 * k : 2 * k + 2] = [[s.real, -s.imag], [s.imag, s.real]]
    sys_c = signal.StateSpace(A, rng.standard_normal((4, 2)), rng.standard_normal((2, 4)),
                              np.zeros((2, 2)))  # fmt: skip
    sys_d = sys_c.to_discrete(DT)
    u = rng.standard_normal((1200, 2))
    _, y, _ = signal.dlsim(sys_d, u)
    res = ssest(IOData(u, y, dt=DT), 4, starts=1)
    f = np.linspace(0.2, 40.0, 200)
    z = np.exp(2j * np.pi * f * DT)
    eye = np.eye(4)
    G_true = np.array([sys_d.C @ np.linalg.solve(zi * eye - sys_d.A, sys_d.B) for zi in z])
    G = res.model.frequency_response(f)
    assert np.max(np.abs(G - G_true)) < 1e-4 * np.max(np.abs(G_true))


def test_identify_ss_by_n4sid_pem_and_an_optimiser_reports_every_output(two_sensor_record):
    _, record = two_sensor_record
    for optimiser, floor in (("n4sid", 97.0), ("pem", 97.0)):
        ident = flexid.identify(record, structure="ss", order=4, optimiser=optimiser)
        fits = {r.output_name: r.fit_simulation for r in ident.held_out}
        assert set(fits) == {"hub", "tip"} and min(fits.values()) > floor, fits
        text = ident.summary()
        assert "Validation record (held out), output 'tip'" in text
        assert ident.to_dict()["outputs"][1]["output"] == "tip"
        assert "residuals between outputs" in text and len(ident.output_tests) == 1
        # one verdict over both outputs' tests and the test between them, at the level
        joint = ident.to_dict()["joint"]
        n_tests = sum(len(r.all_tests) for r in ident.held_out) + 1
        assert len(joint["tests"]) == n_tests and joint["passed"] == ident.passed
        said = " ".join(f"joint verdict of the 2 outputs (held out): {joint['verdict']}".split())
        assert said in " ".join(text.split())  # wrapped at a terminal's width
    ident = flexid.identify(record, structure="ss", order=4, optimiser="de", budget=300, seed=2)
    assert ident.nfev == 300 and ident.model.is_stable
    one = flexid.identify(record, structure="ss", order=4, output="tip")
    assert one.model.output_names == ("tip",) and not one.outputs
    direct = flexid.identify(record, structure="ss", order=4, feedthrough=True)
    assert direct.model.structure.feedthrough and direct.model.D.shape == (2, 1)


def test_identify_ss_bad_input_is_a_typed_error():
    rng = np.random.default_rng(0)
    record = IOData(rng.standard_normal((300, 1)), rng.standard_normal((300, 2)), dt=DT,
                    output_names=["a", "b"])  # fmt: skip
    with pytest.raises(ModelOrderError, match="needs its order"):
        flexid.identify(record, structure="ss")
    with pytest.raises(ModelOrderError, match="damping and feedthrough, not na"):
        flexid.identify(record, 2, structure="ss", order=2)
    with pytest.raises(DataError, match="no output channel 'c'"):
        flexid.identify(record, structure="ss", order=2, output="a,c")
    with pytest.raises(ConfigError, match="output-error model"):
        flexid.identify(record, structure="ss", order=2, predictor="one-step")
    with pytest.raises(ConfigError, match="no estimate 'n4sid'"):
        flexid.identify(record, structure="oe", nb=2, nf=2, output="a", optimiser="n4sid")
    model = StateSpaceStructure(2, 1, 2).model(np.r_[3.0, 0.1, np.ones(6)], DT)
    with pytest.raises(DataError, match="give the one to validate"):
        flexid.validate(model, record)


def test_the_command_line_route_prints_every_output_and_refuses_in_one_line(
    two_sensor_record, tmp_path, capsys
):
    from flexid.cli import main

    _, record = two_sensor_record
    path = tmp_path / "two.csv"
    record.save(path)
    assert main(["identify", str(path), "--structure", "ss", "--order", "4",
                 "--optimiser", "n4sid"]) == 0  # fmt: skip
    out = capsys.readouterr().out
    assert "identified by n4sid" in out and "output 'tip'" in out
    assert main(["identify", str(path), "--structure", "ss", "--order", "4",
                 "--modes", "3"]) == 2  # fmt: skip
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "3 modes need order >= 6" in err[0]
    for option, value, words in (("--damping", "0.01,2", "must lie in (0, 1]"),
                                 ("--frequency", "1,80", "above Nyquist"),
                                 ("--frequency", "5", "two numbers"),
                                 ("--output", "hub,nope", "no output channel 'nope'")):  # fmt: skip
        assert main(["identify", str(path), "--structure", "ss", "--order", "4",
                     option, value]) == 2  # fmt: skip
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and words in err[0], err
    assert not list(tmp_path.glob("*.json"))  # nothing half-made
    # the bounds reach the search: every mode inside them
    ident = flexid.identify(record, structure="ss", order=4, frequency=(2.0, 20.0),
                            damping=(0.01, 0.2), optimiser="pso", budget=200)  # fmt: skip
    for mode in ident.model.modes():
        assert 2.0 - 1e-9 <= mode.frequency <= 20.0 + 1e-9
        assert 0.01 - 1e-12 <= mode.damping <= 0.2 + 1e-12


@pytest.fixture(scope="module")
def small_problem():
    rng = np.random.default_rng(4)
    true = _true_model(rng)
    u = rng.standard_normal((400, 1))
    record = IOData(u, true.simulate(u), dt=DT)
    return build_problem(
        record, StateSpaceStructure(4, 1, 2), flexid.CostSpec(predictor="simulation"),
        flexid.SearchSpec(),
    )  # fmt: skip


@pytest.mark.parametrize("name", sorted(flexid.optimisers.available()))
def test_every_registered_optimiser_searches_the_modal_space(name, small_problem):
    # every optimiser and adapter of the registry (nevergrad's, pycma's, pymoo's when they
    # are installed) runs its exact budget in the modal space, and every candidate it can
    # propose is a stable model
    pytest.importorskip({"ng": "nevergrad", "cma": "cma", "pymoo": "pymoo"}.get(
        name.split(":")[0], "numpy"))  # fmt: skip
    res = flexid.minimize(name, small_problem.problem, 60, seed=1)
    assert res.nfev == 60 and np.isfinite(res.fun)
    model = small_problem.structure.model(small_problem.theta(res.x), DT)
    assert model.is_stable
    assert float(small_problem.cost(small_problem.modal_box.physical(res.x[None]))[0]) == res.fun


def test_the_manipulator_s_modes_are_the_simulated_beam_s_own():
    # the paper's record (lab sensors, 1 % noise on the end-point acceleration), its first
    # 1,533 samples: ssest's four lowest modes against the finite-difference beam's own
    # natural frequencies and damping ratios (what the plant simulates).  Frequencies within
    # 1 %; damping within the record's resolution: a mode's half-power bandwidth 2 zeta f is
    # known to about one frequency bin 1 / T of the record, so |zeta - zeta_true| <=
    # 1 / (2 f T) (for the first mode 0.028, for the fourth 0.0032)
    from flexid.data.datasets import generate
    from flexid.envs import beam

    record = generate("manipulator", preset="paper-manipulator", seed=0,
                      outputs=["tip_acceleration"])  # fmt: skip
    est = record.split(index=1533)[0]
    res = ssest(est, 10, modes=5, starts=2, seed=0)
    found = [(m.frequency, m.damping) for m in res.model.modes() if m.kind == "pair"]
    params = beam.BeamParameters()
    T = est.n_samples * est.dt
    for k, f_true in enumerate(beam.natural_frequencies(params, n_modes=4), start=1):
        f, zeta = min(found, key=lambda fz: abs(fz[0] - f_true))
        assert abs(f - f_true) <= 0.01 * f_true, (k, f, f_true)
        assert abs(zeta - params.damping_ratio(k)) <= 1.0 / (2 * f_true * T), (k, zeta)


def test_a_comparison_of_a_state_space_model_reports_every_output(two_sensor_record, tmp_path):
    from flexid.config import ComparisonSpec, CostSpec, DataSpec, ModelSpec, OptimiserSpec

    _, record = two_sensor_record
    path = tmp_path / "two.csv"
    record.save(path)
    spec = ComparisonSpec(
        data=DataSpec(file=str(path)),
        model=ModelSpec(structure="ss", options={"order": 4}),
        cost=CostSpec(predictor="simulation"),
        optimisers=(OptimiserSpec("pso"), OptimiserSpec("de")), runs=2, budget=300,
    )  # fmt: skip
    store = tmp_path / "runs.sqlite"
    result = flexid.compare(spec, store=store)
    text = result.summary()
    assert "subspace estimate (n4sid)" in text and "state-space reference" in text
    assert "fit sim % hub" in text and "pass tip" in text
    # the reference finds the known system: both held-out fits above 97 %
    per = result.reference["output_error"]["validation"]["outputs"]
    assert set(per) == {"hub", "tip"} and min(v["fit_simulation"] for v in per.values()) > 97
    # the headline is the weakest output's fit, not the first output's; no one error range
    # across outputs of different units, each output's range in its own table
    rows = result._validation_rows()
    ref_row = next(r for r in rows if r[0] == "reference (LM)")
    assert ref_row[2] == format_fit(min(v["fit_simulation"] for v in per.values()))
    assert ref_row[3] == "per output" and "error range hub" in text
    for label, rs in result.records.items():
        runs = [r["validation"] for r in rs if r["status"] == "ok"]
        worst = [min(o["fit_simulation"] for o in v["outputs"].values()) for v in runs]
        assert result.stats[label]["fit_simulation"] == pytest.approx(np.median(worst), abs=0)
    # read back from the store, the same tables
    (again,) = flexid.load_result(store, result.key)
    assert again.summary() == text


def test_the_residuals_of_several_outputs_are_tested_against_each_other():
    from flexid.validation.diagnostics import output_cross_tests

    rng = np.random.default_rng(11)
    n = 2000
    a, b, c = rng.standard_normal((3, n))
    # independent residuals pass; a shared component at lag 0 alone (correlated sensor noise)
    # is not counted; one output's residual in another's two samples later fails
    assert all(t.passed for t in output_cross_tests(np.column_stack([a, b, c]), 20))
    (same,) = output_cross_tests(np.column_stack([a, a + 0.3 * b]), 20, ["p", "q"])
    assert same.passed and same.name == "cross p-q"
    late = np.concatenate([np.zeros(2), a[:-2]]) + 0.5 * b
    (test,) = output_cross_tests(np.column_stack([a, late]), 20)
    assert not test.passed
    # the coefficient at lag -2 (corr(e1(t), e2(t + 2))) against numpy's on the overlap: the
    # biased estimator scales by the whole records' norms, so they differ by about 2 / N
    r = np.corrcoef(a[:-2], late[2:])[0, 1]
    assert test.values[list(test.lags).index(-2)] == pytest.approx(r, abs=2e-3)
    with pytest.raises(DataError, match="ny >= 2"):
        output_cross_tests(a[:, None], 20)


def test_the_figures_of_a_state_space_identification_show_every_output(two_sensor_record,
                                                                         tmp_path):  # fmt: skip
    pytest.importorskip("matplotlib")
    from flexid.report.plots import identification_figures

    _, record = two_sensor_record
    ident = flexid.identify(record, structure="ss", order=4, optimiser="n4sid")
    names = {p.name for p in identification_figures(ident, tmp_path)}
    for output in ("hub", "tip"):
        assert {f"validation_simulation_{output}.png", f"spectra_{output}.png",
                f"correlations_{output}.png"} <= names  # fmt: skip
    assert "pole_zero.png" in names
    # the zeros it draws, from the input to the first output, against an independent route:
    # the finite generalised eigenvalues of the Rosenbrock pencil [[A, B], [C, D]] - z diag(I, 0)
    # (polynomial roots and a pencil agree to about 1e-8 on a model of order 4)
    from scipy import linalg

    m = ident.model
    n = m.order
    pencil = np.block([[m.A, m.B], [m.C[:1], m.D[:1]]])
    mass = np.block([[np.eye(n), np.zeros((n, 1))], [np.zeros((1, n + 1))]])
    want = linalg.eigvals(pencil, mass)
    want = want[np.isfinite(want)]
    # sorted by the real part to 1e-6, then the imaginary part: a conjugate pair's real parts
    # agree only to rounding, so np.sort_complex orders its two members by the last bits
    def by_value(z):
        return z[np.lexsort((z.imag, np.round(z.real, 6)))]

    np.testing.assert_allclose(by_value(m.zeros()), by_value(want), rtol=1e-6)


def test_select_ranks_state_space_orders_on_the_joint_cost():
    # the known system has two modes (order 4): the criteria on the joint cost and the
    # held-out fits agree on it, every output's tests are kept. Not the record of seed 1: there
    # the true order's held-out residuals fail the test between the outputs by chance
    # (p = 0.0004; 1 of the records of seeds 1-20 at 5 %, identify's verdict alike)
    _, record = _two_sensor(2)
    sel = flexid.select(record, structures="ss", orders={"order": [2, 3, 4, 5, 6]})
    assert sel.best.structure.order == 4
    assert min(sel.candidates, key=lambda c: c.mdl_normalized).structure.order == 4
    best = sel.best
    assert [r.output_name for r in best.reports] == ["hub", "tip"]
    assert best.fit_simulation == min(r.fit_simulation for r in best.reports)
    assert best.K == 2 * 1000  # two outputs of the 1,000 estimation samples
    grids = {"ss": [{"order": 4}], "oe": [{"nb": 2, "nf": 2}]}
    with pytest.raises(DataError, match="models one: select among state-space"):
        flexid.select(record, structures=("ss", "oe"), orders=grids)


def test_select_judges_the_outputs_residuals_against_each_other():
    # the hub's noise reaches the tip two samples later (a disturbance the inputs do not
    # explain): each output's residual alone is white and independent of the input, and only
    # the test between the two outputs' residuals sees it. select's verdict is identify's
    rng = np.random.default_rng(4)
    true = _true_model(rng)
    u = rng.standard_normal((1500, 1))
    y = true.simulate(u)
    hub = 0.05 * np.std(y[:, 0]) * rng.standard_normal(1500)
    y[:, 0] += hub
    y[2:, 1] += 0.5 * np.std(y[:, 1]) / np.std(y[:, 0]) * hub[:-2]
    y[:, 1] += 0.02 * np.std(y[:, 1]) * rng.standard_normal(1500)
    record = IOData(u, y, dt=DT, output_names=["hub", "tip"])
    sel = flexid.select(record, structures="ss", orders={"order": [4]})
    (c,) = sel.candidates
    assert all(r.passed for r in c.reports)  # each output alone
    assert not c.passed
    ident = flexid.identify(record, structure="ss", order=4, optimiser="pem")
    assert not ident.passed and any(not t.passed for t in ident.output_tests)
    assert "predict each other (cross hub-tip)" in sel.note


def test_the_orthogonal_route_solves_the_same_fit_with_the_rounding_of_a_qr():
    # a rigid body (two real poles at 1e-5 and 2e-5 Hz, about z = 1) and two lightly damped
    # modes: scaled regressors of condition about 6e3, whose normal equations may lose
    # cond**2 eps, about 1e-8, of the fit and QR factors cond eps, about 1e-12. The orthogonal
    # route against an independent one: an SVD least squares of the same regressors with the
    # same scaled ridge
    rng = np.random.default_rng(5)
    s = StateSpaceStructure(6, 1, 2, n_modes=2)
    record = IOData(rng.standard_normal((1200, 1)), rng.standard_normal((1200, 2)), dt=DT)
    cost = ModalCost(record, s, initial="zero")
    modal = np.array([[3.0, 0.02, 11.0, 0.05, 1e-5, 2e-5]])
    _, normal = cost.residuals(modal)
    _, orthogonal = cost.residuals(modal, orthogonal=True)
    a, p = s.denominators(modal, DT)
    phi = kernels.modal_regressors(np.concatenate([a.reshape(1, -1), p], axis=1),
                                   record.u, s.n_modes, False, False)[0]  # fmt: skip
    norms = np.linalg.norm(phi, axis=0)
    ridge = np.sqrt(flexid.costs.modal.RIDGE) * np.eye(phi.shape[1])
    coef = np.linalg.lstsq(np.vstack([phi / norms, ridge]),
                           np.vstack([cost._target, np.zeros((phi.shape[1], 2))]),
                           rcond=None)[0]  # fmt: skip
    svd = cost._target - phi @ (coef / norms[:, None])
    scale = np.linalg.norm(svd)
    assert np.linalg.cond(phi / norms) > 1e3
    assert np.linalg.norm(orthogonal[0] - svd) < 1e-11 * scale
    assert np.linalg.norm(normal[0] - svd) < 1e-6 * scale  # the same fit, coarser rounding
    # with the initial state estimated the two routes still agree to the normal one's rounding
    est = ModalCost(record, s, initial="estimate")
    np.testing.assert_allclose(est.residuals(modal, orthogonal=True)[1], est.residuals(modal)[1],
                               rtol=0, atol=1e-6 * np.abs(record.y).max())  # fmt: skip
