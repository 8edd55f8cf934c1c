"""One way for each fact: identify's cost and search keywords, the specs a program builds, and
the one table (:data:`flexid.config.KEYWORDS`) that maps between them and gives their help."""

from __future__ import annotations

import argparse
import dataclasses
import inspect

import numpy as np
import pytest

import flexid
from flexid.cli import build_parser
from flexid.config import (
    KEYWORDS,
    CostSpec,
    SearchSpec,
    keyword,
    specs_from_keywords,
)
from flexid.errors import ConfigError, UnknownNameError


def _subparser(name: str) -> argparse.ArgumentParser:
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return sub.choices[name]


def test_every_keyword_sets_a_field_of_its_spec_and_is_an_identify_parameter():
    params = inspect.signature(flexid.identify).parameters
    specs = {"cost": CostSpec, "search": SearchSpec}
    doc = " ".join(flexid.identify.__doc__.split())  # the entries, whatever their wrapping
    for k in KEYWORDS:
        assert k.field in {f.name for f in dataclasses.fields(specs[k.spec])}, k
        assert k.name in params and params[k.name].default is None, k
        assert f"{k.name} : " in doc and k.help[1:] in doc, k  # documented from the table
    # each field of the two specs has one keyword at most
    fields = [(k.spec, k.field) for k in KEYWORDS]
    assert len(fields) == len(set(fields))


@pytest.mark.parametrize("command", ["identify", "compare"])
def test_the_command_line_options_say_the_table_s_help(command):
    parser = _subparser(command)
    options = {s: a for a in parser._actions for s in a.option_strings}
    for k in KEYWORDS:
        if k.option is None or k.option not in options:
            continue  # compare takes the search options and --predictor, not --initial
        assert options[k.option].help == k.help, k.option
    assert {"--predictor", "--parametrisation", "--penalty", "--init", "--numerator"} <= set(
        options
    )


def test_keywords_build_the_specs_a_program_would():
    cost, search = specs_from_keywords("rmse", None, predictor="simulation", penalty_kind="flat",
                                       init="uniform", weight=None)  # fmt: skip
    assert cost == CostSpec(metric="rmse", predictor="simulation")
    assert search == SearchSpec(penalty="flat", init="uniform")
    assert specs_from_keywords() == (CostSpec(), SearchSpec())
    whole = CostSpec(metric="sse", initial="zero")
    assert specs_from_keywords(whole, SearchSpec(numerator="search")) == (
        whole, SearchSpec(numerator="search")
    )


def test_a_fact_given_two_ways_is_refused_naming_it():
    with pytest.raises(ConfigError, match=r"predictor given both as keyword\(s\) and in cost="):
        specs_from_keywords(CostSpec(), predictor="simulation")
    with pytest.raises(ConfigError, match=r"penalty_kind, init given both .* search=SearchSpec"):
        specs_from_keywords(None, SearchSpec(), penalty_kind="flat", init="uniform")
    with pytest.raises(ConfigError, match="not a cost or search keyword: bogus"):
        specs_from_keywords(bogus=1)
    assert keyword("--penalty").name == "penalty_kind"  # the option's name for the kind
    assert keyword("penalty").spec == "cost"  # the keyword's: the value
    with pytest.raises(UnknownNameError, match="'metric'"):
        keyword("metric")


def test_identify_refuses_a_fact_given_two_ways():
    rng = np.random.default_rng(0)
    u = rng.standard_normal(300)
    data = flexid.IOData(u, np.convolve(u, [0.0, 1.0, 0.5])[:300], dt=1.0)
    with pytest.raises(ConfigError, match="predictor given both"):
        flexid.identify(data, 2, 2, cost=CostSpec(), predictor="simulation", optimiser="ls")
    fit = flexid.identify(data, 2, 2, cost=CostSpec(predictor="one-step"), optimiser="ls")
    assert fit.cost.predictor == "one-step"
