"""The polynomial model family: ARX, ARMAX, output error (OE) and Box-Jenkins (BJ).

``A(q) y(t) = sum_j B_j(q)/F_j(q) u_j(t - nk_j) + C(q)/D(q) e(t)`` in MATLAB's convention
(``idpoly``): ``A, C, D, F_j`` are monic polynomials in ``q^-1``
(``A = 1 + a_1 q^-1 + ... + a_na q^-na``), ``B_j = b_j1 + b_j2 q^-1 + ... + b_j,nb_j
q^-(nb_j - 1)`` multiplies ``u_j(t - nk_j)``.  The named structures fix some polynomials to 1:

=========  ==============================  ===  ===  ===  ===  ===
structure  MATLAB                          A    B    C    D    F
=========  ==============================  ===  ===  ===  ===  ===
ARX        ``arx(data, [na nb nk])``       ✔    ✔    1    1    1
ARMAX      ``armax(data, [na nb nc nk])``  ✔    ✔    ✔    1    1
OE         ``oe(data, [nb nf nk])``        1    ✔    1    1    ✔
BJ         ``bj(data, [nb nc nd nf nk])``  1    ✔    ✔    ✔    ✔
=========  ==============================  ===  ===  ===  ===  ===

The parameter vector is ``theta = [a, b_1, .., b_m, c, d, f_1, .., f_m]`` (MATLAB's ``getpvec``
order for ``idpoly``); for ARX it is exactly :class:`flexid.models.arx.ARXStructure`'s.

Notes
-----
**Predictors.**  Every predictor of the family is one linear filter of the measured signals,
``den(q) yhat(t) = num_y(q) y(t) + sum_j num_j(q) u_j(t)``, with ``F = prod_j F_j``:

* **one-step** (the structure's own prediction error, ``e = D/C (A y - sum B_j/F_j u_j)``):
  ``den = C F``, ``num_y = C F - D A F``, ``num_j = D B_j q^-nk_j prod_(i != j) F_i``;
* **k steps ahead**: ``yhat_k = y - Hbar_k e`` with ``Hbar_k`` the first ``k`` impulse
  response coefficients of the noise model ``H = C/(A D)`` (Ljung, eq. 3.31), so
  ``num_y = C F - Hbar_k D A F`` and ``num_j = Hbar_k D B_j ...``;
* **simulation** (``k = inf``): ``den = A F``, ``num_y = 0``, ``num_j = B_j q^-nk_j prod_(i
  != j) F_i``.

:func:`run_predictor` runs any of them under one of three **initial-condition rules**, the
error always being counted over ``t >= start`` (:attr:`PolynomialStructure.start`, the first
sample where every term of every predictor uses measured data only):

``"estimate"``
    the predictor's initial state fitted by least squares to the measured output, as MATLAB
    ``compare`` and ``pem`` do by default.  :meth:`PolynomialModel.predict` and ``simulate``
    (and so every reported fit) fit the state at ``t = 0`` of the predictor's realisation
    (order ``max(deg den, deg num)``), and every sample counts, as in MATLAB; the costs and
    :func:`run_predictor` fit the direct form's ``n`` past outputs
    ``yhat(start-1..start-n)`` and count ``t >= start`` (the two differ by the samples the
    state is fitted to);
``"zero"``
    every signal zero before ``t = 0`` and the filter run from rest over the whole record;
``"measured"``
    the recursion started at ``t = start`` from the measured outputs
    ``yhat(t) = y(t), t < start``.

With a lightly damped high-order model the three differ a lot: the measured outputs are not
the model's state, and the mismatch starts a transient that may not die out within the
record; ``"estimate"`` removes that transient, ``"zero"`` suits a record that starts at rest.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy import linalg, signal

from .._json import jsonable
from .._validate import checked_keywords, integer
from ..errors import ConfigError, DataError, ModelOrderError, UnknownNameError, check_finite
from .arx import ARX, ARXStructure, _check_samples, _equal_lengths, _orders, _TransferModel
from .realisation import Path, accurate_roots, run_paths
from .vocabulary import STRUCTURE_NAMES

if TYPE_CHECKING:  # pragma: no cover - python-control loads on first use
    import control

__all__ = [
    "INITIAL_RULES",
    "STRUCTURES",
    "PolynomialModel",
    "PolynomialStructure",
    "run_predictor",
    "structure",
]

#: The named structures (:data:`flexid.config.STRUCTURE_NAMES`), each with the orders it takes
#: (``nk`` is optional everywhere).
STRUCTURES: dict[str, tuple[str, ...]] = dict(
    zip(
        STRUCTURE_NAMES,
        (
            ("na", "nb", "nk"),
            ("na", "nb", "nc", "nk"),
            ("nb", "nf", "nk"),
            ("nb", "nc", "nd", "nf", "nk"),
        ),
    )
)
_ORDER_NAMES = ("na", "nb", "nc", "nd", "nf", "nk")
_PER_INPUT = ("nb", "nf", "nk")

#: Initial-condition rules of every predictor and simulation (see the module docstring).
INITIAL_RULES: dict[str, str] = {
    "estimate": "initial state estimated by least squares",
    "zero": "from rest (signals zero before t = 0)",
    "measured": "started from the measured outputs",
}


class _UnknownInitialRule(UnknownNameError, ConfigError, DataError):
    """An unknown initial-condition rule: an :class:`~flexid.errors.UnknownNameError` naming
    the valid rules, and the :class:`~flexid.errors.ConfigError` of an estimator's option or
    the :class:`~flexid.errors.DataError` of :func:`flexid.validation.validate`, which is
    what each of them raises for a bad argument."""


def _check_initial(initial: Any, what: str = "initial-condition rule") -> str:
    """``initial`` if it names a rule of :data:`INITIAL_RULES`, else the error above."""
    if not isinstance(initial, str) or initial not in INITIAL_RULES:
        raise _UnknownInitialRule(what, str(initial), tuple(INITIAL_RULES))
    return initial


def _poly_mul(*polys: np.ndarray) -> np.ndarray:
    out = np.ones(1)
    for p in polys:
        out = np.convolve(out, p)
    return out


def _poly_sub(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    n = max(p.size, q.size)
    return np.pad(p, (0, n - p.size)) - np.pad(q, (0, n - q.size))


def _monic(coefficients: np.ndarray) -> np.ndarray:
    return np.concatenate([[1.0], coefficients])


# ================================================================================ structure
class PolynomialStructure:
    """The orders of a polynomial model ``A y = sum B_j/F_j u_j(t - nk_j) + C/D e``.

    Build one with :func:`structure` (by MATLAB name) or the class methods :meth:`arx`,
    :meth:`armax`, :meth:`oe` and :meth:`bj`; the constructor takes any combination.

    Parameters
    ----------
    na, nc, nd : int
        Orders of ``A``, ``C`` and ``D`` (>= 0).
    nb, nf, nk : int or sequence of int
        Per input: number of ``B`` coefficients (>= 0), order of ``F`` (>= 0) and input delay
        in samples (>= 0).  A single value is used for every input.
    kind : str, optional
        The name of the structure (``"arx"``, ``"armax"``, ``"oe"``, ``"bj"``), or
        ``"polynomial"`` for any other combination; inferred when omitted.

    Attributes
    ----------
    n_inputs : int
    n_params : int
        ``na + sum(nb) + nc + nd + sum(nf)``.
    start : int
        First sample where the one-step predictor and the simulation use measured data only
        (the degrees of their polynomials in :meth:`PolynomialModel.predictor_polynomials`);
        errors, fits and tests are counted from it.
    n_state : int
        Order of the one-step predictor's denominator ``C F``.
    n_state_simulation : int
        Order of the simulation's denominator ``A F``.
    """

    def __init__(
        self,
        na: int = 0,
        nb: int | Sequence[int] = 1,
        nc: int = 0,
        nd: int = 0,
        nf: int | Sequence[int] = 0,
        nk: int | Sequence[int] = 1,
        *,
        kind: str | None = None,
    ) -> None:
        (self.na,) = _orders(na, "na", 0)
        (self.nc,) = _orders(nc, "nc", 0)
        (self.nd,) = _orders(nd, "nd", 0)
        self.nb = _orders(nb, "nb", 0)
        m = len(self.nb)
        per_input = {}
        for name, value in (("nf", nf), ("nk", nk)):
            t = _orders(value, name, 0)
            if len(t) == 1 and m > 1:
                t = t * m
            if len(t) != m:
                raise ModelOrderError(
                    f"nb has {m} value(s) but {name} has {len(t)}; give one per input"
                )
            per_input[name] = t
        self.nf, self.nk = per_input["nf"], per_input["nk"]
        self.n_inputs = m
        self.n_params = self.na + sum(self.nb) + self.nc + self.nd + sum(self.nf)
        if sum(self.nb) == 0:
            raise ModelOrderError("the model has no B coefficients (every nb is 0)")
        inferred = self._infer_kind()
        if kind is None:
            kind = inferred
        elif kind not in STRUCTURES and kind != "polynomial":
            raise UnknownNameError("model structure", str(kind), (*STRUCTURES, "polynomial"))
        elif kind != "polynomial":
            # a named structure may have zero orders (ARMAX with nc = 0 is still named so),
            # but no polynomial it does not take
            nonzero = [k for k in ("na", "nc", "nd") if getattr(self, k)]
            nonzero += ["nf"] if any(self.nf) else []
            extra = [k for k in nonzero if k not in STRUCTURES[kind]]
            if extra:
                raise ModelOrderError(
                    f"the {kind} structure has no order {', '.join(extra)}; it takes "
                    f"{', '.join(STRUCTURES[kind])}"
                )
        self.kind = kind
        sf = sum(self.nf)
        # degree of each input's numerator in the simulation, delays included
        lags = [sf - nf + nk + nb - 1 for nb, nf, nk in zip(self.nb, self.nf, self.nk) if nb]
        self.n_state = self.nc + sf
        self.n_state_simulation = self.na + sf
        self.start = max(
            [self.n_state, max(self.nc, self.nd + self.na) + sf, self.n_state_simulation]
            + [self.nd + lag for lag in lags]
        )

    def _infer_kind(self) -> str:
        has = {k: getattr(self, k) != 0 for k in ("na", "nc", "nd")}
        has["nf"] = any(self.nf)
        if not (has["nc"] or has["nd"] or has["nf"]):
            return "arx"
        if has["na"] and has["nc"] and not (has["nd"] or has["nf"]):
            return "armax"
        if not (has["na"] or has["nc"] or has["nd"]):
            return "oe"
        if not has["na"] and has["nf"] and (has["nc"] or has["nd"]):
            return "bj"
        return "polynomial"

    # ------------------------------------------------------------------ named constructors
    @classmethod
    def arx(cls, na: int, nb: int | Sequence[int], nk: int | Sequence[int] = 1):
        """ARX ``[na nb nk]``: ``A y = B u(t - nk) + e``.

        Parameters
        ----------
        na : int
        nb, nk : int or sequence of int

        Returns
        -------
        PolynomialStructure
        """
        return cls(na=na, nb=nb, nk=nk, kind="arx")

    @classmethod
    def armax(cls, na: int, nb: int | Sequence[int], nc: int, nk: int | Sequence[int] = 1):
        """ARMAX ``[na nb nc nk]``: ``A y = B u(t - nk) + C e``.

        Parameters
        ----------
        na, nc : int
        nb, nk : int or sequence of int

        Returns
        -------
        PolynomialStructure
        """
        return cls(na=na, nb=nb, nc=nc, nk=nk, kind="armax")

    @classmethod
    def oe(cls, nb: int | Sequence[int], nf: int | Sequence[int], nk: int | Sequence[int] = 1):
        """Output error ``[nb nf nk]``: ``y = B/F u(t - nk) + e``.

        Parameters
        ----------
        nb, nf, nk : int or sequence of int

        Returns
        -------
        PolynomialStructure
        """
        return cls(nb=nb, nf=nf, nk=nk, kind="oe")

    @classmethod
    def bj(
        cls,
        nb: int | Sequence[int],
        nc: int,
        nd: int,
        nf: int | Sequence[int],
        nk: int | Sequence[int] = 1,
    ):
        """Box-Jenkins ``[nb nc nd nf nk]``: ``y = B/F u(t - nk) + C/D e``.

        Parameters
        ----------
        nb, nf, nk : int or sequence of int
        nc, nd : int

        Returns
        -------
        PolynomialStructure
        """
        return cls(nb=nb, nc=nc, nd=nd, nf=nf, nk=nk, kind="bj")

    # ------------------------------------------------------------------ description
    @property
    def orders(self) -> dict[str, Any]:
        """The orders the structure's name takes, MATLAB's order (``{"nb": .., "nf": ..}``).

        Per-input orders are ints for one input and lists for several.
        """
        names = STRUCTURES.get(self.kind, _ORDER_NAMES)
        out = {}
        for name in names:
            v = getattr(self, name)
            out[name] = (v[0] if self.n_inputs == 1 else list(v)) if name in _PER_INPUT else v
        return out

    def _orders_text(self) -> str:
        return ", ".join(f"{k}={v}" for k, v in self.orders.items())

    @property
    def has_noise_model(self) -> bool:
        """True when ``C`` or ``D`` is estimated (the one-step predictor differs from ``A``'s)."""
        return bool(self.nc or self.nd)

    @property
    def param_names(self) -> list[str]:
        """Parameter names in ``theta`` order: ``a1.., b1.., c1.., d1.., f1..``.

        With several inputs the ``b`` and ``f`` names carry a ``[u_i]`` suffix.
        """
        names = [f"a{i + 1}" for i in range(self.na)]
        multi = self.n_inputs > 1
        for j, nb in enumerate(self.nb):
            names += [f"b{i + 1}" + (f"[u{j + 1}]" if multi else "") for i in range(nb)]
        names += [f"c{i + 1}" for i in range(self.nc)]
        names += [f"d{i + 1}" for i in range(self.nd)]
        for j, nf in enumerate(self.nf):
            names += [f"f{i + 1}" + (f"[u{j + 1}]" if multi else "") for i in range(nf)]
        return names

    @property
    def b_columns(self) -> np.ndarray:
        """Indices in ``theta`` of every ``b`` coefficient, inputs in order (int array)."""
        return np.concatenate([np.arange(s.start, s.stop) for s in self.slices()["b"]])

    def slices(self) -> dict[str, Any]:
        """Where each polynomial sits in ``theta``.

        Returns
        -------
        dict
            ``"a"``, ``"c"``, ``"d"``: a slice each; ``"b"``, ``"f"``: a list of slices, one
            per input.
        """
        i = 0
        out: dict[str, Any] = {}
        out["a"] = slice(i, i + self.na)
        i += self.na
        out["b"] = []
        for nb in self.nb:
            out["b"].append(slice(i, i + nb))
            i += nb
        out["c"] = slice(i, i + self.nc)
        i += self.nc
        out["d"] = slice(i, i + self.nd)
        i += self.nd
        out["f"] = []
        for nf in self.nf:
            out["f"].append(slice(i, i + nf))
            i += nf
        return out

    def __repr__(self) -> str:
        name = self.kind.upper() if self.kind != "polynomial" else "Polynomial"
        return f"{name}({self._orders_text()})"

    def __eq__(self, other: object) -> bool:
        return isinstance(other, PolynomialStructure) and self._key() == other._key()

    def __hash__(self) -> int:
        return hash(self._key())

    def _key(self) -> tuple:
        return (self.na, self.nb, self.nc, self.nd, self.nf, self.nk)

    def to_dict(self) -> dict[str, Any]:
        """The structure as a JSON-safe dictionary; :meth:`from_dict` rebuilds it.

        Returns
        -------
        dict
            ``{"structure": kind, "na", "nb", "nc", "nd", "nf", "nk"}`` (per-input orders as
            lists).
        """
        return {
            "structure": self.kind,
            "na": self.na,
            "nb": list(self.nb),
            "nc": self.nc,
            "nd": self.nd,
            "nf": list(self.nf),
            "nk": list(self.nk),
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> PolynomialStructure:
        """Rebuild a structure from :meth:`to_dict` (or an ARX ``{"na", "nb", "nk"}``).

        Parameters
        ----------
        d : mapping
            Orders; missing ones are 0 (``nk``: 1).

        Returns
        -------
        PolynomialStructure
        """
        kind = d.get("structure")
        kind = None if kind == "polynomial" else kind
        try:
            return cls(
                na=d.get("na", 0),
                nb=d["nb"],
                nc=d.get("nc", 0),
                nd=d.get("nd", 0),
                nf=d.get("nf", 0),
                nk=d.get("nk", 1),
                kind=kind,
            )
        except KeyError as exc:
            raise DataError(f"a model structure needs the key {exc.args[0]!r}") from None

    def check_samples(self, n_samples: int) -> None:
        """Check that a record of ``n_samples`` leaves more error samples than parameters.

        Parameters
        ----------
        n_samples : int
            Number of samples N of the record.

        Raises
        ------
        ModelOrderError
            If ``N - start <= n_params``.
        """
        _check_samples(self, n_samples, "error samples")

    def model(self, theta: Any, dt: float = 1.0) -> PolynomialModel:
        """A model of this structure with the given parameters.

        Parameters
        ----------
        theta : array_like, shape (n_params,)
            In :attr:`param_names` order.
        dt : float, optional
            Sample time in seconds.

        Returns
        -------
        PolynomialModel
        """
        return PolynomialModel(self, theta, dt=dt)

    def arx_structure(self) -> ARXStructure:
        """The :class:`~flexid.models.arx.ARXStructure` of an ARX structure.

        Raises :class:`~flexid.errors.ModelOrderError` for another structure.

        Returns
        -------
        ARXStructure
        """
        if self.kind != "arx":
            raise ModelOrderError(f"{self!r} is not an ARX structure")
        return ARXStructure(self.na, self.nb, self.nk)


@checked_keywords(also=("na", "nb", "nc", "nd", "nf", "nk"))
def structure(name: str, **orders: Any) -> PolynomialStructure:
    """A structure by its MATLAB name and orders: ``structure("oe", nb=16, nf=16, nk=1)``.

    Parameters
    ----------
    name : {"arx", "armax", "oe", "bj"}
        The structure (case-insensitive).
    **orders : int or sequence of int
        The orders that structure takes (:data:`STRUCTURES`); ``nk`` defaults to 1, the
        others are required.  ``nb``, ``nf`` and ``nk`` take one value per input.

    Returns
    -------
    PolynomialStructure

    Raises
    ------
    UnknownNameError
        An unknown structure name.
    ModelOrderError
        An order the structure does not have (``nc`` with ``"oe"``), a missing order, or an
        invalid value.
    """
    key = str(name).lower()
    if key not in STRUCTURES:
        raise UnknownNameError("model structure", str(name), tuple(STRUCTURES))
    allowed = STRUCTURES[key]
    extra = [k for k in orders if k not in allowed and orders[k] is not None]
    if extra:
        raise ModelOrderError(
            f"the {key} structure has no order {', '.join(extra)}; it takes "
            f"{', '.join(allowed)}"
        )
    missing = [k for k in allowed if k != "nk" and orders.get(k) is None]
    if missing:
        raise ModelOrderError(
            f"the {key} structure needs the order(s) {', '.join(missing)} "
            f"(it takes {', '.join(allowed)})"
        )
    given = {k: v for k, v in orders.items() if v is not None}
    return PolynomialStructure(**given, kind=key)


# ================================================================================ predictor
def run_predictor(
    den: np.ndarray,
    num_y: np.ndarray,
    nums_u: Sequence[np.ndarray],
    u: np.ndarray,
    y: np.ndarray,
    start: int,
    initial: str,
) -> tuple[np.ndarray, np.ndarray]:
    """Run ``den(q) yhat = num_y(q) y + sum_j num_j(q) u_j`` under an initial-condition rule.

    The reference route (``scipy.signal.lfilter``, one model); the batched costs are checked
    against it.

    Parameters
    ----------
    den : ndarray, shape (n + 1,)
        Monic denominator in powers of ``q^-1``.
    num_y : ndarray
        Numerator of the output (its leading coefficient 0: the predictor is causal).
    nums_u : sequence of ndarray
        Numerator of each input, delays included.
    u : ndarray, shape (N, n_u)
    y : ndarray, shape (N,)
        Measured output (used by ``num_y`` and by the rules ``"measured"``/``"estimate"``).
    start : int
        First counted sample; at least the degree of every polynomial.
    initial : {"estimate", "zero", "measured"}

    Returns
    -------
    yhat : ndarray, shape (N,)
        The prediction; under ``"measured"`` and ``"estimate"`` the samples before ``start``
        are the measured outputs.
    x0 : ndarray, shape (n,)
        The past outputs ``yhat(start-1), .., yhat(start-n)`` the recursion started from
        (zeros under ``"zero"``, where the filter runs from ``t = 0``).
    """
    n = den.size - 1
    degrees = [n, num_y.size - 1, *[p.size - 1 for p in nums_u]]
    start = max(start, *degrees)  # a k-step predictor reaches further back
    forced = np.zeros(y.size)
    if np.any(num_y):
        forced += signal.lfilter(num_y, [1.0], y)
    for j, num in enumerate(nums_u):
        if np.any(num):
            forced += signal.lfilter(num, [1.0], u[:, j])
    if initial == "zero" or n == 0:
        out = signal.lfilter([1.0], den, forced) if n else forced
        if n == 0 and initial != "zero":
            out = out.copy()
            out[:start] = y[:start]
        return out, np.zeros(n)
    out = y.astype(float).copy()
    f = forced[start:]
    if initial == "measured":
        x0 = y[start - n : start][::-1].copy()
    else:  # estimate: the free responses to unit past outputs span the initial state
        base = signal.lfilter([1.0], den, f)
        free = np.empty((f.size, n))
        for i in range(n):
            past = np.zeros(n)
            past[i] = 1.0
            free[:, i] = signal.lfilter(
                [1.0], den, np.zeros(f.size), zi=signal.lfiltic([1.0], den, past)
            )[0]
        x0 = linalg.lstsq(free, y[start:] - base)[0]
    zi = signal.lfiltic([1.0], den, x0)
    out[start:] = signal.lfilter([1.0], den, f, zi=zi)[0]
    return out, x0


# ================================================================================ model
class PolynomialModel(_TransferModel):
    """A polynomial model (ARX, ARMAX, OE, BJ or general) with its parameters.

    Parameters
    ----------
    structure : PolynomialStructure
    theta : array_like, shape (n_params,)
        In ``structure.param_names`` order.
    dt : float
        Sample time in seconds.
    param_std : array_like, shape (n_params,), optional
        Standard errors of ``theta``.
    noise_variance : float, optional
        Variance of the innovation ``e`` (output units squared).
    input_names : sequence of str, optional
        The inputs' channel names (default ``u``, or ``u1, u2, ..``).
    output_name : str, optional
        The output's channel name (default ``y``).
    """

    @staticmethod
    def _check_structure(structure: Any) -> None:
        """Refuse a structure that is not a :class:`PolynomialStructure`."""
        if not isinstance(structure, PolynomialStructure):
            raise DataError(
                f"structure must be a PolynomialStructure, got {type(structure).__name__}"
            )

    # ------------------------------------------------------------------ polynomials
    def _part(self, key: str) -> np.ndarray:
        return _monic(self.theta[self.structure.slices()[key]])

    @property
    def a(self) -> np.ndarray:
        """``[1, a_1, .., a_na]``."""
        return self._part("a")

    @property
    def c(self) -> np.ndarray:
        """``[1, c_1, .., c_nc]``."""
        return self._part("c")

    @property
    def d(self) -> np.ndarray:
        """``[1, d_1, .., d_nd]``."""
        return self._part("d")

    @property
    def b(self) -> list[np.ndarray]:
        """Per input ``[b_1 .. b_nb]`` (the first multiplies ``u(t - nk)``)."""
        return [self.theta[s].copy() for s in self.structure.slices()["b"]]

    @property
    def f(self) -> list[np.ndarray]:
        """Per input ``[1, f_1, .., f_nf]``."""
        return [_monic(self.theta[s]) for s in self.structure.slices()["f"]]

    # ------------------------------------------------------------------ predictors
    def predictor_polynomials(
        self, k: float = 1
    ) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
        """The ``k``-step predictor as one filter ``den yhat = num_y y + sum_j num_j u_j``.

        Parameters
        ----------
        k : int or inf
            Prediction horizon in samples (>= 1); ``inf`` is the simulation.

        Returns
        -------
        den : ndarray
            Monic denominator in powers of ``q^-1``.
        num_y : ndarray
            Numerator of the measured output (zero for the simulation).
        nums_u : list of ndarray
            Numerator of each input, delays included.
        """
        f_all = _poly_mul(*self.f)
        nums = []
        for j in range(self.structure.n_inputs):
            others = [fi for i, fi in enumerate(self.f) if i != j]
            nums.append(_poly_mul(self._b_delayed(j), *others))
        if k == np.inf:
            return _poly_mul(self.a, f_all), np.zeros(1), nums
        k = integer(k, "prediction horizon k", error=DataError, minimum=1)
        ad = _poly_mul(self.a, self.d)
        den = _poly_mul(self.c, f_all)
        if k == 1:
            hbar = np.ones(1)
        else:
            impulse = np.zeros(k)
            impulse[0] = 1.0
            hbar = signal.lfilter(self.c, ad, impulse)
        num_y = _poly_sub(den, _poly_mul(hbar, ad, f_all))
        num_y[0] = 0.0  # exactly: both terms are monic
        nums_u = [_poly_mul(hbar, self.d, n) for n in nums]
        return den, num_y, nums_u

    def _signals(self, u: Any, y: Any, need_y: bool) -> tuple[np.ndarray, np.ndarray | None]:
        from ..data.records import IOData

        if isinstance(u, IOData):
            if y is not None:
                raise DataError("pass either an IOData or (u, y) arrays, not both")
            if u.n_outputs != 1:
                raise DataError(f"the record has {u.n_outputs} outputs; select one first")
            u, y = u.u, u.y[:, 0]
        u = np.asarray(u, dtype=float)
        if u.ndim == 1:
            u = u[:, None]
        if u.ndim != 2 or u.shape[1] != self.structure.n_inputs:
            raise DataError(
                f"u must have {self.structure.n_inputs} column(s), got shape {u.shape}"
            )
        check_finite(u, "u", DataError)
        if y is None:
            if need_y:
                raise DataError("the measured output y is needed (prediction, or the "
                                "initial-condition rules 'estimate' and 'measured')")
            return u, None
        y = np.asarray(y, dtype=float).reshape(-1)
        if y.size != u.shape[0]:
            raise DataError(f"u has {u.shape[0]} samples but y has {y.size}")
        check_finite(y, "y", DataError)
        if u.shape[0] <= self.structure.start and need_y:
            raise ModelOrderError(
                f"a record of {u.shape[0]} samples does not reach past the model's first "
                f"counted sample (start = {self.structure.start})"
            )
        return u, y

    def predict(
        self, u: Any, y: Any = None, *, k: float = 1, initial: str = "estimate",
        from_start: bool = False,
    ) -> np.ndarray:
        """``k``-step-ahead prediction of the output.

        Parameters
        ----------
        u : array_like, shape (N,) or (N, n_u), or IOData
            Inputs.
        y : array_like, shape (N,), optional
            Measured output (omit when ``u`` is an IOData).
        k : int or inf, optional
            Horizon in samples (default 1, the one-step predictor the structure is estimated
            with); ``inf`` gives the simulation.
        initial : {"estimate", "zero", "measured"}, optional
            Initial-condition rule (see the module docstring; default ``"estimate"``).
        from_start : bool, optional
            Under ``"estimate"``, fit the direct form's state at ``t = start`` (the costs'
            rule, the samples before it the measured outputs) instead of the state at
            ``t = 0`` (MATLAB's, the default).

        Returns
        -------
        ndarray, shape (N,)
            The prediction in output units (the samples before ``structure.start`` are the
            measured outputs under ``"measured"``, and under ``"estimate"`` with
            ``from_start``).

        Notes
        -----
        ``k = 1`` and ``inf`` under ``"estimate"`` and ``"zero"`` run in a well-conditioned
        realisation (:meth:`realisation`); other horizons and ``"measured"`` (a direct-form
        rule by definition) in the direct form (:func:`run_predictor`), which lightly damped
        high-order models make inaccurate.
        """
        initial = _check_initial(initial)
        u, y = self._signals(u, y, need_y=True)
        return self._run(k, u, y, initial, from_start)

    def residuals(
        self, u: Any, y: Any = None, *, initial: str = "estimate", from_start: bool = False
    ) -> np.ndarray:
        """One-step prediction errors ``y - predict(u, y)``: the innovations' estimate.

        Parameters
        ----------
        u, y : see :meth:`predict`
        initial : {"estimate", "zero", "measured"}, optional
        from_start : bool, optional
            See :meth:`predict`.

        Returns
        -------
        ndarray, shape (N,)
        """
        u, y = self._signals(u, y, need_y=True)
        return y - self.predict(u, y, initial=initial, from_start=from_start)

    def simulate(
        self, u: Any, y: Any = None, *, initial: str = "zero", from_start: bool = False
    ) -> np.ndarray:
        """Free-run simulation ``y_sim = sum_j B_j/(A F_j) u_j(t - nk_j)``.

        Parameters
        ----------
        u : array_like, shape (N,) or (N, n_u), or IOData
            Inputs.
        y : array_like, shape (N,), optional
            Measured output, needed by ``"estimate"`` and ``"measured"``.
        initial : {"zero", "estimate", "measured"}, optional
            Initial-condition rule (default ``"zero"``: from rest).
        from_start : bool, optional
            See :meth:`predict`.

        Returns
        -------
        ndarray, shape (N,)
        """
        initial = _check_initial(initial)
        u, y = self._signals(u, y, need_y=initial != "zero")
        return self._run(np.inf, u, y, initial, from_start)

    def _run(
        self, k: float, u: np.ndarray, y: np.ndarray | None, initial: str, from_start: bool
    ) -> np.ndarray:
        """The ``k``-step prediction (``inf``: the simulation) of checked signals: in the
        realisation for ``k`` 1 or ``inf`` under ``"zero"`` and ``"estimate"``, else in the
        direct form (see :meth:`predict`)."""
        if k in (1, np.inf) and initial != "measured":
            return self._run_realised(k, u, y, initial, from_start)
        den, num_y, nums = self.predictor_polynomials(k)
        return run_predictor(den, num_y, nums, u, y, self.structure.start, initial)[0]

    # ------------------------------------------------------------------ realisation
    def _roots(self, key: str, j: int = 0) -> np.ndarray:
        """Accurate roots of ``A``, ``C``, ``D`` or input ``j``'s ``F`` or ``B`` (cached)."""
        cache = self.__dict__.setdefault("_root_cache", {})
        if (key, j) not in cache:
            poly = {"a": lambda: self.a, "c": lambda: self.c, "d": lambda: self.d,
                    "f": lambda: self.f[j], "b": lambda: self.b[j]}[key]()
            cache[key, j] = accurate_roots(poly)
        return cache[key, j].copy()

    def realisation(self, k: float = 1) -> tuple[list[Path], np.ndarray, bool]:
        """The one-step predictor (``k = 1``) or simulation (``k = inf``) as second-order
        sections, well conditioned for lightly damped high-order models.

        Parameters
        ----------
        k : {1, inf}

        Returns
        -------
        paths : list of Path
            One per input (``D B_j / (C F_j)`` one-step, ``B_j / (A F_j)`` simulated;
            signal ``j + 1``) and, one-step with ``A``, ``C`` or ``D``, the measured output's
            ``D A / C`` (signal 0) to subtract from ``y``.
        modes : ndarray of complex
            The poles of the direct form's denominator (``C F`` or ``A F``) with multiplicity:
            the span of its free responses.
        uses_y : bool
            Whether the prediction is ``y`` less the output path (one-step with ``A``, ``C``
            or ``D``).
        """
        s = self.structure
        one_step = k != np.inf
        noise = [] if not one_step else [self._roots("d")]
        den = self._roots("c") if one_step else self._roots("a")
        paths = []
        uses_y = one_step and (s.na + s.nc + s.nd) > 0
        if uses_y:
            zeros = np.concatenate([self._roots("d"), self._roots("a")])
            paths.append(Path(0, zeros, self._roots("c"), 1.0, 0, sign=-1.0))
        modes = [den]
        for j in range(s.n_inputs):
            b = self.b[j]
            nonzero = np.flatnonzero(b)
            modes.append(self._roots("f", j))
            if nonzero.size == 0:
                continue
            lead = int(nonzero[0])
            zeros = np.concatenate([*noise, self._roots("b", j)])
            poles = np.concatenate([den, self._roots("f", j)])
            paths.append(Path(j + 1, zeros, poles, float(b[lead]), s.nk[j] + lead))
        return paths, np.concatenate(modes), uses_y

    def _run_realised(
        self, k: float, u: np.ndarray, y: np.ndarray | None, initial: str,
        from_start: bool = False,
    ) -> np.ndarray:
        """The one-step prediction or simulation by :meth:`realisation` under ``"zero"`` or
        ``"estimate"``, without the direct form's rounding (:mod:`flexid.models.realisation`).

        ``"estimate"`` fits the initial state at ``t = 0`` of the predictor's realisation
        (MATLAB ``compare``'s): its free responses are the modes of the direct form's
        denominator and, where a numerator reaches further back than the denominator, the
        first samples alone.  ``from_start``: the costs' rule instead, the state at
        ``t = start`` of the direct form (:func:`run_predictor`), the samples before it the
        measured outputs.
        """
        paths, modes, uses_y = self.realisation(k)
        n = u.shape[0]
        y_col = np.zeros(n) if y is None else y
        signals = np.column_stack([y_col, u])
        den, num_y, nums = self.predictor_polynomials(k)
        reach = max(num_y.size - 1, *[p.size - 1 for p in nums])  # the numerators' memory
        n_den = den.size - 1
        if from_start:  # the direct form's first sample: every polynomial's degree
            start = max(self.structure.start, n_den, reach)
            leading = 0
        else:  # a realisation of order max(n_den, reach): the extra poles at 0 free the
            start = 0  # first samples (and a root at exactly 0 gives no mode: the same)
            leading = max(n_den, reach) - int(np.count_nonzero(modes))
        if initial == "estimate" and start + leading >= n:
            raise ModelOrderError(
                f"a record of {n} samples does not reach past the predictor's first sample "
                f"(start = {start + leading})"
            )
        return run_paths(paths, signals, start=start, initial=initial, modes=modes,
                         target=y, offset=y_col if uses_y else None,
                         leading=leading)  # fmt: skip

    # ------------------------------------------------------------------ poles, zeros
    def poles(self) -> np.ndarray:
        """Poles of the plant part: the roots of ``A`` and of every ``F_j``.

        Correct to about one unit in the last place (:func:`~flexid.models.realisation.
        accurate_roots`), also where :func:`numpy.roots` is not (clustered lightly damped
        poles).

        Returns
        -------
        ndarray of complex
        """
        parts = [self._roots("a"), *(self._roots("f", j) for j in range(self.structure.n_inputs))]
        return np.concatenate(parts).astype(complex)

    def zeros(self, input: int = 0) -> np.ndarray:
        """Finite zeros of one input's ``B`` (leading zero coefficients dropped).

        Parameters
        ----------
        input : int, optional

        Returns
        -------
        ndarray of complex
        """
        return self._roots("b", input)

    def noise_poles(self) -> np.ndarray:
        """Poles of the noise model ``C/(A D)``: the roots of ``A`` and ``D``.

        Returns
        -------
        ndarray of complex
        """
        return np.concatenate([self._roots("a"), self._roots("d")]).astype(complex)

    def noise_zeros(self) -> np.ndarray:
        """Zeros of the noise model: the roots of ``C`` (inside the unit circle when the
        predictor is stable).

        Returns
        -------
        ndarray of complex
        """
        return self._roots("c")

    @property
    def max_pole_radius(self) -> float:
        """Largest modulus of the plant's poles (0.0 without poles)."""
        p = self.poles()
        return float(np.abs(p).max()) if p.size else 0.0

    @property
    def is_stable(self) -> bool:
        """True if every pole of the plant (``A`` and every ``F_j``) is inside the unit circle."""
        from .stability import is_stable

        return all(bool(is_stable(p[None, 1:])[0]) for p in (self.a, *self.f) if p.size > 1)

    @property
    def predictor_stable(self) -> bool:
        """True if the one-step predictor is stable: ``C`` and every ``F_j`` inside the circle."""
        from .stability import is_stable

        return all(bool(is_stable(p[None, 1:])[0]) for p in (self.c, *self.f) if p.size > 1)

    # ------------------------------------------------------------------ export
    def _plant_tf(self, j: int) -> tuple[np.ndarray, np.ndarray]:
        """Input ``j``'s ``B_j q^-nk_j / (A F_j)`` in positive powers of z (equal lengths)."""
        return _equal_lengths(self._b_delayed(j), _poly_mul(self.a, self.f[j]))

    def _noise_tf(self) -> tuple[np.ndarray, np.ndarray]:
        """The noise model ``C / (A D)`` in positive powers of z (equal lengths)."""
        return _equal_lengths(self.c, _poly_mul(self.a, self.d))

    def to_control(self, *, noise: bool = False) -> control.TransferFunction:
        """The plant ``B/(A F)`` (or the noise model ``C/(A D)``) as a python-control system.

        Parameters
        ----------
        noise : bool, optional
            Return the noise model ``H = C/(A D)`` (input ``e``, unit variance scale: multiply
            by ``sqrt(noise_variance)`` for the innovation's level) instead of the plant.

        Returns
        -------
        control.TransferFunction
            Discrete time with sample time ``dt`` (s); 1 output x n_inputs for the plant.
        """
        if noise:
            import control

            outputs = [self.output_name]
            return control.tf(*self._noise_tf(), self.dt, inputs=["e"], outputs=outputs)
        return self._plant_control()

    def to_dlti(self, input: int = 0, *, noise: bool = False) -> signal.dlti:
        """One input's plant ``B/(A F)`` (or the noise model) as a SciPy ``dlti``.

        Parameters
        ----------
        input : int, optional
            Input index (ignored with ``noise=True``).
        noise : bool, optional
            Return the noise model ``C/(A D)``.

        Returns
        -------
        scipy.signal.dlti
            With sample time ``dt`` (s).
        """
        return self._dlti(*(self._noise_tf() if noise else self._plant_tf(input)))

    def to_dict(self) -> dict[str, Any]:
        """The model as a JSON-safe dictionary; :meth:`from_dict` restores it.

        Returns
        -------
        dict
            The structure's orders (:meth:`PolynomialStructure.to_dict`), ``theta``,
            ``param_names``, ``dt`` (s), ``param_std``, ``noise_variance``, the channel names
            ``input_names`` and ``output_name``, and the derived ``stable`` and
            ``max_pole_radius``.
        """
        return {
            **self.structure.to_dict(),
            **self._parameters_dict(),
        }

    @classmethod
    def from_arx(cls, model: ARX) -> PolynomialModel:
        """An ARX model as a polynomial model of the same structure and parameters.

        Parameters
        ----------
        model : ARX
            The model (:class:`~flexid.models.arx.ARX`).

        Returns
        -------
        PolynomialModel
            Of ``PolynomialStructure.arx(na, nb, nk)``, with the same ``theta`` (the order
            is the same), ``dt``, ``param_std`` and ``noise_variance``; its predictors take
            the initial-condition rules of :mod:`flexid.models.polynomial`.

        Raises
        ------
        ModelOrderError
            If every ``nb`` is 0 (a pure AR model has no polynomial-family form).
        """
        s = model.structure
        return cls(
            PolynomialStructure.arx(s.na, s.nb, s.nk),
            model.theta,
            dt=model.dt,
            param_std=None if model.param_std is None else model.param_std.copy(),
            noise_variance=model.noise_variance,
            input_names=getattr(model, "input_names", None),
            output_name=getattr(model, "output_name", None),
        )

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> PolynomialModel:
        """Rebuild a model from :meth:`to_dict` (an ARX model's dictionary reads too).

        Parameters
        ----------
        d : mapping

        Returns
        -------
        PolynomialModel
        """
        if "theta" not in d:
            raise DataError("a model dictionary needs the key 'theta'")
        return cls._from_entries(PolynomialStructure.from_dict(d), d)

    def to_json(self) -> str:
        """:meth:`to_dict` as JSON text (no NaN or infinity).

        Returns
        -------
        str
        """
        return json.dumps(jsonable(self.to_dict()), allow_nan=False)

    @classmethod
    def from_json(cls, text: str) -> PolynomialModel:
        """Rebuild a model from :meth:`to_json` text.

        Parameters
        ----------
        text : str

        Returns
        -------
        PolynomialModel
        """
        return cls._read_json(text, "a polynomial model")

    def summary(self) -> str:
        """A readable account: structure, parameters with standard errors, poles, stability.

        Returns
        -------
        str
        """
        s = self.structure
        lines = self._summary_lines(f"{s!r} model, dt = {self.dt:g} s")
        if s.nc:
            r = np.abs(self.noise_zeros()).max()
            lines.append(
                f"  C {'minimum phase' if r < 1 else 'NOT minimum phase'}, largest root "
                f"radius {r:.6f}"
            )
        return "\n".join(lines)

    def __repr__(self) -> str:
        return (
            f"PolynomialModel({self.structure!r}, "
            f"theta={np.array2string(self.theta, precision=4)})"
        )
