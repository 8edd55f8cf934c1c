"""Frequency-response estimates: against scipy.signal by hand, their bands' coverage of a
known system, the models' responses, the verdict in validation, the figure and the CLI."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy import signal

import flexid
from flexid.cli import main
from flexid.data import IOData
from flexid.errors import DataError, UnknownNameError
from flexid.validation.frequency import frequency_agreement, frf

# a known two-input system: one first-order and one second-order path (scipy's lfilter)
B1, A1 = [0.0, 0.5], [1.0, -0.5]
B2, A2 = [0.0, 0.2, 0.1], [1.0, -0.3, 0.2]


def two_input_record(seed: int, n: int = 4000, noise: float = 0.5) -> IOData:
    rng = np.random.default_rng(seed)
    u = rng.standard_normal((n, 2))
    y = signal.lfilter(B1, A1, u[:, 0]) + signal.lfilter(B2, A2, u[:, 1])
    return IOData(u, y + noise * rng.standard_normal(n), dt=0.01)


def true_response(frequencies: np.ndarray, dt: float = 0.01) -> np.ndarray:
    g1 = signal.freqz(B1, A1, worN=frequencies, fs=1 / dt)[1]
    g2 = signal.freqz(B2, A2, worN=frequencies, fs=1 / dt)[1]
    return np.stack([g1, g2], axis=-1)[:, None, :]


@pytest.fixture(scope="module")
def siso():
    rng = np.random.default_rng(1)
    u = rng.standard_normal(6000)
    y = signal.lfilter([0.0, 0.3, 0.2], [1.0, -1.2, 0.6], u) + 0.2 * rng.standard_normal(6000)
    return IOData(u, y, dt=0.002)


def test_h1_equals_scipy_csd_over_welch_and_the_coherence_scipy_s(siso):
    # the same Hann segments, overlap and mean removal as scipy's defaults: equal to
    # rounding (relative 1e-10: a ratio of sums of 8 segments' products)
    est = frf(siso, segment=800)
    fs = 1 / siso.dt
    _, puu = signal.welch(siso.u[:, 0], fs=fs, nperseg=800)
    _, puy = signal.csd(siso.u[:, 0], siso.y[:, 0], fs=fs, nperseg=800)
    _, coh = signal.coherence(siso.u[:, 0], siso.y[:, 0], fs=fs, nperseg=800)
    np.testing.assert_allclose(est.response[:, 0, 0], puy[1:] / puu[1:], rtol=1e-10)
    np.testing.assert_allclose(est.coherence[:, 0], coh[1:], rtol=1e-10, atol=1e-13)
    assert est.frequency[0] == pytest.approx(fs / 800) and est.frequency[-1] == fs / 2


def test_several_inputs_solve_the_cross_spectral_matrix_of_scipy_csd():
    # H = S_yu S_uu^-1 per frequency, the spectral matrix assembled from scipy.signal.csd
    # pairs by hand; the multiple coherence from the same matrix
    data = two_input_record(3)
    est = frf(data)
    n = est.settings["segment"]
    x = np.hstack([data.u, data.y])
    s = np.empty((n // 2 + 1, 3, 3), dtype=complex)
    for a in range(3):
        for b in range(3):  # csd(x_b, x_a) = E[X_a conj(X_b)]
            s[:, a, b] = signal.csd(x[:, b], x[:, a], nperseg=n)[1]
    h = s[1:, 2:, :2] @ np.linalg.inv(s[1:, :2, :2])
    np.testing.assert_allclose(est.response, h, rtol=1e-9)
    gamma2 = np.einsum("fi,fij,fj->f", s[1:, 2, :2], np.linalg.inv(s[1:, :2, :2]),
                       s[1:, :2, 2]).real / s[1:, 2, 2].real  # fmt: skip
    np.testing.assert_allclose(est.coherence[:, 0], gamma2, rtol=1e-9)


def test_spa_is_the_hann_windowed_covariances_transformed_by_hand(siso):
    m = 40
    est = frf(siso, "spa", lag_width=m, frequencies=[10.0, 50.0, 120.0])
    u, y = siso.u[:, 0] - siso.u.mean(), siso.y[:, 0] - siso.y.mean()
    n = u.size
    lags = np.arange(-m, m + 1)

    def cov(a, b):  # R_ab(tau) = 1/N sum_t a(t + tau) b(t)
        return np.array([np.dot(a[max(t, 0): n + min(t, 0)], b[max(-t, 0): n - max(t, 0)])
                         for t in lags]) / n  # fmt: skip

    w = 0.5 * (1 + np.cos(np.pi * lags / m))
    for k, f in enumerate([10.0, 50.0, 120.0]):
        e = np.exp(-2j * np.pi * f * siso.dt * lags)
        expected = np.sum(cov(y, u) * w * e) / np.sum(cov(u, u) * w * e)
        assert est.response[k, 0, 0] == pytest.approx(expected, rel=1e-9)
    assert est.averages == pytest.approx(n / np.sum(w**2))


def test_etfe_is_the_hann_smoothed_periodograms_by_hand(siso):
    est = frf(siso, "etfe", width=5)
    u, y = siso.u[:, 0] - siso.u.mean(), siso.y[:, 0] - siso.y.mean()
    U, Y = np.fft.fft(u), np.fft.fft(y)
    w = np.array([0.25, 0.75, 1.0, 0.75, 0.25]) / 3.0  # Hann over 5 bins, normalised
    n = u.size
    for k in (1, 2, 700, n // 2):  # the first bins smooth across 0 Hz, the last across Nyquist
        idx = (k + np.arange(-2, 3)) % n
        expected = np.sum(w * Y[idx] * U[idx].conj()) / np.sum(w * np.abs(U[idx]) ** 2)
        assert est.response[k - 1, 0, 0] == pytest.approx(expected, rel=1e-9)
    assert est.averages == pytest.approx(1 / np.sum(w**2))


@pytest.mark.parametrize("method", ["tfestimate", "spa", "etfe"])
def test_the_band_holds_the_true_response_at_its_level(method):
    # 20 records of a known two-input system: the analytic response lies inside each
    # element's 95 % circle at a share consistent with 95 %.  The circle assumes Gaussian
    # noise and independent averages; the smoothing's equivalent averages (Welch's overlap
    # correction, the lag window's and kernel's sum of squares) and its bias (the response
    # varies across the bandwidth) make it approximate: measured 95.5-96.4 %, so the
    # mean share must lie in [0.93, 0.98] (its seed-to-seed spread over 20 records is below
    # 0.005)
    shares = []
    for seed in range(20):
        est = frf(two_input_record(seed), method)
        shares.append(est.inside(true_response(est.frequency)).mean())
    assert 0.93 <= np.mean(shares) <= 0.98, np.mean(shares)


def test_every_linear_model_s_response_is_scipy_s():
    rng = np.random.default_rng(0)
    arx = flexid.ARXStructure(2, [2, 1], [1, 2]).model(rng.uniform(-0.2, 0.2, 5), dt=0.1)
    oe = flexid.structure("oe", nb=2, nf=2, nk=1).model([0.5, 0.2, -1.2, 0.5], dt=0.1)
    f = np.linspace(0.05, 5.0, 37)
    w = 2 * np.pi * f * 0.1
    for model in (arx, oe):
        g = model.frequency_response(f)
        assert g.shape == (f.size, 1, model.structure.n_inputs)
        for i in range(model.structure.n_inputs):
            expected = signal.dfreqresp(model.to_dlti(i), w=w)[1]
            np.testing.assert_allclose(g[:, 0, i], expected, rtol=1e-10)


def test_a_true_model_agrees_and_a_model_6_db_low_does_not():
    data = two_input_record(7, n=8000, noise=0.1)
    est = frf(data)
    true = frequency_agreement(est, true_response(est.frequency))
    assert true.share[0] >= 0.9 and true.judged[0] == 2 * np.sum(est.coherence[:, 0] >= 0.9)
    wrong = 0.5 * true_response(est.frequency)
    assert frequency_agreement(est, wrong).share[0] < 0.25


def test_modes_of_a_known_model_are_the_eigenvalues_of_its_realisation():
    from flexid.models.statespace import StateSpaceModel

    rng = np.random.default_rng(2)
    a = rng.standard_normal((6, 6))
    a *= 0.95 / np.max(np.abs(np.linalg.eigvals(a)))
    model = StateSpaceModel(a, rng.standard_normal((6, 1)), rng.standard_normal((1, 6)),
                            np.zeros((1, 1)), dt=0.01)  # fmt: skip
    eig = np.linalg.eigvals(a)
    s = np.log(eig) / 0.01
    expected = sorted(np.abs(s) / (2 * np.pi))
    found = sorted(m.frequency for m in model.modes() for _ in range(1 + (m.kind == "pair")))
    np.testing.assert_allclose(found, expected, rtol=1e-9)


def test_the_reference_oe_model_has_the_beam_s_first_three_modes():
    # the paper's record (2,300 samples at 1 kHz, lab sensors): its resolution 1/T = 0.43 Hz
    # and the anti-alias filter let the beam's modes at 11.8, 32.2 and 58.2 Hz through
    # (the fourth, 101.6 Hz, too; above it the 1 % sensor noise dominates); the reference
    # OE(16,16,1) model's modes lie within 1 % of the finite-difference beam's
    from flexid.data.datasets import generate
    from flexid.envs import beam
    from flexid.models.modes import modes

    record = generate("manipulator", preset="paper-manipulator", seed=0,
                      outputs=["tip_acceleration"])  # fmt: skip
    ident = flexid.identify(record, structure="oe", nb=16, nf=16, nk=1, optimiser="pem")
    pairs = [m.frequency for m in modes(ident.model.poles(), record.dt) if m.kind == "pair"]
    for f_true in beam.natural_frequencies(beam.BeamParameters(), n_modes=3):
        assert min(abs(f - f_true) for f in pairs) <= 0.01 * f_true
    verdict = ident.validation.frequency
    assert verdict is not None and verdict.share[0] >= 0.9
    assert "inside the 95 % band" in ident.validation.summary()


def test_a_grey_box_report_says_why_it_has_no_frequency_verdict():
    from flexid.validation import residual_report

    rng = np.random.default_rng(0)
    u, y = rng.standard_normal((300, 1)), rng.standard_normal(300)
    report = residual_report(y, None, y * 0.9, u, start=0, dt=0.1, max_lag=10, names=["u"],
                             output_name="y", initial="estimate", initial_one_step=None,
                             poles=[0.5], zeros=[[]])  # fmt: skip
    assert report.frequency is None and "no frequency response" in report.frequency_note
    assert report.to_dict()["frequency"] is None


def test_peaks_are_the_known_resonances():
    # two lightly damped modes at 5 and 12 Hz (100 Hz sampling), 20,000 samples
    rng = np.random.default_rng(4)
    dt, n = 0.01, 20000
    den = np.convolve(*[[1, -2 * 0.99 * np.cos(2 * np.pi * f * dt), 0.99**2] for f in (5, 12)])
    u = rng.standard_normal(n)
    y = signal.lfilter([0, 0.01], den, u) + 0.01 * rng.standard_normal(n)
    peaks = frf(IOData(u, y, dt=dt)).peaks()
    assert peaks.size == 2 and np.allclose(peaks, [5, 12], atol=0.2)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"segment": 5000}, "longer than the record"),
        ({"method": "spa", "lag_width": 3000}, "longer than the record"),
        ({"method": "etfe", "width": 4}, "odd"),
        ({"resolution": 0.05}, "too short for this resolution"),
        ({"resolution": 80.0}, "above the Nyquist"),
        ({"method": "spa", "frequencies": [10, 60]}, "above the Nyquist"),
        ({"frequencies": [10]}, "chosen by method 'spa'"),
        ({"level": 1.0}, "level"),
    ],
)
def test_bad_settings_raise_a_data_error(kwargs, match):
    data = two_input_record(0, n=2000)  # 20 s at 100 Hz: Nyquist 50 Hz
    with pytest.raises(DataError, match=match):
        frf(data, **kwargs)


def test_inputs_that_carry_nothing_apart_are_refused():
    rng = np.random.default_rng(0)
    u = rng.standard_normal(1000)
    with pytest.raises(DataError, match="constant"):
        frf(IOData(np.column_stack([u, np.full(1000, 2.0)]), u, dt=1.0))
    with pytest.raises(DataError, match="linear combinations"):
        frf(IOData(np.column_stack([u, 2 * u]), u, dt=1.0))
    with pytest.raises(UnknownNameError, match="tfestimate"):
        frf(IOData(u, u, dt=1.0), "welch")


def test_the_cli_writes_the_figure_and_the_json(tmp_path, capsys):
    path = tmp_path / "rec.csv"
    two_input_record(0, n=3000).save(path)
    figure = tmp_path / "bode.png"
    assert main(["frf", str(path), "--figure", str(figure)]) == 0
    assert figure.stat().st_size > 10_000 and "peaks [Hz]" in capsys.readouterr().out
    assert main(["frf", str(path), "--method", "etfe", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["method"] == "etfe" and len(out["coherence"]) == 1500


@pytest.mark.parametrize(
    "extra, match",
    [
        (["--segment", "99999"], "longer than the record"),
        (["--figure", "x.jpg"], ".png, .pdf or .svg"),
        (["--figure", "nowhere/x.png"], "no folder"),
    ],
)
def test_the_cli_refuses_bad_input_in_one_line_and_leaves_no_file(tmp_path, capsys, extra,
                                                                  match):  # fmt: skip
    path = tmp_path / "rec.csv"
    two_input_record(0, n=2000).save(path)
    extra = [str(tmp_path / e) if e.endswith((".png", ".jpg")) else e for e in extra]
    assert main(["frf", str(path), *extra]) == 2
    err = capsys.readouterr().err
    assert match in err and err.count("\n") == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rec.csv"]


def test_identification_figures_include_the_bode_figure(tmp_path):
    from flexid.report.plots import identification_figures

    data = IOData(*[two_input_record(1, n=3000).u[:, :1], two_input_record(1, n=3000).y],
                  dt=0.01)  # fmt: skip
    ident = flexid.identify(data, 2, 2, 1)
    paths = identification_figures(ident, tmp_path)
    assert tmp_path / "bode.png" in paths


# ============================================================================ modes
def test_the_beam_s_own_modes_are_its_finite_difference_frequencies_and_damping():
    # two routes: eig of the damped first-order A against eigh(K, M) and the modal damping
    # law (equal for modal damping: |s| = omega; rounding of eig on a 30-state A, 1e-9)
    from flexid.data.plants import get_plant
    from flexid.envs import beam

    params = beam.BeamParameters()
    f, zeta = get_plant("manipulator").true_modes()
    np.testing.assert_allclose(f[:5], beam.natural_frequencies(params, n_modes=5), rtol=1e-9)
    np.testing.assert_allclose(zeta[:3], [params.damping_ratio(k) for k in (1, 2, 3)],
                               rtol=1e-9)  # fmt: skip
    f_rotor, z_rotor = get_plant("twin-rotor").true_modes({"Mg": 0.5})
    from flexid.envs.twin_rotor_physics import TwinRotorParameters, pitch_linear_mode

    assert (f_rotor[0], z_rotor[0]) == pitch_linear_mode(TwinRotorParameters(Mg=0.5))


def test_a_mode_table_matches_model_modes_peaks_and_the_truth_one_to_one():
    from flexid.models.statespace import StateSpaceModel
    from flexid.validation.frequency import mode_table, mode_table_text

    dt = 0.01
    blocks = []
    for f, zeta in ((5.0, 0.02), (12.0, 0.05)):
        s = 2 * np.pi * f * (-zeta + 1j * np.sqrt(1 - zeta**2))
        z = np.exp(s * dt)
        blocks.append(np.array([[z.real, z.imag], [-z.imag, z.real]]))
    a = np.block([[blocks[0], np.zeros((2, 2))], [np.zeros((2, 2)), blocks[1]]])
    model = StateSpaceModel(a, np.ones((4, 1)), np.ones((1, 4)), np.zeros((1, 1)), dt=dt)
    truth = ([5.01, 12.0, 30.0, 80.0], [0.02, 0.05, 0.1, 0.1])  # 80 Hz: above Nyquist
    rows = mode_table(model, truth=truth)
    assert [round(r.frequency, 9) for r in rows[:2]] == [5.0, 12.0]
    assert rows[0].true_frequency == 5.01 and rows[0].frequency_error == pytest.approx(
        100 * (5.0 - 5.01) / 5.01)  # fmt: skip
    assert rows[1].damping_error == pytest.approx(0.0, abs=1e-12)
    assert len(rows) == 3 and np.isnan(rows[2].frequency) and rows[2].true_frequency == 30.0
    text = mode_table_text(rows)
    assert "missed" in text and "record peak" not in text  # no estimate: no peak column
    # the simulated record's peaks join the table
    rng = np.random.default_rng(0)
    u = rng.standard_normal(20000)
    y = model.simulate(u[:, None])[:, 0] + 0.01 * rng.standard_normal(20000)
    rows = mode_table(model, estimate=frf(IOData(u, y, dt=dt)))
    # a resonance's peak lies near, not at, its natural frequency (the damping and the other
    # mode move it: 12.05 Hz here): within 1 %
    np.testing.assert_allclose([r.peak for r in rows], [5.0, 12.0], rtol=0.01)


def test_identify_reports_the_modes_against_the_simulated_plant_s(tmp_path):
    record = flexid.generate("manipulator", preset="paper-manipulator", seed=0)
    path = tmp_path / "man.csv"
    record.save(path)  # the plant and its parameters travel in the file's header
    ident = flexid.identify(str(path), structure="oe", nb=16, nf=16, nk=1, optimiser="pem")
    first = ident.modes[0]
    assert abs(first.frequency_error) < 0.1 and first.true_damping == pytest.approx(0.026)
    assert "Modes: the model's" in ident.summary() and "plant f [Hz]" in ident.summary()
    assert ident.to_dict()["modes"][0]["true_frequency_hz"] == pytest.approx(11.8398, rel=1e-4)


def test_select_from_a_flat_grid_over_arx_and_oe_writes_its_frequency_figures(tmp_path, capsys):
    # the README's command, small: each structure takes the grid's orders it has (ARX ties
    # na = nb), and --figure writes the selection, Bode and stabilisation figures
    record = flexid.generate("manipulator", preset="paper-manipulator", seed=0, n_samples=900)
    path = tmp_path / "man.csv"
    record.save(path)
    figure = tmp_path / "sel.png"
    argv = ["select", str(path), "--structures", "arx,oe", "--orders", "nb=2,4",
            "--orders", "nf=2,4", "--nk", "1", "--figure", str(figure), "--no-progress"]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "ARX(na=4, nb=4, nk=1)" in out and "OE(nb=2, nf=4, nk=1)" in out
    assert "in band" in out
    for name in ("sel.png", "sel_bode.png", "sel_stabilisation.png"):
        assert (tmp_path / name).stat().st_size > 10_000


def test_the_stabilisation_diagram_marks_a_mode_found_again_at_the_next_order():
    from flexid.report.plots import stabilisation_diagram

    rng = np.random.default_rng(0)
    dt, n = 0.01, 6000
    den = np.convolve(*[[1, -2 * 0.98 * np.cos(2 * np.pi * f * dt), 0.98**2] for f in (5, 15)])
    u = rng.standard_normal(n)
    y = signal.lfilter([0, 0.05, 0.02], den, u) + 0.001 * rng.standard_normal(n)
    sel = flexid.select(IOData(u, y, dt=dt), structures="arx",
                        orders={"na": [4, 6], "nb": [3]}, nk=1)  # fmt: skip
    fig = stabilisation_diagram(sel)
    labels = fig.axes[0].get_legend_handles_labels()[1]
    assert "stable" in labels and fig.axes[0].get_ylabel() == "model order (poles) [-]"


def test_the_twin_rotor_s_mode_at_an_operating_point_is_its_linearisation_s():
    # an independent route: the eigenvalues of a central-difference Jacobian of the model's
    # own equations (Coulomb friction off: no linearisation at rest) at the balance point of
    # 0.6 V on the main rotor; the difference step 1e-6 leaves ~1e-8 relative error
    from dataclasses import replace

    from flexid.data.plants import get_plant
    from flexid.envs import twin_rotor_physics as tr

    p = tr.TwinRotorParameters(lock_yaw=True)  # the paper's preset: yaw held at rest
    f, zeta = get_plant("twin-rotor").true_modes(p, inputs={"main_rotor": 0.6})
    tau1 = p.k1 * 0.6 / p.T10
    psi = np.arcsin(float(tr.thrust(tau1, p.a1, p.b1, p.thrust_law)) / p.Mg)
    x0 = np.array([psi, 0.0, 0.0, 0.0, tau1, 0.0, p.kc * tau1])
    u0 = np.array([[0.6, 0.0]])
    smooth = replace(p, B2psi=0.0, B2phi=0.0)
    assert np.abs(tr.derivatives(x0[None], u0, smooth)).max() < 1e-12  # a balance point
    h = 1e-6
    jac = np.column_stack([
        (tr.derivatives((x0 + h * e)[None], u0, smooth)[0]
         - tr.derivatives((x0 - h * e)[None], u0, smooth)[0]) / (2 * h)
        for e in np.eye(7)
    ])  # fmt: skip
    s = np.linalg.eigvals(jac)
    s = s[s.imag > 0]
    assert s.size == 1
    assert f[0] == pytest.approx(abs(s[0]) / (2 * np.pi), rel=1e-7)
    assert zeta[0] == pytest.approx(-s[0].real / abs(s[0]), rel=1e-6)
