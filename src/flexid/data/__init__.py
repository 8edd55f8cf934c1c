"""Records and where they come from: :class:`IOData`, file formats, excitation signals and
the seeded synthetic records of the plants.

The names of :mod:`flexid.data.records` are importable from here (``flexid.data.IOData``,
``flexid.data.load``); :mod:`flexid.data.signals` makes excitations and
:mod:`flexid.data.datasets` simulated records.
"""

from .records import (
    DETRENDS,
    ESTIMATION_SHARE,
    OFFSET_RATIO,
    IOData,
    detrend_kind,
    detrend_pair,
    is_records,
    joined,
    load,
    prepare_data,
    save,
    split_parts,
)

__all__ = [
    "DETRENDS",
    "ESTIMATION_SHARE",
    "OFFSET_RATIO",
    "IOData",
    "detrend_kind",
    "detrend_pair",
    "is_records",
    "joined",
    "load",
    "prepare_data",
    "save",
    "split_parts",
]
