"""Plain JSON types for results, record metadata and the command line's ``--json`` output.

Every ``to_dict`` of a result and every JSON header flexid writes goes through
:func:`jsonable`, so non-finite numbers follow one rule everywhere: NaN, ``inf`` and
``-inf`` become ``None`` (JSON ``null``).  Strict JSON (RFC 8259) has no such numbers and
``json.dumps(..., allow_nan=False)`` rejects them; a result whose non-finite values carry
meaning says so in a field of its own (e.g. ``simulation_diverged``).

The result store keeps run records with Python's ``NaN``/``Infinity`` tokens instead, so that
a stored history reads back exactly; it is private to flexid and does not use this module.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import PurePath
from typing import Any

import numpy as np

__all__ = ["jsonable"]


def jsonable(value: Any) -> Any:
    """Convert ``value`` into plain JSON types, with ``None`` for non-finite floats.

    Parameters
    ----------
    value : object
        A scalar, NumPy scalar or array, path, or mappings and sequences of these, nested
        to any depth.

    Returns
    -------
    object
        The same data as ``dict`` (keys converted with ``str``), ``list`` (from tuples,
        lists and arrays), ``int``, ``float``, ``bool``, ``str`` and ``None``.  NaN,
        ``inf`` and ``-inf``, Python or NumPy, become ``None``; paths become strings.
        Other objects are returned unchanged.

    Examples
    --------
    >>> import numpy as np
    >>> jsonable({"cost": np.float64("inf"), "fit": [98.5, float("nan")], 3: (1, 2)})
    {'cost': None, 'fit': [98.5, None], '3': [1, 2]}
    """
    if isinstance(value, Mapping):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        if value.dtype.kind == "f":
            # one vectorised pass instead of a Python call per element of long signals
            out = value.astype(object)
            out[~np.isfinite(value)] = None
            return out.tolist()
        return jsonable(value.tolist())
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, PurePath):
        return str(value)
    return value
