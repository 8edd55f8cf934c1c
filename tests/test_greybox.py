"""Grey-box models: parameters, batched simulation, the simulation cost and the reference.

The twin rotor's fits simulate hundreds of populations of 600-2,000 samples: they run where
the compiled kernels do (``COMPILED``) and are skipped on the NumPy route, which is held to
the compiled one and to the plant's reference RK4 on short records by
``test_twin_rotor_models_are_the_plant`` (the NumPy route of the pitch model takes about
0.5 s per candidate for 2,000 samples).  The user-model tests run on the NumPy route always.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

import flexid
from flexid.costs.greybox import GreyBoxCost
from flexid.envs import twin_rotor_physics as trs
from flexid.envs import twin_rotor_steppers
from flexid.errors import ConfigError, DataError, UnknownNameError
from flexid.fit.greybox_fit import greyest
from flexid.models.greybox import GreyBoxModel, GreyParameter
from flexid.models.greybox_library import greybox_model, twin_rotor_coupled, twin_rotor_pitch
from numerics import assert_close_to_terms
from test_twin_rotor import trajectory_bound

PITCH_TRUE = {n: getattr(trs.TwinRotorParameters(), n) for n in twin_rotor_pitch().free}
COMPILED = pytest.mark.skipif(
    twin_rotor_steppers._compiled() is None,
    reason="twin-rotor fits need the compiled kernels' speed",
)


def _pitch_record(n: int, seed: int = 0, sensors: str = "ideal") -> flexid.IOData:
    return flexid.generate(
        "twin-rotor", preset="paper-twin-rotor", sensors=sensors, n_samples=n, seed=seed
    )


# ---------------------------------------------------------------------- a user's model
def _msd(x, u, p):
    """Mass-spring-damper with (smoothed) Coulomb friction, x = (position, velocity)."""
    pos, vel = x[:, 0], x[:, 1]
    force = u[:, 0] - p.k * pos - p.c * vel - p.fc * np.tanh(vel / 1e-2)
    return np.column_stack([vel, force / p.m])


def _msd_model(substep: float = 1e-3, **changes) -> GreyBoxModel:
    model = GreyBoxModel(
        "mass-spring-damper",
        _msd,
        lambda x, u, p: x[:, :1],
        states=("position", "velocity"),
        inputs=("force",),
        outputs=("position",),
        parameters=(
            GreyParameter("m", 2.0, 0.1, 10.0, "kg", fixed=True),
            GreyParameter("k", 80.0, 1.0, 1000.0, "N/m"),
            GreyParameter("c", 1.5, 0.01, 50.0, "N s/m"),
            GreyParameter("fc", 0.0, 0.0, 5.0, "N"),
        ),
        substep=substep,
    )
    return model.with_parameters(**changes) if changes else model


def test_linear_model_sampled_like_its_exact_discretisation():
    # Independent route: with no Coulomb friction the model is linear, and its exact sampled
    # response with the input held (zero-order hold) is scipy's cont2discrete + dlsim.
    # Tolerance: RK4 with 20 substeps of 1 ms on modes of 6.4 rad/s has a local error of
    # (w h)^5 / 120 ~ 1e-13 per substep relative; over 500 samples the global error is
    # below 1e-9 of the response's scale (measured 2e-12).
    model = _msd_model()
    rng = np.random.default_rng(3)
    u = rng.uniform(-1, 1, 500)
    dt = 0.02
    m, k, c = 2.0, 80.0, 1.5
    A = np.array([[0.0, 1.0], [-k / m, -c / m]])
    B = np.array([[0.0], [1.0 / m]])
    discrete = signal.cont2discrete((A, B, np.array([[1.0, 0.0]]), np.zeros((1, 1))), dt)
    exact = signal.dlsim(discrete, u)[1][:, 0]
    y = model.simulate(model.nominal, u, dt)[0, :, 0]
    assert model.n_substeps(dt) == 20
    np.testing.assert_allclose(y, exact, rtol=0, atol=1e-9 * np.abs(exact).max())


def test_each_row_runs_its_own_parameters():
    model = _msd_model()
    u = np.random.default_rng(0).uniform(-1, 1, 200)
    theta = model.full([[80.0, 1.5, 0.0], [40.0, 3.0, 0.2], [200.0, 0.5, 1.0]])
    together = model.simulate(theta, u, 0.02)
    for i in range(3):
        alone = model.simulate(theta[i], u, 0.02)
        np.testing.assert_array_equal(together[i], alone[0])  # same arithmetic per row


def test_user_model_recovered_by_the_reference_and_de():
    # noiseless data from the model at k = 80, c = 1.5, fc = 0.3: the reference ends on the
    # true parameters to 1e-6 (the fit is exact to rounding); DE at 3,000 evaluations within
    # 2 % (measured over seeds 0-5: largest relative error 0.1-0.7 %)
    truth = _msd_model(substep=5e-3, fc=0.3)
    rng = np.random.default_rng(1)
    u = np.repeat(rng.uniform(-3, 3, 15), 10)
    y = truth.simulate(truth.nominal, u, 0.02)[0, :, 0]
    start = _msd_model(substep=5e-3, k=30.0, c=5.0, fc=1.0)
    fit = greyest((u, y), start, starts=0, dt=0.02)
    assert fit.local_minimum
    for name, value in (("k", 80.0), ("c", 1.5), ("fc", 0.3)):
        assert fit.values[name] == pytest.approx(value, rel=1e-6)
    cost = GreyBoxCost(start, (u, y), dt=0.02)
    result = flexid.minimize("de", cost.problem(), 3000, seed=0)
    found = start.from_search(result.x)
    np.testing.assert_allclose(found, [80.0, 1.5, 0.3], rtol=2e-2)


# ---------------------------------------------------------------------- the twin rotor
@pytest.mark.numerics
@pytest.mark.parametrize("coupled", [False, True])
def test_twin_rotor_models_are_the_plant(coupled):
    # The grey-box models are the plant's equations: at the plant's parameters their NumPy
    # route is the plant's reference RK4 (trajectory_bound: the rounding of two routes along
    # the trajectory), and the compiled route, each row with its own parameters, too.
    model = twin_rotor_coupled() if coupled else twin_rotor_pitch()
    rng = np.random.default_rng(5)
    n = 120
    u = rng.uniform(-2.0, 2.0, (n, 2 if coupled else 1))
    theta = np.repeat(model.nominal[None, :], 3, axis=0)
    scale = np.array([1.0, 1.3, 0.7])
    for name in ("Mg", "a1", "T11"):
        theta[:, model.names.index(name)] *= scale
    columns = [0, 2] if coupled else [0]
    volts = u if coupled else np.column_stack([u[:, 0], np.zeros(n)])
    routes = {"numpy": model.simulate_reference(theta, u, 0.1)}
    if twin_rotor_steppers._compiled() is not None:
        routes["compiled"] = model.simulate(theta, u, 0.1)
    for i in range(3):
        p = trs.TwinRotorParameters(
            lock_yaw=not coupled, encoder_counts=None,
            **{name: theta[i, model.names.index(name)] for name in ("Mg", "a1", "T11")},
        )
        ref = trs.reference_trajectory(volts, p, 0.1)[:-1][:, columns]
        bound = trajectory_bound(np.zeros(7), volts, p, 0.1)[:-1][:, columns]
        for route, y in routes.items():
            assert_close_to_terms(y[i], ref, bound, 1.0), route


@COMPILED
def test_ideal_record_is_the_model_at_the_plant_parameters():
    data = _pitch_record(300)
    model = twin_rotor_pitch()
    cost = GreyBoxCost(model, data)
    true = [PITCH_TRUE[n] for n in model.free]
    # the record is the plant's simulation read without the encoder: the same RK4, so the
    # error is rounding (the compiled and NumPy routes differ from the record's by the
    # bound above, below 1e-12 rad here)
    assert cost(true)[0] < 1e-12
    other = np.array(true) * 1.05
    assert cost(other)[0] > 1e-4


@COMPILED
def test_pitch_recovered_from_a_distant_start_on_ideal_data():
    data = _pitch_record(1500)
    start = twin_rotor_pitch(Mg=0.5, T11=3.0, a1=0.005, B1psi=0.02)
    fit = greyest(data, start, starts=0)
    assert fit.local_minimum and not fit.on_bound and not fit.unidentifiable
    for name, value in PITCH_TRUE.items():
        assert fit.values[name] == pytest.approx(value, rel=1e-7), name
    assert fit.fit > 99.999999


@COMPILED
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_pitch_through_the_encoder_within_its_standard_errors(seed):
    # With the lab chain the measurement error is the encoder's quantisation (1.5 mrad,
    # white and independent of the input at this amplitude), so the standard errors of
    # nlgreyest's formula hold: every parameter within 3 of them (measured: within 1.7
    # over seeds 0-4)
    data = _pitch_record(2000, seed=seed, sensors="lab")
    fit = greyest(data, twin_rotor_pitch(Mg=0.5, T11=3.0, a1=0.005), starts=0)
    assert fit.local_minimum
    for name, value in PITCH_TRUE.items():
        z = (fit.values[name] - value) / fit.std_errors[name]
        assert abs(z) < 3.0, (name, z)


@COMPILED
def test_inertia_and_moments_are_reported_as_a_ratio():
    # freeing I1: pitch's equation holds it only in ratios with Mg, B1psi, B2psi, a1, b1
    data = _pitch_record(600)
    model = twin_rotor_pitch().fixing("I1", free=True)
    fit = greyest(data, model, starts=0)
    assert len(fit.unidentifiable) == 1
    text = fit.unidentifiable[0]
    for name in ("I1", "Mg", "B1psi", "a1", "b1"):
        assert f"{name}^+1.00" in text
    assert "T11" not in text
    assert np.isinf(fit.std_errors["I1"]) and np.isinf(fit.std_errors["Mg"])
    assert np.isfinite(fit.std_errors["T11"])


def test_search_space_is_log_where_a_parameter_spans_decades():
    model = twin_rotor_pitch()
    assert model.parameter("Mg").log  # 0.01 to 3 N m
    lower, upper = model.search_bounds()
    assert lower[0] == pytest.approx(np.log10(1e-2)) and upper[0] == pytest.approx(np.log10(3))
    values = np.array([PITCH_TRUE[n] for n in model.free])
    np.testing.assert_allclose(model.from_search(model.to_search(values)), values, rtol=1e-15)
    coupled = twin_rotor_coupled()
    assert not coupled.parameter("kc").log  # bounds of both signs
    assert not coupled.parameter("Kgy").log  # from 0


# ---------------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"value": 5.0, "lower": 0.0, "upper": 1.0}, "outside its bounds"),
        ({"value": 0.5, "lower": 1.0, "upper": 0.0}, "bounds reversed"),
        ({"value": 0.5}, "needs finite bounds"),
        ({"value": 0.5, "lower": 0.0, "upper": 1.0, "scale": "log"}, "log scale needs"),
        ({"value": float("nan"), "lower": 0.0, "upper": 1.0}, "finite"),
    ],
)
def test_bad_parameters_name_themselves(kwargs, match):
    with pytest.raises(ConfigError, match=f"'Mg'.*{match}|{match}"):
        GreyParameter("Mg", **kwargs)


def test_unknown_parameter_and_channel_are_named():
    model = twin_rotor_pitch()
    with pytest.raises(UnknownNameError, match="'mass'"):
        model.fixing("mass")
    with pytest.raises(UnknownNameError, match="twin-rotor-pitch"):
        greybox_model("twin-rotor-pitchh")
    data = _pitch_record(50).replace(input_names=("voltage",))
    with pytest.raises(DataError, match=r"input column\(s\) \[.main_rotor.\]"):
        GreyBoxCost(model, data)


def test_wrong_shape_is_an_error_and_divergence_costs_inf():
    bad = GreyBoxModel(
        "bad", lambda x, u, p: x[:, :1], lambda x, u, p: x[:, :1], states=("a", "b"),
        inputs=("u",), outputs=("y",), parameters=(GreyParameter("g", 1.0, 0.1, 10.0),),
    )
    with pytest.raises(ConfigError, match=r"derivatives function returned shape \(2, 1\)"):
        bad.simulate([[1.0], [2.0]], np.zeros(5), 0.1)
    # dx/dt = g x from x0 = 1: a large g overflows that row only, which costs +inf and is
    # counted; the other rows are unaffected
    growth = GreyBoxModel(
        "growth", lambda x, u, p: p.g[:, None] * x + u, lambda x, u, p: x,
        states=("x",), inputs=("u",), outputs=("y",), x0=[1.0],
        parameters=(GreyParameter("g", -1.0, -2.0, 1e4, scale="linear"),),
    )
    u = np.zeros(400)
    y = growth.simulate([-1.0], u, 0.1)[0, :, 0]
    cost = GreyBoxCost(growth, (u, y), dt=0.1)
    out = cost([[-1.0], [9000.0], [-1.5]])
    assert out[0] == 0.0 and np.isinf(out[1]) and np.isfinite(out[2]) and out[2] > 0
    assert cost.n_diverged == 1


# ---------------------------------------------------------------------- validation
@COMPILED
def test_validation_runs_the_model_on_from_the_record_start():
    # independent route: the model simulated over the whole record, its last third scored
    # by fit_percent and the correlation tests directly
    from flexid.validation.diagnostics import fit_percent, residual_tests

    data = _pitch_record(900, sensors="lab")
    model = twin_rotor_pitch()
    report = flexid.validate(model, data, split=2 / 3)
    k = data.split(2 / 3)[0].n_samples
    y_sim = model.simulate(model.nominal, data.u, data.dt)[0, :, 0]
    assert report.start == k and report.initial == "model"
    assert "initial state at t = 0, run on through" in report.initial_rule
    assert report.fit_simulation == fit_percent(data.y[k:, 0], y_sim[k:])
    direct = residual_tests(data.y[k:, 0] - y_sim[k:], data.u[k:, 0])
    assert [t.n_outside for t in report.correlation_tests] == [t.n_outside for t in direct]


def test_validation_poles_are_the_linearised_pitch():
    # at rest pitch's equation linearises to I1 s^2 + (B1psi + B2psi / eps) s + Mg = 0 (the
    # Coulomb term tanh(v / eps) has slope 1 / eps), and the main motor's lag to
    # T11 s + T10 = 0; the other rotor states are the tail motor and the reaction torque
    # lags; yaw, locked, is left out.  Central differences: relative error ~1e-10 here.
    p = trs.TwinRotorParameters()
    data = _pitch_record(200)
    report = flexid.validate(twin_rotor_pitch(), data)
    s_pitch = np.roots([p.I1, p.B1psi + p.B2psi / p.coulomb_velocity, p.Mg])
    expected = np.r_[s_pitch, -p.T10 / p.T11, -p.T20 / p.T21, -1 / p.Tp]
    got = np.sort_complex(np.log(report.stability.poles) / data.dt)
    np.testing.assert_allclose(got, np.sort_complex(expected), rtol=1e-6)


@COMPILED
def test_coupled_pitch_and_yaw_recovered_on_ideal_data():
    # both axes free, both rotors driven: 15 parameters, five of them 0.5-1.6 times off at
    # the start; the fit is exact to rounding, so the values are the true ones to 1e-7
    data = flexid.generate(
        "twin-rotor", n_samples=1500, seed=0, sensors="ideal", outputs=["pitch", "yaw"]
    )
    model = twin_rotor_coupled()
    start = model.with_parameters(Mg=0.4, T11=1.5, a2=0.03, kc=-0.1, Tp=3.0)
    fit = greyest(data, start, starts=0)
    assert fit.local_minimum and not fit.unidentifiable
    truth = trs.TwinRotorParameters()
    for name in model.free:
        assert fit.values[name] == pytest.approx(getattr(truth, name), rel=1e-7), name


@COMPILED
def test_pitch_recovered_by_cmaes_and_de_on_ideal_data():
    # From the shared initial populations in the log-scaled box, 800 noiseless samples.
    # CMA-ES at 6,000 evaluations ends on the true parameters (measured over seeds 0-3:
    # largest relative error 4e-14 to 4e-7); DE at 15,000 reaches them in most runs
    # (seeds 0-5: 1e-6 to 1.4e-4 in five, 46 % in one), so two of three seeds must.
    data = _pitch_record(800)
    model = twin_rotor_pitch()
    problem = GreyBoxCost(model, data).problem()
    true = np.array([PITCH_TRUE[n] for n in model.free])

    def error(name: str, budget: int, seed: int) -> float:
        result = flexid.minimize(name, problem, budget, seed=seed)
        return float(np.max(np.abs(model.from_search(result.x) / true - 1.0)))

    assert error("cmaes", 6000, 0) < 1e-5
    assert sum(error("de", 15000, seed) < 1e-3 for seed in range(3)) >= 2


# ---------------------------------------------------------------------- command line
@COMPILED
def test_greybox_command_fits_and_validates(capsys):
    from flexid.cli import main

    assert main(["greybox", "--plant", "twin-rotor", "--starts", "0", "--set", "Mg=0.5"]) == 0
    out = capsys.readouterr().out
    assert "local minimum" in out and "overall              PASS" in out


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--model", "nope"], "unknown grey-box model 'nope'"),
        (["--fix", "mass"], "'mass'"),
        (["--set", "Mg=50"], "'Mg': value 50 is outside its bounds"),
        (["--set", "Mg"], "--set must look like NAME=VALUE"),
        (["--plant", "manipulator"], "twin rotor's"),
    ],
)
def test_greybox_command_refuses_bad_input_in_one_line(argv, message, capsys):
    from flexid.cli import main

    base = ["greybox"] if "--plant" in argv else ["greybox", "--plant", "twin-rotor"]
    assert main([*base, *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0]


def test_greybox_command_names_a_missing_channel(tmp_path, capsys):
    from flexid.cli import main

    path = tmp_path / "rec.csv"
    path.write_text("u,y\n" + "\n".join(f"{i % 3},{i % 5}" for i in range(30)) + "\n")
    assert main(["greybox", str(path), "--dt", "0.1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "main_rotor" in err[0]


@COMPILED
def test_a_population_gives_the_same_numbers_on_any_number_of_threads():
    """The compiled RK4 splits a population into groups of 4 rotors between threads; each
    group is computed as one thread computes it, so the results are equal to the last bit."""
    from flexid import kernels

    model = twin_rotor_pitch()
    rng = np.random.default_rng(5)
    lo, hi = model.search_bounds()
    theta = model.full(model.from_search(lo + (hi - lo) * rng.random((18, model.n_free))))
    u = rng.uniform(-1.0, 1.0, (400, 1))
    before = kernels.set_threads(1)
    try:
        one = model.simulate(theta, u, 0.1)
        kernels.set_threads(2)
        two = model.simulate(theta, u, 0.1)
    finally:
        kernels.set_threads(before)
    assert np.array_equal(one, two, equal_nan=True)
