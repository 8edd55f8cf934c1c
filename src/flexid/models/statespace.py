"""Discrete-time state-space models with several inputs and outputs (MATLAB ``idss``).

``x(t+1) = A x(t) + B u(t) + K e(t)``, ``y(t) = C x(t) + D u(t) + e(t)``, ``x(0) = x0``;
``nu`` inputs, ``ny`` outputs, order ``n``.  ``K = 0`` is the output-error form (the model
run free); with ``K`` the innovations form gives the one-step predictor

    ``xh(t+1) = (A - K C) xh(t) + (B - K D) u(t) + K y(t)``,  ``yh(t) = C xh(t) + D u(t)``,

stable when ``A - K C`` is (Ljung, *System Identification*, 2nd ed., sec. 4.3).  The model
simulates and predicts, gives its frequency response, lists its modes
(:func:`flexid.models.modes.modes` of the eigenvalues of ``A``) and exports to
python-control (``StateSpace`` with ``dt``) and :class:`scipy.signal.dlti`.

Notes
-----
**Simulation.**  The state recursion (:func:`state_sequence`) runs over time, one
matrix-vector step per sample, its input terms formed beforehand for every sample at once;
a simulation is checked against
:func:`scipy.signal.dlsim` in the tests.  What a search evaluates for a whole population is
a batched cost of its own (the modal space), not this method.

**The modal structure.**  A flexible structure's response is a sum of modes, each a natural
frequency ``f`` (Hz) and a damping ratio ``zeta``, seen by every sensor with its own gain.
:class:`StateSpaceStructure` writes a discrete state-space model of order ``n`` as ``m``
such modes and ``n - 2 m`` real poles (each a corner frequency ``f_c``), every one stable
for every ``f > 0``, ``0 < zeta <= 1``, ``f_c > 0``:

- mode: continuous poles ``s = 2 pi f (-zeta +- j sqrt(1 - zeta^2))``, discrete
  ``z = exp(s dt)``, denominator ``1 + a1 q^-1 + a2 q^-2`` with ``a1 = -2 Re z``,
  ``a2 = |z|^2``;
- real pole: ``p = exp(-2 pi f_c dt)``.

Its realisation has one block per pole group and input (``nu (2 m + r)`` states): the
companion block ``[[-a1, -a2], [1, 0]]`` of a mode driven by input ``j`` alone (``B`` a one
in its first state), or ``p`` for a real pole; ``C`` (every sensor's gains), ``D`` and
``x0`` are free.  For one input this realisation is minimal; for several each mode appears
once per input (each input-output pair then has its own residue, which a minimal model
would tie to rank one).  It is what a search over shared modes needs: for fixed modes the
output is linear in ``C``, ``D`` and ``x0`` (see :class:`flexid.costs.modal.ModalCost`).

The parameter vector ``theta`` is ``[f_1, zeta_1, .., f_m, zeta_m, f_c1, .., f_cr]``
followed by ``C`` (``ny`` rows of ``nu (2 m + r)``), ``D`` (``ny`` rows of ``nu``, with
feedthrough) and ``x0``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .._table import wrapped
from .._validate import integer
from ..errors import ConfigError, DataError, ModelOrderError
from .modes import Mode, modes

__all__ = [
    "DAMPING_FLOOR",
    "INTEGRATOR_SHARE",
    "StateSpaceModel",
    "StateSpaceStructure",
    "state_sequence",
]


def state_sequence(F: np.ndarray, forced: np.ndarray, x0: np.ndarray) -> np.ndarray:
    """The states of ``x(t+1) = F x(t) + forced[t]`` from ``x(0) = x0``, for ``t < N``.

    Parameters
    ----------
    F : ndarray, shape (n, n)
    forced : ndarray, shape (N, n) or (N, n, m)
        Every sample's input term, computed beforehand as one array operation.
    x0 : ndarray, shape (n,) or (n, m)
        The initial state; ``m`` columns run side by side (one recursion for all).

    Returns
    -------
    ndarray, shape of ``forced``
        ``x(0) .. x(N-1)``.
    """
    out = np.empty(forced.shape)
    state = np.array(x0, dtype=float)
    for t in range(forced.shape[0]):  # the recursion itself is sequential
        out[t] = state
        state = F @ state + forced[t]
    return out


def _matrix(value: Any, name: str, shape: tuple[int, int]) -> np.ndarray:
    m = np.array(value, dtype=float, copy=True)
    if m.ndim == 1 and 0 in shape:
        m = m.reshape(shape)
    if m.ndim != 2 or m.shape != shape:
        raise DataError(f"state-space model: {name} must have shape {shape}, got {m.shape}")
    if not np.isfinite(m).all():
        raise DataError(f"state-space model: {name} has non-finite entries")
    return m


class StateSpaceModel:
    """A discrete-time state-space model ``(A, B, C, D, K, x0)`` with sample time ``dt``.

    Parameters
    ----------
    A : array_like, shape (n, n)
    B : array_like, shape (n, nu)
    C : array_like, shape (ny, n)
    D : array_like, shape (ny, nu), optional
        Feedthrough (default zero, MATLAB ``ssest``'s default).
    K : array_like, shape (n, ny), optional
        Innovations gain (default zero: the output-error form).
    x0 : array_like, shape (n,), optional
        Initial state (default zero).
    dt : float, optional
        Sample time in seconds (default 1).
    input_names, output_names : sequence of str, optional
        Channel names (default ``u1 ..``, ``y1 ..``).
    structure : StateSpaceStructure, optional
        The structure the model was realised from (default: a structure of its order and
        channels).
    theta : array_like, optional
        Its parameter vector in that structure (default: ``A, B, C, D, x0`` row by row, for
        a model not realised from one).

    Raises
    ------
    DataError
        A matrix of the wrong shape or with non-finite entries, or a bad ``dt``; the message
        names the matrix and the shape it needs.
    """

    def __init__(
        self,
        A: Any,
        B: Any,
        C: Any,
        D: Any = None,
        K: Any = None,
        x0: Any = None,
        *,
        dt: float = 1.0,
        input_names: Sequence[str] | None = None,
        output_names: Sequence[str] | None = None,
        structure: Any = None,
        theta: Any = None,
    ) -> None:
        A = np.atleast_2d(np.array(A, dtype=float))
        n = A.shape[0]
        self.A = _matrix(A, "A", (n, n))
        B = np.array(B, dtype=float)
        nu = B.shape[1] if B.ndim == 2 else (1 if n else 0)
        self.B = _matrix(B.reshape(n, -1) if B.ndim == 1 else B, "B", (n, nu))
        C = np.array(C, dtype=float)
        ny = C.shape[0] if C.ndim == 2 else 1
        self.C = _matrix(C.reshape(1, -1) if C.ndim == 1 else C, "C", (ny, n))
        self.D = np.zeros((ny, nu)) if D is None else _matrix(D, "D", (ny, nu))
        self.K = np.zeros((n, ny)) if K is None else _matrix(K, "K", (n, ny))
        self.x0 = np.zeros(n) if x0 is None else _matrix(np.reshape(x0, (n, 1)), "x0",
                                                         (n, 1))[:, 0]  # fmt: skip
        dt = float(dt)
        if not (math.isfinite(dt) and dt > 0):
            raise DataError(f"state-space model: dt must be a positive number of seconds, got {dt}")
        self.dt = dt
        self.input_names = self._names(input_names, nu, "u", "input_names")
        self.output_names = self._names(output_names, ny, "y", "output_names")
        if structure is None:
            pairs = int(np.sum(np.linalg.eigvals(self.A).imag > 0)) if n else 0
            structure = StateSpaceStructure(max(n, 1), nu, ny, n_modes=pairs,
                                            feedthrough=D is not None)  # fmt: skip
        self.structure = structure
        self._theta = None if theta is None else np.array(theta, dtype=float).reshape(-1)

    @property
    def realised(self) -> bool:
        """Whether :attr:`theta` is the parameter vector of :attr:`structure` (a model its
        ``model(theta)`` made), rather than the matrices' entries."""
        return self._theta is not None

    @property
    def theta(self) -> np.ndarray:
        """The parameter vector (see the ``theta`` parameter)."""
        if self._theta is not None:
            return self._theta
        return np.concatenate([m.reshape(-1) for m in (self.A, self.B, self.C, self.D,
                                                       self.x0)])  # fmt: skip

    def named(self, inputs: Sequence[str], outputs: Sequence[str] | str) -> StateSpaceModel:
        """The same model with the record's channel names.

        Parameters
        ----------
        inputs : sequence of str
        outputs : sequence of str, or str for one output

        Returns
        -------
        StateSpaceModel
        """
        outputs = [outputs] if isinstance(outputs, str) else list(outputs)
        return StateSpaceModel(self.A, self.B, self.C, self.D, self.K, self.x0, dt=self.dt,
                               input_names=inputs, output_names=outputs,
                               structure=self.structure, theta=self._theta)  # fmt: skip

    @staticmethod
    def _names(names: Sequence[str] | None, count: int, stem: str, what: str) -> tuple:
        if names is None:
            return tuple(f"{stem}{i + 1}" for i in range(count))
        names = tuple(str(v) for v in names)
        if len(names) != count:
            raise DataError(f"state-space model: {what} has {len(names)} names for {count}")
        return names

    # ------------------------------------------------------------------ sizes and poles
    @property
    def order(self) -> int:
        """``n``, the number of states."""
        return self.A.shape[0]

    @property
    def n_inputs(self) -> int:
        """``nu``."""
        return self.B.shape[1]

    @property
    def n_outputs(self) -> int:
        """``ny``."""
        return self.C.shape[0]

    def poles(self) -> np.ndarray:
        """The eigenvalues of ``A``.

        Returns
        -------
        ndarray of complex, shape (n,)
        """
        return np.linalg.eigvals(self.A) if self.order else np.zeros(0, complex)

    @property
    def is_stable(self) -> bool:
        """Every pole strictly inside the unit circle."""
        return bool(np.all(np.abs(self.poles()) < 1.0))

    @property
    def predictor_stable(self) -> bool:
        """Every eigenvalue of ``A - K C`` strictly inside the unit circle."""
        if not self.order:
            return True
        return bool(np.all(np.abs(np.linalg.eigvals(self.A - self.K @ self.C)) < 1.0))

    def zeros(self, input: int = 0, output: int = 0) -> np.ndarray:
        """The finite transmission zeros from one input to one output.

        Parameters
        ----------
        input, output : int, optional
            0-based channels (default the first of each).

        Returns
        -------
        ndarray of complex
            The zeros of ``C_o (z I - A)^-1 B_j + D_oj``.
        """
        import warnings

        from scipy import signal

        if not self.order:
            return np.zeros(0, complex)
        with np.errstate(all="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", signal.BadCoefficients)  # leading zero numerators
            z, _, _ = signal.ss2zpk(self.A, self.B, self.C[output : output + 1],
                                    self.D[output : output + 1], input=input)  # fmt: skip
        return np.asarray(z, dtype=complex)[np.isfinite(z)]

    def modes(self) -> list[Mode]:
        """The modes of ``A``: natural frequency (Hz) and damping ratio of each pole or pair.

        Returns
        -------
        list of Mode
            By increasing frequency (:func:`flexid.models.modes.modes`); a model realised
            from its modal structure lists the structure's modes, each once.
        """
        if not self._realised():
            return modes(self.poles(), self.dt)
        # the structure's own modes: (frequency, damping) as searched, even a critically
        # damped one (a double real root of its block, two "real" poles to ``modes``)
        s = self.structure
        modal = self._theta[: s.n_search]
        a, p = s.denominators(modal[None], self.dt)
        out = []
        for k in range(s.n_modes):
            pole = complex(np.roots([1.0, *a[0, k]])[0])
            out.append(Mode(float(modal[2 * k]), float(np.clip(modal[2 * k + 1], 0.0, 1.0)),
                            complex(pole.real, abs(pole.imag)), "pair"))  # fmt: skip
        out += modes(p[0], self.dt)
        return sorted(out, key=lambda m: (m.frequency, m.kind))

    def _realised(self) -> bool:
        """Whether ``A`` is its modal structure's realisation of ``theta``: each mode and real
        pole a block once per input (with several inputs every pole of ``A`` repeats)."""
        return self._theta is not None and self.order == self.structure.n_states

    # ------------------------------------------------------------------ time responses
    def _inputs(self, u: Any) -> np.ndarray:
        u = np.asarray(u, dtype=float)
        if u.ndim == 1:
            u = u[:, None]
        if u.ndim != 2 or u.shape[1] != self.n_inputs:
            raise ModelOrderError(
                f"the model has {self.n_inputs} input(s); u must have shape (N, {self.n_inputs}), "
                f"got {np.shape(u)}"
            )
        if not np.isfinite(u).all():
            raise DataError("u has non-finite values")
        return u

    def _run(self, F: np.ndarray, G: np.ndarray, H: np.ndarray, J: np.ndarray,
             w: np.ndarray, x0: np.ndarray) -> np.ndarray:  # fmt: skip
        """``x(t+1) = F x + G w``, ``out = H x + J w`` over the rows of ``w``."""
        return state_sequence(F, w @ G.T, x0) @ H.T + w @ J.T

    def simulate(self, u: Any, x0: Any = None) -> np.ndarray:
        """The output of the model run free (``e = 0``) from ``x0``.

        Parameters
        ----------
        u : array_like, shape (N, nu) or (N,)
            Inputs.
        x0 : array_like, shape (n,), optional
            Initial state (default the model's ``x0``).

        Returns
        -------
        ndarray, shape (N, ny)
        """
        u = self._inputs(u)
        start = self.x0 if x0 is None else _matrix(np.reshape(x0, (-1, 1)), "x0",
                                                   (self.order, 1))[:, 0]  # fmt: skip
        return self._run(self.A, self.B, self.C, self.D, u, start)

    def predict(self, u: Any, y: Any, x0: Any = None) -> np.ndarray:
        """The one-step prediction of the innovations form.

        Parameters
        ----------
        u : array_like, shape (N, nu) or (N,)
        y : array_like, shape (N, ny) or (N,)
            Measured outputs.
        x0 : array_like, shape (n,), optional
            The predictor's initial state (default the model's ``x0``).

        Returns
        -------
        ndarray, shape (N, ny)
            ``yh(t) = C xh(t) + D u(t)``, ``xh`` from the predictor recursion above.
        """
        u = self._inputs(u)
        y = np.asarray(y, dtype=float)
        y = y[:, None] if y.ndim == 1 else y
        if y.shape != (u.shape[0], self.n_outputs) or not np.isfinite(y).all():
            raise DataError(f"y must be finite with shape ({u.shape[0]}, {self.n_outputs})")
        start = self.x0 if x0 is None else np.asarray(x0, dtype=float).reshape(self.order)
        F = self.A - self.K @ self.C
        G = np.hstack([self.B - self.K @ self.D, self.K])
        J = np.hstack([self.D, np.zeros((self.n_outputs, self.n_outputs))])
        return self._run(F, G, self.C, J, np.hstack([u, y]), start)

    # ------------------------------------------------------------------ frequency domain
    def frequency_response(self, frequencies: Any) -> np.ndarray:
        """``G(z) = C (z I - A)^-1 B + D`` at ``z = exp(j 2 pi f dt)``.

        Parameters
        ----------
        frequencies : array_like, shape (F,)
            Frequencies in Hz.

        Returns
        -------
        ndarray of complex, shape (F, ny, nu)
        """
        f = np.asarray(frequencies, dtype=float).reshape(-1)
        z = np.exp(2j * np.pi * f * self.dt)
        eye = np.eye(self.order)
        # one batched solve of (z I - A) X = B for every frequency
        X = np.linalg.solve(z[:, None, None] * eye - self.A, np.broadcast_to(
            self.B, (f.size, *self.B.shape)))  # fmt: skip
        return self.C @ X + self.D

    # ------------------------------------------------------------------ exports
    def to_control(self) -> Any:
        """The model as a python-control ``StateSpace`` with ``dt`` (``K`` and ``x0`` left out).

        Returns
        -------
        control.StateSpace
        """
        import control

        names = {"inputs": list(self.input_names), "outputs": list(self.output_names)}
        return control.ss(self.A, self.B, self.C, self.D, self.dt, **names)

    def to_dlti(self) -> Any:
        """The model as :class:`scipy.signal.dlti` (``K`` and ``x0`` left out).

        Returns
        -------
        scipy.signal.dlti
        """
        from scipy import signal

        return signal.dlti(self.A, self.B, self.C, self.D, dt=self.dt)

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe form: the matrices as nested lists, ``dt``, the names and the modes.

        Returns
        -------
        dict
        """
        return {
            "kind": "state-space",
            "A": self.A.tolist(), "B": self.B.tolist(), "C": self.C.tolist(),
            "D": self.D.tolist(), "K": self.K.tolist(), "x0": self.x0.tolist(),
            "dt": self.dt, "inputs": list(self.input_names), "outputs": list(self.output_names),
            "modes": [m.to_dict() for m in self.modes()],
        }  # fmt: skip

    def _order_text(self) -> str:
        if not self._realised() or self.n_inputs == 1:
            return str(self.order)
        return f"{self.structure.order} ({self.order} states: each mode once per input)"

    def summary(self) -> str:
        """The sizes and the table of modes.

        Returns
        -------
        str
        """
        lines = [
            wrapped(f"state-space model: order {self._order_text()}, {self.n_inputs} input(s) "
                    f"({', '.join(self.input_names)}), {self.n_outputs} output(s) "
                    f"({', '.join(self.output_names)}), dt {self.dt:g} s, "
                    f"{'stable' if self.is_stable else 'UNSTABLE'}"),
            f"{'mode':>4}  {'frequency Hz':>12}  {'damping':>9}  kind",
        ]
        for i, m in enumerate(self.modes(), 1):
            lines.append(f"{i:>4}  {m.frequency:>12.5g}  {m.damping:>9.4g}  {m.kind}")
        return "\n".join(lines)

    def __repr__(self) -> str:
        return (f"StateSpaceModel(order={self.order}, inputs={self.n_inputs}, "
                f"outputs={self.n_outputs}, dt={self.dt:g})")  # fmt: skip


#: The default lowest corner frequency of a real pole, as a share of the record's frequency
#: resolution ``1 / (N dt)``: such a pole decays by 0.6 % over the record, an integrator as
#: far as the record can tell (a hub angle's rigid-body mode, driven by torque).
INTEGRATOR_SHARE = 1e-3

#: Lowest damping ratio the default search box reaches: its damping is searched on a log
#: scale, which needs a positive floor; structural modes are rarely below 1e-3.
DAMPING_FLOOR = 1e-4


def _interval(value: Any, name: str) -> tuple[float, float] | None:
    if value is None:
        return None
    try:
        lo, hi = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ConfigError(f"{name} must be a pair (low, high), got {value!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and 0 < lo < hi):
        raise ConfigError(f"{name} must be a pair 0 < low < high, got {value!r}")
    return lo, hi


@dataclass(frozen=True)
class StateSpaceStructure:
    """A state-space model of order ``n`` as ``m`` modes and ``n - 2 m`` real poles.

    Parameters
    ----------
    order : int
        The number of poles ``n`` (each mode is two), >= 1.
    n_inputs, n_outputs : int, optional
        ``nu`` and ``ny`` (default 1 each).
    n_modes : int, optional
        Lightly damped modes ``m`` (default ``order // 2``); the other ``order - 2 m`` poles
        are real.
    feedthrough : bool, optional
        Estimate ``D`` (default False: ``D = 0``, MATLAB ``ssest``'s default).
    frequency : (float, float), optional
        Bounds in Hz of the modes' natural frequencies and the real poles' corner
        frequencies, within (0, Nyquist]; default from the record's frequency resolution
        ``1 / (N dt)`` to Nyquist for the modes, and from ``1e-3 / (N dt)`` for the real
        poles, which then reach integrators (:data:`INTEGRATOR_SHARE`); checked when posed
        on a record.
    damping : (float, float), optional
        Bounds of the damping ratios, within (0, 1]; default ``(1e-4, 1)``.

    Raises
    ------
    ModelOrderError
        A bad order or channel count, or more modes than the order allows.
    ConfigError
        Bounds that are not pairs ``0 < low < high``, or damping above 1.
    """

    order: int
    n_inputs: int = 1
    n_outputs: int = 1
    n_modes: int | None = None
    feedthrough: bool = False
    frequency: tuple[float, float] | None = None
    damping: tuple[float, float] | None = None

    kind = "ss"
    start = 0  # the model runs from its estimated state: every sample is scored

    def __post_init__(self) -> None:
        set_ = object.__setattr__  # frozen: normalise once here
        order = integer(self.order, "order", error=ModelOrderError, minimum=1)
        set_(self, "order", order)
        for name in ("n_inputs", "n_outputs"):
            set_(self, name, integer(getattr(self, name), name, error=ModelOrderError,
                                     minimum=1))  # fmt: skip
        m = order // 2 if self.n_modes is None else integer(
            self.n_modes, "modes", error=ModelOrderError, minimum=0)  # fmt: skip
        if 2 * m > order:
            raise ModelOrderError(
                f"{m} modes need order >= {2 * m} (two poles each); order {order} allows at "
                f"most {order // 2}"
            )
        set_(self, "n_modes", m)
        set_(self, "feedthrough", bool(self.feedthrough))
        set_(self, "frequency", _interval(self.frequency, "frequency bounds (Hz)"))
        damping = _interval(self.damping, "damping bounds")
        if damping is not None and damping[1] > 1.0:
            raise ConfigError(f"damping bounds must lie in (0, 1], got {self.damping!r}")
        set_(self, "damping", damping)

    def __repr__(self) -> str:
        io = f", inputs={self.n_inputs}, outputs={self.n_outputs}"
        fd = ", feedthrough" if self.feedthrough else ""
        return f"SS(order={self.order}, modes={self.n_modes}{io}{fd})"

    # ------------------------------------------------------------------ sizes
    @property
    def n_real(self) -> int:
        """Real poles, ``order - 2 m``."""
        return self.order - 2 * self.n_modes

    @property
    def n_search(self) -> int:
        """The modal parameters searched: ``2 m + r``."""
        return 2 * self.n_modes + self.n_real

    @property
    def n_states(self) -> int:
        """States of the realisation: ``nu (2 m + r)``."""
        return self.n_inputs * self.order

    @property
    def n_params(self) -> int:
        """Length of ``theta``: the modal parameters, ``C``, ``D`` and ``x0``."""
        ny, nu, ns = self.n_outputs, self.n_inputs, self.n_states
        return self.n_search + ny * ns + (ny * nu if self.feedthrough else 0) + ns

    @property
    def orders(self) -> dict[str, Any]:
        """The orders by name: ``order`` and ``modes``."""
        return {"order": self.order, "modes": self.n_modes}

    def check_samples(self, n_samples: int) -> None:
        """Refuse a record too short for the linear parameters.

        Parameters
        ----------
        n_samples : int

        Raises
        ------
        ModelOrderError
            Fewer than twice the linear parameters of one output.
        """
        need = 2 * (self.n_states + self.n_search + (self.n_inputs if self.feedthrough else 0))
        if n_samples < need:
            raise ModelOrderError(
                f"{self!r} needs at least {need} samples (twice its gains and initial state "
                f"per output), the record has {n_samples}: give a lower order"
            )

    # ------------------------------------------------------------------ bounds
    def bounds(self, dt: float, n_samples: int) -> tuple[tuple[float, float], ...]:
        """The frequency (Hz), damping and corner-frequency (Hz) bounds on a record.

        Parameters
        ----------
        dt : float
            Sample time (s).
        n_samples : int
            Length of the estimation record.

        Returns
        -------
        frequency, damping, corner : (float, float)
            The modes' natural frequencies, their damping ratios and the real poles' corner
            frequencies.

        Raises
        ------
        ConfigError
            Frequency bounds above Nyquist.
        """
        nyquist = 0.5 / dt
        if self.frequency is None:
            lowest = min(1.0 / (n_samples * dt), 0.5 * nyquist)
            frequency = (lowest, nyquist)
            corner = (INTEGRATOR_SHARE * lowest, nyquist)
        else:
            frequency = self.frequency
            if frequency[1] > nyquist * (1 + 1e-12):
                raise ConfigError(
                    f"frequency bounds {frequency} Hz reach above Nyquist ({nyquist:g} Hz at "
                    f"dt = {dt:g} s): give bounds within (0, {nyquist:g}]"
                )
            corner = frequency
        damping = (DAMPING_FLOOR, 1.0) if self.damping is None else self.damping
        return frequency, damping, corner

    # ------------------------------------------------------------------ poles and model
    def denominators(
        self, modal: np.ndarray, dt: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """The modes' second-order and the real poles' first-order denominators.

        Parameters
        ----------
        modal : ndarray, shape (P, 2 m + r)
            ``[f_1, zeta_1, .., f_m, zeta_m, f_c1, ..]`` of each candidate.
        dt : float
            Sample time (s).

        Returns
        -------
        a : ndarray, shape (P, m, 2)
            ``a1, a2`` of each mode.
        p : ndarray, shape (P, r)
            Each real pole.
        """
        modal = np.atleast_2d(np.asarray(modal, dtype=float))
        m = self.n_modes
        f, zeta = modal[:, 0 : 2 * m : 2], np.clip(modal[:, 1 : 2 * m : 2], 0.0, 1.0)
        w = 2 * np.pi * f * dt
        radius = np.exp(-zeta * w)
        a = np.stack([-2 * radius * np.cos(w * np.sqrt(1 - zeta * zeta)), radius * radius],
                     axis=-1)  # fmt: skip
        p = np.exp(-2 * np.pi * modal[:, 2 * m :] * dt)
        return a, p

    def model(self, theta: Any, dt: float = 1.0) -> StateSpaceModel:
        """The realisation of ``theta``.

        Parameters
        ----------
        theta : array_like, shape (n_params,)
        dt : float, optional
            Sample time (s).

        Returns
        -------
        StateSpaceModel
            Block-diagonal ``A`` (companion blocks of the modes, then the real poles, each
            once per input), with this structure and ``theta``.

        Raises
        ------
        ModelOrderError
            ``theta`` of the wrong length.
        """
        theta = np.asarray(theta, dtype=float).reshape(-1)
        if theta.size != self.n_params:
            raise ModelOrderError(f"{self!r} has {self.n_params} parameters, got {theta.size}")
        m, r, nu, ny, ns = self.n_modes, self.n_real, self.n_inputs, self.n_outputs, self.n_states
        a, p = self.denominators(theta[None, : self.n_search], dt)
        A, B = np.zeros((ns, ns)), np.zeros((ns, nu))
        i = 0
        for k in range(m):
            for j in range(nu):
                A[i, i : i + 2] = -a[0, k]
                A[i + 1, i] = 1.0
                B[i, j] = 1.0
                i += 2
        for k in range(r):
            for j in range(nu):
                A[i, i], B[i, j] = p[0, k], 1.0
                i += 1
        rest = theta[self.n_search :]
        C = rest[: ny * ns].reshape(ny, ns)
        rest = rest[ny * ns :]
        D = rest[: ny * nu].reshape(ny, nu) if self.feedthrough else None
        x0 = rest[ny * nu :] if self.feedthrough else rest
        return StateSpaceModel(A, B, C, D, x0=x0, dt=dt, structure=self, theta=theta)

    def to_dict(self) -> dict[str, Any]:
        """The structure as a result stores it.

        Returns
        -------
        dict
            ``structure``, ``order``, ``modes``, ``n_inputs``, ``n_outputs``,
            ``feedthrough`` and the bounds that were given.
        """
        out = {"structure": self.kind, "order": self.order, "modes": self.n_modes,
               "n_inputs": self.n_inputs, "n_outputs": self.n_outputs,
               "feedthrough": self.feedthrough}  # fmt: skip
        for name in ("frequency", "damping"):
            if getattr(self, name) is not None:
                out[name] = list(getattr(self, name))
        return out
