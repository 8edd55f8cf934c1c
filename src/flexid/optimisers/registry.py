"""The optimiser registry: built-ins, configured variants and third-party plugins.

* ``@register`` puts an :class:`~flexid.optimisers.Optimiser` subclass under its
  ``name``; registering a taken name is a :class:`~flexid.errors.RegistryError`.
* :func:`register_variant` registers a configured variant (the same algorithm with other
  default hyper-parameters) under its own name, e.g. ``hbcsd-paper-trs``.
* Third-party packages expose optimisers through the entry-point group
  ``flexid.optimisers`` (``name = "package.module:Class"``).  They are loaded lazily, the
  first time the registry is listed or a name is not found among the built-ins.  A plugin
  that fails to import, or is not an Optimiser subclass, raises a :class:`PluginWarning`
  and is skipped: it never breaks flexid.
* An optimiser is *trusted* (:func:`is_trusted`) when it may run in the caller's process: the
  built-ins and the caller's own optimisers are; a plugin's are not unless registered with
  ``trusted=True``.  A serial comparison runs the others in a child process, so that one that
  ends its process (``os._exit``, a crash in compiled code) is a failed run, not the end.
"""

from __future__ import annotations

import copy
import importlib
import importlib.util
import warnings
from collections.abc import Callable
from importlib.metadata import entry_points
from typing import Any

from .._validate import checked_keywords
from ..errors import RegistryError, UnknownOptimiserError
from ._params import Optimiser, Param

__all__ = [
    "ENTRY_POINT_GROUP",
    "PluginWarning",
    "available",
    "create",
    "describe",
    "get",
    "is_trusted",
    "register",
    "register_prefix",
    "register_variant",
    "reload_plugins",
    "unregister",
]

ENTRY_POINT_GROUP = "flexid.optimisers"

# modules of flexid.optimisers that define built-in optimisers (imported on first use)
_BUILTIN_MODULES = (
    "sda",
    "bfa",
    "hbcsd",
    "pso",
    "de",
    "ga",
    "cmaes",
    "cmaes_restarts",
    "lshade",
    "hbcsd_scaled",
    "random_search",
    "scipy_methods",
    "external",
)

_REGISTRY: dict[str, type[Optimiser]] = {}
_SOURCES: dict[str, str] = {}
_TRUSTED: dict[str, bool] = {}
# names "prefix:rest" resolved on first use (the optimisers of another library, "ng:NGOpt")
_PREFIXES: dict[str, Callable[[str], type[Optimiser]]] = {}
_state = {"builtins": False, "plugins": False}
# the entry point being loaded: what a plugin module registers on import is the plugin's
_loading: dict[str, str | None] = {"entry_point": None}


class PluginWarning(UserWarning):
    """A third-party optimiser plugin could not be loaded and was skipped."""


@checked_keywords
def register(
    cls: type[Optimiser] | None = None,
    *,
    name: str | None = None,
    source: str | None = None,
    trusted: bool | None = None,
) -> type[Optimiser] | Callable[[type[Optimiser]], type[Optimiser]]:
    """Class decorator: register an optimiser under ``name`` (default ``cls.name``).

    Parameters
    ----------
    cls : type, optional
        The :class:`Optimiser` subclass; omitted when the decorator is called with keywords,
        ``@register(name=...)``.
    name : str, optional
        Registry name; default ``cls.name``.
    source : str, optional
        Where the optimiser comes from, for listings; default ``"flexid"``, or
        ``"plugin module:Class"`` for a plugin module that registers its optimisers as it is
        loaded through its entry point.
    trusted : bool, optional
        Whether a serial comparison may run the optimiser in the caller's process, where a
        run that ends its process (``os._exit``, a segfault of compiled code) ends the whole
        comparison.  An untrusted optimiser's runs are done in a child process: one that
        dies is a failed run with its reason, at the cost of starting the process.  Default:
        True, except for a plugin's optimisers (registered while its entry point of the
        ``flexid.optimisers`` group loads).  A plugin says ``trusted=True`` when it
        registers its optimisers itself; the child process finds an untrusted optimiser by
        its name, so one registered with ``trusted=False`` must be importable (a module, not
        a notebook cell).  Runs in worker processes (``workers > 1``) are safe either way.

    Returns
    -------
    type or callable
        ``cls`` itself, registered; or, without ``cls``, the decorator.

    Raises
    ------
    RegistryError
        If the name is empty, already taken, or the class is not an Optimiser subclass.
    """
    loading = _loading["entry_point"]
    if source is None:
        source = "flexid" if loading is None else f"plugin {loading}"
    if trusted is None:
        trusted = loading is None
    elif not isinstance(trusted, bool):
        raise RegistryError(f"trusted must be True or False, not {trusted!r}")

    def decorate(klass: type[Optimiser]) -> type[Optimiser]:
        if not (isinstance(klass, type) and issubclass(klass, Optimiser)):
            raise RegistryError(f"only Optimiser subclasses can be registered, not {klass!r}")
        key = name or klass.name
        if not key or not isinstance(key, str):
            raise RegistryError(f"{klass.__name__} has no name to register under")
        if key in _REGISTRY:
            raise RegistryError(
                f"an optimiser named {key!r} is already registered (from {_SOURCES[key]})"
            )
        if key != klass.name:
            klass = type(klass.__name__, (klass,), {"name": key, "__module__": klass.__module__})
        _REGISTRY[key] = klass
        _SOURCES[key] = source
        _TRUSTED[key] = trusted
        return klass

    return decorate(cls) if cls is not None else decorate


def register_variant(
    name: str, base: str | type[Optimiser], doc: str = "", **defaults: Any
) -> type[Optimiser]:
    """Register ``base`` with other default hyper-parameters under ``name``.

    Parameters
    ----------
    name : str
        The variant's registry name.
    base : str or Optimiser subclass
        The algorithm.
    doc : str
        One sentence saying where the settings come from, ending with a period (it is the
        summary line of the variant's docstring).
    **defaults
        New defaults, validated now against the base's hyper-parameters (an alias of a
        hyper-parameter stands for it).

    Returns
    -------
    type
        The variant class (a subclass of ``base``).
    """
    base_cls = get(base) if isinstance(base, str) else base
    spec = base_cls.hyperparameters()
    # aliases are accepted and replaced by the canonical names
    defaults = base_cls.canonical_params(defaults, owner=f"variant {name!r} of {base_cls.name!r}")
    for key, value in defaults.items():  # clear errors before the class is built
        spec[key].validate(value, owner=name)
    namespace: dict[str, Any] = {
        "name": name,
        "__module__": base_cls.__module__,
        "__doc__": (doc or f"{base_cls.name} with other defaults.")
        + "\n\n"
        + (base_cls.__doc__ or ""),
        "variant_of": base_cls.name,
        "variant_doc": doc,
    }
    for key, value in defaults.items():
        param = copy.copy(spec[key])
        param.default = value
        namespace[key] = param  # type() calls __set_name__, which validates the default
    variant = type(f"{base_cls.__name__}_{_identifier(name)}", (base_cls,), namespace)
    variant()  # the constructor runs check(): cross-parameter rules hold for the new defaults
    return register(variant, source=_SOURCES.get(base_cls.name, "flexid") + " (variant)",
                    trusted=_TRUSTED.get(base_cls.name, True))  # fmt: skip


def _identifier(name: str) -> str:
    return "".join(c if c.isalnum() else "_" for c in name)


def unregister(name: str) -> None:
    """Remove ``name`` from the registry (for tests and interactive work).

    Parameters
    ----------
    name : str
        Registered name; an unknown name is ignored.
    """
    _REGISTRY.pop(name, None)
    _SOURCES.pop(name, None)
    _TRUSTED.pop(name, None)


def _load_builtins() -> None:
    if _state["builtins"]:
        return
    _state["builtins"] = True
    for module in _BUILTIN_MODULES:
        qualified = f"{__package__}.{module}"
        if importlib.util.find_spec(qualified) is None:  # a misspelled name is an error
            raise RegistryError(
                f"built-in optimiser module {qualified!r} (registry._BUILTIN_MODULES) does "
                "not exist"
            )
        importlib.import_module(qualified)


def _load_plugins() -> None:
    if _state["plugins"]:
        return
    _state["plugins"] = True
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        if ep.name in _REGISTRY:
            if _SOURCES.get(ep.name, "").startswith("plugin") and _SOURCES[ep.name].endswith(
                ep.value
            ):
                continue
            warnings.warn(
                f"flexid: optimiser plugin {ep.name!r} ({ep.value}) clashes with an "
                "existing optimiser of that name; skipped",
                PluginWarning,
                stacklevel=3,
            )
            continue
        _loading["entry_point"] = ep.value
        try:
            obj = ep.load()
        except Exception as exc:  # a broken plugin must never break flexid
            warnings.warn(
                f"flexid: optimiser plugin {ep.name!r} ({ep.value}) failed to load: "
                f"{type(exc).__name__}: {exc}; skipped",
                PluginWarning,
                stacklevel=3,
            )
            continue
        finally:
            _loading["entry_point"] = None
        if not (isinstance(obj, type) and issubclass(obj, Optimiser)):
            warnings.warn(
                f"flexid: optimiser plugin {ep.name!r} ({ep.value}) is not an "
                "flexid.optimisers.Optimiser subclass; skipped",
                PluginWarning,
                stacklevel=3,
            )
            continue
        if ep.name in _REGISTRY:  # the plugin registered itself on import
            continue
        register(obj, name=ep.name, source=f"plugin {ep.value}", trusted=False)


def reload_plugins() -> None:
    """Look for entry-point plugins again (after installing a package at run time)."""
    importlib.invalidate_caches()
    _state["plugins"] = False
    _load_plugins()


def register_prefix(prefix: str, resolver: Callable[[str], type[Optimiser]]) -> None:
    """Resolve the unregistered names ``prefix:...`` with ``resolver(name)`` on first use.

    Parameters
    ----------
    prefix : str
        The part of the name before the first colon, e.g. ``"ng"`` for ``"ng:NGOpt"``.
    resolver : callable
        ``resolver(name)`` registers and returns the optimiser class of ``name``, or raises
        :class:`~flexid.errors.UnknownOptimiserError` (with suggestions).

    Raises
    ------
    RegistryError
        If the prefix is empty, contains a colon, or already has a resolver.
    """
    if not prefix or ":" in prefix or prefix in _PREFIXES:
        raise RegistryError(f"cannot register the name prefix {prefix!r} (empty, ':' or taken)")
    _PREFIXES[prefix] = resolver


def get(name: str) -> type[Optimiser]:
    """The optimiser class registered under ``name``.

    Parameters
    ----------
    name : str
        Registered optimiser name, or a name a plugin or prefix resolver knows.

    Returns
    -------
    type
        The :class:`Optimiser` subclass.

    Raises
    ------
    UnknownOptimiserError
        If neither a built-in, a plugin nor the resolver of the name's prefix knows the
        name; the message lists the names (or the resolver's suggestions).
    """
    _load_builtins()
    if name not in _REGISTRY:
        _load_plugins()
    if name not in _REGISTRY:
        prefix, colon, _ = name.partition(":")
        if colon and prefix in _PREFIXES:
            return _PREFIXES[prefix](name)
        raise UnknownOptimiserError(name, available())
    return _REGISTRY[name]


def is_trusted(name: str) -> bool:
    """Whether optimiser ``name`` runs in the caller's process in a serial comparison.

    Parameters
    ----------
    name : str
        Registered optimiser name, or a name a plugin or prefix resolver knows.

    Returns
    -------
    bool
        True for the built-ins, their variants and optimisers registered by the caller's own
        code; False for a plugin's optimisers not registered with ``trusted=True`` (see
        :func:`register`), whose runs a serial comparison does in a child process.

    Raises
    ------
    UnknownOptimiserError
        If the name is not known.
    """
    get(name)  # loads the built-ins and plugins, or resolves a prefixed name
    # a prefix resolver's class need not be registered under the name: the caller's own
    return _TRUSTED.get(name, True)


def create(name: str, **params: Any) -> Optimiser:
    """An instance of optimiser ``name`` with validated hyper-parameters ``params``.

    Parameters
    ----------
    name : str
        Registered optimiser name (see :func:`available`).
    **params
        Hyper-parameters, by name or alias (see :func:`describe`).

    Returns
    -------
    Optimiser
        The configured instance.
    """
    return get(name)(**params)


def available() -> list[str]:
    """Names of every registered optimiser, built-ins, variants and plugins, sorted.

    Returns
    -------
    list of str
        The registered names.
    """
    _load_builtins()
    _load_plugins()
    return sorted(_REGISTRY)


def describe(name: str) -> dict[str, Any]:
    """Name, source, reference, summary and hyper-parameters (type, default, range, doc).

    Parameters
    ----------
    name : str
        Registered optimiser name.

    Returns
    -------
    dict
        ``name``, ``source``, ``variant_of``, ``trusted`` (see :func:`is_trusted`),
        ``summary``, ``reference``, ``bounds`` (what it does at the bounds: ``kind`` in a few
        words, ``note`` in one sentence and ``stays_in_box``, True, False or None when not
        stated) and ``hyperparameters`` (name -> type, default, range and description).
    """
    cls = get(name)
    doc = (cls.__doc__ or "").strip().splitlines()
    params: dict[str, dict] = {k: p.describe() for k, p in cls.hyperparameters().items()}
    return {
        "name": name,
        "source": _SOURCES.get(name, "?"),
        "variant_of": getattr(cls, "variant_of", None),
        "trusted": is_trusted(name),
        "summary": doc[0] if doc else "",
        "reference": cls.reference,
        "bounds": {
            "kind": cls.bounds or "not stated",
            "note": cls.bounds_note,
            "stays_in_box": cls.stays_in_box,
        },
        "hyperparameters": params,
    }


# re-exported for plugin authors: ``from flexid.optimisers import Optimiser, Param, register``
__all__ += ["Optimiser", "Param"]
