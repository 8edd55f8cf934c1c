"""Judging a model on a record: the residual tests, their statistics, and the measured
frequency response.

:func:`validate` and its reports are importable from here (they live in
:mod:`flexid.validation.verdict`); :mod:`flexid.validation.diagnostics` holds the tests on
plain arrays, :mod:`flexid.validation.portmanteau` their statistics and
:mod:`flexid.validation.frequency` the non-parametric frequency-response estimates.
"""

from . import verdict as _verdict
from .verdict import *  # noqa: F403  (its __all__ is the contract)

__all__ = list(_verdict.__all__)
