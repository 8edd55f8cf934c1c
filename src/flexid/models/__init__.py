"""The model structures: what a record is identified as.

:mod:`flexid.models.arx`
    ARX (MATLAB's ``na, nb, nk``): regressors, least squares, simulation (the paper's
    structure).
:mod:`flexid.models.polynomial`
    The polynomial family ``A y = B/F u + C/D e`` (ARX, ARMAX, OE, BJ and the general
    form): orders, predictors, the initial-condition rules, exports.
:mod:`flexid.models.greybox`
    Grey-box models: a plant's equations with named, bounded physical parameters.
:mod:`flexid.models.greybox_library`
    The named grey-box models: built in (the twin rotor's), registered, in a file or in an
    installed package.
:mod:`flexid.models.statespace`
    Discrete-time state-space models with several inputs and outputs (``A, B, C, D, K,
    x0``): simulation, the one-step predictor, frequency responses, exports, modes; the
    modal structure the searches fit (``structure="ss"``).
:mod:`flexid.models.modes`
    The modes of any model's poles: natural frequency (Hz) and damping ratio.

Their batched costs are in :mod:`flexid.costs`; the front door :mod:`flexid` exports the
classes.
"""

from __future__ import annotations

from .._lazy import lazy_exports

# public name -> submodule that defines it (imported on first use, so importing one
# submodule does not import the others)
_LAZY = {
    "ARX": "arx",
    "ARXStructure": "arx",
    "PolynomialStructure": "polynomial",
    "PolynomialModel": "polynomial",
    "structure": "polynomial",
    "GreyBoxModel": "greybox",
    "GreyParameter": "greybox",
    "greybox_model": "greybox_library",
    "register_greybox_model": "greybox_library",
    "StateSpaceModel": "statespace",
    "StateSpaceStructure": "statespace",
    "Mode": "modes",
}

__all__ = sorted(_LAZY)

__getattr__, __dir__ = lazy_exports(__name__, _LAZY)
