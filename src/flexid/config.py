"""Comparison specifications and their TOML configuration files.

A comparison is fully described by a :class:`ComparisonSpec`: where the data come from
(a simulated plant and its excitation, or a recorded file), the ARX orders, the cost, the
search box, the optimisers with their hyper-parameters, the number of runs, the seed and
the budget.  ``flexid compare CONFIG.toml`` reads one; ``flexid compare --plant ...``
builds one from the defaults and the command-line options.

Example (``experiments/paper-manipulator.toml`` is a complete one)::

    name = "small-manipulator"

    [data]
    plant = "manipulator"          # or: file = "record.csv", inputs = ["u"], outputs = ["y"]
    preset = "paper-manipulator"
    seed = 0

    [model]
    na = 8
    nb = 8
    nk = 1

    [cost]
    metric = "paper"               # paper | rmse | nrmse | sse | mse
    predictor = "one-step"         # one-step | simulation

    [run]
    runs = 10
    seed = 1
    budget = 10000                 # FE; a list runs several budgets; "schedule" = the
                                   # optimisers' own loop counts (capped by schedule_cap)

    [[optimisers]]
    name = "hbcsd"
    [[optimisers]]
    name = "bfa"
    params = { step_size = 0.01 }

    [compare]
    run_timeout = 600              # seconds; a longer run is ended and recorded as failed
"""

from __future__ import annotations

from .jobs.config_file import (
    command_specs,
    load_config,
    spec_from_mapping,
)
from .jobs.config_schema import (
    CONFIG_SCHEMA,
    ConfigKey,
    check_config,
)
from .jobs.specs import (
    KEYWORDS,
    ComparisonSpec,
    Keyword,
    OptimiserSpec,
    default_spec,
    keyword,
    specs_from_keywords,
    with_optimiser_params,
)
from .models.specs import (
    PAPER_SEARCH,
    CostSpec,
    DataSpec,
    ModelSpec,
    SearchSpec,
)
from .models.vocabulary import (
    COMPARE_BUDGET,
    COMPARE_RUNS,
    CORRELATION_LAGS,
    DEFAULT_OPTIMISERS,
    DEPRECATED_REFERENCES,
    GREYBOX,
    IDENTIFY_BUDGET,
    LEAST_SQUARES,
    OUTPUT_ERROR,
    POLE_RADIUS_CAP,
    PREDICTION_ERROR,
    REFERENCES,
    REFLECTION_CAP,
    SCHEDULE,
    STATE_SPACE,
    STRUCTURE_NAMES,
    SUBSPACE,
    VALIDATION_ALPHA,
    VALIDATION_GUIDE,
    add_structure_names,
    auto_initial,
    current_reference,
)

__all__ = [
    "COMPARE_BUDGET",
    "COMPARE_RUNS",
    "CONFIG_SCHEMA",
    "CORRELATION_LAGS",
    "DEFAULT_OPTIMISERS",
    "DEPRECATED_REFERENCES",
    "GREYBOX",
    "IDENTIFY_BUDGET",
    "KEYWORDS",
    "LEAST_SQUARES",
    "OUTPUT_ERROR",
    "PAPER_SEARCH",
    "POLE_RADIUS_CAP",
    "PREDICTION_ERROR",
    "REFERENCES",
    "REFLECTION_CAP",
    "SCHEDULE",
    "STATE_SPACE",
    "STRUCTURE_NAMES",
    "SUBSPACE",
    "VALIDATION_ALPHA",
    "VALIDATION_GUIDE",
    "ComparisonSpec",
    "ConfigKey",
    "CostSpec",
    "DataSpec",
    "Keyword",
    "ModelSpec",
    "OptimiserSpec",
    "SearchSpec",
    "add_structure_names",
    "auto_initial",
    "check_config",
    "command_specs",
    "current_reference",
    "default_spec",
    "keyword",
    "load_config",
    "spec_from_mapping",
    "specs_from_keywords",
    "with_optimiser_params",
]
