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
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from ..errors import DataError, ModelOrderError
from .modes import Mode, modes

__all__ = ["StateSpaceModel", "state_sequence"]


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

    def modes(self) -> list[Mode]:
        """The modes of ``A``: natural frequency (Hz) and damping ratio of each pole or pair.

        Returns
        -------
        list of Mode
            By increasing frequency (:func:`flexid.models.modes.modes`).
        """
        return modes(self.poles(), self.dt)

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

    def summary(self) -> str:
        """The sizes and the table of modes.

        Returns
        -------
        str
        """
        lines = [
            f"state-space model: order {self.order}, {self.n_inputs} input(s) "
            f"({', '.join(self.input_names)}), {self.n_outputs} output(s) "
            f"({', '.join(self.output_names)}), dt {self.dt:g} s, "
            f"{'stable' if self.is_stable else 'UNSTABLE'}",
            f"{'mode':>4}  {'frequency Hz':>12}  {'damping':>9}  kind",
        ]
        for i, m in enumerate(self.modes(), 1):
            lines.append(f"{i:>4}  {m.frequency:>12.5g}  {m.damping:>9.4g}  {m.kind}")
        return "\n".join(lines)

    def __repr__(self) -> str:
        return (f"StateSpaceModel(order={self.order}, inputs={self.n_inputs}, "
                f"outputs={self.n_outputs}, dt={self.dt:g})")  # fmt: skip
