"""Tests of flexid.data.datasets: presets, reproducibility, metadata, noise, channel selection.

Noise levels are checked with statistical tolerances (15-20 %); everything else is the same
computation repeated, hence exact.
"""

from __future__ import annotations

import numpy as np
import pytest

from flexid.data import IOData
from flexid.data.datasets import PRESETS, generate
from flexid.envs import beam
from flexid.errors import DataError, PlantParameterError, UnknownNameError


def test_paper_presets():
    man = generate("manipulator", preset="paper-manipulator", seed=0)
    assert man.n_samples == 2300 and man.dt == 1e-3
    assert list(man.output_names) == ["tip_acceleration"] and list(man.input_names) == ["torque"]
    assert man.u.min() >= -0.3 and man.u.max() <= 0.3
    assert man.metadata["preset"] == "paper-manipulator" and man.metadata["noise_rule"] == "1%"
    trs = generate("twin-rotor", preset="paper-twin-rotor", seed=0)
    assert trs.n_samples == 8000 and trs.dt == 0.1
    assert list(trs.output_names) == ["pitch"] and list(trs.input_names) == ["main_rotor"]
    assert trs.metadata["parameters"]["lock_yaw"] is True
    assert trs.u.min() >= -1 and trs.u.max() <= 1
    assert set(PRESETS) == {"paper-manipulator", "paper-twin-rotor"}


def test_noise_free_output_is_the_plant_response_and_noise_is_separate():
    prbs = {"signal": "prbs", "n_samples": 500, "seed": 3,
            "signal_options": {"order": 7, "low": -0.2, "high": 0.2}}
    clean = generate("manipulator", sensors="ideal", **prbs)
    # generate() runs this very function on these very samples (same model, same FFT
    # lengths): exact on any machine.  Ideal sensors are the beam alone, as before the
    # measurement chain existed.
    ideal = beam.BeamParameters(**beam.IDEAL_SENSORS)
    np.testing.assert_array_equal(clean.y, beam.simulate(clean.u[:, 0], ideal))
    assert clean.metadata["sensors"] == "ideal"
    assert clean.metadata["parameters"]["encoder_counts"] is None
    noisy = generate("manipulator", sensors="ideal", noise_std=[0, 0, 0, 1], **prbs)
    np.testing.assert_array_equal(noisy.u, clean.u)  # the input does not change with noise
    np.testing.assert_array_equal(noisy.y[:, :3], clean.y[:, :3])
    assert np.std(noisy.y[:, 3] - clean.y[:, 3]) == pytest.approx(1.0, rel=0.15)
    rel = generate("manipulator", n_samples=400, seed=1, noise_std="5%", outputs=["hub_angle"])
    base = generate("manipulator", n_samples=400, seed=1, outputs=["hub_angle"])
    ratio = np.std(rel.y - base.y) / np.std(base.y)
    assert ratio == pytest.approx(0.05, rel=0.2)


def test_lab_sensors_are_the_chain_model_read_by_the_encoder_with_tachometer_noise():
    lab = generate("manipulator", n_samples=2000, seed=4)
    p = beam.BeamParameters()
    expected = beam.measure(beam.simulate(lab.u[:, 0], p), p)
    np.testing.assert_array_equal(lab.y[:, [0, 2, 3]], expected[:, [0, 2, 3]])
    counts = lab.y[:, 0] / (2 * np.pi / 2048)
    np.testing.assert_allclose(counts, np.round(counts), rtol=0, atol=1e-9)
    # the tachometer's 0.005 rad/s: 2,000 draws put the sample std within 10 % w.p. > 1 - 1e-5
    assert np.std(lab.y[:, 1] - expected[:, 1]) == pytest.approx(0.005, rel=0.1)
    assert lab.metadata["sensors"] == "lab"
    assert lab.metadata["parameters"]["actuator_bandwidth"] == 500.0
    with pytest.raises(PlantParameterError, match="sensors"):
        generate("manipulator", n_samples=100, sensors="perfect")


def test_same_seed_byte_identical_files(tmp_path):
    for suffix in (".csv", ".npz"):
        paths = []
        for i in range(2):
            d = generate("manipulator", preset="paper-manipulator", seed=11)
            path = tmp_path / f"d{i}{suffix}"
            d.save(path)
            paths.append(path)
        assert paths[0].read_bytes() == paths[1].read_bytes()
        back = IOData.from_csv(paths[0]) if suffix == ".csv" else IOData.from_npz(paths[0])
        assert back.metadata["seed"] == 11 and back.metadata["plant"] == "manipulator"
    other = generate("manipulator", preset="paper-manipulator", seed=12)
    assert not np.array_equal(other.u, d.u)


def test_parameters_and_signals_are_applied():
    a = generate("manipulator", n_samples=800, seed=0, outputs=["hub_angle"])
    b = generate("manipulator", n_samples=800, seed=0, outputs=["hub_angle"],
                 plant_params={"payload_mass": 0.05})
    assert not np.allclose(a.y, b.y)
    assert b.metadata["parameters"]["payload_mass"] == 0.05
    c = generate("twin-rotor", signal="multisine", n_samples=300, seed=0,
                 signal_options={"band": [0.05, 1.0], "amplitude": 1.5})
    assert c.u.shape == (300, 2) and np.abs(c.u).max() == pytest.approx(1.5)
    assert list(c.output_names) == ["pitch", "yaw", "pitch_rate", "yaw_rate"]


def test_bad_arguments():
    with pytest.raises(UnknownNameError, match="plant"):
        generate("moon-lander")
    with pytest.raises(UnknownNameError, match="signal"):
        generate("manipulator", signal="jazz")
    with pytest.raises(UnknownNameError, match="output"):
        generate("manipulator", outputs=["tip_temperature"])
    with pytest.raises(UnknownNameError, match="preset"):
        generate("manipulator", preset="paper-pendulum")
    with pytest.raises(DataError, match="preset"):
        generate("twin-rotor", preset="paper-manipulator")
    with pytest.raises(PlantParameterError, match="colour"):
        generate("manipulator", plant_params={"colour": 1})
    with pytest.raises(DataError):
        generate("manipulator", n_samples=-5)
    with pytest.raises(DataError):
        generate("manipulator", noise_std="lots")


def test_sensors_reach_generate_from_a_comparison_spec_and_the_cli(tmp_path):
    from flexid.cli import main
    from flexid.config import ComparisonSpec, DataSpec
    from flexid.jobs._compare import build_data

    options = {"preset": "paper-twin-rotor", "n_samples": 300, "seed": 2, "noise_std": "1%"}
    spec = ComparisonSpec(data=DataSpec(plant="twin-rotor", sensors="ideal", **options))
    want = generate("twin-rotor", sensors="ideal", **options)
    np.testing.assert_array_equal(build_data(spec).y, want.y)
    assert "ideal sensors" in spec.data.describe()
    out = tmp_path / "d.npz"
    # --output: the former spelling of --out, still read
    argv = ["generate", "twin-rotor", "--preset", "paper-twin-rotor", "--samples", "300",
            "--seed", "2", "--noise", "1%", "--sensors", "ideal", "--output", str(out)]
    assert main(argv) == 0
    np.testing.assert_array_equal(IOData.from_npz(out).y, want.y)
    lab = generate("twin-rotor", **options)
    assert not np.array_equal(lab.y, want.y)
