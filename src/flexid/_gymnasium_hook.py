"""Register flexid's Gymnasium environments once Gymnasium is imported, without importing it.

Gymnasium 1.x has no plugin entry points (0.x read the ``gymnasium.envs`` group at import;
1.0 removed it), so a package registers its environments when the package itself is
imported.  ``import flexid`` should not pay for Gymnasium (and NumPy through it) when no
environment is used, so :func:`install` does this instead:

* Gymnasium already imported: import :mod:`flexid.envs` now (it registers the environments);
* otherwise: put a finder on :data:`sys.meta_path` that, when ``gymnasium`` is imported,
  lets the normal finders locate it and imports :mod:`flexid.envs` right after Gymnasium's
  own module has run.  The finder removes itself then, and restores Gymnasium's loader.

Either way ``import flexid; import gymnasium; gymnasium.make("flexid/...")`` works, as does
``gymnasium.make("flexid.envs:flexid/...")`` without importing flexid at all (Gymnasium
imports the module named before the colon).
"""

from __future__ import annotations

import importlib
import sys
import warnings
from importlib.machinery import ModuleSpec
from types import ModuleType
from typing import Any

__all__ = ["install"]

_GYMNASIUM = "gymnasium"
_ENVS = "flexid.envs"


class _RegisteringLoader:
    """Gymnasium's own loader, then the import of :mod:`flexid.envs`."""

    def __init__(self, loader: Any, finder: _GymnasiumFinder) -> None:
        self._loader = loader
        self._finder = finder

    def create_module(self, spec: ModuleSpec) -> ModuleType | None:
        return self._loader.create_module(spec)

    def exec_module(self, module: ModuleType) -> None:
        self._loader.exec_module(module)  # on an error the finder stays, for a retry
        module.__loader__ = self._loader
        if module.__spec__ is not None:
            module.__spec__.loader = self._loader
        self._finder.remove()
        try:
            importlib.import_module(_ENVS)
        except Exception as exc:  # a flexid bug must not break `import gymnasium`
            warnings.warn(
                f"flexid could not register its Gymnasium environments: {exc!r}",
                RuntimeWarning,
                stacklevel=2,
            )

    def __getattr__(self, name: str) -> Any:
        return getattr(self._loader, name)


class _GymnasiumFinder:
    """Finds ``gymnasium`` with the finders after it and wraps the loader."""

    def find_spec(
        self, fullname: str, path: Any = None, target: ModuleType | None = None
    ) -> ModuleSpec | None:
        if fullname != _GYMNASIUM:
            return None
        for finder in list(sys.meta_path):
            if isinstance(finder, _GymnasiumFinder):
                continue
            find = getattr(finder, "find_spec", None)
            spec = None if find is None else find(fullname, path, target)
            if spec is not None:
                break
        else:
            return None
        if spec.loader is None or not hasattr(spec.loader, "exec_module"):
            return spec
        spec.loader = _RegisteringLoader(spec.loader, self)
        return spec

    def remove(self) -> None:
        if self in sys.meta_path:
            sys.meta_path.remove(self)


def install() -> None:
    """Register the environments now if Gymnasium is loaded, else when it is (idempotent)."""
    if _GYMNASIUM in sys.modules:
        importlib.import_module(_ENVS)
    elif not any(isinstance(f, _GymnasiumFinder) for f in sys.meta_path):
        sys.meta_path.insert(0, _GymnasiumFinder())
