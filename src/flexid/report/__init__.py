"""What a user reads of a comparison: the Markdown report and its figures
(:mod:`flexid.report.writer`, importable from here), the figures of every result
(:mod:`flexid.report.plots`) and the IOHanalyzer export.
"""

from .writer import (
    IOH_LAYOUTS,
    comparison_ecdf,
    ecdf_fraction,
    ecdf_targets,
    export_ioh,
    figure_prefix,
    write_report,
)

__all__ = [
    "IOH_LAYOUTS",
    "comparison_ecdf",
    "ecdf_fraction",
    "ecdf_targets",
    "export_ioh",
    "figure_prefix",
    "write_report",
]
