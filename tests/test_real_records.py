"""flexid on measured records (``../shared/data/real/`` beside the repository, or the folder
``FLEXID_REAL_RECORDS`` names): the numbers an engineer reads.  Skipped where the records are
absent; they are never copied into the repository."""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import numpy as np
import pytest

import flexid
from flexid.data import prepare_data
from flexid.errors import DataWarning
from flexid.fit.delay import estimate_delay

ROOT = Path(__file__).resolve().parents[1]
RECORDS = Path(os.environ.get("FLEXID_REAL_RECORDS", ROOT.parent / "shared" / "data" / "real"))


def record(name: str) -> Path:
    path = RECORDS / f"{name}.csv"
    if not path.is_file():
        pytest.skip(f"the measured record {path} is not here")
    return path


def test_twin_rotor_oe16_prints_the_fit_of_the_exact_model():
    """The home-built twin rotor, OE(16, 16, 1) by DE: its poles crowd z = 1, so the direct
    form printed "< -999 %" with an output of 5.4e7.  On this machine the model found has
    55.68 % over every sample (the issue's 55.7 %).  Whatever model the search ends on, the
    printed held-out fit is the exact model's (its direct form at 100 digits,
    ``tests/test_realisation.py``'s reference)."""
    mp = pytest.importorskip("mpmath")
    from test_realisation import FIT_BOUND, exact_fit, exact_polynomials, exact_predictor

    path = record("twinrotor_prbs_a")
    options = {"dt": 0.1, "inputs": ["u"], "outputs": ["y"]}
    ident = flexid.identify(path, structure="oe", nb=16, nf=16, nk=1, optimiser="de",
                            budget=10_000, seed=1, detrend=True, load_options=options)  # fmt: skip
    _, val = prepare_data(path, detrend=True, load_options=options)
    model = ident.model
    with mp.workdps(100):
        exact = exact_predictor(*exact_polynomials(model, np.inf), val.u, val.y[:, 0],
                                0, "estimate")  # fmt: skip
    fit = exact_fit(val.y[:, 0], exact, 0)  # every sample, as MATLAB
    assert abs(ident.validation.fit_simulation - fit) <= FIT_BOUND
    assert fit > 40  # a model worth printing: the direct form's "< -999 %" was wrong
    assert np.abs(ident.validation.y_simulation).max() < 30  # degrees; the record's within 15


def test_twin_rotor_pitch_offset_warns_without_detrending():
    path = record("twinrotor_prbs_a")
    with pytest.warns(DataWarning, match=r"output 'y' has mean 2\d\.\d+ and standard"):
        prepare_data(path, load_options={"dt": 0.1, "inputs": ["u"], "outputs": ["y"]})
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        prepare_data(path, detrend="constant",
                     load_options={"dt": 0.1, "inputs": ["u"], "outputs": ["y"]})  # fmt: skip


def test_dryer_delay_is_three_samples_and_it_fits_better():
    """The DaISy dryer: both delay estimates say 3 samples; ARX(2, 2) at nk = 3 fits the held-out
    third far better than at the default nk = 1 (84.3 % against 70.1 %)."""
    path = record("dryer")
    options = {"dt": 0.08}
    est, _ = prepare_data(path, detrend=True, load_options=options)
    assert estimate_delay(est).nk == estimate_delay(est, method="correlation").nk == (3,)
    auto = flexid.identify(path, 2, 2, "auto", optimiser="ls", detrend=True,
                           load_options=options)  # fmt: skip
    one = flexid.identify(path, 2, 2, 1, optimiser="ls", detrend=True, load_options=options)
    assert list(auto.model.structure.nk) == [3]
    assert auto.validation.fit_simulation > 84 > 71 > one.validation.fit_simulation


def test_select_and_identify_give_one_model_for_one_structure():
    """The DaISy flutter record, BJ(2, 2, 2, 7, 1): select and identify fit it with the same
    reference (the same starts), so the same model and held-out fit (they were 49.21 % and
    18.66 % apart)."""
    path = record("flutter")
    sel = flexid.select(path, "bj", [{"nb": 2, "nc": 2, "nd": 2, "nf": 7}], nk=1)
    ident = flexid.identify(path, structure="bj", nb=2, nc=2, nd=2, nf=7, nk=1)
    np.testing.assert_array_equal(sel.best.model.theta, ident.model.theta)
    assert sel.best.fit_simulation == ident.validation.fit_simulation


def test_cd_player_arm_oe_reference_drops_crawling_extra_starts():
    """The CD player arm's first output, OE([8, 8], [8, 8], [1, 1]) on the first 2/3: two of
    the random and perturbed starts crawl (SSE 11.1 and 11.6 after 640 evaluations, 40 %
    above the best run's 7.58).  Run to their budgets they cost 6,400 of 7,200 evaluations
    and ended 40 % above; the reference drops them and ends at the same minimum."""
    from flexid.fit.prediction_error import oe

    data = flexid.load(record("cd_player_arm"), inputs=["u1", "u2"], outputs=["y1"])
    est, _ = data.split(2 / 3)
    res = oe(est, [8, 8], [8, 8], [1, 1], initial="estimate")
    dropped = [r for r in res.runs if "too slowly" in r.message]
    assert dropped and all(r.kind in ("perturbed", "random") for r in dropped)
    assert all(r.sse > res.sse for r in dropped)
    assert res.nfev < 3_000
    # the best run's minimum is 7.583 here; another machine's rounding may pick another
    # start's minimum, not one 5 % higher
    assert res.local_minimum and res.sse < 8.0


def test_built_in_twin_rotor_model_on_the_home_built_rig():
    """The 33-949S pitch model on a rig it was not written for: the record's columns mapped
    and converted (an ESC pulse offset in microseconds read as 0.02 V per microsecond: the
    thrust coefficients absorb the gain; the pitch in degrees), the operating point's line
    removed, the initial pitch estimated, and refitted on the second record.  Measured:
    48.1 % on record a, 57.4 % on record b, where OE(2,2), OE(4,4) and OE(16,16) reach
    53.9 %, 54.5 % and 55.3 % (with its columns renamed and nothing else changed, -629 % on
    the held-out third)."""
    import math

    from flexid.envs import twin_rotor_steppers
    from flexid.models.greybox_library import twin_rotor_pitch

    if twin_rotor_steppers._compiled() is None:  # about 11,000 simulations of 1,473 samples
        pytest.skip("the twin-rotor fit needs the compiled kernels' speed")

    model = twin_rotor_pitch().reading(main_rotor=("u", 0.02), pitch=("y", math.pi / 180))
    options = {"dt": 0.1}
    ident = flexid.identify(record("twinrotor_prbs_a"), structure=model,
                            validation=record("twinrotor_prbs_b"), initial="estimate",
                            detrend="linear", load_options=options)  # fmt: skip
    oe2 = flexid.identify(record("twinrotor_prbs_a"), structure="oe", nb=2, nf=2, nk=1,
                          validation=record("twinrotor_prbs_b"), detrend="linear",
                          load_options={**options, "inputs": ["u"], "outputs": ["y"]})  # fmt: skip
    assert ident.validation.fit_simulation > oe2.validation.fit_simulation > 45.0
    assert "estimated initial state" in ident.validation.initial_rule


def test_dryer_oe_reference_keeps_a_crawling_start_near_the_best():
    """The dryer, OE(8,8,3) on the first 2/3 (means removed): the best run is a random
    start whose budget stopped it at SSE 4.75, 1.01 times the best of the others (4.70),
    still crawling; continued, it ends at 3.83.  A rule that dropped every slow crawl lost
    that minimum (the reference printed 90.7 % instead of 91.7 %)."""
    from flexid.fit.prediction_error import oe

    est, _ = prepare_data(record("dryer"), detrend="constant", load_options={"dt": 0.08})
    res = oe(est, 8, 8, 3, initial="estimate")
    assert res.sse < 4.0
    assert any(r.kind == "random, continued" and r.sse < 4.0 for r in res.runs)
