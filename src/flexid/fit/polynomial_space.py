"""The search space of a polynomial structure: stable ``A``, ``F_j``, ``D`` and minimum-phase
``C`` from a box, batched over a population.

Each monic polynomial of the structure is searched in one of the spaces of
:mod:`flexid.fit.parametrisation` (``"poles"``: pole pairs by radius and angle; ``"reflection"``:
lattice coefficients; ``"coefficients"``: the coefficients themselves), so every point of the
``"poles"`` and ``"reflection"`` boxes is a valid model: ``A``, ``F_j`` and ``D`` stable and
``C`` minimum phase (its roots in the same space, so ``1/C`` is a stable filter).  ``B``
enters the predictor linearly: with ``numerator="fit"`` it is not searched but fitted by
:meth:`flexid.costs.polynomial.PolynomialCost.fit_numerator` (variable projection); with
``"search"`` it is searched in a box.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import ConfigError
from ..models.arx import ARXStructure
from ..models.polynomial import PolynomialStructure
from ..models.vocabulary import REFLECTION_CAP
from .parametrisation import BOX_RADIUS, Parametrisation, make_parametrisation

__all__ = ["PolynomialSpace"]


class PolynomialSpace:
    """Search vectors ``z`` to parameters ``theta`` of a polynomial structure.

    The search vector is ``[z_A, z_C, z_D, z_F1, .., z_Fm]`` (each in its polynomial's own
    space, e.g. ``r1, w1, ..`` for pole pairs), followed by the ``b`` coefficients when
    ``numerator="search"``.

    Parameters
    ----------
    structure : PolynomialStructure
    parametrisation : {"poles", "reflection", "coefficients"}
    numerator : {"fit", "search"}
    b_lower, b_upper : ndarray, shape (sum nb,), optional
        Box of the ``b`` coefficients (``numerator="search"`` only).
    r_max, real_pairs, k_max : see :func:`flexid.fit.parametrisation.make_parametrisation`

    Attributes
    ----------
    n_search : int
    lower, upper : ndarray, shape (n_search,)
    labels : list of str
        ``"F: r1"``, ``"C: k1"``, ``"b3"``, ...
    """

    def __init__(
        self,
        structure: PolynomialStructure,
        parametrisation: str = "poles",
        numerator: str = "fit",
        *,
        b_lower: Any = None,
        b_upper: Any = None,
        r_max: float = BOX_RADIUS,
        real_pairs: int = 0,
        k_max: float = REFLECTION_CAP,
    ) -> None:
        self.structure = structure
        self.name = parametrisation
        self.numerator = numerator
        slices = structure.slices()
        self._maps: list[tuple[str, slice, Parametrisation]] = []
        lower, upper, labels = [], [], []
        named = [("a", slices["a"]), ("c", slices["c"]), ("d", slices["d"])]
        named += [(f"f{j + 1}" if structure.n_inputs > 1 else "f", s)
                  for j, s in enumerate(slices["f"])]
        for name, part in named:
            order = part.stop - part.start
            if order == 0:
                continue
            # the parametrisations map the A of an ARX structure; one without b is exactly a
            # map of one monic polynomial of this order
            pair = min(real_pairs, order // 2)
            param = make_parametrisation(
                parametrisation, ARXStructure(order, 0), b_lower=0.0, b_upper=0.0,
                r_max=r_max, real_pairs=pair, k_max=k_max,
            )
            self._maps.append((name, part, param))
            lower.append(param.lower)
            upper.append(param.upper)
            title = name.upper() if len(name) == 1 else f"F[u{name[1:]}]"
            labels += [f"{title}: {lab}" for lab in param.labels]
        b_cols = structure.b_columns
        self._b_cols = b_cols
        if numerator == "search":
            if b_lower is None or b_upper is None:
                raise ConfigError("numerator='search' needs the box of the b coefficients")
            b_lo = np.broadcast_to(np.asarray(b_lower, float), (b_cols.size,))
            b_hi = np.broadcast_to(np.asarray(b_upper, float), (b_cols.size,))
            lower.append(b_lo)
            upper.append(b_hi)
            names = structure.param_names
            labels += [names[i] for i in b_cols]
        elif numerator != "fit":
            raise ConfigError(f"numerator must be 'fit' or 'search', got {numerator!r}")
        self.lower = np.concatenate(lower) if lower else np.zeros(0)
        self.upper = np.concatenate(upper) if upper else np.zeros(0)
        self.n_search = self.lower.size
        self.labels = labels

    @property
    def stable_by_construction(self) -> bool:
        """True for ``"poles"`` and ``"reflection"``: every point of the box is a valid model."""
        return self.name != "coefficients"

    def to_theta(self, Z: Any) -> np.ndarray:
        """Map search vectors to ``theta`` (``b`` zero when it is fitted).

        Points outside the box are read as their projection on it in the stable spaces, so
        every candidate stays valid.

        Parameters
        ----------
        Z : array_like, shape (P, n_search) or (n_search,)

        Returns
        -------
        ndarray, shape (P, n_params) or (n_params,)
        """
        Z = np.asarray(Z, dtype=float)
        single = Z.ndim == 1
        Z = np.atleast_2d(Z)
        if Z.shape[1] != self.n_search:
            raise ConfigError(f"search vectors must have {self.n_search} entries, got {Z.shape}")
        if self.stable_by_construction:
            Z = np.clip(Z, self.lower, self.upper)
        theta = np.zeros((Z.shape[0], self.structure.n_params))
        i = 0
        for _, part, param in self._maps:
            n = param.na
            theta[:, part] = param.denominator(Z[:, i : i + n])
            i += n
        if self.numerator == "search":
            theta[:, self._b_cols] = Z[:, i:]
        return theta[0] if single else theta

    def from_theta(self, theta: Any) -> np.ndarray:
        """Search vectors of parameters (the inverse map; ``b`` dropped when it is fitted).

        Parameters
        ----------
        theta : array_like, shape (P, n_params) or (n_params,)

        Returns
        -------
        ndarray, shape (P, n_search) or (n_search,)
        """
        theta = np.asarray(theta, dtype=float)
        single = theta.ndim == 1
        theta = np.atleast_2d(theta)
        parts = [param.from_coefficients(theta[:, part]) for _, part, param in self._maps]
        if self.numerator == "search":
            parts.append(theta[:, self._b_cols])
        z = np.hstack(parts) if parts else np.zeros((theta.shape[0], 0))
        return z[0] if single else z

    def describe(self) -> str:
        """One line: what is searched, in which space, and what is fitted.

        Returns
        -------
        str
        """
        parts = []
        for name, _, param in self._maps:
            what = {"a": "A", "c": "C (roots)", "d": "D"}.get(name, "F" + name[1:])
            parts.append(f"{what}: {param._describe_a().rsplit('; every', 1)[0]}")
        text = f"{self.name} parametrisation of {self.structure!r}: " + "; ".join(parts)
        if self.numerator == "fit":
            return text + "; b fitted by least squares for each candidate (variable projection)"
        return text + f"; {self._b_cols.size} b coefficient(s) searched in a box"

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe description (name, structure, labels, bounds).

        Returns
        -------
        dict
        """
        return {
            "name": self.name,
            "structure": self.structure.to_dict(),
            "labels": list(self.labels),
            "bounds": {"lower": self.lower.tolist(), "upper": self.upper.tolist()},
        }
