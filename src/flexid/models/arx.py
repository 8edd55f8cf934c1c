"""ARX models in MATLAB's convention: structure, regressors, least squares, simulation, export.

``A(q) y(t) = B_1(q) u_1(t - nk_1) + ... + B_m(q) u_m(t - nk_m) + e(t)`` with
``A(q) = 1 + a_1 q^-1 + ... + a_na q^-na`` and
``B_i(q) = b_i1 + b_i2 q^-1 + ... + b_i,nb_i q^-(nb_i - 1)``, exactly as MATLAB's ``arx``:
``nb_i`` coefficients, the first multiplying ``u_i(t - nk_i)``.  The parameter vector is
``theta = [a_1 .. a_na, b_11 .. b_1nb_1, b_21 ..]``.
"""

from __future__ import annotations

import copy
import json
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy import linalg

from .._json import jsonable
from .._table import wrapped
from .._validate import integer, positive_real
from ..errors import DataError, ModelOrderError, check_finite
from .stability import is_stable as _is_stable
from .stability import stability_words

if TYPE_CHECKING:  # pragma: no cover - python-control and scipy.signal load on first use
    import control
    from scipy import signal


__all__ = ["ARX", "ARXStructure", "NamedChannels", "PlantResponse", "channel_names"]


def _orders(value: Any, what: str, low: int) -> tuple[int, ...]:
    items = [value] if np.isscalar(value) else list(value)
    if not items:
        raise ModelOrderError(f"{what} needs at least one value (one per input)")
    # orders may come from float arrays (8.0), so integer-valued floats count as integers
    return tuple(
        integer(v, f"model order {what}", error=ModelOrderError, minimum=low, integral_float=True)
        for v in items
    )


def _io_arrays(u: Any, y: Any) -> tuple[np.ndarray, np.ndarray]:
    """``u`` (N, n_u) and ``y`` (N,) as checked float arrays; ``u`` may be an IOData."""
    from ..data.records import IOData

    if isinstance(u, IOData):
        if y is not None:
            raise DataError("pass either an IOData or (u, y) arrays, not both")
        if u.n_outputs != 1:
            raise DataError(
                f"the record has {u.n_outputs} outputs; select one first, "
                f"e.g. data.select(outputs=[{u.output_names[0]!r}])"
            )
        return u.u, u.y[:, 0]
    if y is None:
        raise DataError("the output y is missing")
    u = np.asarray(u, dtype=float)
    y = np.asarray(y, dtype=float)
    if u.ndim == 1:
        u = u[:, None]
    if y.ndim == 2 and y.shape[1] == 1:
        y = y[:, 0]
    if u.ndim != 2:
        raise DataError(f"u must have shape (N,) or (N, n_u), got {u.shape}")
    if y.ndim != 1:
        raise DataError(f"y must have shape (N,) or (N, 1) (single output), got {y.shape}")
    if u.shape[0] != y.shape[0]:
        raise DataError(f"u has {u.shape[0]} samples but y has {y.shape[0]}")
    check_finite(u, "u", DataError)
    check_finite(y, "y", DataError)
    return u, y


def _check_samples(structure: Any, n_samples: int, what: str) -> None:
    """Raise ModelOrderError unless ``n_samples - structure.start > structure.n_params``.

    Parameters
    ----------
    structure : ARXStructure or PolynomialStructure
        Any structure with ``start`` and ``n_params``.
    n_samples : int
        Number of samples N of the record.
    what : str
        What the ``N - start`` samples give (``"equations"``, ``"error samples"``).

    Raises
    ------
    ModelOrderError
        If ``N - start <= n_params``.
    """
    k = n_samples - structure.start
    if k <= structure.n_params:
        raise ModelOrderError(
            f"too few samples for {structure!r}: {n_samples} samples give {max(k, 0)} {what} "
            f"for {structure.n_params} parameters (need more than "
            f"{structure.start + structure.n_params} samples)"
        )


def channel_names(
    input_names: Sequence[str] | None, output_name: str | None, n_inputs: int
) -> tuple[tuple[str, ...], str]:
    """A model's channel names: the given ones, or ``u`` (``u1, u2, ..``) and ``y``.

    Parameters
    ----------
    input_names : sequence of str or None
    output_name : str or None
    n_inputs : int

    Returns
    -------
    input_names : tuple of str
    output_name : str

    Raises
    ------
    DataError
        A count of names other than ``n_inputs``.
    """
    if input_names is None:
        names = ("u",) if n_inputs == 1 else tuple(f"u{j + 1}" for j in range(n_inputs))
    else:
        names = (input_names,) if isinstance(input_names, str) else tuple(map(str, input_names))
        if len(names) != n_inputs:
            raise DataError(f"{len(names)} input name(s) {list(names)} for {n_inputs} input(s)")
    return names, "y" if output_name is None else str(output_name)


class PlantResponse:
    """The frequency response of a single-output model from its transfer functions
    ``_plant_tf(j)`` (each input's numerator and denominator in positive powers of ``z``,
    equal lengths)."""

    dt: float

    def frequency_response(self, frequencies: Any) -> np.ndarray:
        """The plant ``G(z)`` of every input at ``z = exp(j 2 pi f dt)``.

        Parameters
        ----------
        frequencies : array_like, shape (F,)
            Frequencies in Hz.

        Returns
        -------
        ndarray of complex, shape (F, 1, n_inputs)
        """
        f = np.asarray(frequencies, dtype=float).reshape(-1)
        z = np.exp(2j * np.pi * f * self.dt)
        columns = []
        for j in range(self.structure.n_inputs):  # type: ignore[attr-defined]
            num, den = self._plant_tf(j)  # type: ignore[attr-defined]
            columns.append(np.polyval(num, z) / np.polyval(den, z))
        return np.stack(columns, axis=-1)[:, None, :]


class NamedChannels:
    """The record's channel names a model keeps (``input_names``, ``output_name``)."""

    input_names: tuple[str, ...]
    output_name: str
    structure: Any

    def named(self, input_names: Sequence[str], output_name: str) -> Any:
        """A copy with the record's channel names (kept in exports and dictionaries).

        Parameters
        ----------
        input_names : sequence of str
        output_name : str

        Returns
        -------
        model
            Of the same class.
        """
        out = copy.copy(self)
        out.input_names, out.output_name = channel_names(
            input_names, output_name, self.structure.n_inputs
        )
        return out


def _equal_lengths(num: np.ndarray, den: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``num`` and ``den`` zero-padded at the end to one length: coefficients in powers of
    ``q^-1`` read as the same polynomials in positive powers of ``z``."""
    n = max(num.size, den.size)
    return np.pad(num, (0, n - num.size)), np.pad(den, (0, n - den.size))


class _TransferModel(NamedChannels, PlantResponse):
    """What the ARX and polynomial models share: their constructor, delayed numerators,
    exports and summary (each class keeps its own public methods and their docstrings)."""

    structure: Any
    theta: np.ndarray
    param_std: np.ndarray | None
    noise_variance: float | None
    b: list[np.ndarray]
    is_stable: bool
    max_pole_radius: float

    def __init__(
        self,
        structure: Any,
        theta: Any,
        dt: float = 1.0,
        param_std: Any = None,
        noise_variance: float | None = None,
        input_names: Sequence[str] | None = None,
        output_name: str | None = None,
    ) -> None:
        """Check and keep the arguments (the subclasses' docstrings say what they are)."""
        self._check_structure(structure)
        theta = np.array(theta, dtype=float).reshape(-1)
        if theta.shape != (structure.n_params,):
            raise DataError(
                f"theta has {theta.size} values but {structure!r} has {structure.n_params}"
            )
        check_finite(theta, "theta", DataError)
        dt = positive_real(dt, "dt", error=DataError, unit="s")
        self.structure = structure
        self.theta = theta
        self.theta.setflags(write=False)
        self.dt = dt
        self.param_std = None if param_std is None else np.asarray(param_std, dtype=float)
        self.noise_variance = None if noise_variance is None else float(noise_variance)
        self.input_names, self.output_name = channel_names(
            input_names, output_name, structure.n_inputs
        )

    @staticmethod
    def _check_structure(structure: Any) -> None:
        """Refuse a structure of another class (none is refused here)."""

    def _b_delayed(self, j: int) -> np.ndarray:
        """``B_j`` including the delay, in powers of ``q^-1``: ``[0]*nk + b``."""
        return np.concatenate([np.zeros(self.structure.nk[j]), self.b[j]])

    def _plant_control(self) -> control.TransferFunction:
        """The plant of every input (:meth:`_plant_tf`) as a python-control system."""
        import control

        parts = [self._plant_tf(j) for j in range(self.structure.n_inputs)]
        names = {"inputs": list(self.input_names), "outputs": [self.output_name]}
        if len(parts) == 1:
            return control.tf(*parts[0], self.dt, **names)
        return control.tf([[p[0] for p in parts]], [[p[1] for p in parts]], self.dt, **names)

    def _dlti(self, num: np.ndarray, den: np.ndarray) -> signal.dlti:
        """``num / den`` (equal lengths, positive powers of ``z``) as a SciPy ``dlti``."""
        from scipy import signal

        num = np.trim_zeros(num, "f")  # leading zeros are the delay; scipy warns about them
        return signal.dlti(num if num.size else [0.0], den, dt=self.dt)

    def _parameters_dict(self) -> dict[str, Any]:
        """The dictionary entries after the structure's orders (see ``to_dict``)."""
        return {
            "theta": self.theta.tolist(),
            "param_names": self.structure.param_names,
            "dt": self.dt,
            "param_std": None if self.param_std is None else self.param_std.tolist(),
            "noise_variance": self.noise_variance,
            "stable": self.is_stable,
            "max_pole_radius": self.max_pole_radius,
            "input_names": list(self.input_names),
            "output_name": self.output_name,
        }

    @classmethod
    def _from_entries(cls, structure: Any, d: Mapping[str, Any]) -> Any:
        """A model of ``structure`` with the parameters and names of a ``to_dict`` mapping
        (``theta`` required: a KeyError without it)."""
        return cls(
            structure,
            d["theta"],
            dt=d.get("dt", 1.0),
            param_std=d.get("param_std"),
            noise_variance=d.get("noise_variance"),
            input_names=d.get("input_names"),
            output_name=d.get("output_name"),
        )

    @classmethod
    def _read_json(cls, text: str, what: str) -> Any:
        """``from_dict`` of JSON text; a DataError naming ``what`` for text that is not JSON."""
        try:
            return cls.from_dict(json.loads(text))
        except json.JSONDecodeError as exc:
            raise DataError(f"not {what} in JSON: {exc}") from None

    def _summary_lines(self, title: str) -> list[str]:
        """The summary's lines: ``title``, the parameters, noise variance, poles, stability."""
        lines = [title]
        std = self.param_std
        for i, name in enumerate(self.structure.param_names):
            extra = f"  +- {std[i]:.3g}" if std is not None else ""
            lines.append(f"  {name:>8} = {self.theta[i]: .6g}{extra}")
        if self.noise_variance is not None:
            lines.append(f"  noise variance = {self.noise_variance:.4g}")
        p = self.poles()
        if p.size:
            poles = ", ".join(f"{z.real:.4f}{z.imag:+.4f}j" for z in p)
            lines.append(wrapped(f"poles: {poles}", indent="  ", hang="       "))
        lines.append(f"  {stability_words(self.is_stable, self.max_pole_radius, sep=', ')}")
        return lines


class ARXStructure:
    """The orders of an ARX model (MATLAB's ``[na nb nk]``).

    Parameters
    ----------
    na : int
        Number of ``A`` coefficients (poles), >= 0.
    nb : int or sequence of int
        Number of ``B`` coefficients per input, >= 0 (one value per input).
    nk : int or sequence of int, optional
        Input delay in samples per input, >= 0 (default 1).  A single value is used for
        every input.

    Attributes
    ----------
    kind : str
        ``"arx"``, the structure's name (as a polynomial structure's ``kind``).
    n_params : int
        ``na + sum(nb)``.
    start : int
        First sample with a complete regressor, ``max(na, max(nk_i + nb_i - 1))``.
    param_names : list of str
        ``["a1", ..., "b1", ...]`` (with ``[u_i]`` suffixes for several inputs).
    """

    kind = "arx"

    def __init__(self, na: int, nb: int | Sequence[int], nk: int | Sequence[int] = 1) -> None:
        (self.na,) = _orders(na, "na", 0)
        self.nb = _orders(nb, "nb", 0)
        nk_t = _orders(nk, "nk", 0)
        if len(nk_t) == 1 and len(self.nb) > 1:
            nk_t = nk_t * len(self.nb)
        if len(nk_t) != len(self.nb):
            raise ModelOrderError(
                f"nb has {len(self.nb)} value(s) but nk has {len(nk_t)}; give one per input"
            )
        self.nk = nk_t
        self.n_inputs = len(self.nb)
        self.n_params = self.na + sum(self.nb)
        if self.n_params == 0:
            raise ModelOrderError("the model has no parameters (na = 0 and nb = 0)")
        lags = [k + b - 1 for k, b in zip(self.nk, self.nb) if b > 0]
        self.start = max([self.na, *lags])

    @property
    def param_names(self) -> list[str]:
        """Parameter names in ``theta`` order, ``["a1", ..., "b1", ...]``.

        With several inputs each ``b`` name carries a ``[u_i]`` suffix (``"b1[u2]"``).
        """
        names = [f"a{i + 1}" for i in range(self.na)]
        for j, nb in enumerate(self.nb):
            suffix = f"[u{j + 1}]" if self.n_inputs > 1 else ""
            names += [f"b{i + 1}{suffix}" for i in range(nb)]
        return names

    def __repr__(self) -> str:
        nb = self.nb[0] if self.n_inputs == 1 else list(self.nb)
        nk = self.nk[0] if self.n_inputs == 1 else list(self.nk)
        return f"ARXStructure(na={self.na}, nb={nb}, nk={nk})"

    def __eq__(self, other: object) -> bool:
        return isinstance(other, ARXStructure) and (self.na, self.nb, self.nk) == (
            other.na,
            other.nb,
            other.nk,
        )

    def __hash__(self) -> int:
        return hash((self.na, self.nb, self.nk))

    def to_dict(self) -> dict[str, Any]:
        """The orders as a JSON-safe dictionary.

        Returns
        -------
        dict
            ``{"na": int, "nb": list of int, "nk": list of int}``; ``ARXStructure(**d)``
            rebuilds the structure.
        """
        return {"na": self.na, "nb": list(self.nb), "nk": list(self.nk)}

    def check_samples(self, n_samples: int) -> None:
        """Check that a record of ``n_samples`` leaves more equations than parameters.

        Parameters
        ----------
        n_samples : int
            Number of samples N in the record.

        Raises
        ------
        ModelOrderError
            If ``N - start <= n_params``.
        """
        _check_samples(self, n_samples, "equations")

    def regressors(self, u: Any, y: Any = None) -> tuple[np.ndarray, np.ndarray]:
        """Regressor matrix and target of the one-step equation ``y(t) = phi(t) theta + e(t)``.

        Parameters
        ----------
        u : array_like (N,) or (N, n_u), or IOData
            Inputs.
        y : array_like (N,), optional
            Output (omit when ``u`` is an IOData).

        Returns
        -------
        Phi : ndarray, shape (N - start, n_params)
            Row ``t - start`` is ``[-y(t-1) .. -y(t-na), u_1(t-nk_1) .. u_1(t-nk_1-nb_1+1), ..]``.
        target : ndarray, shape (N - start,)
            ``y(start:)``.
        """
        u, y = self._data(u, y)
        self.check_samples(y.shape[0])
        return self._phi(u, y, self.start), y[self.start :]

    def _data(self, u: Any, y: Any) -> tuple[np.ndarray, np.ndarray]:
        u, y = _io_arrays(u, y)
        if u.shape[1] != self.n_inputs:
            raise DataError(
                f"the model has {self.n_inputs} input(s) (len(nb)) but u has {u.shape[1]} columns"
            )
        return u, y

    def _phi(self, u: np.ndarray, y: np.ndarray, start: int) -> np.ndarray:
        n = y.shape[0]
        cols = [-y[start - i : n - i] for i in range(1, self.na + 1)]
        for j, (nb, nk) in enumerate(zip(self.nb, self.nk)):
            cols += [u[start - nk - i : n - nk - i, j] for i in range(nb)]
        return np.column_stack(cols) if cols else np.zeros((n - start, 0))

    def _phi_padded(self, u: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Regressors for every t >= 0 with zero pre-history (for one-step prediction)."""
        pad = self.start
        up = np.vstack([np.zeros((pad, u.shape[1])), u])
        yp = np.concatenate([np.zeros(pad), y])
        return self._phi(up, yp, pad)

    def least_squares(self, u: Any, y: Any = None, dt: float = 1.0) -> ARX:
        """Least-squares estimate (QR) with parameter standard deviations.

        Parameters
        ----------
        u, y : see :meth:`regressors`
            Or ``u`` a list of records (IOData or ``(u, y)`` pairs) and no ``y``: separate
            experiments, whose regressors are stacked (each from its own ``start``).
        dt : float
            Sample time in seconds (taken from an IOData when one is given).

        Returns
        -------
        ARX
            With ``param_std`` from ``sigma^2 (Phi' Phi)^-1`` and
            ``noise_variance = SSE / (K - n_params)``.
        """
        from ..data.records import IOData

        records = u if isinstance(u, list) and y is None else [u if y is None else (u, y)]
        if isinstance(records[0], IOData):
            dt = records[0].dt
        pairs = [self.regressors(*r) if isinstance(r, tuple) else self.regressors(r)
                 for r in records]  # fmt: skip
        phi = np.concatenate([p[0] for p in pairs])
        target = np.concatenate([p[1] for p in pairs])
        q, r = linalg.qr(phi, mode="economic")
        diag = np.abs(np.diag(r))
        if diag.size and diag.min() <= diag.max() * 1e-13:
            raise DataError(
                "the regressors are rank deficient (the input is not persistently exciting "
                f"for {self!r}); use lower orders or a richer input"
            )
        theta = linalg.solve_triangular(r, q.T @ target)
        resid = target - phi @ theta
        k = target.shape[0]
        sigma2 = float(resid @ resid) / (k - self.n_params)
        rinv = linalg.solve_triangular(r, np.eye(self.n_params))
        std = np.sqrt(sigma2 * np.sum(rinv * rinv, axis=1))
        return ARX(self, theta, dt=dt, param_std=std, noise_variance=sigma2)

    def model(self, theta: Any, dt: float = 1.0) -> ARX:
        """An ARX model of this structure with the given parameters.

        Parameters
        ----------
        theta : array_like, shape (n_params,)
            ``[a_1 .. a_na, b ...]`` in :attr:`param_names` order.
        dt : float, optional
            Sample time in seconds (default 1).

        Returns
        -------
        ARX
            The model, without ``param_std`` or ``noise_variance``.
        """
        return ARX(self, theta, dt=dt)


class ARX(_TransferModel):
    """An ARX model with its parameters.

    Parameters
    ----------
    structure : ARXStructure
    theta : array_like, shape (n_params,)
        ``[a_1 .. a_na, b ...]``.
    dt : float
        Sample time in seconds.
    param_std, noise_variance : optional
        Uncertainty from least squares.
    input_names : sequence of str, optional
        The inputs' channel names (default ``u``, or ``u1, u2, ..``).
    output_name : str, optional
        The output's channel name (default ``y``).
    """

    # ------------------------------------------------------------------ polynomials
    @property
    def a(self) -> np.ndarray:
        """``[1, a_1, ..., a_na]``, shape (na + 1,)."""
        return np.concatenate([[1.0], self.theta[: self.structure.na]])

    @property
    def b(self) -> list[np.ndarray]:
        """Per input, ``[b_1 .. b_nb]`` (first multiplies ``u(t - nk)``)."""
        out, i = [], self.structure.na
        for nb in self.structure.nb:
            out.append(self.theta[i : i + nb].copy())
            i += nb
        return out

    def _plant_tf(self, j: int) -> tuple[np.ndarray, np.ndarray]:
        """Numerator and denominator in positive powers of z (equal lengths)."""
        return _equal_lengths(self._b_delayed(j), self.a)

    # ------------------------------------------------------------------ prediction
    def predict(self, u: Any, y: Any = None) -> np.ndarray:
        """One-step-ahead prediction ``yhat(t) = phi(t) theta``; samples before t = 0 are 0.

        Parameters
        ----------
        u : array_like, shape (N,) or (N, n_u), or IOData
            Inputs, in the units of the identification data.
        y : array_like, shape (N,), optional
            Measured output (omit when ``u`` is an IOData).

        Returns
        -------
        ndarray, shape (N,)
            The predicted output, in the units of ``y``.
        """
        u, y = self.structure._data(u, y)
        return self.structure._phi_padded(u, y) @ self.theta

    def residuals(self, u: Any, y: Any = None) -> np.ndarray:
        """One-step prediction errors ``y - predict(u, y)``.

        Parameters
        ----------
        u : array_like, shape (N,) or (N, n_u), or IOData
            Inputs, in the units of the identification data.
        y : array_like, shape (N,), optional
            Measured output (omit when ``u`` is an IOData).

        Returns
        -------
        ndarray, shape (N,)
            The residuals, in the units of ``y``.
        """
        u, y = self.structure._data(u, y)
        return y - self.structure._phi_padded(u, y) @ self.theta

    def simulate(self, u: Any, y_init: Any = None) -> np.ndarray:
        """Free-run (output-error) simulation.

        Parameters
        ----------
        u : array_like (N,) or (N, n_u), or IOData
        y_init : array_like, optional
            Initial conditions: the first ``start`` outputs (measured values); the recursion
            runs from ``t = start`` and the first ``start`` samples of the result are
            ``y_init``.  Default: zero initial state (all signals zero before ``t = 0``).

        Returns
        -------
        ndarray, shape (N,)
        """
        from scipy import signal

        from ..data.records import IOData

        if isinstance(u, IOData):
            y_meas = u.y[:, 0] if u.n_outputs == 1 else None
            u = u.u
            if y_init is True and y_meas is not None:
                y_init = y_meas
        u = np.asarray(u, dtype=float)
        if u.ndim == 1:
            u = u[:, None]
        if u.ndim != 2 or u.shape[1] != self.structure.n_inputs:
            raise DataError(f"u must have {self.structure.n_inputs} column(s), got {u.shape}")
        check_finite(u, "u", DataError)
        n = u.shape[0]
        forced = np.zeros(n)
        for j in range(self.structure.n_inputs):
            forced += signal.lfilter(self._b_delayed(j), [1.0], u[:, j])
        s = self.structure.start
        if y_init is None or s == 0:
            return signal.lfilter([1.0], self.a, forced)
        y_init = np.asarray(y_init, dtype=float).reshape(-1)[:s]
        if y_init.size < s:
            raise DataError(f"y_init needs the first {s} outputs, got {y_init.size}")
        check_finite(y_init, "y_init", DataError)
        na = self.structure.na
        out = np.empty(n)
        out[:s] = y_init
        if n > s:
            # y(t) = forced(t) - sum a_i y(t-i) for t >= s, with y(s-1..s-na) = y_init
            zi = signal.lfiltic([1.0], self.a, y_init[::-1][:na]) if na else None
            if na:
                out[s:] = signal.lfilter([1.0], self.a, forced[s:], zi=zi)[0]
            else:
                out[s:] = forced[s:]
        return out

    # ------------------------------------------------------------------ poles, zeros
    def poles(self) -> np.ndarray:
        """The poles of the model.

        Returns
        -------
        ndarray of complex, shape (na,)
            Roots of ``z^na A(z^-1)`` (empty when ``na = 0``).
        """
        return np.roots(self.a) if self.structure.na else np.zeros(0, dtype=complex)

    def zeros(self, input: int = 0) -> np.ndarray:
        """The finite zeros of one input's numerator.

        Parameters
        ----------
        input : int, optional
            Input index, ``0 <= input < n_inputs`` (default 0).

        Returns
        -------
        ndarray of complex, shape (m,)
            Roots in z of ``B_input`` with its leading zero coefficients dropped; ``m`` is
            the number of remaining coefficients minus 1 (empty when fewer than 2 remain).
        """
        b = np.trim_zeros(self.b[input], "f")
        return np.roots(b) if b.size > 1 else np.zeros(0, dtype=complex)

    @property
    def is_stable(self) -> bool:
        """True if every pole lies strictly inside the unit circle."""
        return bool(_is_stable(self.theta[: self.structure.na])[0])

    @property
    def max_pole_radius(self) -> float:
        """Largest pole modulus ``max |p_i|`` (0.0 when ``na = 0``); below 1 means stable."""
        p = self.poles()
        return float(np.abs(p).max()) if p.size else 0.0

    # ------------------------------------------------------------------ export
    def to_control(self) -> control.TransferFunction:
        """The model as a python-control transfer function.

        Returns
        -------
        control.TransferFunction
            Discrete-time, 1 output x n_inputs, with sample time ``dt`` (s); the numerators
            include the input delays.
        """
        return self._plant_control()

    def to_dlti(self, input: int = 0) -> signal.dlti:
        """One input's transfer function as a SciPy discrete-time system.

        Parameters
        ----------
        input : int, optional
            Input index, ``0 <= input < n_inputs`` (default 0).

        Returns
        -------
        scipy.signal.dlti
            ``B_input(z) / A(z)`` with sample time ``dt`` (s).
        """
        return self._dlti(*self._plant_tf(input))

    def to_dict(self) -> dict[str, Any]:
        """The model as a JSON-safe dictionary; :meth:`from_dict` restores it exactly.

        Returns
        -------
        dict
            The orders (``na``, ``nb``, ``nk``), ``theta``, ``param_names``, ``dt`` (s),
            ``param_std``, ``noise_variance``, the channel names ``input_names`` and
            ``output_name``, and the derived ``stable`` and ``max_pole_radius``.
        """
        return {
            "na": self.structure.na,
            "nb": list(self.structure.nb),
            "nk": list(self.structure.nk),
            **self._parameters_dict(),
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> ARX:
        """Rebuild a model from :meth:`to_dict` output.

        Parameters
        ----------
        d : dict
            Needs ``na``, ``nb``, ``nk`` and ``theta``; ``dt`` (s, default 1),
            ``param_std`` and ``noise_variance`` are optional and other keys are ignored.

        Returns
        -------
        ARX
            The model.

        Raises
        ------
        DataError
            If a required key is missing or ``theta`` does not fit the orders.
        """
        try:
            return cls._from_entries(ARXStructure(d["na"], d["nb"], d["nk"]), d)
        except KeyError as exc:
            raise DataError(f"ARX dictionary lacks the key {exc.args[0]!r}") from None

    def to_json(self) -> str:
        """The model as JSON text (:meth:`to_dict` serialised; no NaN or infinity).

        Returns
        -------
        str
            JSON text that :meth:`from_json` reads back.
        """
        return json.dumps(jsonable(self.to_dict()), allow_nan=False)

    @classmethod
    def from_json(cls, text: str) -> ARX:
        """Rebuild a model from :meth:`to_json` text.

        Parameters
        ----------
        text : str
            JSON text of a :meth:`to_dict` dictionary.

        Returns
        -------
        ARX
            The model.

        Raises
        ------
        DataError
            If the text is not JSON or lacks a required key.
        """
        return cls._read_json(text, "an ARX model")

    def summary(self) -> str:
        """A multi-line, human-readable description of the model.

        Returns
        -------
        str
            The orders and ``dt``, each parameter (with its standard deviation when known),
            the noise variance, the poles and whether the model is stable.
        """
        title = f"ARX model {self.structure!r}, dt = {self.dt:g} s"
        return "\n".join(self._summary_lines(title))

    def __repr__(self) -> str:
        return f"ARX({self.structure!r}, theta={np.array2string(self.theta, precision=4)})"
