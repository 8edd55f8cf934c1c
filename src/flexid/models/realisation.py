"""A well-conditioned realisation of polynomial transfer functions: accurate roots, second-order
sections and a modal basis of free responses.

A polynomial model is stored as the coefficients of its polynomials, and the batched costs run
it in that direct form, which is fast.  For high-order lightly damped models the direct form
is ill-conditioned: a recursion ``den(q) y = f`` of order 16 with poles clustered near
``z = 1`` amplifies each rounding error by up to ``1e15`` (a measured twin rotor OE(16,16,1)),
and the free responses that span its initial state are nearly parallel, so the estimated
initial state and every fit computed from it can be wrong by any amount.  What a user reads
(fits, simulated and predicted outputs) is computed here instead:

* **Roots accurate to the last bit of the coefficients' model.**  The roots of a polynomial
  whose coefficients are exact doubles are found by :func:`numpy.roots` and polished by the
  Aberth-Ehrlich iteration with the polynomial evaluated in double-double arithmetic
  (compensated Horner, Graillat-Langlois-Louvet 2005), so a cluster of roots whose
  :func:`numpy.roots` values are off by ``1e-2`` (the roots of a lightly damped direct form
  are that sensitive to the last bit) comes out correct to about one unit in the last place;
  conjugate pairs are made exact.
* **Second-order sections** (:func:`scipy.signal.zpk2sos`, poles paired with their nearest
  zeros) for the filter itself.
* **A modal basis** ``p^t`` (real and imaginary parts of each complex pair, ``t^k p^t`` for a
  repeated pole) for its free response: the same span as the direct form's free responses,
  so fitting the initial state in it projects onto the same subspace, in well-separated
  columns.

The route is independent of the direct form's rounding; ``tests/test_realisation.py`` checks
it against the exact recursion computed with 100 significant digits (``mpmath``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import linalg, signal

__all__ = ["Path", "accurate_roots", "free_response_basis", "run_paths"]

_EPS = np.finfo(float).eps
_SPLITTER = 134217729.0  # 2**27 + 1: Dekker's split of a double into two 26-bit halves
_ABERTH_STEPS = 200


# ------------------------------------------------------------- error-free transformations
def _two_sum(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    s = a + b
    bb = s - a
    return s, (a - (s - bb)) + (b - bb)


def _two_prod(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    p = a * b
    ca = _SPLITTER * a
    ah = ca - (ca - a)
    al = a - ah
    cb = _SPLITTER * b
    bh = cb - (cb - b)
    bl = b - bh
    return p, ((ah * bh - p) + ah * bl + al * bh) + al * bl


def _dd_mul(h: np.ndarray, lo: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Double-double ``(h + lo)`` times double ``d``."""
    p, e = _two_prod(h, d)
    return _two_sum(p, e + lo * d)


def _dd_add(
    h1: np.ndarray, l1: np.ndarray, h2: np.ndarray, l2: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    s, e = _two_sum(h1, h2)
    return _two_sum(s, e + (l1 + l2))


def _horner_dd(c: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``p(z)`` and ``p'(z)`` at complex points ``z``, each sum in double-double arithmetic.

    ``c`` holds the real coefficients, highest power first.  The result is as accurate as
    Horner's rule in twice the working precision, rounded to double.
    """
    x, y = z.real, z.imag
    zero = np.zeros_like(x)
    pr, prl, pi, pil = zero + c[0], zero, zero.copy(), zero.copy()
    dr, drl, di, dil = zero.copy(), zero.copy(), zero.copy(), zero.copy()
    for ck in c[1:]:
        # p' <- p' z + p (before p is updated)
        a = _dd_mul(dr, drl, x)
        b = _dd_mul(di, dil, -y)
        r1 = _dd_add(*a, *b)
        r1 = _dd_add(*r1, pr, prl)
        a = _dd_mul(dr, drl, y)
        b = _dd_mul(di, dil, x)
        i1 = _dd_add(*a, *b)
        i1 = _dd_add(*i1, pi, pil)
        dr, drl, di, dil = *r1, *i1
        # p <- p z + c_k
        a = _dd_mul(pr, prl, x)
        b = _dd_mul(pi, pil, -y)
        r0 = _dd_add(*a, *b)
        s, e = _two_sum(r0[0], np.full_like(x, ck))
        r0 = _two_sum(s, e + r0[1])
        a = _dd_mul(pr, prl, y)
        b = _dd_mul(pi, pil, x)
        i0 = _dd_add(*a, *b)
        pr, prl, pi, pil = *r0, *i0
    return (pr + prl) + 1j * (pi + pil), (dr + drl) + 1j * (di + dil)


def _conjugate_pairs(r: np.ndarray) -> np.ndarray:
    """Roots of a real polynomial made exactly real or exact conjugate pairs.

    A root nearer its own conjugate than any other root's is real; otherwise it is paired
    with the root nearest its conjugate and both become the pair's mean.
    """
    r = r.astype(complex)
    n = r.size
    done = np.zeros(n, dtype=bool)
    for i in np.argsort(-np.abs(r.imag)):
        if done[i]:
            continue
        dist = np.abs(r[i] - np.conj(r))
        dist[i] = np.inf
        dist[done] = np.inf
        j = int(np.argmin(dist)) if n > 1 else i
        if n == 1 or 2 * abs(r[i].imag) <= dist[j]:
            r[i] = r[i].real
            done[i] = True
            continue
        mean = 0.5 * (r[i] + np.conj(r[j]))
        if mean.imag < 0:
            mean = np.conj(mean)
        r[i], r[j] = mean, np.conj(mean)
        done[i] = done[j] = True
    return r


def accurate_roots(coefficients: Sequence[float] | np.ndarray) -> np.ndarray:
    """Roots of a real polynomial, correct to about one unit in the last place.

    Parameters
    ----------
    coefficients : array_like, shape (m + 1,)
        ``c_0 x^m + c_1 x^(m-1) + .. + c_m``, highest power first: a polynomial in ``q^-1``
        ``[1, a_1, .., a_n]`` read this way has the poles ``z`` of ``1 / A(q^-1)``.  Leading
        zeros are dropped; each trailing zero is an exact root ``0``.

    Returns
    -------
    ndarray of complex, shape (m',)
        ``m'`` is ``m`` less the leading zeros; real roots have an exactly zero imaginary
        part and complex ones come in exact conjugate pairs.

    Notes
    -----
    :func:`numpy.roots` (companion-matrix eigenvalues) is backward stable, which for clustered
    roots is not enough: a coefficient change in the last bit moves them by ``1e-2`` in the
    lightly damped models identified here.  Its values start the Aberth-Ehrlich simultaneous
    iteration, with the polynomial and its derivative evaluated by compensated Horner in
    double-double arithmetic: the roots then hold to the accuracy of a twice-as-precise
    computation, about ``eps`` for every root whose condition number is below ``1/eps``.
    The starting values are perturbed by ``1e-9`` asymmetrically so that a pair that
    :func:`numpy.roots` returns complex can split into two real roots.
    """
    c = np.trim_zeros(np.asarray(coefficients, dtype=float).reshape(-1), "f")
    if c.size == 0:
        return np.zeros(0, dtype=complex)
    n_zero = c.size - np.trim_zeros(c, "b").size
    c = np.trim_zeros(c, "b")
    m = c.size - 1
    if m == 0:
        return np.zeros(n_zero, dtype=complex)
    if m == 1:
        return np.concatenate([[complex(-c[1] / c[0])], np.zeros(n_zero, dtype=complex)])
    z = np.roots(c).astype(complex)  # c is not scaled: c / c[0] would round a new polynomial
    k = np.arange(m)
    z = z + 1e-9 * np.maximum(np.abs(z), 1e-3) * np.exp(1j * (0.7 + 2.3999632 * k))
    # a root far outside the unit circle can overflow its powers; such roots are well
    # conditioned (the polynomial's value there is dominated by one term) and stay as found
    movable = m * np.log10(np.maximum(np.abs(z), 1.0)) < 250
    tol = 4 * _EPS
    for _ in range(_ABERTH_STEPS):
        p, dp = _horner_dd(c, z[movable])
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where(p == 0, 0.0, p / dp)
            diff = z[movable][:, None] - z[None, :]
            idx = np.flatnonzero(movable)
            diff[np.arange(idx.size), idx] = np.inf
            repulsion = np.sum(1.0 / diff, axis=1)
            step = ratio / (1.0 - ratio * repulsion)
        step = np.where(np.isfinite(step), step, 0.0)
        z[movable] -= step
        if np.all(np.abs(step) <= tol * np.maximum(np.abs(z[movable]), 1e-300)):
            break
    return np.concatenate([_conjugate_pairs(z), np.zeros(n_zero, dtype=complex)])


# ------------------------------------------------------------- sections and free responses
@dataclass(frozen=True)
class Path:
    """One transfer function ``gain q^-delay prod(1 - z_i q^-1) / prod(1 - p_i q^-1)``.

    Attributes
    ----------
    signal : int
        Which column of the stacked signals it filters.
    zeros, poles : ndarray of complex
        Exact conjugate pairs (from :func:`accurate_roots`); ``len(zeros) <= len(poles)``
        is not required (the extra zeros make the path improper only through ``delay``).
    gain : float
        The numerator's leading nonzero coefficient.
    delay : int
        Samples of pure delay (``nk`` and any leading zero coefficients).
    sign : float
        +1 to add the path's output, -1 to subtract it.
    """

    signal: int
    zeros: np.ndarray
    poles: np.ndarray
    gain: float
    delay: int
    sign: float = 1.0

    def sos(self) -> np.ndarray:
        """The path without its delay as second-order sections.

        Returns
        -------
        ndarray, shape (n_sections, 6)
            :func:`scipy.signal.sosfilt`'s layout; poles paired with their nearest zeros.
        """
        nz, npol = self.zeros.size, self.poles.size
        zeros = np.concatenate([self.zeros, np.zeros(max(npol - nz, 0))])
        poles = np.concatenate([self.poles, np.zeros(max(nz - npol, 0))])
        if zeros.size == 0:
            return np.array([[self.gain, 0.0, 0.0, 1.0, 0.0, 0.0]])
        return signal.zpk2sos(zeros, poles, self.gain, pairing="nearest")

    def run(self, x: np.ndarray) -> np.ndarray:
        """The path's response to a signal from rest at ``t = 0``.

        Parameters
        ----------
        x : ndarray, shape (N,)

        Returns
        -------
        ndarray, shape (N,)
        """
        out = signal.sosfilt(self.sos(), x)
        if self.delay:
            out = np.concatenate([np.zeros(self.delay), out[: out.size - self.delay]])
        return out


def free_response_basis(poles: np.ndarray, length: int) -> np.ndarray:
    """Real columns spanning the free responses ``sum_k c_k p_k^t`` of a set of poles.

    Parameters
    ----------
    poles : ndarray of complex
        With multiplicity (a pole listed ``m`` times, bit for bit, gives ``t^j p^t`` for
        ``j < m``); exact conjugate pairs give the real and imaginary parts of ``p^t``.  Poles
        exactly at ``0`` give nothing: a direct form whose last coefficient is zero does not
        use that past value.
    length : int
        Samples ``t = 0 .. length - 1``.

    Returns
    -------
    ndarray, shape (length, n_columns)
        Each column scaled to unit norm (a column that underflows to zero is dropped).
    """
    t = np.arange(length, dtype=float)
    cols = []
    seen: dict[complex, int] = {}
    for p in poles:
        p = complex(p)
        if p == 0 or p.imag < 0:
            continue
        power = seen.get(p, 0)
        seen[p] = power + 1
        with np.errstate(under="ignore", over="ignore", invalid="ignore"):
            g = (t**power) * np.power(p, t)
        if p.imag == 0:
            cols.append(g.real)
        else:
            cols.extend([g.real, g.imag])
    if not cols:
        return np.zeros((length, 0))
    basis = np.column_stack(cols)
    norms = np.linalg.norm(basis, axis=0)
    keep = np.isfinite(norms) & (norms > 0)
    return basis[:, keep] / norms[keep]


def run_paths(
    paths: Sequence[Path],
    signals: np.ndarray,
    *,
    start: int,
    initial: str,
    modes: np.ndarray,
    target: np.ndarray | None = None,
    offset: np.ndarray | None = None,
    leading: int = 0,
) -> np.ndarray:
    """The sum of the paths' responses under an initial-condition rule.

    Parameters
    ----------
    paths : sequence of Path
    signals : ndarray, shape (N, n_signals)
        The signals the paths filter (``Path.signal`` indexes the columns).
    start : int
        First counted sample.
    initial : {"zero", "estimate"}
        From rest at ``t = 0``, or with the free response over ``t >= start`` fitted by least
        squares to ``target - output`` in the modal basis of ``modes``.
    modes : ndarray of complex
        The poles of the whole predictor's denominator, with multiplicity.
    target : ndarray, shape (N,), optional
        The measured output (needed by ``"estimate"``).
    offset : ndarray, shape (N,), optional
        A signal added to the paths' sum before the fit (the one-step predictor's ``y``).
    leading : int, optional
        Free responses of poles at the origin beside the modes: the first ``leading``
        samples from ``start`` are fitted exactly (a realisation whose numerator reaches
        further back than its denominator).

    Returns
    -------
    ndarray, shape (N,)
        Under ``"estimate"`` the samples before ``start`` are the measured outputs.
    """
    n = signals.shape[0]
    out = np.zeros(n) if offset is None else offset.astype(float).copy()
    with np.errstate(over="ignore", invalid="ignore"):
        for path in paths:
            out += path.sign * path.run(signals[:, path.signal])
    if initial == "zero":
        return out
    if target is None:
        raise ValueError("the rule 'estimate' needs the measured output")
    basis = free_response_basis(modes, n - start)
    if leading:
        basis = np.column_stack([basis, np.eye(n - start, leading)])
    fitted = target.astype(float).copy()
    seg = out[start:]
    if basis.shape[1] and np.all(np.isfinite(seg)):
        coef = linalg.lstsq(basis, target[start:] - seg)[0]
        seg = seg + basis @ coef
    fitted[start:] = seg
    return fitted
