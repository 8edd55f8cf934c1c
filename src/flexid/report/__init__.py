"""What a user reads of a comparison: the Markdown report and its figures
(:mod:`flexid.report.writer`, importable from here), the figures of every result
(:mod:`flexid.report.plots`) and the IOHanalyzer export.
"""

from . import writer as _writer
from .writer import *  # noqa: F403  (its __all__ is the contract)

__all__ = list(_writer.__all__)
