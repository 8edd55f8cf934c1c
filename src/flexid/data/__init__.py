"""Records and where they come from: :class:`IOData`, file formats, excitation signals and
the seeded synthetic records of the plants.

The names of :mod:`flexid.data.records` are importable from here (``flexid.data.IOData``,
``flexid.data.load``); :mod:`flexid.data.signals` makes excitations and
:mod:`flexid.data.datasets` simulated records.
"""

from . import records as _records
from .records import *  # noqa: F403  (its __all__ is the contract)

__all__ = list(_records.__all__)
