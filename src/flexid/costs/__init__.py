"""The batched costs of the model structures: a population ``(P, n)`` in, ``(P,)`` out.

:mod:`flexid.costs.arx`
    :class:`~flexid.costs.arx.ARXCost`: ARX's one-step and simulation costs, penalties,
    the least-squares reference, and the pieces every cost shares (``population``, the
    predictor and penalty names).
:mod:`flexid.costs.polynomial`
    :class:`~flexid.costs.polynomial.PolynomialCost`: the prediction-error and simulation
    costs of the polynomial family, with variable projection of ``B``.
:mod:`flexid.costs.experiments`
    :class:`~flexid.costs.experiments.MultiExperimentCost`: the polynomial costs over several
    records at once, each with its own initial state.
:mod:`flexid.costs.greybox`
    :class:`~flexid.costs.greybox.GreyBoxCost`: a grey-box model's simulation cost.
:mod:`flexid.costs.modal`
    :class:`~flexid.costs.modal.ModalCost`: the modal state-space structure's simulation
    cost over every output, gains and initial state fitted for each candidate.

The metrics a cost reports are :mod:`flexid.costs.metrics`.
"""

from __future__ import annotations

from .._lazy import lazy_exports

# public name -> submodule that defines it (imported on first use, so importing one
# submodule does not import the others)
_LAZY = {
    "ARXCost": "arx",
    "PolynomialCost": "polynomial",
    "GreyBoxCost": "greybox",
    "MultiExperimentCost": "experiments",
    "ModalCost": "modal",
}

__all__ = sorted(_LAZY)

__getattr__, __dir__ = lazy_exports(__name__, _LAZY)
