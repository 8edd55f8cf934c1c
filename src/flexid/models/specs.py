"""What an identification problem is made of: the record (:class:`DataSpec`), the
structure (:class:`ModelSpec`), the cost (:class:`CostSpec`) and the search
(:class:`SearchSpec`), each a frozen dataclass checked on construction.

:mod:`flexid.config` shows them to users.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from typing import Any

from ..errors import ConfigError
from .vocabulary import (
    GREYBOX,
    POLE_RADIUS_CAP,
    REFLECTION_CAP,
    STRUCTURE_NAMES,
    structure_names,
)

__all__ = [
    "PAPER_SEARCH",
    "CostSpec",
    "DataSpec",
    "ModelSpec",
    "SearchSpec",
]


@dataclass(frozen=True)
class DataSpec:
    """Where the record comes from, and how it is split.

    Either ``plant`` (simulate; ``preset``, ``signal``, ``n_samples``, ``seed``,
    ``noise_std``, ``signal_options``, ``plant_params``, ``sensors`` as in
    :func:`flexid.data.datasets.generate`) or ``file`` (a CSV/NPZ/DAT record; ``inputs``,
    ``outputs``, ``dt`` as in :func:`flexid.data.load`).  ``output`` picks the modelled
    output channel; ``split`` is the estimation share (or a sample index); ``detrend``
    removes the estimation means.

    Attributes
    ----------
    plant : str or None
        A registered plant to simulate (``"manipulator"`` or ``"twin-rotor"``).
    preset : str or None
        A dataset preset (``"paper-manipulator"``, ``"paper-twin-rotor"``); the other
        fields override it.
    signal : str or None
        Excitation signal name (default: the preset's, else ``"uniform"``).
    n_samples : int or None
        Record length in samples (default: the preset's or the plant's).
    seed : int
        Seed of the simulated record (signal and noise), default 0.
    noise_std : float, list of float, str or None
        Measurement noise: one standard deviation for all outputs, one per output (output
        units), or ``"p%"`` of each noise-free output's standard deviation.
    signal_options : dict
        Options of the signal (``{"low": -0.3, "high": 0.3}``, ...).
    plant_params : dict
        Physical parameter overrides of the plant.
    sensors : {"lab", "ideal"}
        The plant read through its measurement chain (``"lab"``, default) or exactly.
    file : str, list of str, or None
        A recorded CSV/NPZ/DAT file to read instead of simulating; a list: several
        estimation records of one system, fitted together, each with its own initial state
        (they need ``validation``).
    validation : str or None
        A recorded file to validate on (read with the same ``inputs``, ``outputs`` and
        ``dt``); ``file`` is then all estimation (or the range ``split``).
    inputs : list of str or None
        Input columns of ``file``.
    outputs : list of str or None
        Output columns of ``file``, or the outputs a simulated plant records.
    dt : float or None
        Sample time of ``file`` in seconds, when the file does not give it.
    output : str, int or None
        The output channel modelled when the record has several.
    split : float, int, str, list or None
        Estimation share in (0, 1) (default 2/3), above 1 the first validation sample, or
        the two parts as sample ranges, ``[[0, 1000], [1000, 1473]]`` or
        ``"0:1000,1000:"`` (:func:`flexid.data.split_parts`).
    detrend : bool or str
        ``"constant"`` (or true): remove the estimation record's means from both records;
        ``"linear"``: its least-squares line (see :func:`flexid.data.prepare_data`); default
        False.
    digest : str or None
        SHA-256 of the record read from ``file`` (its samples, sample time and channel
        names), set by :func:`flexid.compare` when it reads the file, not in configuration
        files.  It is part of the store key, so a comparison on an edited file is a new
        comparison.  None for a simulated record (its settings determine it).

    Raises
    ------
    ConfigError
        Unless exactly one of ``plant`` and ``file`` is given.
    """

    plant: str | None = None
    preset: str | None = None
    signal: str | None = None
    n_samples: int | None = None
    seed: int = 0
    noise_std: Any = None
    signal_options: dict = field(default_factory=dict)
    plant_params: dict = field(default_factory=dict)
    sensors: str = "lab"
    file: str | list | None = None
    validation: str | None = None
    inputs: Any = None
    outputs: Any = None
    dt: float | None = None
    output: str | int | None = None
    split: float | int | str | list | None = None
    detrend: bool | str = False
    digest: str | None = None

    def __post_init__(self) -> None:
        if (self.plant is None) == (self.file is None):
            raise ConfigError("[data] needs exactly one of 'plant' (simulate) or 'file' (a record)")
        files = self.file if isinstance(self.file, list) else [self.file]
        if self.file is not None and not (files and all(isinstance(f, str) for f in files)):
            raise ConfigError(f"[data] file must be a path or a list of paths, got {self.file!r}")
        if self.validation is not None and (
            self.file is None or not isinstance(self.validation, str)
        ):
            raise ConfigError("[data] validation is the path of a recorded file beside 'file'")
        if len(files) > 1 and self.validation is None:
            raise ConfigError(
                f"[data] file lists {len(files)} estimation records: give the validation "
                "record ('validation = \"PATH\"'); none is split off"
            )
        numeric = isinstance(self.detrend, (int, float)) and not isinstance(self.detrend, bool)
        if numeric or self.detrend not in (False, True, "constant", "linear"):
            raise ConfigError(
                f"[data] detrend must be false, true, 'constant' or 'linear', got "
                f"{self.detrend!r}"
            )

    def describe(self) -> str:
        """One line saying where the record comes from.

        Returns
        -------
        str
            ``"file PATH"``, or ``"PLANT / PRESET-OR-SIGNAL[ / SENSORS sensors] (seed S)"``.
        """
        if self.file is not None:
            files = self.file if isinstance(self.file, list) else [self.file]
            text = f"file{'s' if len(files) > 1 else ''} {', '.join(files)}"
            return text + (f" (validation {self.validation})" if self.validation else "")
        parts = [self.plant, self.preset or self.signal or "default signal"]
        if self.sensors != "lab":
            parts.append(f"{self.sensors} sensors")
        return " / ".join(p for p in parts if p) + f" (seed {self.seed})"


@dataclass(frozen=True)
class ModelSpec:
    """The model structure and its orders, in MATLAB's convention.

    Attributes
    ----------
    na : int or None
        Number of ``A`` coefficients (poles); ARX's default is 8, the other structures have
        none unless they take it (``armax``).
    nb : int, list of int or None
        Number of ``B`` coefficients, for every input or one per input; for ARX None
        (default) means ``na``.
    nk : int or list of int
        Input delay in samples, for every input or one per input (default 1).
    structure : {"arx", "armax", "oe", "bj"}
        The structure (default ``"arx"``, the paper's); its orders are those of
        :data:`flexid.models.polynomial.STRUCTURES`.
    nc, nd : int or None
        Orders of ``C`` and ``D`` (``armax``, ``bj``).
    nf : int, list of int or None
        Order of ``F``, for every input or one per input (``oe``, ``bj``).
    greybox : str or None
        With ``structure = "greybox"``: the grey-box model's name
        (:func:`flexid.models.greybox_library.greybox_model`: a built-in, registered or installed
        model, or ``"path/to/file.py:NAME"``, relative to the configuration file).
    parameters : dict
        With ``structure = "greybox"``: parameter changes, ``name -> value`` (a new value)
        or ``name -> {"value": ..., "fixed": ..., "lower": ..., "upper": ...}``.
    options : dict
        With the structure of a registered family (:func:`flexid.models.families.register_family`):
        its orders by name, as its ``structure`` method takes them (``{"n": 6, "pole":
        0.8}``); ``nk`` is passed on when it is not 1.
    """

    na: int | None = None
    nb: Any = None
    nk: Any = 1
    structure: str = "arx"
    nc: int | None = None
    nd: int | None = None
    nf: Any = None
    greybox: str | None = None
    parameters: dict = field(default_factory=dict)
    options: dict = field(default_factory=dict)

    @property
    def registered(self) -> bool:
        """Whether the structure is a registered family's, not a built-in one (polynomial or
        grey-box): its orders are in :attr:`options`."""
        return self.structure not in (*STRUCTURE_NAMES, GREYBOX)

    def __post_init__(self) -> None:
        known = structure_names()
        if self.structure not in known:
            from ..errors import UnknownNameError

            raise UnknownNameError("[model] structure", str(self.structure), known)
        if not isinstance(self.options, Mapping):
            raise ConfigError("[model] options must be a table: name = value")
        object.__setattr__(self, "options", dict(self.options))
        if self.registered:
            self._check_registered()
            return
        if self.options:
            raise ConfigError(
                f"[model] options belong to a registered family's structure, not "
                f"{self.structure!r}: give its orders as na, nb, nc, nd, nf, nk"
            )
        if self.structure == GREYBOX:
            self._check_greybox()
            return
        if self.greybox is not None or self.parameters:
            raise ConfigError(
                "[model] greybox and parameters belong to structure = 'greybox', not "
                f"{self.structure!r}"
            )
        if self.structure == "arx" and self.na is None:
            object.__setattr__(self, "na", 8)  # the paper's order

    def _check_registered(self) -> None:
        """A registered family's structure takes its orders in options only."""
        given = [k for k in ("na", "nb", "nc", "nd", "nf", "greybox") if getattr(self, k)]
        if given or self.parameters:
            raise ConfigError(
                f"[model] structure {self.structure!r} takes its orders in options = "
                f"{{...}}, not {', '.join(given or ['parameters'])}"
            )

    def _check_greybox(self) -> None:
        """A grey-box structure names its model, has no orders and a table of parameter
        changes (stored as a dict)."""
        if not isinstance(self.greybox, str) or not self.greybox:
            raise ConfigError(
                "[model] structure 'greybox' needs greybox = the model's name (e.g. "
                "'twin-rotor-pitch', or 'path/to/file.py:NAME')"
            )
        orders = [k for k in ("na", "nb", "nc", "nd", "nf") if getattr(self, k) is not None]
        if orders or self.nk != 1:
            raise ConfigError(
                f"[model] a grey-box model has no orders; remove {', '.join(orders or ['nk'])}"
            )
        if not isinstance(self.parameters, Mapping):
            raise ConfigError("[model] parameters must be a table: name = value or {...}")
        object.__setattr__(self, "parameters", dict(self.parameters))

    def greybox_model(self) -> Any:
        """The grey-box model this spec names, with its parameter changes.

        Returns
        -------
        GreyBoxModel

        Raises
        ------
        ConfigError, UnknownNameError
            Not a grey-box spec, an unknown model, a bad parameter change.
        """
        if self.structure != GREYBOX:
            raise ConfigError(f"[model] structure {self.structure!r} is not a grey-box model")
        from .greybox_library import greybox_model

        model = greybox_model(self.greybox)
        return model.with_parameters(**self.parameters) if self.parameters else model

    def orders(self) -> dict[str, Any]:
        """The orders given, by name (None left out).

        Returns
        -------
        dict
        """
        if self.registered:
            return {**self.options, **({"nk": self.nk} if self.nk != 1 else {})}
        names = ("na", "nb", "nc", "nd", "nf", "nk")
        return {k: getattr(self, k) for k in names if getattr(self, k) is not None}

    def key_material(self) -> dict[str, Any]:
        """The fields that determine a comparison's numbers; an ARX spec's as before the
        structures existed (so its store key is unchanged).

        Returns
        -------
        dict
        """
        d = asdict(self)
        if self.structure == "arx":
            return {k: d[k] for k in ("na", "nb", "nk")}
        if self.structure == GREYBOX:
            from .greybox_library import definition_digest

            model = self.greybox_model()
            return {
                "structure": GREYBOX,
                "greybox": self.greybox,
                "definition": definition_digest(self.greybox),
                "model": model.to_dict(),
            }
        if self.registered:
            return {"structure": self.structure, **self.orders()}
        for k in ("greybox", "parameters", "options"):  # keys of polynomial specs as before
            del d[k]
        return d

    def describe(self) -> str:
        """The structure and orders in MATLAB's words, e.g. ``"OE(nb=16, nf=16, nk=1)"``.

        Returns
        -------
        str
        """
        if self.structure == "arx":
            nb = self.nb if self.nb is not None else self.na
            return f"ARX(na={self.na}, nb={nb}, nk={self.nk})"
        if self.structure == GREYBOX:
            changed = f", {len(self.parameters)} parameter(s) changed" if self.parameters else ""
            return f"grey-box model {self.greybox}{changed}"
        text = ", ".join(f"{k}={v}" for k, v in self.orders().items())
        if self.registered:  # its name as written
            return f"{self.structure}({text})"
        return f"{self.structure.upper()}({text})"


@dataclass(frozen=True)
class CostSpec:
    """The cost the optimisers minimise (see :class:`flexid.costs.arx.ARXCost`).

    Attributes
    ----------
    metric : str
        Error measure, a name of :data:`flexid.costs.metrics.METRIC_TABLE`; ``"paper"`` (default)
        is ``weight * sqrt(SSE) / K``.
    predictor : {"one-step", "simulation"}
        Equation error (default) or output error.
    weight : float
        ``w`` of the paper's cost (default 1e3).
    penalty : float
        Cost added to an unstable candidate (default 1e9); its kind (flat or graded) is
        :attr:`SearchSpec.penalty`.
    initial : {"auto", "estimate", "zero", "measured"}
        Initial-condition rule of the predictor (default ``"auto"``: ``"measured"`` for ARX,
        the paper's setting, and ``"estimate"`` for the other structures; see
        :func:`flexid.fit.estimation.resolve_initial`).
    """

    metric: str = "paper"
    predictor: str = "one-step"
    weight: float = 1e3
    penalty: float = 1e9
    initial: str = "auto"


@dataclass(frozen=True)
class SearchSpec:
    """How the search space is posed (see :func:`flexid.fit.estimation.build_problem`).

    Attributes
    ----------
    parametrisation : {"poles", "reflection", "coefficients"}
        ``"coefficients"`` is the paper's ``a, b`` box; ``"poles"`` (default) searches pole
        pairs (radius, angle) and ``"reflection"`` lattice coefficients, both stable by
        construction.
    penalty : {"graded", "flat"}
        Stability penalty of an unstable candidate (only the coefficient space has any):
        ``"flat"`` is the paper's constant, ``"graded"`` grows with the largest pole radius.
    init : {"stable", "uniform"}
        Initial population of the coefficient space: stable denominators (drawn in the pole
        space) or uniform in the box (the paper's).  The other spaces are uniform in their
        own box, all stable.
    r_max : float
        Largest pole radius of the ``"poles"`` space and of stable initial populations.
    real_pairs : int
        Pole pairs searched as two real poles instead of a complex pair.
    k_max : float
        Bound of the reflection coefficients.
    numerator : {"fit", "search"}
        ``"search"``: the optimiser searches the ``b`` coefficients too (the paper's).
        ``"fit"`` (default): it searches the denominator only, and each candidate's ``b``
        is the exact least-squares optimum of the cost for its ``A`` (variable projection;
        both predictors are linear in ``b``).
    """

    parametrisation: str = "poles"
    penalty: str = "graded"
    init: str = "stable"
    r_max: float = POLE_RADIUS_CAP
    real_pairs: int = 0
    k_max: float = REFLECTION_CAP
    numerator: str = "fit"


PAPER_SEARCH = SearchSpec(
    parametrisation="coefficients", penalty="flat", init="uniform", numerator="search"
)
