"""Built-in grey-box models: the twin rotor's pitch and its coupled pitch and yaw.

Both are the plant's own equations (:func:`flexid.envs.twin_rotor_physics.derivatives`, the
one statement of the model) with its parameters named, bounded and either estimated or
fixed, read without the encoders (the model's outputs are the exact angles; the encoders'
quantisation is the measurement error the fit leaves).  With flexid's compiled kernels a
population runs in the plant's compiled RK4, each rotor with its own parameters, four per
SIMD vector; otherwise in :meth:`GreyBoxModel.simulate_reference
<flexid.models.greybox.GreyBoxModel.simulate_reference>`.

What a record can determine (and so what is fixed).  Pitch's equation
``I1 psi'' = a1 tau1 |tau1| + b1 tau1 - Mg sin(psi) - B1psi psi' - B2psi sgn(psi')`` holds
``I1`` only in the ratios ``Mg/I1``, ``B1psi/I1``, ``B2psi/I1``, ``a1/I1``, ``b1/I1``; the
rotor state ``tau1`` has no unit of its own (``tau1' = (k1 u1 - T10 tau1) / T11``: scaling
``tau1`` by ``s`` scales ``k1`` by ``s`` and ``a1``, ``b1`` by ``1/s^2``, ``1/s``), and its lag
shows only as ``T11/T10``.  So ``I1``, ``k1`` and ``T10`` are fixed at the manual's values
and the other pitch parameters are estimated relative to them; the same holds for ``I2``,
``k2`` and ``T20`` of yaw.  Freeing one of them makes the problem singular, which
:func:`flexid.fit.greybox_fit.greyest` reports.
"""

from __future__ import annotations

import hashlib
import inspect
from collections.abc import Callable
from dataclasses import fields
from importlib.metadata import entry_points
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np

from .. import kernels
from .._validate import checked_keywords
from ..data.plants import get_plant
from ..envs import twin_rotor_physics as trs
from ..envs import twin_rotor_steppers
from ..errors import ConfigError, FlexidError, UnknownKeywordError
from .greybox import GreyBoxModel, GreyParameter, ParameterSet

__all__ = [
    "ENTRY_POINT_GROUP",
    "GREYBOX_MODELS",
    "available_greybox_models",
    "definition_digest",
    "greybox_model",
    "register_greybox_model",
    "twin_rotor_coupled",
    "twin_rotor_pitch",
]

#: Multiply-adds of one RK4 substep of one rotor (four derivatives with a sine, a cosine
#: and a tanh each): what the thread count of a population's run is chosen by.
_RK4_STEP_WORK = 400

# (name, lower, upper, unit, fixed, description); nominal values are the plant's defaults
_PITCH = (
    ("I1", 1e-3, 1.0, "kg m^2", True, "moment of inertia about the pitch axis"),
    ("Mg", 1e-2, 3.0, "N m", False, "gravity moment at 90 degrees of pitch"),
    ("B1psi", 1e-5, 0.1, "N m s/rad", False, "viscous friction of pitch"),
    ("B2psi", 1e-6, 0.05, "N m", False, "Coulomb friction of pitch"),
    ("a1", 1e-4, 0.5, "N m/unit^2", False, "main rotor thrust, quadratic coefficient"),
    ("b1", 1e-3, 1.0, "N m/unit", False, "main rotor thrust, linear coefficient"),
    ("k1", 0.1, 10.0, "unit/V", True, "main motor gain (sets the unit of tau1)"),
    ("T11", 0.05, 10.0, "s", False, "main motor lag: time constant T11/T10"),
    ("T10", 0.1, 10.0, "-", True, "main motor lag denominator"),
    ("coulomb_velocity", 1e-3, 1.0, "rad/s", True, "smoothing of sgn(v) as tanh(v/this)"),
    ("u_max", 0.1, 10.0, "V", True, "motor voltage limit (inputs are clipped)"),
)
_YAW = (
    ("I2", 1e-3, 1.0, "kg m^2", True, "moment of inertia about the yaw axis"),
    ("a2", 1e-4, 0.5, "N m/unit^2", False, "tail rotor thrust, quadratic coefficient"),
    ("b2", 1e-3, 1.0, "N m/unit", False, "tail rotor thrust, linear coefficient"),
    ("B1phi", 1e-4, 1.0, "N m s/rad", False, "viscous friction of yaw"),
    ("B2phi", 1e-6, 0.1, "N m", False, "Coulomb friction of yaw"),
    ("Kgy", 0.0, 1.0, "s/rad", False, "gyroscopic coefficient"),
    ("k2", 0.1, 10.0, "unit/V", True, "tail motor gain (sets the unit of tau2)"),
    ("T21", 0.05, 10.0, "s", False, "tail motor lag: time constant T21/T20"),
    ("T20", 0.1, 10.0, "-", True, "tail motor lag denominator"),
    ("Tp", 0.05, 20.0, "s", False, "lag of the main rotor's reaction torque on yaw"),
    ("T0", 0.01, 20.0, "s", False, "lead of the main rotor's reaction torque on yaw"),
    ("kc", -2.0, 2.0, "N m/unit", False, "gain of the main rotor's reaction torque on yaw"),
)
_FIELDS = tuple(f.name for f in fields(trs.TwinRotorParameters))


def _twin_rotor(
    name: str, spec: tuple, inputs: tuple[str, ...], outputs: tuple[str, ...], lock_yaw: bool,
    thrust_law: str, overrides: dict[str, Any], description: str,
) -> GreyBoxModel:
    base = trs.TwinRotorParameters(lock_yaw=lock_yaw, thrust_law=thrust_law, encoder_counts=None)
    parameters = [
        GreyParameter(n, getattr(base, n), lo, hi, unit, fixed=fixed, description=text)
        for n, lo, hi, unit, fixed, text in spec
    ]
    names = [p.name for p in parameters]
    columns = [trs.STATE_NAMES.index(o) for o in outputs]
    voltages = [get_plant("twin-rotor").input_names.index(i) for i in inputs]
    i_umax = names.index("u_max")

    def voltages_of(u: np.ndarray, u_max: np.ndarray) -> np.ndarray:
        full = np.zeros((*u.shape[:-1], 2))
        full[..., voltages] = u
        return np.clip(full, -u_max[..., None], u_max[..., None])

    # the plant's parameters the model does not name, once (this runs at every RK4 stage)
    constants = {f: getattr(base, f) for f in _FIELDS if f not in names}

    def derivatives(x: np.ndarray, u: np.ndarray, p: ParameterSet) -> np.ndarray:
        values = SimpleNamespace(**constants, **{n: p[n] for n in names})
        return trs.derivatives(x, voltages_of(u, p["u_max"]), values)

    def output(x: np.ndarray, u: np.ndarray, p: ParameterSet) -> np.ndarray:
        return x[:, columns]

    base_vector = twin_rotor_steppers._kernel_params(base)
    kernel_names = twin_rotor_steppers.KERNEL_PARAMETERS
    kernel_columns = [kernel_names.index(n) for n in names if n in kernel_names]
    model_columns = [i for i, n in enumerate(names) if n in kernel_names]

    def compiled(
        theta: np.ndarray, u: np.ndarray, dt: float, n_sub: int, x0: np.ndarray
    ) -> np.ndarray:
        c = twin_rotor_steppers._compiled()
        n_pop, n = theta.shape[0], u.shape[0]
        params = np.repeat(base_vector[None, :], n_pop, axis=0)
        params[:, kernel_columns] = theta[:, model_columns]
        volts = np.ascontiguousarray(voltages_of(u[:, None, :], theta[None, :, i_umax]))
        x = np.array(x0, dtype=float, order="C")
        states = np.empty((n, n_pop, 7))
        c.twin_rotor_run(
            params, x, volts, states, n_sub, dt / n_sub, lock_yaw, thrust_law == "square",
            kernels._threads_for(n_pop * n * n_sub * _RK4_STEP_WORK),
        )
        y = np.empty((n_pop, n, len(columns)))
        y[:, 0] = x0[:, columns]
        y[:, 1:] = states[:-1, :, columns].transpose(1, 0, 2)
        return y

    model = GreyBoxModel(
        name, derivatives, output, states=trs.STATE_NAMES, inputs=inputs, outputs=outputs,
        parameters=parameters, substep=base.substep, compiled=compiled, description=description,
    )
    return model.with_parameters(**overrides) if overrides else model


def twin_rotor_pitch(*, thrust_law: str = "signed_square", **overrides: Any) -> GreyBoxModel:
    """The twin rotor's pitch with yaw locked (the rig's one-degree-of-freedom setting).

    Input ``main_rotor`` [V], output ``pitch`` [rad]; the plant's seven states (yaw and the
    tail rotor stay at rest).  Estimated: ``Mg``, ``B1psi``, ``B2psi``, ``a1``, ``b1``,
    ``T11``; fixed: ``I1``, ``k1``, ``T10`` (see the module notes), the Coulomb smoothing
    and the voltage limit.

    Parameters
    ----------
    thrust_law : {"signed_square", "square"}
        The plant's thrust law (:data:`flexid.envs.twin_rotor_physics.THRUST_LAWS`).
    **overrides
        Parameter changes, as :meth:`GreyBoxModel.with_parameters
        <flexid.models.greybox.GreyBoxModel.with_parameters>` takes them.

    Returns
    -------
    GreyBoxModel
    """
    return _twin_rotor(
        "twin-rotor-pitch", _PITCH, ("main_rotor",), ("pitch",), True, thrust_law, overrides,
        "Twin rotor, pitch with yaw locked: the Feedback 33-949S model's pitch equation, the "
        "main rotor's lag and thrust law. I1, k1 and T10 are fixed (the record holds pitch's "
        "parameters only relative to I1, the thrust relative to the unit k1 gives tau1, and "
        "the lag as T11/T10).",
    )


def twin_rotor_coupled(*, thrust_law: str = "signed_square", **overrides: Any) -> GreyBoxModel:
    """The twin rotor's coupled pitch and yaw (both axes free).

    Inputs ``main_rotor``, ``tail_rotor`` [V], outputs ``pitch``, ``yaw`` [rad]; the pitch
    parameters of :func:`twin_rotor_pitch` and those of yaw, the tail rotor, the
    gyroscopic coupling and the main rotor's reaction torque.  Fixed: ``I1``, ``I2``,
    ``k1``, ``k2``, ``T10``, ``T20`` (see the module notes).

    Parameters
    ----------
    thrust_law : {"signed_square", "square"}
    **overrides
        Parameter changes (see :func:`twin_rotor_pitch`).

    Returns
    -------
    GreyBoxModel
    """
    return _twin_rotor(
        "twin-rotor-coupled", _PITCH + _YAW, ("main_rotor", "tail_rotor"), ("pitch", "yaw"),
        False, thrust_law, overrides,
        "Twin rotor, pitch and yaw coupled: the Feedback 33-949S model. I1, I2, k1, k2, T10 "
        "and T20 are fixed (each axis's parameters are determined only relative to its "
        "inertia, each rotor's thrust relative to its gain, each lag as a ratio).",
    )


#: Built-in grey-box models by name (factories taking keyword options).
GREYBOX_MODELS = {"twin-rotor-pitch": twin_rotor_pitch, "twin-rotor-coupled": twin_rotor_coupled}

#: Entry-point group through which an installed package offers grey-box models: each entry
#: names a :class:`~flexid.models.greybox.GreyBoxModel` or a function returning one.
ENTRY_POINT_GROUP = "flexid.greybox_models"

_REGISTERED: dict[str, GreyBoxModel | Callable[..., GreyBoxModel]] = {}


@checked_keywords
def register_greybox_model(name: str, model: GreyBoxModel | Callable[..., GreyBoxModel]) -> None:
    """Register a grey-box model under a name, as an optimiser plugin registers itself.

    Registered models are found by :func:`greybox_model`, and so by ``identify``,
    ``compare`` and the command line (``--greybox NAME``), as the built-in ones are.

    Parameters
    ----------
    name : str
        The name (not a built-in's).
    model : GreyBoxModel or callable
        The model, or a function of keyword options returning one.

    Raises
    ------
    ConfigError
        An empty name, a built-in's name, or something that is neither.
    """
    if not isinstance(name, str) or not name.strip():
        raise ConfigError(f"a grey-box model's name must be a non-empty string, got {name!r}")
    if name in GREYBOX_MODELS:
        raise ConfigError(f"{name!r} is a built-in grey-box model's name")
    if not (isinstance(model, GreyBoxModel) or callable(model)):
        raise ConfigError(
            f"grey-box model {name!r}: give a GreyBoxModel or a function returning one, got "
            f"{type(model).__name__}"
        )
    _REGISTERED[name] = model


def _entry_points() -> dict[str, Any]:
    return {ep.name: ep for ep in entry_points(group=ENTRY_POINT_GROUP)}


def available_greybox_models() -> tuple[str, ...]:
    """Names :func:`greybox_model` knows: built-in, registered and installed (entry points).

    Returns
    -------
    tuple of str
    """
    names = list(GREYBOX_MODELS) + list(_REGISTERED)
    names += [n for n in sorted(_entry_points()) if n not in names]
    return tuple(names)


def _as_model(obj: Any, where: str, options: dict[str, Any]) -> GreyBoxModel:
    """``obj`` (a model or a factory) as a model, with ``options`` applied."""
    if isinstance(obj, GreyBoxModel):
        return obj.with_parameters(**options) if options else obj
    if callable(obj):
        try:
            made = obj(**options)
        except FlexidError:  # a parameter change the model refuses says so itself
            raise
        except (TypeError, ValueError) as exc:
            raise ConfigError(f"grey-box model {where}: its factory failed: {exc}") from None
        if isinstance(made, GreyBoxModel):
            return made
        obj = made
    raise ConfigError(
        f"grey-box model {where} is a {type(obj).__name__}, not a GreyBoxModel or a function "
        "returning one"
    )


def _from_file(reference: str) -> Any:
    """``path/to/file.py:NAME``: the object NAME of a Python file, run as a module."""
    import importlib.util
    import sys

    path_text, _, attr = reference.rpartition(":")
    path = Path(path_text).expanduser()
    if not path.is_file():
        raise ConfigError(f"grey-box model {reference!r}: no file {str(path)!r}")
    key = "_flexid_greybox_" + hashlib.sha256(str(path.resolve()).encode()).hexdigest()[:16]
    module = sys.modules.get(key)
    if module is None or getattr(module, "__file__", None) != str(path.resolve()):
        spec = importlib.util.spec_from_file_location(key, path.resolve())
        if spec is None or spec.loader is None:
            raise ConfigError(f"grey-box model {reference!r}: {str(path)!r} is not a Python file")
        module = importlib.util.module_from_spec(spec)
        sys.modules[key] = module  # pickling the model's functions finds them here
        try:
            spec.loader.exec_module(module)
        except Exception as exc:
            del sys.modules[key]
            raise ConfigError(
                f"grey-box model {reference!r}: running {str(path)!r} failed: "
                f"{type(exc).__name__}: {exc}"
            ) from None
    if not attr or not hasattr(module, attr):
        found = sorted(k for k, v in vars(module).items() if isinstance(v, GreyBoxModel))
        raise ConfigError(
            f"grey-box model {reference!r}: {str(path)!r} has no {attr or '(empty name)'!r}"
            + (f" (its models: {', '.join(found)})" if found else "")
        )
    return getattr(module, attr)


def _source(name: str) -> Any:
    """What a name stands for: a model or a factory (built-in, registered, file, installed)."""
    from ..errors import UnknownNameError

    if name in GREYBOX_MODELS:
        return GREYBOX_MODELS[name]
    if name in _REGISTERED:
        return _REGISTERED[name]
    if ":" in name and name.rpartition(":")[0].endswith(".py"):
        return _from_file(name)
    points = _entry_points()
    if name in points:
        try:
            return points[name].load()
        except Exception as exc:  # a broken package must say so, not crash flexid
            raise ConfigError(
                f"grey-box model {name!r} ({points[name].value}) failed to load: "
                f"{type(exc).__name__}: {exc}"
            ) from None
    raise UnknownNameError(
        "grey-box model", name, (*available_greybox_models(), "path/to/file.py:NAME")
    )


def greybox_model(name: str, **options: Any) -> GreyBoxModel:
    """A grey-box model by name: built-in, registered, installed, or ``file.py:NAME``.

    Parameters
    ----------
    name : str
        ``"twin-rotor-pitch"``, ``"twin-rotor-coupled"``, a name given to
        :func:`register_greybox_model` or offered by an installed package (entry-point group
        ``flexid.greybox_models``), or ``"path/to/file.py:NAME"``: the object ``NAME`` (a
        :class:`~flexid.models.greybox.GreyBoxModel` or a function returning one) of that Python
        file, as ``examples/greybox_mass_spring.py:MODEL``.
    **options
        Passed to the model's function (``thrust_law``, parameter changes); for a model
        object, parameter changes (:meth:`GreyBoxModel.with_parameters
        <flexid.models.greybox.GreyBoxModel.with_parameters>`).

    Returns
    -------
    GreyBoxModel

    Raises
    ------
    UnknownNameError
        No such model (the message lists them).
    ConfigError
        A file that does not exist, fails to run or lacks ``NAME``; an object that is not a
        model.
    """
    if not isinstance(name, str):
        raise ConfigError(f"a grey-box model is named by a string, got {type(name).__name__}")
    source, where = _source(name), repr(name)
    if options:  # what the options may name: the model's parameters, its factory's keywords
        takes = set(_as_model(source, where, {}).names)
        if callable(source) and not isinstance(source, GreyBoxModel):
            takes |= {
                p.name for p in inspect.signature(source).parameters.values()
                if p.kind in (p.KEYWORD_ONLY, p.POSITIONAL_OR_KEYWORD)
            }
        extra = sorted(set(options) - takes)
        if extra:
            raise UnknownKeywordError(
                f"greybox_model({name!r}) got unknown option(s) {', '.join(map(repr, extra))}; "
                f"it takes {', '.join(sorted(takes))}"
            )
    return _as_model(source, where, options)


def definition_digest(name: str) -> str:
    """What a grey-box model's name stands for, as a short hash for store keys.

    A model read from a file (``file.py:NAME``) is defined by that file's bytes, so runs on
    an edited file never join the runs on what it held before; a named model by its name
    (its parameters are in the comparison's specification already).

    Parameters
    ----------
    name : str

    Returns
    -------
    str
        ``""`` for a named model, else 16 hexadecimal digits of the file's SHA-256.
    """
    if ":" in name and name.rpartition(":")[0].endswith(".py"):
        path = Path(name.rpartition(":")[0]).expanduser()
        try:
            return hashlib.sha256(path.read_bytes()).hexdigest()[:16]
        except OSError:
            raise ConfigError(f"grey-box model {name!r}: cannot read {str(path)!r}") from None
    return ""
