"""Several estimation records of one system in one cost, each with its own initial state
(MATLAB's multi-experiment data): the cost, its least-squares start and numerator fit, the
prediction-error reference, the records' preparation, ``identify`` and the command line."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy import optimize, signal

import flexid
from flexid.cli import main
from flexid.config import load_config
from flexid.costs.experiments import MultiExperimentCost
from flexid.costs.polynomial import PolynomialCost
from flexid.data import IOData, prepare_data
from flexid.errors import ConfigError, DataError
from flexid.fit.prediction_error import pem
from flexid.jobs._compare import _Context
from flexid.models.polynomial import PolynomialStructure

B_TRUE, F_TRUE = [0.0, 1.0, 0.5], [1.0, -1.5, 0.7]


def experiments(sizes=(300, 500), noise=0.1, seed=0, offsets=(3.0, -5.0)):
    """Records of OE(2, 2, 1), each starting from its own state (a free response of 1/F)."""
    rng = np.random.default_rng(seed)
    out = []
    for n, x0 in zip(sizes, offsets):
        u = rng.standard_normal(n)
        free = signal.lfilter([1.0], F_TRUE, np.r_[x0, np.zeros(n - 1)])
        y = signal.lfilter(B_TRUE, F_TRUE, u) + free + noise * rng.standard_normal(n)
        out.append(IOData(u, y, dt=0.1))
    return out


OE = PolynomialStructure.oe([2], [2], [1])
STRUCTURES = [
    OE,
    PolynomialStructure.arx(2, [2], [1]),
    PolynomialStructure.armax(2, [2], 1, [1]),
    PolynomialStructure.bj([2], 1, 1, [2], [1]),
]


@pytest.mark.parametrize("initial", ["estimate", "zero", "measured"])
def test_cost_is_the_records_costs_pooled(initial):
    recs = experiments()
    cost = MultiExperimentCost(OE, recs, initial=initial, metric="sse")
    X = np.array([[0.9, 0.3, -1.4, 0.6], [1.1, 0.4, -1.2, 0.5]])
    alone = [PolynomialCost(OE, r, initial=initial, metric="sse") for r in recs]
    # the same per-record routes summed: equal up to the rounding of one addition
    np.testing.assert_allclose(cost(X), sum(c(X) for c in alone), rtol=1e-14)
    assert cost.K == sum(c.K for c in alone)
    e = cost.residuals(X[0])
    np.testing.assert_allclose(e @ e, cost(X)[0], rtol=1e-12)


@pytest.mark.parametrize("initial", ["estimate", "zero", "measured"])
def test_numerator_fit_is_the_joint_least_squares_optimum(initial):
    """The fitted B minimises the pooled cost: a general least-squares solver on the
    cost's own errors (another route) ends at the same B.  Both solve a linear problem in
    B with a well-conditioned basis, so they agree to about 1e-9 relative."""
    recs = experiments()
    cost = MultiExperimentCost(OE, recs, initial=initial, metric="sse")
    X = np.array([[0.9, 0.3, -1.4, 0.6]])
    theta = cost.fit_numerator(X)[0]

    def errors(b):
        x = theta.copy()
        x[OE.b_columns] = b
        return cost.residuals(x)

    sol = optimize.least_squares(errors, np.zeros(2), xtol=1e-15, ftol=1e-15, gtol=1e-15)
    np.testing.assert_allclose(theta[OE.b_columns], sol.x, rtol=1e-8)
    np.testing.assert_allclose(cost.fitted_costs(X)[0][0], sol.fun @ sol.fun, rtol=1e-10)
    # not each record's own optimum: the joint one differs from the first record's
    own = PolynomialCost(OE, recs[0], initial=initial).fit_numerator(X)[0]
    assert np.abs(own[OE.b_columns] - theta[OE.b_columns]).max() > 1e-4


def test_least_squares_start_stacks_the_records_regressors():
    recs = experiments()
    arx = PolynomialStructure.arx(2, [2], [1])
    cost = MultiExperimentCost(arx, recs, initial="measured")
    rows, target = [], []
    for r in recs:  # the regressors written out: [-y(t-1), -y(t-2), u(t-1), u(t-2)]
        y, u = r.y[:, 0], r.u[:, 0]
        rows.append(np.column_stack([-y[1:-1], -y[:-2], u[1:-1], u[:-2]]))
        target.append(y[2:])
    ls = np.linalg.lstsq(np.vstack(rows), np.concatenate(target), rcond=None)[0]
    np.testing.assert_allclose(cost.theta_ls, ls, rtol=1e-10)


@pytest.mark.parametrize("structure", STRUCTURES, ids=repr)
@pytest.mark.parametrize("initial", ["estimate", "zero", "measured"])
def test_pem_on_several_records_ends_at_the_pooled_minimum(structure, initial):
    """pem's Levenberg-Marquardt (its own errors and Jacobians, record by record) ends where
    a general solver on the batched cost's pooled errors ends; the SSEs agree to 1e-9
    relative (both stop on tolerances 1e-10 and tighter)."""
    recs = experiments()
    fit = pem(list(recs), structure, initial=initial)
    cost = MultiExperimentCost(structure, recs, initial=initial, metric="sse")
    assert fit.K == cost.K
    np.testing.assert_allclose(cost(fit.theta)[0], fit.sse, rtol=1e-12)
    sol = optimize.least_squares(cost.residuals, fit.theta + 1e-3, xtol=1e-15, ftol=1e-15,
                                 gtol=1e-15)  # fmt: skip
    assert fit.sse <= (sol.fun @ sol.fun) * (1 + 1e-9)
    assert fit.local_minimum


def test_pem_recovers_the_system_from_records_with_their_own_states():
    """Both records start from large states of their own: the estimate is within three
    standard errors of the truth, and the records joined end to end (one state, at the
    first record's start) fit worse."""
    recs = experiments(sizes=(400, 400), noise=0.05, offsets=(20.0, -30.0), seed=3)
    fit = pem(list(recs), OE)
    truth = np.array([*B_TRUE[1:], *F_TRUE[1:]])
    assert np.all(np.abs(fit.theta - truth) <= 3 * fit.model.param_std)
    joined = pem(flexid.data.joined(recs), OE)
    assert joined.sse > 2 * fit.sse


def test_prepare_records_checks_and_detrends():
    a, b = experiments()
    val = experiments(seed=1)[0]
    with pytest.raises(DataError, match="need a separate validation record"):
        prepare_data([a, b])
    with pytest.raises(DataError, match="split with several estimation records"):
        prepare_data([a, b], validation=val, split=0.5)
    with pytest.raises(DataError, match=r"estimation record 1 is sampled every 0\.2 s"):
        prepare_data([a, b.replace(dt=0.2)], validation=val)
    with pytest.raises(DataError, match="the validation record has 2 input"):
        prepare_data([a, b], validation=IOData(np.ones((10, 2)), np.ones(10)))
    shifted = [r.replace(y=r.y + 7.0) for r in (a, b, val)]
    est, v = prepare_data(shifted[:2], validation=shifted[2], detrend="constant")
    assert isinstance(est, tuple) and len(est) == 2
    pooled = np.concatenate([r.y for r in shifted[:2]]).mean()
    np.testing.assert_allclose(est[0].y, shifted[0].y - pooled, atol=1e-12)
    np.testing.assert_allclose(v.y, shifted[2].y - pooled, atol=1e-12)  # no own mean: held out
    est, v = prepare_data(shifted[:2], validation=shifted[2], detrend="linear")
    for r in (*est, v):  # each record loses its own line
        assert abs(r.y.mean()) < 1e-9


def test_identify_on_several_records():
    a, b = experiments()
    val = experiments(seed=1, offsets=(2.0, 0.0))[0]
    ident = flexid.identify([a, b], structure="oe", nb=2, nf=2, nk=1, validation=val)
    assert "800 estimation (300 + 500 in 2 records)" in ident.data_info["description"]
    assert "on 2 records" in ident.cost.describe()
    assert len(ident.estimation_records) == 2
    for report, record in zip(ident.estimation_records, (a, b)):
        again = flexid.validate(ident.model, record)
        assert report.fit_simulation == pytest.approx(again.fit_simulation, abs=1e-9)
    assert ident.validation.fit_simulation > 95  # noise 0.1 against an output of std ~2.5
    text = ident.summary()
    assert "Estimation record 1 of 2" in text and "Estimation record 2 of 2" in text
    d = json.loads(json.dumps(ident.to_dict()))
    assert len(d["estimation_records"]) == 2 and d["data"]["n_estimation"] == 800
    # ARX by least squares: the stacked regressors' solution, read as a polynomial model
    arx = flexid.identify([a, b], 2, 2, 1, optimiser="ls", validation=val)
    assert arx.model.structure.kind == "arx"
    # FIR (no denominator): nothing to search, the stacked least squares
    fir = flexid.identify([a, b], 0, 2, 1, optimiser="ls", validation=val)
    rows = [np.column_stack([r.u[1:-1, 0], r.u[:-2, 0]]) for r in (a, b)]
    target = np.concatenate([r.y[2:, 0] for r in (a, b)])
    fir_ls = np.linalg.lstsq(np.vstack(rows), target, rcond=None)[0]
    np.testing.assert_allclose(fir.model.theta, fir_ls, rtol=1e-10)
    # a metaheuristic searches the pooled cost too
    de = flexid.identify([a, b], structure="oe", nb=2, nf=2, nk=1, validation=val,
                         optimiser="de", budget=3000, seed=0)  # fmt: skip
    # two search dimensions (one pole pair, B fitted): DE reaches pem's minimum
    assert de.cost_value == pytest.approx(ident.cost_value, rel=1e-8)
    with pytest.raises(ConfigError, match="several estimation records are not supported"):
        flexid.identify([a, b], structure="greybox", greybox="twin-rotor-pitch", validation=val)


def test_command_line_takes_several_records(tmp_path, capsys):
    a, b = experiments()
    val = experiments(seed=1)[0]
    paths = []
    for name, r in (("a", a), ("b", b), ("v", val)):
        paths.append(str(r.save(tmp_path / f"{name}.csv")))
    argv = ["identify", paths[0], paths[1], "--structure", "oe", "--nb", "2", "--nf", "2"]
    assert main([*argv, "--validation", paths[2], "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["data"]["n_estimation"] == 800
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "need a separate validation record" in err[0]


def test_a_comparison_config_takes_several_records_and_a_validation_file(tmp_path):
    """``[data] file`` as a list and ``validation``, relative to the config: the comparison's
    least-squares row is identify's on the same records, and its store key changes with
    the numbers of any of the files."""
    a, b = experiments()
    val = experiments(seed=1)[0]
    for name, r in (("a", a), ("b", b), ("v", val)):
        r.save(tmp_path / f"{name}.csv")
    config = tmp_path / "c.toml"
    config.write_text(
        '[data]\nfile = ["a.csv", "b.csv"]\nvalidation = "v.csv"\ndetrend = "constant"\n'
        '[model]\nstructure = "oe"\nnb = 2\nnf = 2\nnk = 1\n[[optimisers]]\nname = "de"\n'
        "[run]\nruns = 1\nbudget = 300\n",
        encoding="utf-8",
    )
    (spec,) = load_config(config)
    assert spec.data.file == [str(tmp_path / "a.csv"), str(tmp_path / "b.csv")]
    assert spec.data.validation == str(tmp_path / "v.csv")
    result = flexid.compare(spec, store=tmp_path / "s.sqlite")
    ls = result.reference
    ident = flexid.identify([tmp_path / "a.csv", tmp_path / "b.csv"], structure="oe", nb=2,
                            nf=2, nk=1, optimiser="ls", validation=tmp_path / "v.csv",
                            detrend="constant")  # fmt: skip
    np.testing.assert_allclose(ls["theta"], ident.model.theta, rtol=1e-12)
    assert ls["validation"]["fit_simulation"] == pytest.approx(
        ident.validation.fit_simulation, abs=1e-9
    )
    key = _Context.from_spec(spec).spec.key
    val.replace(y=val.y * 1.01).save(tmp_path / "v.csv")
    assert _Context.from_spec(spec).spec.key != key
    config.write_text('[data]\nfile = ["a.csv", "b.csv"]\n', encoding="utf-8")
    with pytest.raises(ConfigError, match="give the validation record"):
        load_config(config)
