"""Every public function refuses a keyword it does not take with a FlexidError naming it.

As python-control's ``kwargs_test``: one test over the whole front door (``flexid.__all__``),
so a new public function is covered when it is exported.  The check runs before anything
else, so a bad keyword is reported even when the required arguments are missing too.
"""

from __future__ import annotations

import inspect

import pytest

import flexid
from flexid.errors import FlexidError, UnknownKeywordError

FUNCTIONS = sorted(n for n in flexid.__all__ if inspect.isfunction(getattr(flexid, n)))
BOGUS = "flexid_no_such_keyword"


@pytest.mark.parametrize("name", [n for n in FUNCTIONS if n != "greybox_model"])
def test_an_unknown_keyword_is_a_flexid_error_naming_the_function(name):
    with pytest.raises(UnknownKeywordError, match=rf"^{name}\(\) got .*'{BOGUS}'; it takes "):
        getattr(flexid, name)(**{BOGUS: 1})


def test_forwarded_options_are_checked_against_where_they_go(tmp_path):
    data = flexid.generate("manipulator", n_samples=60, seed=0)
    path = flexid.save(data, tmp_path / "r.csv")
    with pytest.raises(UnknownKeywordError, match=r"^load\(\) got option\(s\) 'variable', "
                       r"which a \.csv file does not take"):
        flexid.load(path, variable="x")
    with pytest.raises(UnknownKeywordError, match=r"^greybox_model\('twin-rotor-pitch'\) got "
                       r"unknown option\(s\) 'mass'"):
        flexid.greybox_model("twin-rotor-pitch", mass=1.0)
    assert flexid.greybox_model("twin-rotor-pitch", Mg=0.5).parameter("Mg").value == 0.5
    with pytest.raises(UnknownKeywordError, match=r"^oe\(\) got .*'starts_'"):
        flexid.oe(data, 2, 2, starts_=1)
    # a keyword a forwarding function passes on is not refused
    assert flexid.structure("oe", nb=2, nf=2).kind == "oe"


def test_the_error_is_a_type_error_too():
    # generic handlers written for Python's own error keep working
    assert issubclass(UnknownKeywordError, TypeError) and issubclass(UnknownKeywordError,
                                                                    FlexidError)
