"""Grey-box models: a plant's equations with named physical parameters (MATLAB ``idnlgrey``).

A :class:`GreyBoxModel` is ``dx/dt = f(x, u, p)``, ``y = h(x, u, p)`` with named states,
inputs, outputs and parameters (:class:`GreyParameter`: a nominal value, bounds, a unit,
fixed or estimated, searched on a log scale where it spans decades).  It simulates a whole
*population* of parameter sets at once: ``f`` and ``h`` take ``x`` of shape ``(P, n_x)``,
``u`` of shape ``(P, n_u)`` and ``p``, a :class:`ParameterSet` whose entries are ``(P,)``
arrays (``p.Mg`` or ``p["Mg"]``), and return ``(P, n_x)`` and ``(P, n_y)``, so one RK4
step advances every candidate.

Sampling convention (that of flexid's plants): the input ``u[k]`` is held over
``[k dt, (k + 1) dt)``, integrated by fixed-step RK4 with ``n_sub`` substeps, and the output
``y[k] = h(x(k dt), u[k], p)`` is read at ``t = k dt`` before ``u[k]`` acts; ``x(0) = x0``
(rest by default).

Writing your own model::

    def f(x, u, p):                      # x (P, 2), u (P, 1), p.m etc. (P,)
        pos, vel = x.T
        force = u[:, 0] - p.k * pos - p.c * vel - p.fc * np.tanh(vel / 1e-3)
        return np.column_stack([vel, force / p.m])

    model = GreyBoxModel(
        "mass-spring", f, lambda x, u, p: x[:, :1],
        states=("position", "velocity"), inputs=("force",), outputs=("position",),
        parameters=(GreyParameter("m", 1.0, 0.1, 10, "kg", fixed=True),
                    GreyParameter("k", 40.0, 1, 1000, "N/m"), ...),
    )

A built-in model may also carry a compiled simulator (``compiled``) with the same
semantics; :meth:`GreyBoxModel.simulate` uses it when flexid's compiled kernels run
(:mod:`flexid.kernels`), and :meth:`GreyBoxModel.simulate_reference` is the NumPy route the
tests hold it to.  The twin rotor's models are in :mod:`flexid.models.greybox_library`; the cost an
optimiser minimises is :class:`flexid.costs.greybox.GreyBoxCost`, the gradient reference
:func:`flexid.fit.greybox_fit.greyest`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..errors import ConfigError, DataError, UnknownNameError

__all__ = ["SCALES", "GreyBoxModel", "GreyParameter", "ParameterSet"]

#: Search scales of a parameter: ``"auto"`` is ``"log"`` when ``0 < lower`` and
#: ``upper >= LOG_SPAN * lower``, else ``"linear"``.
SCALES = ("auto", "linear", "log")
LOG_SPAN = 100.0  # two decades: below that a linear search resolves the range as well

# Largest (samples x rows x states) array of one chunk of a population's simulation
# (2**22 doubles, 32 MB): a population larger than that is simulated in chunks.
_CHUNK = 1 << 22

Derivatives = Callable[[np.ndarray, np.ndarray, "ParameterSet"], np.ndarray]
Compiled = Callable[[np.ndarray, np.ndarray, float, int, np.ndarray], np.ndarray]


@dataclass(frozen=True)
class GreyParameter:
    """One physical parameter of a grey-box model.

    Parameters
    ----------
    name : str
        A Python identifier (``p.name`` in the model's functions).
    value : float
        Nominal value: the start of a search and the value used while ``fixed``.
    lower, upper : float
        Bounds, ``lower < upper``; finite for an estimated parameter.
    unit : str
        Unit, for reports (``"kg m^2"``).
    fixed : bool
        Held at ``value`` instead of estimated.
    scale : {"auto", "linear", "log"}
        Search scale (see :data:`SCALES`); ``"log"`` needs ``lower > 0``.
    description : str
        One line for reports.

    Raises
    ------
    ConfigError
        A name that is not an identifier, a non-finite value, reversed bounds, a value
        outside its bounds, infinite bounds on an estimated parameter, an unknown scale or a
        log scale over non-positive values; the message names the parameter.
    """

    name: str
    value: float
    lower: float = -math.inf
    upper: float = math.inf
    unit: str = ""
    fixed: bool = False
    scale: str = "auto"
    description: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise ConfigError(f"grey-box parameter name must be an identifier, got {self.name!r}")
        where = f"grey-box parameter {self.name!r}"
        for field in ("value", "lower", "upper"):
            raw = getattr(self, field)
            try:
                number = float(raw)
            except (TypeError, ValueError):
                raise ConfigError(f"{where}: {field} must be a number, got {raw!r}") from None
            if math.isnan(number) or (field == "value" and not math.isfinite(number)):
                raise ConfigError(f"{where}: {field} must be finite, got {raw!r}")
            object.__setattr__(self, field, number)
        if not self.lower < self.upper:
            raise ConfigError(
                f"{where}: bounds reversed or empty: lower {self.lower:g} must be below upper "
                f"{self.upper:g}"
            )
        if not self.lower <= self.value <= self.upper:
            raise ConfigError(
                f"{where}: value {self.value:g} is outside its bounds "
                f"[{self.lower:g}, {self.upper:g}]"
            )
        if not self.fixed and not (math.isfinite(self.lower) and math.isfinite(self.upper)):
            raise ConfigError(
                f"{where}: an estimated parameter needs finite bounds (the search box), got "
                f"[{self.lower:g}, {self.upper:g}]"
            )
        if self.scale not in SCALES:
            raise UnknownNameError("parameter scale", self.scale, SCALES)
        if self.scale == "log" and self.lower <= 0:
            raise ConfigError(f"{where}: a log scale needs lower > 0, got {self.lower:g}")
        object.__setattr__(self, "fixed", bool(self.fixed))

    @property
    def log(self) -> bool:
        """Whether the parameter is searched as ``log10(value)``."""
        if self.scale != "auto":
            return self.scale == "log"
        return self.lower > 0 and self.upper >= LOG_SPAN * self.lower

    def describe(self) -> str:
        """One line: name, value, unit, bounds, scale and whether fixed.

        Returns
        -------
        str
        """
        state = "fixed" if self.fixed else ("log scale" if self.log else "linear scale")
        unit = f" {self.unit}" if self.unit else ""
        return f"{self.name} = {self.value:.6g}{unit} in [{self.lower:g}, {self.upper:g}], {state}"


class ParameterSet(Mapping):
    """The parameter values of a population: ``name -> (P,)`` array, also as attributes.

    Parameters
    ----------
    names : sequence of str
    values : ndarray, shape (P, len(names))
    """

    def __init__(self, names: Sequence[str], values: np.ndarray) -> None:
        self._index = {name: i for i, name in enumerate(names)}
        self._values = values

    def __getitem__(self, name: str) -> np.ndarray:
        return self._values[:, self._index[name]]

    def __getattr__(self, name: str) -> np.ndarray:
        index = self.__dict__.get("_index", {})
        if name in index:
            return self._values[:, index[name]]
        raise AttributeError(f"no parameter {name!r}; the model has {sorted(index)}")

    def __iter__(self) -> Iterator[str]:
        return iter(self._index)

    def __len__(self) -> int:
        return len(self._index)

    @property
    def size(self) -> int:
        """Number of parameter sets ``P``."""
        return self._values.shape[0]


def _names(values: Sequence[str] | str, what: str) -> tuple[str, ...]:
    names = (values,) if isinstance(values, str) else tuple(values)
    if not names or not all(isinstance(n, str) and n for n in names):
        raise ConfigError(f"grey-box model: {what} must be non-empty names, got {values!r}")
    if len(set(names)) != len(names):
        raise ConfigError(f"grey-box model: {what} repeat a name: {list(names)}")
    return names


class GreyBoxModel:
    """A plant's equations with named physical parameters, simulated for a population.

    Parameters
    ----------
    name : str
        The model's name (reports, the store).
    derivatives : callable
        ``f(x, u, p) -> dx/dt``: ``x`` (P, n_x), ``u`` (P, n_u), ``p`` a
        :class:`ParameterSet`; returns (P, n_x).
    output : callable
        ``h(x, u, p) -> y``: returns (P, n_y) (or (P,) for one output).
    states, inputs, outputs : sequence of str
        Names; ``inputs`` and ``outputs`` are the record's channels the model reads.
    parameters : sequence of GreyParameter
    x0 : array_like, shape (n_x,), optional
        Initial state (default rest, zeros).
    substep : float, optional
        RK4 substep [s]: a sample of ``dt`` is ``max(1, round(dt / substep))`` substeps;
        default ``dt / 10``.
    compiled : callable, optional
        A faster simulator with the semantics of :meth:`simulate_reference`:
        ``compiled(theta (P, n_params), u (N, n_u), dt, n_sub, x0) -> (P, N, n_y)``, used
        when flexid's compiled kernels run.
    description : str
        One paragraph for reports: what the model is and what it cannot separate.
    columns : mapping, optional
        The record's column each channel is read from and the factor that converts it to
        the model's unit: ``{"pitch": ("y", pi / 180)}`` reads the model's ``pitch`` [rad]
        as ``pi/180`` times the record's column ``y`` [deg] (see :meth:`reading`); a channel
        not named is read from the column of its own name, unscaled.

    Raises
    ------
    ConfigError
        Repeated or empty names, parameters that are not :class:`GreyParameter`, an ``x0``
        of the wrong length, a non-positive substep, a column given for a channel the model
        does not read.

    Notes
    -----
    **Initial state.**  A parameter named ``<state>_0`` (:meth:`with_initial_states`) is that
    state's value at ``t = 0``: fixed, it sets the initial state; estimated, the state is
    fitted with the physical parameters (MATLAB ``idnlgrey``'s free ``InitialStates``).
    """

    def __init__(
        self,
        name: str,
        derivatives: Derivatives,
        output: Derivatives,
        *,
        states: Sequence[str],
        inputs: Sequence[str],
        outputs: Sequence[str],
        parameters: Sequence[GreyParameter],
        x0: Any = None,
        substep: float | None = None,
        compiled: Compiled | None = None,
        description: str = "",
        columns: Mapping[str, Any] | None = None,
    ) -> None:
        if not callable(derivatives) or not callable(output):
            raise ConfigError(f"grey-box model {name!r}: derivatives and output must be callable")
        self.name = str(name)
        self.derivatives = derivatives
        self.output = output
        self.states = _names(states, "states")
        self.inputs = _names(inputs, "inputs")
        self.outputs = _names(outputs, "outputs")
        params = tuple(parameters)
        if not params or not all(isinstance(p, GreyParameter) for p in params):
            raise ConfigError(
                f"grey-box model {name!r}: parameters must be a non-empty sequence of "
                "GreyParameter"
            )
        _names([p.name for p in params], "parameters")
        self.parameters = params
        x0 = np.zeros(len(self.states)) if x0 is None else np.asarray(x0, dtype=float)
        if x0.shape != (len(self.states),) or not np.isfinite(x0).all():
            raise ConfigError(
                f"grey-box model {name!r}: x0 must be {len(self.states)} finite values (one per "
                f"state {list(self.states)}), got {x0.tolist()}"
            )
        self.x0 = x0
        if substep is not None and not (math.isfinite(substep) and substep > 0):
            raise ConfigError(f"grey-box model {name!r}: substep must be > 0 s, got {substep!r}")
        self.substep = None if substep is None else float(substep)
        self.compiled = compiled
        self.description = description
        self.columns = self._checked_columns(columns or {})
        # (parameter index, state index) of every parameter that is an initial state
        self._initial = [
            (i, self.states.index(p.name[:-2]))
            for i, p in enumerate(params)
            if p.name.endswith("_0") and p.name[:-2] in self.states
        ]

    def _checked_columns(self, columns: Mapping[str, Any]) -> dict[str, tuple[str, float]]:
        out = {}
        for channel, spec in columns.items():
            if channel not in self.inputs + self.outputs:
                raise ConfigError(
                    f"grey-box model {self.name!r} has no channel {channel!r} to read from a "
                    f"column (its inputs {list(self.inputs)}, outputs {list(self.outputs)})"
                )
            column, factor = (spec, 1.0) if isinstance(spec, str) else tuple(spec)
            factor = float(factor)
            if not (math.isfinite(factor) and factor != 0.0):
                raise ConfigError(
                    f"grey-box model {self.name!r}: the factor converting column {column!r} to "
                    f"channel {channel!r} must be finite and non-zero, got {factor!r}"
                )
            out[str(channel)] = (str(column), factor)
        return out

    # ------------------------------------------------------------------ parameters
    @property
    def names(self) -> tuple[str, ...]:
        """Every parameter's name, in order."""
        return tuple(p.name for p in self.parameters)

    @property
    def estimated_initial_states(self) -> tuple[str, ...]:
        """The states whose value at ``t = 0`` is estimated (a free ``<state>_0``)."""
        return tuple(self.states[j] for i, j in self._initial if not self.parameters[i].fixed)

    @property
    def free(self) -> tuple[str, ...]:
        """The estimated parameters' names, in order."""
        return tuple(p.name for p in self.parameters if not p.fixed)

    @property
    def n_free(self) -> int:
        """Number of estimated parameters."""
        return len(self.free)

    @property
    def nominal(self) -> np.ndarray:
        """Every parameter's value, shape (n_params,)."""
        return np.array([p.value for p in self.parameters])

    def parameter(self, name: str) -> GreyParameter:
        """The parameter called ``name``.

        Parameters
        ----------
        name : str

        Returns
        -------
        GreyParameter

        Raises
        ------
        UnknownNameError
            No such parameter (the message lists the model's).
        """
        for p in self.parameters:
            if p.name == name:
                return p
        raise UnknownNameError(f"parameter of grey-box model {self.name!r}", name, self.names)

    def with_parameters(self, **changes: Any) -> GreyBoxModel:
        """A copy with parameters changed: ``Mg=0.3`` sets a value, a dict sets fields.

        Parameters
        ----------
        **changes
            ``name=value`` (a new nominal value) or ``name={"fixed": True, "lower": ...}``.

        Returns
        -------
        GreyBoxModel

        Raises
        ------
        UnknownNameError
            A name the model does not have.
        ConfigError
            A change that makes a parameter invalid (see :class:`GreyParameter`).
        """
        for name in changes:
            self.parameter(name)
        params = []
        for p in self.parameters:
            change = changes.get(p.name)
            if change is None:
                params.append(p)
            elif isinstance(change, Mapping):
                unknown = set(change) - {"value", "lower", "upper", "unit", "fixed", "scale"}
                if unknown:
                    raise ConfigError(
                        f"grey-box parameter {p.name!r}: unknown field(s) {sorted(unknown)}"
                    )
                params.append(replace(p, **change))
            else:
                params.append(replace(p, value=change))
        return self._copy(parameters=params)

    def fixing(self, *names: str, free: bool = False) -> GreyBoxModel:
        """A copy with ``names`` fixed at their values (or estimated, with ``free=True``).

        Parameters
        ----------
        *names : str
            Parameter names.
        free : bool
            Estimate them instead of fixing them.

        Returns
        -------
        GreyBoxModel
        """
        return self.with_parameters(**{n: {"fixed": not free} for n in names})

    def reading(self, **columns: Any) -> GreyBoxModel:
        """A copy that reads channels from the record's columns of other names and units.

        Parameters
        ----------
        **columns
            ``channel="column"`` or ``channel=("column", factor)``: the model's ``channel``
            is ``factor`` times the record's ``column`` (e.g. ``pitch=("y", math.pi / 180)``
            for a pitch logged in degrees).  Channels not named keep their reading.

        Returns
        -------
        GreyBoxModel

        Raises
        ------
        ConfigError
            A channel the model does not read, a zero or non-finite factor.
        """
        return self._copy(columns={**self.columns, **columns})

    def column(self, channel: str) -> tuple[str, float]:
        """The record's column a channel is read from and the factor to the model's unit.

        Parameters
        ----------
        channel : str
            One of :attr:`inputs` or :attr:`outputs`.

        Returns
        -------
        column : str
        factor : float
        """
        return self.columns.get(channel, (channel, 1.0))

    def with_initial_states(self, **states: Any) -> GreyBoxModel:
        """A copy whose initial state is estimated (or set) for the named states.

        Parameters
        ----------
        **states
            ``state=(value, lower, upper)`` adds the estimated parameter ``<state>_0`` (the
            state at ``t = 0``, the search starting at ``value``); ``state=value`` sets it,
            fixed.  A state that already has one is changed.

        Returns
        -------
        GreyBoxModel

        Raises
        ------
        UnknownNameError
            A state the model does not have.
        ConfigError
            Reversed bounds or a value outside them.
        """
        params = list(self.parameters)
        names = [p.name for p in params]
        for state, spec in states.items():
            if state not in self.states:
                raise UnknownNameError(f"state of grey-box model {self.name!r}", state, self.states)
            if isinstance(spec, (int, float)):
                new = GreyParameter(f"{state}_0", float(spec), fixed=True,
                                    description=f"{state} at t = 0")  # fmt: skip
            else:
                value, lower, upper = spec
                new = GreyParameter(f"{state}_0", value, lower, upper, scale="linear",
                                    description=f"{state} at t = 0")  # fmt: skip
            if new.name in names:
                params[names.index(new.name)] = new
            else:
                params.append(new)
                names.append(new.name)
        return self._copy(parameters=params)

    def _copy(self, **changes: Any) -> GreyBoxModel:
        kwargs = {
            "states": self.states,
            "inputs": self.inputs,
            "outputs": self.outputs,
            "parameters": self.parameters,
            "x0": self.x0,
            "substep": self.substep,
            "compiled": self.compiled,
            "description": self.description,
            "columns": self.columns,
        }
        kwargs.update(changes)
        return GreyBoxModel(self.name, self.derivatives, self.output, **kwargs)

    # ------------------------------------------------------------------ as a model structure
    #: Samples before the first error an identification scores (a grey-box model is
    #: simulated from its initial state, so every sample counts).
    start = 0
    #: The structure's name beside the polynomial ones' (``"arx"``, ``"oe"``, ...).
    kind = "greybox"

    @property
    def orders(self) -> dict[str, Any]:
        """Orders, as a polynomial structure has them: none."""
        return {}

    @property
    def n_params(self) -> int:
        """Estimated parameters (what an information criterion counts)."""
        return self.n_free

    @property
    def n_inputs(self) -> int:
        """Inputs the model reads."""
        return len(self.inputs)

    @property
    def theta(self) -> np.ndarray:
        """The estimated parameters' values, shape (n_free,) (what a search returns)."""
        return np.array([p.value for p in self._free_params()], dtype=float)

    def model(self, theta: Any, dt: float | None = None) -> GreyBoxModel:
        """A copy with the estimated parameters at ``theta`` (the structure interface).

        Parameters
        ----------
        theta : array_like, shape (n_free,)
            The estimated parameters' values, in the order of :attr:`free`.
        dt : float, optional
            Accepted for the interface the polynomial structures share; a grey-box model
            is continuous-time and takes the sample time when simulated.

        Returns
        -------
        GreyBoxModel

        Raises
        ------
        DataError
            ``theta`` of the wrong length.
        ConfigError
            A value outside its parameter's bounds.
        """
        values = np.asarray(theta, dtype=float).reshape(-1)
        if values.size != self.n_free:
            raise DataError(
                f"grey-box model {self.name!r}: {values.size} values for its {self.n_free} "
                f"estimated parameters {list(self.free)}"
            )
        return self.with_parameters(**dict(zip(self.free, values.tolist())))

    def check_samples(self, n_samples: int) -> None:
        """Raise when a record of ``n_samples`` cannot determine the estimated parameters.

        Parameters
        ----------
        n_samples : int

        Raises
        ------
        ModelOrderError
            Fewer samples than twice the estimated parameters (or than 2).
        """
        from ..errors import ModelOrderError

        need = max(2, 2 * self.n_free)
        if n_samples < need:
            raise ModelOrderError(
                f"a record of {n_samples} samples is too short for grey-box model "
                f"{self.name!r} ({self.n_free} estimated parameters need at least {need})"
            )

    def summary(self) -> str:
        """The model and every parameter's value, unit and bounds (estimated ones marked).

        Returns
        -------
        str
        """
        return self.describe()

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe description: name, channels, and each parameter's value and bounds.

        Returns
        -------
        dict
        """
        return {
            "structure": "greybox",
            "name": self.name,
            "states": list(self.states),
            "inputs": list(self.inputs),
            "outputs": list(self.outputs),
            "columns": {k: {"column": c, "factor": f} for k, (c, f) in self.columns.items()},
            "parameters": {
                p.name: {
                    "value": p.value,
                    "lower": p.lower,
                    "upper": p.upper,
                    "unit": p.unit,
                    "fixed": p.fixed,
                }
                for p in self.parameters
            },
        }

    # ------------------------------------------------------------------ search coordinates
    def _free_params(self) -> list[GreyParameter]:
        return [p for p in self.parameters if not p.fixed]

    def _on_log_columns(self, values: Any, transform: Callable[[np.ndarray], Any]) -> np.ndarray:
        """``values`` (estimated parameters in the last axis) as floats, ``transform`` applied
        to the columns of the log-scaled ones."""
        values = np.asarray(values, dtype=float)
        logs = np.array([p.log for p in self._free_params()], dtype=bool)
        out = values.copy()
        out[..., logs] = transform(values[..., logs])
        return out

    def search_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """The search box of the estimated parameters: ``log10`` bounds for log-scaled ones.

        Returns
        -------
        lower, upper : ndarray, shape (n_free,)
        """
        lo = [math.log10(p.lower) if p.log else p.lower for p in self._free_params()]
        hi = [math.log10(p.upper) if p.log else p.upper for p in self._free_params()]
        return np.array(lo, dtype=float), np.array(hi, dtype=float)

    def from_search(self, Z: Any) -> np.ndarray:
        """Estimated parameters' physical values from search coordinates.

        Parameters
        ----------
        Z : array_like, shape (P, n_free) or (n_free,)

        Returns
        -------
        ndarray, same shape
        """
        return self._on_log_columns(Z, lambda z: 10.0**z)

    def to_search(self, values: Any) -> np.ndarray:
        """Search coordinates of estimated parameters' values (the inverse of :meth:`from_search`).

        Parameters
        ----------
        values : array_like, shape (P, n_free) or (n_free,)

        Returns
        -------
        ndarray, same shape
        """

        def log10(v: np.ndarray) -> np.ndarray:
            with np.errstate(divide="ignore", invalid="ignore"):
                return np.log10(v)

        return self._on_log_columns(values, log10)

    def full(self, free_values: Any) -> np.ndarray:
        """Every parameter's value, the estimated ones from ``free_values``.

        Parameters
        ----------
        free_values : array_like, shape (P, n_free) or (n_free,)

        Returns
        -------
        ndarray, shape (P, n_params)
        """
        free_values = np.atleast_2d(np.asarray(free_values, dtype=float))
        if free_values.shape[1] != self.n_free:
            raise DataError(
                f"grey-box model {self.name!r}: {free_values.shape[1]} values for its "
                f"{self.n_free} estimated parameters {list(self.free)}"
            )
        theta = np.repeat(self.nominal[None, :], free_values.shape[0], axis=0)
        theta[:, [not p.fixed for p in self.parameters]] = free_values
        return theta

    # ------------------------------------------------------------------ simulation
    def n_substeps(self, dt: float) -> int:
        """RK4 substeps per sample of ``dt`` seconds.

        Parameters
        ----------
        dt : float
            Sample time [s].

        Returns
        -------
        int
            ``max(1, round(dt / substep))``, or 10 when the model sets no substep.
        """
        if self.substep is None:
            return 10
        return max(1, round(dt / self.substep))

    def _inputs(self, u: Any) -> np.ndarray:
        u = np.asarray(u, dtype=float)
        if u.ndim == 1:
            u = u[:, None]
        if u.ndim != 2 or u.shape[1] != len(self.inputs):
            raise DataError(
                f"grey-box model {self.name!r} reads {len(self.inputs)} input(s) "
                f"{list(self.inputs)}; got inputs of shape {u.shape}"
            )
        return u

    def simulate(
        self, theta: Any, u: Any, dt: float, *, x0: Any = None, reference: bool = False
    ) -> np.ndarray:
        """Outputs of a population of parameter sets driven by one input record.

        Parameters
        ----------
        theta : array_like, shape (P, n_params) or (n_params,)
            Every parameter's value (see :meth:`full`).
        u : array_like, shape (N, n_u) or (N,)
            Inputs, held over each sample.
        dt : float
            Sample time [s].
        x0 : array_like, shape (n_x,) or (P, n_x), optional
            Initial states; default the model's ``x0``.  The states with a ``<state>_0``
            parameter start from its value in ``theta`` either way.
        reference : bool
            Use the NumPy route even where a compiled one exists.

        Returns
        -------
        ndarray, shape (P, N, n_y)
            ``y[k]`` at ``t = k dt``; rows whose simulation overflowed hold non-finite
            values.

        Raises
        ------
        ConfigError
            The model's functions return arrays of the wrong shape.
        """
        theta = np.atleast_2d(np.asarray(theta, dtype=float))
        if theta.shape[1] != len(self.parameters):
            raise DataError(
                f"grey-box model {self.name!r}: theta has {theta.shape[1]} columns, the model "
                f"{len(self.parameters)} parameters {list(self.names)}"
            )
        u = self._inputs(u)
        dt = float(dt)
        n_sub = self.n_substeps(dt)
        x0 = self.x0 if x0 is None else np.asarray(x0, dtype=float)
        x0 = np.broadcast_to(x0, (theta.shape[0], len(self.states)))
        if self._initial:
            params, states = (list(index) for index in zip(*self._initial))
            x0 = x0.copy()
            x0[:, states] = theta[:, params]
        from ..kernels import BACKEND

        route = self.compiled if (self.compiled and BACKEND == "c" and not reference) else None
        if route is None:
            route = self._simulate_numpy
        rows = max(1, _CHUNK // max(1, u.shape[0] * (len(self.states) + 2)))
        parts = [
            route(theta[i : i + rows], u, dt, n_sub, np.ascontiguousarray(x0[i : i + rows]))
            for i in range(0, theta.shape[0], rows)
        ]
        return parts[0] if len(parts) == 1 else np.concatenate(parts, axis=0)

    def simulate_reference(self, theta: Any, u: Any, dt: float, *, x0: Any = None) -> np.ndarray:
        """:meth:`simulate` by the NumPy route (the reference of any compiled simulator).

        Parameters
        ----------
        theta, u, dt, x0
            As for :meth:`simulate`.

        Returns
        -------
        ndarray, shape (P, N, n_y)
        """
        return self.simulate(theta, u, dt, x0=x0, reference=True)

    def _call(self, fn: Derivatives, x: np.ndarray, u: np.ndarray, p: ParameterSet,
              width: int, what: str) -> np.ndarray:
        out = np.asarray(fn(x, u, p), dtype=float)
        if out.ndim == 1 and width == 1 and out.shape[0] == x.shape[0]:
            out = out[:, None]
        if out.shape != (x.shape[0], width):
            raise ConfigError(
                f"grey-box model {self.name!r}: its {what} function returned shape "
                f"{out.shape}, expected {(x.shape[0], width)} (one row per parameter set)"
            )
        return out

    def _simulate_numpy(
        self, theta: np.ndarray, u: np.ndarray, dt: float, n_sub: int, x0: np.ndarray
    ) -> np.ndarray:
        """Fixed-step RK4 of the whole population, in NumPy (the reference route)."""
        n_pop, n_x, n_y = theta.shape[0], len(self.states), len(self.outputs)
        p = ParameterSet(self.names, theta)
        h = dt / n_sub
        x = np.array(x0, dtype=float)
        y = np.empty((n_pop, u.shape[0], n_y))

        def f(state: np.ndarray, uk: np.ndarray) -> np.ndarray:
            return self._call(self.derivatives, state, uk, p, n_x, "derivatives")

        # a candidate that overflows is reported by its non-finite outputs
        with np.errstate(all="ignore"):
            for k in range(u.shape[0]):
                uk = np.broadcast_to(u[k], (n_pop, u.shape[1]))
                y[:, k] = self._call(self.output, x, uk, p, n_y, "output")
                for _ in range(n_sub):
                    k1 = f(x, uk)
                    k2 = f(x + (0.5 * h) * k1, uk)
                    k3 = f(x + (0.5 * h) * k2, uk)
                    k4 = f(x + h * k3, uk)
                    x = x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        return y

    # ------------------------------------------------------------------ reporting
    def describe(self) -> str:
        """Several lines: the model's name, channels and parameters.

        Returns
        -------
        str
        """
        lines = [
            f"grey-box model {self.name}: states {', '.join(self.states)}; inputs "
            f"{', '.join(self.inputs)}; outputs {', '.join(self.outputs)}",
            *(f"  {p.describe()}" for p in self.parameters),
        ]
        return "\n".join(lines)

    def __repr__(self) -> str:
        return f"GreyBoxModel({self.name!r}, {self.n_free} of {len(self.parameters)} estimated)"

    def __str__(self) -> str:
        return f"grey-box {self.name}"
