"""The batched simulation cost of the modal state-space structure, by variable projection.

:class:`ModalCost` scores a population of modal parameter vectors (natural frequencies,
damping ratios, corner frequencies; see :class:`flexid.models.statespace.StateSpaceStructure`)
on a record with any number of inputs and outputs.  For fixed poles the simulated output
is linear in every sensor's gains ``C``, in ``D`` and in the initial state, so each
candidate's are fitted by linear least squares (variable projection: Golub & Pereyra 1973;
Ljung, *System Identification*, 2nd ed., sec. 7.3 "separable least squares"), and every
candidate is stable.

Notes
-----
For each candidate the regressors are each input filtered through each mode's
``1 / (1 + a1 q^-1 + a2 q^-2)`` and each real pole's ``1 / (1 - p q^-1)``, delayed by one
and two samples: the states of the structure's realisation
(:func:`flexid.kernels.modal_regressors`; their normal equations and errors,
:func:`~flexid.kernels.modal_normal` and :func:`~flexid.kernels.modal_residual`, are
compiled where the polynomial costs are).
Under ``initial="estimate"``:

1. the gains are fitted together with each output's own free response (two columns per
   mode and one per real pole, shared by the outputs), so that a transient at the record's
   start does not bias them;
2. the realisation's initial state ``x0`` is then fitted to what remains, jointly over the
   outputs (each output's free response is ``C A^t x0``: its modes' shapes are shared).

With one output step 2 reaches the same fit as step 1 (the free responses span the same
functions).  The cost is the metric of the residual of the realised model: a
:func:`scipy.signal.dlsim` of :meth:`ModalCost.model` of a candidate gives the same errors
to rounding.  With several outputs each output's errors are divided by its standard
deviation before they are summed (its fit's denominator), so that the outputs count alike
whatever their units.

The compiled route never stores the regressors: each candidate's rows are made a block at a
time, summed into its normal equations and dropped, and its fit (both steps) is solved in the
same call (:func:`flexid.kernels.modal_fit`); no BLAS call is left to thread small products
(which OpenBLAS would, at a large cost, on a busy machine).  The cost's sum of squares is read
from the normal equations, ``|y|^2 - 2 c' phi'y + c' G c``, where its rounding bound allows
(:meth:`ModalCost._expanded_sse`: within :data:`EXPANSION_TOLERANCE` of the errors' own sum,
about 1e-10 at worst as measured), and summed from the errors themselves elsewhere (a
near-perfect fit, or gains that cancel on nearly collinear columns); :meth:`residuals`
always makes the errors.

Each least-squares problem is solved by its normal equations, scaled to a unit diagonal
with a ridge of ``1e-10`` (:data:`RIDGE`): a damping ratio of 1 makes a mode's two columns
nearly collinear, and the fit then takes the well-determined part.  The normal equations
square the regressors' condition number; ``residuals(..., orthogonal=True)`` solves the same
problems by QR factors of the stored regressors, for the reference's last steps and its
optimality test (:func:`flexid.fit.statespace_fit.refine`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .. import kernels
from ..data.records import IOData
from ..errors import DataError, ModelOrderError
from ..models.statespace import StateSpaceModel, StateSpaceStructure
from .metrics import metric_from_sse

__all__ = ["ModalCost"]

#: Ridge added to the unit diagonal of the scaled normal equations: it bounds their
#: condition number by about ``1 / RIDGE`` where columns are collinear (repeated or critically
#: damped poles, a mode at the record's lowest frequency) and changes a well-posed fit by a
#: relative ``RIDGE``, far below the noise of any record.
RIDGE = 1e-10

#: A bound on the rounding error of one entry of the normal equations, relative to
#: ``sqrt(G_ii G_jj)``: ``(64 + N / 64)`` roundings of a sum over blocks of 64 rows, for
#: records of up to about 100,000 samples (``2^-53 (64 + 1600)``).
SUM_ROUNDING = 2e-13

#: The largest rounding error, relative to the sum of squares itself, that the cost may carry
#: when read from the normal equations instead of from the errors
#: (:meth:`ModalCost._expanded_sse`).  The bound it is checked against is a worst case: the
#: errors measured on the manipulator's populations, in the box and around ``ssest``'s
#: minimum, were 1e-3 of the bound or less, 1e-10 of the sum at most; far below the 3 %
#: (``1 / sqrt(N)`` at N = 1,500) at which two candidates' costs differ significantly.
EXPANSION_TOLERANCE = 1e-6


def _solve(gram: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Normal equations of every candidate: ``gram`` (P, k, k), ``rhs`` (P, k, q) -> (P, k, q).

    Scaled to a unit diagonal, with a ridge of :data:`RIDGE`: it keeps the solve defined
    where columns are (nearly) collinear, taking the well-determined part of the fit there,
    as a truncated pseudo-inverse would.
    """
    norms = np.sqrt(np.abs(np.einsum("pkk->pk", gram)))
    norms[norms == 0.0] = 1.0
    scaled = gram / (norms[:, :, None] * norms[:, None, :])
    scaled[:, np.arange(gram.shape[1]), np.arange(gram.shape[1])] += RIDGE
    return np.linalg.solve(scaled, rhs / norms[:, :, None]) / norms[:, :, None]


def _solve_orthogonal(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The problem of :func:`_solve` from the regressors themselves: ``A`` (P, n, k), ``b``
    (P, n, q) -> (P, k, q).

    ``min |A c - b|^2 + RIDGE |D c|^2`` (``D`` the column norms: the scaled ridge of
    :func:`_solve`) by a QR factorisation of ``A``'s scaled columns stacked on the ridge's
    rows, so its error grows as ``cond(A)``, not as ``cond(A)**2``.
    """
    P, _, k = A.shape
    norms = np.linalg.norm(A, axis=1)
    norms[norms == 0.0] = 1.0
    ridge = np.broadcast_to(np.sqrt(RIDGE) * np.eye(k), (P, k, k))
    Q, R = np.linalg.qr(np.concatenate([A / norms[:, None, :], ridge], axis=1))
    padded = np.concatenate([b, np.zeros((P, k, b.shape[2]))], axis=1)
    return np.linalg.solve(R, np.swapaxes(Q, 1, 2) @ padded) / norms[:, :, None]


class ModalCost:
    """The batched simulation cost of a :class:`StateSpaceStructure` on a record.

    Parameters
    ----------
    data : IOData
        The estimation record: ``structure.n_inputs`` inputs and ``structure.n_outputs``
        outputs.
    structure : StateSpaceStructure
    metric : str, optional
        A metric of :mod:`flexid.costs.metrics` (default ``"rmse"``).
    weight : float, optional
        ``w`` of the paper's metric.
    initial : {"estimate", "zero"}, optional
        Fit the initial state (default) or start from rest.

    Attributes
    ----------
    predictor : str
        ``"simulation"``: a modal model is an output-error model (``K = 0``).
    scale : ndarray, shape (ny,)
        What each output's errors are divided by (ones for one output).

    Raises
    ------
    ModelOrderError
        A record whose channels do not match the structure, or too short for it.
    DataError
        An initial-condition rule other than ``"estimate"`` or ``"zero"``.
    """

    predictor = "simulation"

    def __init__(
        self, data: IOData, structure: StateSpaceStructure, metric: str = "rmse",
        weight: float = 0.0, initial: str = "estimate",
    ) -> None:  # fmt: skip
        if (data.n_inputs, data.n_outputs) != (structure.n_inputs, structure.n_outputs):
            raise ModelOrderError(
                f"{structure!r} has {structure.n_inputs} input(s) and {structure.n_outputs} "
                f"output(s); the record has {data.n_inputs} and {data.n_outputs}"
            )
        structure.check_samples(data.n_samples)
        if initial not in ("estimate", "zero"):
            raise DataError(
                f"a state-space model's initial state is estimated or zero, not {initial!r}"
            )
        self.structure, self.metric, self.weight, self.initial = structure, metric, weight, initial
        self.u = np.ascontiguousarray(data.u, dtype=float)
        self.y = np.asarray(data.y, dtype=float)
        self.dt = float(data.dt)
        ny = self.y.shape[1]
        std = np.std(self.y, axis=0)
        self.scale = np.where(std > 0, std, 1.0) if ny > 1 else np.ones(1)
        self._target = self.y / self.scale
        self._yy = np.einsum("no,no->o", self._target, self._target)
        self._std = float(np.std(self._target)) if ny == 1 else 1.0

    # ------------------------------------------------------------------ the fit
    def _free_map(self, a: np.ndarray, C: np.ndarray) -> np.ndarray:
        """The free response of every output from each state, in the free-response basis of
        :func:`flexid.kernels.modal_regressors`.

        ``L[p, o, :, i]``: the coefficients of output ``o``'s response from ``x0 = e_i``.  A
        mode's block state is ``[x(t - 1), x(t - 2)]``; from ``s0`` its first component is
        the basis times ``s0`` and its second the basis times ``S s0``, ``S = [[0, 1],
        [-1/a2, -a1/a2]]`` (the recursion run one step back), so an output of gains
        ``(c1, c2)`` sees ``(c1 I + c2 S) s0``.

        Parameters
        ----------
        a : ndarray, shape (P, m, 2)
        C : ndarray, shape (P, ns, ny)
            The gains (scaled outputs).

        Returns
        -------
        ndarray, shape (P, ny, 2 m + r, ns)
        """
        s = self.structure
        P, ns, ny = C.shape
        L = np.zeros((P, ny, s.n_search, ns))
        i = 0
        for k in range(s.n_modes):
            a1, a2 = a[:, k, 0], a[:, k, 1]
            S = np.zeros((P, 2, 2))
            S[:, 0, 1] = 1.0
            S[:, 1, 0], S[:, 1, 1] = -1.0 / a2, -a1 / a2
            for _ in range(s.n_inputs):
                c1, c2 = C[:, i, :], C[:, i + 1, :]  # (P, ny)
                block = c2[:, :, None, None] * S[:, None]
                block[:, :, 0, 0] += c1
                block[:, :, 1, 1] += c1
                L[:, :, 2 * k : 2 * k + 2, i : i + 2] = block
                i += 2
        for k in range(s.n_real):
            for _ in range(s.n_inputs):
                L[:, :, 2 * s.n_modes + k, i] = C[:, i, :]
                i += 1
        return L

    # ------------------------------------------------------------------ the fit
    def fit(self, modal: Any) -> tuple[np.ndarray, np.ndarray]:
        """The fitted gains and initial state of every candidate, and its sum of squares.

        Parameters
        ----------
        modal : array_like, shape (P, 2 m + r)
            Physical modal parameters ``[f_1, zeta_1, .., f_c1, ..]`` (Hz, ratio, Hz).

        Returns
        -------
        theta : ndarray, shape (P, n_params)
            The whole parameter vector of each candidate (its model:
            ``structure.model(theta[i], dt)``).
        sse : ndarray, shape (P,)
            Sum over outputs of the squared simulation errors, each output divided by
            :attr:`scale`.
        """
        theta, _, sse = self._fit(modal, want_residual=False)
        return theta, sse

    def residuals(
        self, modal: Any, *, orthogonal: bool = False
    ) -> tuple[np.ndarray, np.ndarray]:
        """The fitted parameters of every candidate and its simulation errors.

        Parameters
        ----------
        modal : array_like, shape (P, 2 m + r)
            Physical modal parameters.
        orthogonal : bool, optional
            Solve each least-squares problem by QR factors of the stored regressors instead
            of their normal equations: the same fit (the same ridge), with rounding errors
            that grow as the regressors' condition number instead of its square (about 1e-11
            of the residual instead of 1e-9 on the manipulator's order-16 model, which a
            first-order optimality test of 1e-6 from finite differences needs), about ten
            times slower. For a reference's last steps; default False.

        Returns
        -------
        theta : ndarray, shape (P, n_params)
        residual : ndarray, shape (P, N, ny)
            ``y - y_sim`` of each output, divided by :attr:`scale`.
        """
        theta, residual, _ = self._fit(modal, want_residual=True, orthogonal=orthogonal)
        return theta, residual

    def _fit(self, modal: Any, *, want_residual: bool, orthogonal: bool = False) -> tuple:
        """``(theta, residual or None, sse)`` of every candidate (see :meth:`residuals`)."""
        s = self.structure
        modal = np.atleast_2d(np.asarray(modal, dtype=float))
        P = modal.shape[0]
        nu, ns = s.n_inputs, s.n_states
        a, p = s.denominators(modal, self.dt)
        estimate = self.initial == "estimate"
        # regressors: the states from rest, the inputs (feedthrough), each output's own free
        # response (compiled: made row by row, never stored, unless orthogonal)
        job = (np.concatenate([a.reshape(P, -1), p], axis=1), self.u, self._target)
        options = (s.n_modes, s.feedthrough, estimate)
        k_in = ns + (nu if s.feedthrough else 0)
        phi = sse = None
        if orthogonal:
            phi = kernels.modal_regressors(job[0], self.u, *options)
            gram = rhs = None
            coef, used, x0 = self._steps(a, k_in, phi=phi)
        elif kernels.BACKEND == "c" and not want_residual:
            gram, rhs, coef, used, x0, sse, ok = kernels.modal_fit(
                *job, *options, ridge=RIDGE, rounding=SUM_ROUNDING, tolerance=EXPANSION_TOLERANCE
            )
            if not ok.all():  # a pivot lost to rounding: those rows by the NumPy steps
                bad = ~ok
                coef[bad], used[bad], x0[bad] = self._steps(a[bad], k_in, gram[bad], rhs[bad])
                sse[bad] = self._expanded_sse(gram[bad], rhs[bad], used[bad])
        else:
            gram, rhs = kernels.modal_normal(*job, *options)
            coef, used, x0 = self._steps(a, k_in, gram, rhs)
        if orthogonal:
            residual = self._target - phi @ used
            sse = np.einsum("pno,pno->p", residual, residual)
        elif want_residual:
            residual, sse = kernels.modal_residual(*job, used, *options)
        else:
            residual = None
            if sse is None:
                sse = self._expanded_sse(gram, rhs, used)
            again = np.flatnonzero(np.isnan(sse))
            if again.size:
                sse[again] = kernels.modal_residual(job[0][again], *job[1:], used[again],
                                                    *options, want_residual=False)[1]  # fmt: skip
        gains = coef[:, :k_in, :] * self.scale  # back to output units
        parts = [modal, np.swapaxes(gains[:, :ns, :], 1, 2).reshape(P, -1)]
        if s.feedthrough:
            parts.append(np.swapaxes(gains[:, ns:, :], 1, 2).reshape(P, -1))
        parts.append(x0)
        return np.concatenate(parts, axis=1), residual, sse

    def _steps(
        self, a: np.ndarray, k_in: int, gram: np.ndarray | None = None,
        rhs: np.ndarray | None = None, *, phi: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
        """The module's two steps from the normal equations (or, with ``phi``, from the
        stored regressors by QR factors): ``(coef, used, x0)``.

        ``coef`` (P, k, ny) is step 1's least-squares fit, ``used`` the realised model's
        coefficients (its gains, and the free responses of its ``x0`` (P, ns)).
        """
        P, ns = a.shape[0], self.structure.n_states
        if phi is not None:
            target = np.broadcast_to(self._target, (P, *self._target.shape))
            coef = _solve_orthogonal(phi, target)
        else:
            coef = _solve(gram, rhs)  # (P, k, ny)
        x0 = np.zeros((P, ns))
        used = coef[:, :k_in, :]  # the gains, and no free response of each output's own
        if self.initial != "estimate":
            return coef, used, x0
        # step 2: the residual of step 1 is orthogonal to the free basis, so the x0 that
        # best matches the outputs' free responses minimises the weighted distance of its
        # coefficients L x0 to step 1's beta in the basis's Gram matrix M
        L = self._free_map(a, coef[:, :ns, :])  # (P, ny, F, ns)
        beta = np.moveaxis(coef[:, k_in:, :], 2, 1)[..., None]  # (P, ny, F, 1)
        if phi is not None:
            # the basis's Gram matrix is R' R of its QR factor R: the distance is
            # |R (L x0 - beta)|, a least-squares problem over every output's rows
            R = np.linalg.qr(phi[:, :, k_in:], mode="r")[:, None]
            x0 = _solve_orthogonal((R @ L).reshape(P, -1, ns),
                                   (R @ beta).reshape(P, -1, 1))[:, :, 0]  # fmt: skip
        else:
            ML = gram[:, None, k_in:, k_in:] @ L
            normal = np.swapaxes(L.reshape(P, -1, ns), 1, 2) @ ML.reshape(P, -1, ns)
            toward = np.swapaxes(ML.reshape(P, -1, ns), 1, 2) @ beta.reshape(P, -1, 1)
            x0 = _solve(normal, toward)[:, :, 0]
        shared = np.moveaxis((L @ x0[:, None, :, None])[..., 0], 1, 2)  # (P, F, ny)
        return coef, np.concatenate([used, shared], axis=1), x0

    def _expanded_sse(self, gram: np.ndarray, rhs: np.ndarray, used: np.ndarray) -> np.ndarray:
        """``sum_o |y_o - phi c_o|^2`` from the normal equations, NaN where rounding could
        move it by more than :data:`EXPANSION_TOLERANCE` of itself.

        ``y_o' y_o - 2 c_o' phi' y_o + c_o' G c_o`` for every candidate (``gram`` (P, k, k),
        ``rhs`` (P, k, ny), ``used`` (P, k, ny)).  Each entry of ``G`` and ``phi' y`` is a sum
        of ``N`` products, summed in blocks of 64 rows: its rounding error is at most
        :data:`SUM_ROUNDING` of ``sqrt(G_ii G_jj)`` (Cauchy-Schwarz bounds the sum of the
        products' magnitudes), so the expansion is within ``SUM_ROUNDING (|y_o| + sum_i |c_i|
        sqrt(G_ii))^2`` of the errors' own sum of squares.  Where that bound exceeds the
        tolerance (a near-perfect fit, or gains that cancel each other on nearly collinear
        columns) the candidate is marked NaN for the exact pass over its errors.
        """
        c = used
        quad = np.einsum("pio,pio->po", c, gram @ c)
        sse = self._yy - 2.0 * np.einsum("pio,pio->po", c, rhs) + quad
        weight = np.einsum("pio,pi->po", np.abs(c), np.sqrt(np.abs(np.einsum("pii->pi", gram))))
        bound = SUM_ROUNDING * (np.sqrt(self._yy) + weight) ** 2
        total = sse.sum(axis=1)
        return np.where(bound.sum(axis=1) <= EXPANSION_TOLERANCE * total, total, np.nan)

    # ------------------------------------------------------------------ the cost
    def __call__(self, modal: Any) -> np.ndarray:
        """The metric of every candidate's simulation errors.

        Parameters
        ----------
        modal : array_like, shape (P, 2 m + r)
            Physical modal parameters.

        Returns
        -------
        ndarray, shape (P,)
        """
        return self.score(self.fit(modal)[1])

    def score(self, sse: Any) -> np.ndarray:
        """The metric of sums of squared (scaled) simulation errors.

        Parameters
        ----------
        sse : float or ndarray
            Sums over every output and sample of the errors divided by :attr:`scale`.

        Returns
        -------
        ndarray
            Like ``sse``.
        """
        return metric_from_sse(self.metric, np.asarray(sse, dtype=float), self.y.size,
                               self.weight, self._std)  # fmt: skip

    def model(self, modal: Any) -> StateSpaceModel:
        """The fitted model of one candidate.

        Parameters
        ----------
        modal : array_like, shape (2 m + r,)

        Returns
        -------
        StateSpaceModel
        """
        theta = self.fit(np.reshape(modal, (1, -1)))[0][0]
        return self.structure.model(theta, self.dt)

    def describe(self) -> str:
        """One line: the metric, the predictor and what is fitted.

        Returns
        -------
        str
        """
        outs = self.structure.n_outputs
        per = " (each output over its standard deviation)" if outs > 1 else ""
        return (f"{self.metric} of the simulation error{per}; gains"
                f"{' and initial state' if self.initial == 'estimate' else ''} fitted by "
                "least squares for each candidate's modes")  # fmt: skip
