"""The shared argument validators: what each accepts, what it rejects, and what it raises."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest

from flexid._validate import integer, is_integer, positive_int, positive_real, real
from flexid.errors import (
    BudgetError,
    ConfigError,
    DataError,
    FlexidError,
    HyperParameterError,
    PlantParameterError,
)

ERRORS = [BudgetError, ConfigError, DataError, HyperParameterError, PlantParameterError]
NOT_NUMBERS = [True, False, np.True_, "3", b"3", None, [3], (3,), np.array([3.0]), object()]


# ------------------------------------------------------------------------------- is_integer
@pytest.mark.parametrize(
    "value", [0, -5, 7, 2**70, np.int8(3), np.int64(-2), np.uint64(9), np.intp(1)]
)
def test_is_integer_accepts_python_and_numpy_integers(value):
    assert is_integer(value)


@pytest.mark.parametrize(
    "value", [True, False, np.True_, 3.0, np.float64(3.0), "3", None, np.array(3), Fraction(3)]
)
def test_is_integer_rejects_bools_floats_strings_and_arrays(value):
    assert not is_integer(value)


# ---------------------------------------------------------------------------------- integer
@pytest.mark.parametrize("value", [1, 5, np.int32(1), np.uint8(200), np.int64(10**12)])
def test_positive_int_returns_a_python_int(value):
    out = positive_int(value, "hold", error=DataError)
    assert out == int(value) and type(out) is int


@pytest.mark.parametrize(
    "value", [0, -1, np.int64(0), 1.0, 2.5, np.float64(3.0), math.nan, math.inf, *NOT_NUMBERS]
)
@pytest.mark.parametrize("error", ERRORS)
def test_positive_int_rejects_with_the_given_error_naming_the_argument(value, error):
    with pytest.raises(error, match=r"^hold must be an integer >= 1, got ") as info:
        positive_int(value, "hold", error=error)
    assert isinstance(info.value, FlexidError)
    assert repr(value) in str(info.value)


def test_integer_bounds_are_inclusive():
    assert integer(4, "n_sections", error=PlantParameterError, minimum=4, maximum=400) == 4
    assert integer(400, "n_sections", error=PlantParameterError, minimum=4, maximum=400) == 400
    for bad in (3, 401):
        with pytest.raises(PlantParameterError, match=r"^n must be an integer in \[4, 400\]"):
            integer(bad, "n", error=PlantParameterError, minimum=4, maximum=400)
    with pytest.raises(ConfigError, match=r"^k must be an integer <= 2, got 3$"):
        integer(3, "k", error=ConfigError, maximum=2)
    assert integer(-(10**30), "k", error=ConfigError) == -(10**30)  # no bound: any integer


def test_integer_minimum_zero_accepts_zero_and_rejects_negatives():
    assert integer(0, "seed", error=ConfigError, minimum=0) == 0
    with pytest.raises(ConfigError, match=r"^seed must be an integer >= 0, got -1$"):
        integer(-1, "seed", error=ConfigError, minimum=0)


def test_integer_none_only_when_allowed():
    assert integer(None, "max_nfev", error=ConfigError, minimum=1, none_ok=True) is None
    with pytest.raises(ConfigError, match=r"^max_nfev must be an integer >= 1, got None$"):
        integer(None, "max_nfev", error=ConfigError, minimum=1)
    with pytest.raises(ConfigError, match=r"max_nfev must be an integer >= 1 or None, got 0"):
        integer(0, "max_nfev", error=ConfigError, minimum=1, none_ok=True)


@pytest.mark.parametrize("value", [8.0, np.float64(8.0), np.float32(8.0), 8, np.int16(8)])
def test_integer_valued_floats_only_when_asked(value):
    out = integer(value, "na", error=DataError, minimum=0, integral_float=True)
    assert out == 8 and type(out) is int
    if not is_integer(value):
        with pytest.raises(DataError, match="na must be an integer"):
            integer(value, "na", error=DataError, minimum=0)


@pytest.mark.parametrize("value", [8.5, math.nan, math.inf, -math.inf, True, "8"])
def test_integral_float_still_rejects_fractions_non_finite_bools_and_strings(value):
    with pytest.raises(DataError, match="na must be an integer"):
        integer(value, "na", error=DataError, integral_float=True)


def test_integral_float_applies_the_bounds():
    with pytest.raises(DataError, match=r"na must be an integer >= 1, got 0.0"):
        integer(0.0, "na", error=DataError, minimum=1, integral_float=True)


# ------------------------------------------------------------------------------------- real
@pytest.mark.parametrize(
    "value",
    [1e-3, 2, np.float64(0.5), np.float32(0.25), np.int64(3), np.array(0.1), Fraction(1, 4)],
)
def test_positive_real_returns_a_python_float(value):
    out = positive_real(value, "dt", error=DataError)
    assert out == float(value) and type(out) is float


@pytest.mark.parametrize("value", [0, 0.0, -1e-300, -2, math.nan, math.inf, -math.inf])
@pytest.mark.parametrize("error", ERRORS)
def test_positive_real_rejects_values_with_the_given_error(value, error):
    with pytest.raises(error, match=r"^dt \[s\] must be positive and finite, got ") as info:
        positive_real(value, "dt", error=error, unit="s")
    assert repr(value) in str(info.value)


@pytest.mark.parametrize("value", NOT_NUMBERS)
def test_real_rejects_bools_strings_and_non_numbers(value):
    with pytest.raises(PlantParameterError, match=r"^amplitude must be a number, got "):
        real(value, "amplitude", error=PlantParameterError)


def test_real_without_bounds_needs_only_a_finite_number():
    assert real(-1e300, "x", error=DataError) == -1e300
    for bad in (math.nan, math.inf, -math.inf, np.float64("nan")):
        with pytest.raises(DataError, match=r"^x must be finite, got "):
            real(bad, "x", error=DataError)


def test_real_closed_and_open_bounds():
    kw = dict(error=PlantParameterError, minimum=0, maximum=0.1, low_open=True)
    assert real(0.1, "dt", **kw) == 0.1  # closed above
    assert real(1e-9, "dt", **kw) == 1e-9
    for bad in (0.0, 0.1000001, -1.0):
        with pytest.raises(PlantParameterError, match=r"dt must be finite and in \(0, 0.1\]"):
            real(bad, "dt", **kw)
    both_open = dict(error=ConfigError, minimum=0, maximum=1, low_open=True, high_open=True)
    for bad in (0, 1, 1.0):
        with pytest.raises(ConfigError, match=r"r_max must be finite and in \(0, 1\)"):
            real(bad, "r_max", **both_open)
    assert real(0, "w", error=DataError, minimum=0) == 0.0  # closed below
    with pytest.raises(DataError, match=r"^w must be finite and >= 0, got -0.5$"):
        real(-0.5, "w", error=DataError, minimum=0)
    with pytest.raises(DataError, match=r"^w must be finite and < 2, got 2$"):
        real(2, "w", error=DataError, maximum=2, high_open=True)


def test_real_allow_inf_still_rejects_nan_and_applies_the_bounds():
    kw = dict(error=BudgetError, minimum=0, low_open=True, allow_inf=True)
    assert real(math.inf, "max_time", **kw) == math.inf
    for bad in (math.nan, 0.0, -math.inf):
        with pytest.raises(BudgetError, match=r"^max_time must be positive \(not NaN\), got "):
            real(bad, "max_time", **kw)
    assert real(-math.inf, "target", error=BudgetError, allow_inf=True) == -math.inf
    with pytest.raises(BudgetError, match=r"^target must be a number \(not NaN\), got nan$"):
        real(math.nan, "target", error=BudgetError, allow_inf=True)


def test_real_none_only_when_allowed():
    assert real(None, "target", error=BudgetError, none_ok=True) is None
    with pytest.raises(BudgetError, match=r"^target must be a number, got None$"):
        real(None, "target", error=BudgetError)
    with pytest.raises(BudgetError, match=r"target must be finite, or None, got inf"):
        real(math.inf, "target", error=BudgetError, none_ok=True)


# ---------------------------------------------------------------- through the public modules
def test_the_modules_raise_their_own_error_types_through_the_validators():
    from flexid.data.signals import prbs
    from flexid.optimisers import Budget

    with pytest.raises(DataError, match="n_samples"):
        prbs(True)
    with pytest.raises(DataError, match="PRBS clock"):
        prbs(100, clock=np.float64(2.0))
    assert prbs(np.int64(50), np.int8(5)).shape == (50,)
    with pytest.raises(BudgetError, match="max_fe"):
        Budget(max_fe=True)
    with pytest.raises(BudgetError, match="max_time"):
        Budget(max_time=math.nan)
