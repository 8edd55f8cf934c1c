"""Judging a model on a record: the residual tests, their statistics, and the measured
frequency response.

:func:`validate` and its reports are importable from here (they live in
:mod:`flexid.validation.verdict`); :mod:`flexid.validation.diagnostics` holds the tests on
plain arrays, :mod:`flexid.validation.portmanteau` their statistics and
:mod:`flexid.validation.frequency` the non-parametric frequency-response estimates.
"""

from .verdict import (
    INITIAL_RULES,
    StabilityReport,
    ValidationReport,
    between_outputs,
    joint_tests,
    joint_verdict,
    residual_report,
    stability_report,
    validate,
)

__all__ = [
    "INITIAL_RULES",
    "StabilityReport",
    "ValidationReport",
    "between_outputs",
    "joint_tests",
    "joint_verdict",
    "residual_report",
    "stability_report",
    "validate",
]
