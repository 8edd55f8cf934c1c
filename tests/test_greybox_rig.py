"""A grey-box model on a user's rig: the record's columns and units, the initial state, the
operating point, a second record to validate on.

The model is the damped spring of ``test_greybox_integration`` (the NumPy route, fast on 300
samples); its records are its own simulations, so every fit is exact to rounding and each
tolerance below is the reference's convergence (LM to ``tol = 1e-10``), far above rounding
and far below an error a wrong reading, a fixed initial state or a missing offset would leave
(percent).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import flexid
from flexid.errors import ConfigError, UnknownNameError
from flexid.fit.greybox_fit import greyest
from flexid.models.greybox import GreyBoxModel
from flexid.models.greybox_library import greybox_model
from test_greybox_integration import MODEL_FILE, TRUE

DT = 0.02


@pytest.fixture(scope="module")
def spring(tmp_path_factory) -> Path:
    """The damped spring of ``test_greybox_integration`` as a model file."""
    path = tmp_path_factory.mktemp("model") / "spring.py"
    path.write_text(MODEL_FILE, encoding="utf-8")
    return path


def _model(spring: Path, **changes) -> GreyBoxModel:
    return greybox_model(f"{spring}:MODEL", **changes)


def _record(spring: Path, seed: int, x0=(0.0, 0.0), n: int = 300) -> tuple:
    """Force [N] and position [m] of the true model (k = 80, c = 1.5) from ``x0``."""
    rng = np.random.default_rng(seed)
    u = np.repeat(rng.uniform(-3, 3, n // 10), 10)
    truth = _model(spring, **TRUE)
    return u, truth.simulate(truth.nominal, u, DT, x0=np.asarray(x0, float))[0, :, 0]


def _rig(u: np.ndarray, y: np.ndarray, offset: float = 0.0) -> flexid.IOData:
    """The record as the rig logs it: force in N as ``F``, position in mm as ``x_mm``."""
    return flexid.IOData(u, 1e3 * y + offset, dt=DT, input_names=["F"], output_names=["x_mm"])


def test_reading_maps_columns_and_units(spring):
    u, y = _record(spring, 0)
    start = _model(spring, k=30.0, c=5.0).reading(force="F", position=("x_mm", 1e-3))
    fit = greyest(_rig(u, y), start, starts=0)
    assert fit.values["k"] == pytest.approx(80.0, rel=1e-6)
    assert fit.values["c"] == pytest.approx(1.5, rel=1e-6)
    # unmapped, the model reads columns of its own names and says how to map them
    with pytest.raises(flexid.DataError, match=r"input column\(s\) \['force'\].*reading"):
        greyest(_rig(u, y), _model(spring), starts=0)
    assert start.to_dict()["columns"]["position"] == {"column": "x_mm", "factor": 1e-3}


@pytest.mark.parametrize(
    ("columns", "error", "match"),
    [
        ({"speed": "v"}, ConfigError, "no channel 'speed'"),
        ({"position": ("x_mm", 0.0)}, ConfigError, "finite and non-zero"),
    ],
)
def test_reading_refuses_what_it_cannot_read(spring, columns, error, match):
    with pytest.raises(error, match=match):
        _model(spring).reading(**columns)


def test_initial_state_is_estimated_with_the_parameters(spring):
    u, y = _record(spring, 1, x0=(0.05, -0.2))
    start = _model(spring, k=30.0, c=5.0).with_initial_states(
        position=(0.0, -0.2, 0.2), velocity=(0.0, -1.0, 1.0)
    )
    assert start.estimated_initial_states == ("position", "velocity")
    fit = greyest((u, y), start, starts=0, dt=DT)
    for name, value in (("k", 80.0), ("c", 1.5), ("position_0", 0.05), ("velocity_0", -0.2)):
        assert fit.values[name] == pytest.approx(value, rel=1e-6, abs=1e-9), name
    # held at rest, the same search cannot fit the record
    rest = greyest((u, y), _model(spring, k=30.0, c=5.0), starts=0, dt=DT)
    assert rest.fit < 99.0 < fit.fit
    with pytest.raises(UnknownNameError, match="'angle'"):
        _model(spring).with_initial_states(angle=(0.0, -1.0, 1.0))
    fixed = _model(spring).with_initial_states(position=0.05)
    assert fixed.estimated_initial_states == () and "position_0" not in fixed.free


def test_identify_estimates_the_initial_state_and_refits_it_on_a_second_record(spring, ):
    """``initial="estimate"``: the states that are outputs start where the record does, on
    the estimation record and (refitted, the physical parameters held) on a separate
    validation record, as MATLAB ``compare`` estimates ``x0``."""
    u1, y1 = _record(spring, 2, x0=(0.04, 0.0))
    u2, y2 = _record(spring, 3, x0=(-0.03, 0.0))
    model = _model(spring, k=30.0, c=5.0).reading(force="F", position=("x_mm", 1e-3))
    ident = flexid.identify(_rig(u1, y1), structure=model, validation=_rig(u2, y2),
                            initial="estimate")  # fmt: skip
    assert ident.model.parameter("position_0").value == pytest.approx(0.04, rel=1e-6)
    assert ident.estimation.fit_simulation > 99.999
    assert ident.validation.fit_simulation > 99.999
    assert "estimated initial state" in ident.validation.initial_rule
    # with the model's own (rest) initial state the second record's start is missed
    plain = flexid.identify(_rig(u1, y1), structure=model, validation=_rig(u2, y2))
    assert plain.validation.fit_simulation < 99.9


def test_identify_removes_the_operating_point_from_the_whole_record(spring, ):
    u, y = _record(spring, 4)
    offset = 250.0  # mm: the rig's zero is not the model's
    model = _model(spring, k=30.0, c=5.0).reading(force="F", position=("x_mm", 1e-3))
    raw = flexid.identify(_rig(u, y, offset), structure=model)
    ident = flexid.identify(_rig(u, y, offset), structure=model, detrend="constant")
    # the estimation part's means are not the model's rest (its input's mean is not zero),
    # so the fit is not exact: measured 91.6 %, and -238 % with the offset left in
    assert ident.validation.fit_simulation > 85.0
    assert raw.validation.fit_simulation < 0.0
    # the estimation part's mean, removed from every sample the model runs on
    n_est = ident.estimation.n_samples
    est_mean = 1e-3 * (1e3 * y[:n_est] + offset).mean()
    held_out = ident.validation.arrays()["y"]  # the samples t >= n_est
    np.testing.assert_allclose(held_out, 1e-3 * (1e3 * y[n_est:] + offset) - est_mean,
                               rtol=0, atol=1e-12)  # fmt: skip


def test_command_line_maps_channels_in_one_option(spring, tmp_path, capsys):
    from flexid.cli import main

    u, y = _record(spring, 5)
    path = tmp_path / "rig.csv"
    rows = "\n".join(f"{a:.17g},{b:.17g}" for a, b in zip(u, 1e3 * y))
    path.write_text("F,x_mm\n" + rows + "\n")
    base = ["identify", str(path), "--dt", str(DT), "--structure", "greybox", "--greybox",
            f"{spring}:MODEL", "--set", "k=30", "--set", "c=5",
            "--no-progress"]  # fmt: skip
    assert main([*base, "--channels", "force=F,position=x_mm*0.001", "--json"]) == 0
    import json

    out = json.loads(capsys.readouterr().out)
    assert out["model"]["parameters"]["k"]["value"] == pytest.approx(80.0, rel=1e-5)
    for bad, message in (("force", "CHANNEL=COLUMN"), ("force=F*x", "CHANNEL=COLUMN"),
                         ("speed=F", "no channel 'speed'")):  # fmt: skip
        assert main([*base, "--channels", bad]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and message in err[0], err
    # compare runs on a plant's own record or a configuration's: it has no columns to map
    assert main(["compare", "--plant", "twin-rotor", "--channels", "a=b"]) == 2
    assert "--channels" in capsys.readouterr().err
