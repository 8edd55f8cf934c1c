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

from .jobs import config_file as _jobs_config_file
from .jobs import config_schema as _jobs_config_schema
from .jobs import specs as _jobs_specs

# every name each module lists in its __all__: the pieces live in their layers
from .jobs.config_file import *  # noqa: F403
from .jobs.config_schema import *  # noqa: F403
from .jobs.specs import *  # noqa: F403
from .models import specs as _models_specs
from .models import vocabulary as _models_vocabulary
from .models.specs import *  # noqa: F403
from .models.vocabulary import *  # noqa: F403

__all__ = sorted([
    *_jobs_config_file.__all__,
    *_jobs_config_schema.__all__,
    *_jobs_specs.__all__,
    *_models_specs.__all__,
    *_models_vocabulary.__all__,
])
