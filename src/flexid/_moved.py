"""The import paths the public modules had before the package was arranged in its layer
folders: ``import flexid.selection`` is the module :mod:`flexid.jobs.selection` itself (one
module object under two names, so a patch through either name is seen through both).

The front door installs :data:`FINDER` on :data:`sys.meta_path`; nothing else imports this.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import importlib.util
import types
from collections.abc import Sequence

__all__: list[str] = []

#: Old name under ``flexid.`` -> the module's home under ``flexid.``.  ``flexid.data``,
#: ``flexid.validation`` and ``flexid.report`` are packages that keep their names.
MOVED = {
    "datasets": "data.datasets",
    "signals": "data.signals",
    "plants": "data.plants",
    "stability": "models.stability",
    "families": "models.families",
    "metrics": "costs.metrics",
    "diagnostics": "validation.diagnostics",
    "portmanteau": "validation.portmanteau",
    "frequency": "validation.frequency",
    "delay": "fit.delay",
    "estimation": "fit.estimation",
    "greybox_estimation": "fit.greybox_estimation",
    "greybox_family": "fit.greybox_family",
    "greybox_fit": "fit.greybox_fit",
    "output_error": "fit.output_error",
    "parametrisation": "fit.parametrisation",
    "polynomial_family": "fit.polynomial_family",
    "polynomial_space": "fit.polynomial_space",
    "prediction_error": "fit.prediction_error",
    "reference": "fit.reference",
    "statespace_family": "fit.statespace_family",
    "statespace_fit": "fit.statespace_fit",
    "subspace": "fit.subspace",
    "progress": "jobs.progress",
    "selection": "jobs.selection",
    "statistics": "jobs.statistics",
    "store": "jobs.store",
    "suite": "jobs.suite",
    "plots": "report.plots",
}


class _MovedFinder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Finds ``flexid.<old>`` and loads it as the module at its home."""

    def __init__(self) -> None:
        self._homes: dict[str, importlib.machinery.ModuleSpec | None] = {}

    def find_spec(
        self,
        fullname: str,
        path: Sequence[str] | None = None,
        target: types.ModuleType | None = None,
    ) -> importlib.machinery.ModuleSpec | None:
        package, _, name = fullname.partition(".")
        if package != "flexid" or name not in MOVED:
            return None
        return importlib.util.spec_from_loader(fullname, self)

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> types.ModuleType:
        """The home module itself (imported now if it is not yet)."""
        module = importlib.import_module(f"flexid.{MOVED[spec.name.partition('.')[2]]}")
        self._homes[module.__name__] = module.__spec__
        return module

    def exec_module(self, module: types.ModuleType) -> None:
        """Nothing runs again; the module's own spec is given back.

        The import system sets ``__spec__`` to the old name's spec whatever the loader
        returns; ``reload``, ``pickle`` and ``inspect`` read the home's.
        """
        module.__spec__ = self._homes[module.__name__]


FINDER = _MovedFinder()
