"""The fast routes of the twin rotor: the steppers that ``simulate`` and the environments run.

The model is :mod:`flexid.envs.twin_rotor_physics`: its
:func:`~flexid.envs.twin_rotor_physics.derivatives` states the equations and its
:func:`~flexid.envs.twin_rotor_physics.step_states` (RK4 over one sample, inputs held) is the
reference route.  The routes here compute
the same RK4 samples faster; they import the model, never the reverse, and the tests hold each
of them to :func:`~flexid.envs.twin_rotor_physics.step_states` within a rounding bound
(``tests/test_twin_rotor.py``):

:class:`ScalarStepper`
    one state in Python floats (the single environment and ``simulate``);
:class:`BatchStepper`
    a batch in NumPy, one row per state variable (the vector environment).

Both use the structure of the model.  The rotor states and the reaction torque
``(tau1, tau2, M_R)`` obey linear equations that pitch and yaw do not enter, so with the input
held over a sample RK4 is linear in them: their values at all ``4 n_sub`` stages of a sample
are one matrix times ``(tau1, tau2, M_R, u1, u2)`` at its start.  The matrix is built by
running the reference recursion on the unit vectors (:func:`_linear_stages`).  The thrusts at
all stages then follow in bulk (:func:`~flexid.envs.twin_rotor_physics.thrust`, the same
function as in the model), and only pitch, pitch rate and yaw rate are stepped stage by stage;
yaw is their integral.  The routes differ from the reference by rounding only.

When the compiled kernels run (:mod:`flexid.kernels`), :class:`CompiledScalarStepper` and
:class:`CompiledBatchStepper` take the place of both: the equations of ``derivatives`` and
the RK4 of ``step_states`` in C, four rotors per SIMD vector, with ``sin``, ``cos`` and
``tanh`` as inline polynomials within a few eps of the exact values (absolute error).  They too
differ from the reference by rounding only.  :func:`scalar_stepper` and :func:`batch_stepper`
pick the fastest route available.
"""

from __future__ import annotations

import functools
import math
from itertools import islice
from typing import Any

import numpy as np
from scipy.special import expit

from .twin_rotor_physics import (
    _OUTPUT_COLUMNS,
    TwinRotorParameters,
    _check_dt,
    _rk4,
    _run_arguments,
    substeps,
    thrust,
)

__all__ = [
    "BatchStepper",
    "CompiledBatchStepper",
    "CompiledScalarStepper",
    "ScalarStepper",
    "batch_stepper",
    "scalar_stepper",
    "simulate",
]


@functools.lru_cache(maxsize=32)
def _linear_stages(p: TwinRotorParameters, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """The RK4 stage values of ``(tau1, tau2, M_R)`` over one sample as linear maps.

    Returns ``stages`` (5, n_sub, 4, 3) and ``end`` (5, 3): row ``i`` is the response to the
    ``i``-th unit vector of ``(tau1, tau2, M_R, u1, u2)`` at the sample start, from the
    reference recursion itself (the model's ``_rk4``).  Their rows of
    :func:`~flexid.envs.twin_rotor_physics.derivatives` are linear in these five numbers and
    independent of the other states, so the stage values of any start are these rows combined
    (up to rounding).  Read-only (shared by the cache).
    """
    n_sub, _ = substeps(p, dt)
    x = np.zeros((5, 7))
    x[[0, 1, 2], [4, 5, 6]] = 1.0
    u = np.zeros((5, 2))
    u[[3, 4], [0, 1]] = 1.0
    points: list[np.ndarray] = []
    end = _rk4(x, u, p, dt, points)[:, 4:7]
    stages = np.stack(points, axis=1)[:, :, 4:7].reshape(5, n_sub, 4, 3)
    for a in (stages, end):
        a.flags.writeable = False
    return stages, end


def _forcing_map(p: TwinRotorParameters, dt: float, scale: float):
    """Matrix and thrust coefficients that give the pitch and yaw forcing of every stage.

    With ``s = (tau1, tau2, M_R, u1, u2)`` at the sample start and ``n = n_sub``,
    ``z = s @ matrix`` has shape (12 n + 3,).  ``f = thrust(z[:8n], a, b, law)`` followed by
    ``f[1::2] -= z[8n:12n]`` holds, for each substep and each of its 4 stages, the pair
    ``scale M1 / I1`` (pitch) and ``scale (M2 - M_R) / I2`` (yaw).  ``z[12n:]`` is
    ``(tau1, tau2, M_R)`` at the end of the sample.
    """
    stages, end = _linear_stages(p, dt)
    n_sub = stages.shape[1]
    tau = stages[..., :2].reshape(5, -1)  # tau1, tau2 at each stage
    torque = scale / p.I2 * stages[..., 2].reshape(5, -1)
    matrix = np.concatenate([tau, torque, end], axis=1)
    a = np.tile([scale / p.I1 * p.a1, scale / p.I2 * p.a2], 4 * n_sub)
    b = np.tile([scale / p.I1 * p.b1, scale / p.I2 * p.b2], 4 * n_sub)
    return matrix, a, b


def _pitch_yaw_substeps(rows, psi, w, phi, v, c):
    """RK4 substeps of pitch and yaw in Python floats (the scalar route's inner loop).

    The state is ``psi``, ``w = psi' / eps``, ``phi``, ``v = phi' / eps`` (``eps`` the Coulomb
    velocity), so that the Coulomb terms are ``tanh(w)`` and ``tanh(v)``; the stage
    derivatives ``k``, ``l`` of ``w``, ``v`` are computed times ``h / 2``, so that a half-step
    stage point is one addition.  ``rows`` yields per substep, for its 4 stages, the pitch and
    yaw forcing ``(h / 2) M1 / (I1 eps)`` and ``(h / 2) (M2 - M_R) / (I2 eps)``
    (:func:`_forcing_map`); ``c`` are the constants of :class:`ScalarStepper`.
    """
    he, hfe, h6e, third, kg, mg, b1, b2, f1, f2 = c
    sin, cos, tanh = math.sin, math.cos, math.tanh
    for a1, g1, a2, g2, a3, g3, a4, g4 in rows:
        k1 = a1 * (1.0 - kg * v * cos(psi)) - mg * sin(psi) - b1 * w - b2 * tanh(w)
        l1 = g1 - f1 * v - f2 * tanh(v)
        q = psi + he * w
        w2 = w + k1
        v2 = v + l1
        k2 = a2 * (1.0 - kg * v2 * cos(q)) - mg * sin(q) - b1 * w2 - b2 * tanh(w2)
        l2 = g2 - f1 * v2 - f2 * tanh(v2)
        q = psi + he * w2
        w3 = w + k2
        v3 = v + l2
        k3 = a3 * (1.0 - kg * v3 * cos(q)) - mg * sin(q) - b1 * w3 - b2 * tanh(w3)
        l3 = g3 - f1 * v3 - f2 * tanh(v3)
        q = psi + hfe * w3
        w4 = w + 2.0 * k3
        v4 = v + 2.0 * l3
        k4 = a4 * (1.0 - kg * v4 * cos(q)) - mg * sin(q) - b1 * w4 - b2 * tanh(w4)
        l4 = g4 - f1 * v4 - f2 * tanh(v4)
        psi += h6e * (w + 2.0 * (w2 + w3) + w4)
        phi += h6e * (v + 2.0 * (v2 + v3) + v4)
        w += third * (k1 + 2.0 * (k2 + k3) + k4)
        v += third * (l1 + 2.0 * (l2 + l3) + l4)
    return psi, w, phi, v


def _pitch_substeps(rows, psi, w, phi, v, c):
    """:func:`_pitch_yaw_substeps` with the yaw locked: yaw and yaw rate (0) do not change,
    the yaw forcing is not used."""
    he, hfe, h6e, third, _, mg, b1, b2, _, _ = c
    sin, tanh = math.sin, math.tanh
    for a1, _, a2, _, a3, _, a4, _ in rows:
        k1 = a1 - mg * sin(psi) - b1 * w - b2 * tanh(w)
        q = psi + he * w
        w2 = w + k1
        k2 = a2 - mg * sin(q) - b1 * w2 - b2 * tanh(w2)
        q = psi + he * w2
        w3 = w + k2
        k3 = a3 - mg * sin(q) - b1 * w3 - b2 * tanh(w3)
        q = psi + hfe * w3
        w4 = w + 2.0 * k3
        k4 = a4 - mg * sin(q) - b1 * w4 - b2 * tanh(w4)
        psi += h6e * (w + 2.0 * (w2 + w3) + w4)
        w += third * (k1 + 2.0 * (k2 + k3) + k4)
    return psi, w, phi, v


class ScalarStepper:
    """Fast route for one twin rotor: RK4 samples in Python floats.

    Parameters
    ----------
    params : TwinRotorParameters
        The model; its constants are bound once as Python floats.
    dt : float
        Sample time [s], > 0.

    Notes
    -----
    Per sample: one small NumPy product gives the forcing of pitch and yaw at all RK4 stages
    (see the module notes), then :func:`_pitch_yaw_substeps` steps pitch, pitch rate, yaw and
    yaw rate in plain floats with the constants bound once.  Inputs are voltages, already
    clipped; with ``lock_yaw`` the yaw rate of a state must be 0.
    """

    def __init__(self, params: TwinRotorParameters, dt: float) -> None:
        p = params
        self.params = p
        self.dt = _check_dt(dt)
        self.n_sub, h = substeps(p, self.dt)
        eps = p.coulomb_velocity
        self._eps, self._inv_eps = eps, 1.0 / eps
        hh = 0.5 * h
        self._matrix, self._a, self._b = _forcing_map(p, self.dt, hh / eps)
        self._law = p.thrust_law
        self._nf = 8 * self.n_sub
        self._consts = (
            hh * eps, h * eps, h / 6.0 * eps, 1.0 / 3.0,
            p.Kgy * eps, hh * p.Mg / (p.I1 * eps), hh * p.B1psi / p.I1,
            hh * p.B2psi / (p.I1 * eps), hh * p.B1phi / p.I2, hh * p.B2phi / (p.I2 * eps),
        )  # fmt: skip
        self._substeps = _pitch_substeps if p.lock_yaw else _pitch_yaw_substeps

    def _forcing(self, s: np.ndarray) -> tuple[list[float], np.ndarray]:
        """Stage forcing and end linear states from sample starts ``s`` (..., 5).

        Returns the forcing as one flat list, 8 numbers per substep (one list: nested lists
        of a long record cost as much as the arithmetic, and keep the garbage collector
        busy), and the linear states (..., 3) at the sample ends.
        """
        z = np.dot(s, self._matrix)
        nf = self._nf
        force = thrust(z[..., :nf], self._a, self._b, self._law)
        force[..., 1::2] -= z[..., nf : nf + nf // 2]
        return force.ravel().tolist(), z[..., nf + nf // 2 :]

    def step(self, x, u1: float, u2: float) -> tuple[float, ...]:
        """State one sample later.

        Parameters
        ----------
        x : sequence of 7 float
            State, :data:`~flexid.envs.twin_rotor_physics.STATE_NAMES` order and units.
        u1, u2 : float
            Main and tail rotor voltages (V), held over the sample.

        Returns
        -------
        tuple of 7 float
        """
        psi, dpsi, phi, dphi, t1, t2, mr = x
        force, end = self._forcing(np.array((t1, t2, mr, u1, u2)))
        t1, t2, mr = end.tolist()
        ie = self._inv_eps
        rows = zip(*[iter(force)] * 8)
        psi, w, phi, v = self._substeps(rows, psi, dpsi * ie, phi, dphi * ie, self._consts)
        eps = self._eps
        return psi, w * eps, phi, v * eps, t1, t2, mr

    def run(self, u: np.ndarray, x0: np.ndarray) -> np.ndarray:
        """States at the sample times for a whole input record.

        Parameters
        ----------
        u : ndarray, shape (N, 2)
            Voltages (V), already clipped.
        x0 : ndarray, shape (7,)
            Initial state.

        Returns
        -------
        ndarray, shape (N + 1, 7)
            States at ``t = k dt``, ``k = 0 .. N``.
        """
        n = u.shape[0]
        out = np.empty((n + 1, 7))
        out[0] = x0
        # the linear states at every sample start first (their own recursion), then the
        # forcing of the stages chunk by chunk
        end = self._matrix[:, self._nf + self._nf // 2 :].T.tolist()
        (e10, e11, e12, e13, e14), (e20, e21, e22, e23, e24), (e30, e31, e32, e33, e34) = end
        t1, t2, mr = x0[4:].tolist()
        lin = []
        for u1, u2 in u.tolist():
            lin.append((t1, t2, mr))
            t1, t2, mr = (
                e10 * t1 + e11 * t2 + e12 * mr + e13 * u1 + e14 * u2,
                e20 * t1 + e21 * t2 + e22 * mr + e23 * u1 + e24 * u2,
                e30 * t1 + e31 * t2 + e32 * mr + e33 * u1 + e34 * u2,
            )
        lin.append((t1, t2, mr))
        out[:, 4:] = lin
        s = np.concatenate([out[:-1, 4:], u], axis=1)
        psi, dpsi, phi, dphi = x0[:4].tolist()
        ie, eps = self._inv_eps, self._eps
        w, v = dpsi * ie, dphi * ie
        advance, consts, n_sub = self._substeps, self._consts, self.n_sub
        nonlinear = []
        for start in range(0, n, _CHUNK):
            rows = zip(*[iter(self._forcing(s[start : start + _CHUNK])[0])] * 8)
            for _ in range(min(_CHUNK, n - start)):
                psi, w, phi, v = advance(islice(rows, n_sub), psi, w, phi, v, consts)
                nonlinear.append((psi, w, phi, v))
        out[1:, :4] = nonlinear
        out[1:, 1] *= eps
        out[1:, 3] *= eps
        return out


_CHUNK = 512  # samples whose stage forcing is held at once by ScalarStepper.run


class _BatchRoute:
    """What the batch routes share: ``B`` twin rotors, their state held inside.

    A route builds what pickling cannot carry (views of its arrays, a module) in
    ``_bind``, called after ``__init__`` and after unpickling; ``_UNPICKLED`` names those
    attributes, and ``_angles`` must be one of them.  ``__init__(params, dt, batch)`` keeps
    the model, the checked sample time, the batch size and the RK4 substeps.
    """

    _UNPICKLED: tuple[str, ...] = ()

    def __init__(self, params: TwinRotorParameters, dt: float, batch: int) -> None:
        self.params = params
        self.dt = _check_dt(dt)
        self.batch = int(batch)
        self.n_sub, self._h = substeps(params, self.dt)

    def _bind(self) -> None:
        raise NotImplementedError

    def __getstate__(self) -> dict[str, Any]:
        # views do not survive pickling (they come back as copies): rebuild them
        state = self.__dict__.copy()
        for key in self._UNPICKLED:
            del state[key]
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._bind()

    @property
    def angles(self) -> np.ndarray:
        """Pitch and yaw (rad), shape (2, B), a read-only view of the state."""
        return self._angles

    def reset(self, mask: np.ndarray) -> None:
        """Put the rotors where ``mask`` is true at rest.

        Parameters
        ----------
        mask : ndarray of bool, shape (B,)
            The rotors to reset; the others keep their states.
        """
        raise NotImplementedError

    def outputs(self, out: np.ndarray) -> None:
        """Write the outputs (pitch, yaw and their rates) of every rotor into ``out[:, :4]``.

        Parameters
        ----------
        out : ndarray, shape (B, k), k >= 4
            Receives pitch, yaw, pitch rate and yaw rate [rad, rad, rad/s, rad/s] in its
            first four columns; the others are left alone.
        """
        raise NotImplementedError

    def advance(self, u: np.ndarray) -> None:
        """Step every rotor over one sample with its voltages held.

        Parameters
        ----------
        u : ndarray, shape (B, 2)
            Main and tail rotor voltages [V], already clipped.
        """
        raise NotImplementedError


class BatchStepper(_BatchRoute):
    """Fast route for a batch of twin rotors: RK4 samples in NumPy, the state held inside.

    Parameters
    ----------
    params : TwinRotorParameters
        The model; its constants are folded into the stage matrices once.
    dt : float
        Sample time [s], > 0.
    batch : int
        Number of twin rotors ``B``, each a column of the state rows.

    Notes
    -----
    The forcing of every stage comes in bulk as in :class:`ScalarStepper`.  Pitch, yaw and
    the two rates are rows of ``B`` values.  Per RK4 stage the nonlinear terms take four NumPy
    calls on whole rows (``sin`` of pitch and of pitch + pi/2 for the cosine, the logistic
    function of both scaled rates for the Coulomb terms, two products for the gyroscopic
    term); the derivative is linear in them, so one matrix product gives both the next stage
    point and the running RK4 sum.  The rates are held as ``W = 2 psi' / eps`` and
    ``V = 2 phi' / eps``, so that ``tanh(psi' / eps) = 2 expit(W) - 1`` needs no scaling; the
    pitch + pi/2 row is integrated with the pitch and re-derived from it at each sample.
    Every call works on ``B`` numbers, so the time per sample grows slowly with ``B`` up to a
    few hundred rotors.
    """

    # Rows of a stage block (one per substep and stage, each row B numbers): the substep's
    # start, the running RK4 sum, the stage point (5 rows each: psi, phi, W, V, psi + pi/2,
    # the outputs first), then the terms the derivative is linear in.
    _START, _SUM, _POINT = 0, 5, 10
    _SIN, _COS, _SW, _SV, _GYRO, _A, _F, _ONE = 15, 16, 17, 18, 19, 20, 21, 22
    _ROWS = 23
    _UNPICKLED = ("_y", "_angles", "_output_scale", "_plan")

    def __init__(self, params: TwinRotorParameters, dt: float, batch: int) -> None:
        super().__init__(params, dt, batch)
        p, nb, n_sub, h = params, self.batch, self.n_sub, self._h
        eps = p.coulomb_velocity
        self._half_eps = 0.5 * eps
        self._lock = bool(p.lock_yaw)
        self._law = p.thrust_law
        self._nf = 8 * n_sub
        matrix, a, b = _forcing_map(p, self.dt, 1.0)
        self._matrix = np.ascontiguousarray(matrix.T)  # one row per forcing value
        # full-size coefficients: in NumPy's inner loops a broadcast column costs twice as
        # much as an operand of the same shape
        self._a = np.repeat(a[:, None], nb, axis=1)
        self._b = np.repeat(b[:, None], nb, axis=1)
        self._s = np.zeros((5, nb))  # tau1, tau2, M_R, u1, u2 at the sample start
        self._z = np.empty((matrix.shape[1], nb))
        self._force = np.empty((self._nf, nb))
        self._blocks = np.zeros((n_sub + 1, 4, self._ROWS, nb))
        self._blocks[:, :, self._ONE] = 1.0
        self._blocks[n_sub, 0, self._POINT + 4] = 0.5 * math.pi  # at rest: psi + pi/2
        # derivative of the stage point rows from the rows POINT .. ONE of its block
        d = np.zeros((5, self._ROWS - self._POINT))
        psi, phi, w, v, shifted = range(5)
        sin, sw, sv, gyro, fa, ff, one = (
            r - self._POINT
            for r in (self._SIN, self._SW, self._SV, self._GYRO, self._A, self._F, self._ONE)
        )
        d[psi, w] = d[shifted, w] = eps / 2  # psi' = (eps / 2) W
        d[w, fa] = 2 / eps  # W' = (2 / eps) psi''; the A row is M1 / I1
        d[w, gyro] = -p.Kgy  # the gyro row is A V cos(psi)
        d[w, sin] = -2 / eps * p.Mg / p.I1
        d[w, w] = -p.B1psi / p.I1
        d[w, sw] = -4 / eps * p.B2psi / p.I1  # tanh(W / 2) = 2 expit(W) - 1
        d[w, one] = 2 / eps * p.B2psi / p.I1
        if not self._lock:
            d[phi, v] = eps / 2
            d[v, ff] = 2 / eps  # the F row is (M2 - M_R) / I2
            d[v, v] = -p.B1phi / p.I2
            d[v, sv] = -4 / eps * p.B2phi / p.I2
            d[v, one] = 2 / eps * p.B2phi / p.I2
        # per stage: [running sum; next stage point] from [start; running sum; point; terms]
        eye, zero = np.eye(5), np.zeros((5, 5))
        self._stage_matrices = []
        for c, weight in ((0.5, 1.0), (0.5, 2.0), (1.0, 2.0), (None, 1.0)):
            add = np.hstack([zero, eye, (h / 6.0) * weight * d])
            if c is None:  # the last stage completes the sum: the next substep's start
                point = add
            else:
                point = np.hstack([eye, zero, c * h * d])
            self._stage_matrices.append(np.ascontiguousarray(np.vstack([add, point])))
        self._bind()

    def _bind(self) -> None:
        """Views into the blocks: the current state and, per stage, the rows it works on.

        Built once: slicing in the loop would cost about as much as the arithmetic.
        """
        blocks, n, start, pt = self._blocks, self.n_sub, self._START, self._POINT
        self._y = blocks[n, 0, pt : pt + 5]
        self._angles = self._y[:2].view()  # pitch, yaw
        self._angles.flags.writeable = False
        self._output_scale = np.array([1.0, 1.0, self._half_eps, self._half_eps])
        self._plan = []
        for j in range(n):
            for s in range(4):
                blk = blocks[j, s]
                nxt = blocks[j, s + 1] if s < 3 else blocks[j + 1, 0]
                if s == 0:  # the substep's start, into the start rows of its 4 blocks
                    copy = (blocks[j, :, start : start + 5], blk[pt : pt + 5])
                else:
                    copy = None
                if self._lock:  # no cosine, no yaw rate, no gyroscopic term
                    terms = (blk[pt], blk[self._SIN], blk[pt + 2], blk[self._SW], None)
                else:
                    gyro = (blk[self._COS], blk[pt + 3], blk[self._GYRO], blk[self._A])
                    terms = (blk[pt : pt + 5 : 4], blk[self._SIN : self._COS + 1],
                             blk[pt + 2 : pt + 4], blk[self._SW : self._SV + 1], gyro)  # fmt: skip
                out = nxt[self._SUM : pt + 5]
                self._plan.append((copy, *terms, self._stage_matrices[s], blk, out))

    @property
    def state(self) -> np.ndarray:
        """States (B, 7), ``STATE_NAMES`` order and units (a copy); assign to set them.

        With ``lock_yaw`` the yaw rate is held at 0.
        """
        y = self._y
        x = np.empty((self.batch, 7))
        x[:, 0] = y[0]
        x[:, 1] = y[2] * self._half_eps
        x[:, 2] = y[1]
        x[:, 3] = y[3] * self._half_eps
        x[:, 4:] = self._s[:3].T
        return x

    @state.setter
    def state(self, x: np.ndarray) -> None:
        x = np.asarray(x, dtype=float)
        y = self._y
        y[0] = x[:, 0]
        y[1] = x[:, 2]
        y[2] = x[:, 1] / self._half_eps
        y[3] = 0.0 if self._lock else x[:, 3] / self._half_eps
        y[4] = x[:, 0] + 0.5 * math.pi
        self._s[:3] = x[:, 4:].T

    def reset(self, mask: np.ndarray) -> None:
        self._y[:, mask] = 0.0
        self._y[4, mask] = 0.5 * math.pi
        self._s[:3, mask] = 0.0

    def outputs(self, out: np.ndarray) -> None:
        np.multiply(self._y[:4].T, self._output_scale, out=out[:, :4])

    def advance(self, u: np.ndarray) -> None:
        s, z, force, nf, n = self._s, self._z, self._force, self._nf, self.n_sub
        s[3:] = u.T
        np.dot(self._matrix, s, out=z)
        thrust(z[:nf], self._a, self._b, self._law, out=force)
        blocks = self._blocks
        blocks[:n, :, self._A : self._F + 1] = force.reshape(n, 4, 2, -1)
        blocks[:n, :, self._F] -= z[nf : nf + nf // 2].reshape(n, 4, -1)
        s[:3] = z[nf + nf // 2 :]
        y = self._y
        np.add(y[0], 0.5 * math.pi, out=y[4])
        first = blocks[0, 0]
        first[self._SUM : self._POINT + 5].reshape(2, 5, -1)[...] = y  # sum and point
        sin, dot, mul = np.sin, np.dot, np.multiply
        for copy, ang, trig, rate, logit, gyro, mat, blk, out in self._plan:
            if copy is not None:
                copy[0][...] = copy[1]
            sin(ang, out=trig)
            expit(rate, out=logit)
            if gyro is not None:
                cos_row, v_row, g_row, a_row = gyro
                mul(cos_row, v_row, out=g_row)
                mul(g_row, a_row, out=g_row)
            dot(mat, blk, out=out)


# ------------------------------------------------------------------------ compiled route
def _compiled():
    """The compiled kernels module when it runs and has the twin rotor stepper, else None."""
    from .. import kernels

    c = getattr(kernels, "_c", None)
    if kernels.BACKEND != "c" or not hasattr(c, "twin_rotor_run"):
        return None
    return c


#: The compiled stepper's parameters, in the order of ``TRS_PARAMS`` in kernels/twin_rotor.h.
KERNEL_PARAMETERS = ("I1", "I2", "a1", "b1", "a2", "b2", "Mg", "B1psi", "B2psi", "B1phi",
                     "B2phi", "Kgy", "k1", "k2", "T11", "T10", "T21", "T20", "Tp", "T0", "kc",
                     "coulomb_velocity")  # fmt: skip


def _kernel_params(p: TwinRotorParameters) -> np.ndarray:
    """The parameter vector of the compiled stepper (:data:`KERNEL_PARAMETERS`)."""
    return np.array([float(getattr(p, n)) for n in KERNEL_PARAMETERS])


def _kernel_arguments(p: TwinRotorParameters, dt: float) -> tuple[np.ndarray, tuple]:
    """The parameter vector and the trailing arguments ``(n_sub, h, lock_yaw, square_law)``
    of ``twin_rotor_run`` for the sample time ``dt``."""
    n_sub, h = substeps(p, dt)
    return _kernel_params(p), (n_sub, h, bool(p.lock_yaw), p.thrust_law == "square")


class CompiledScalarStepper(ScalarStepper):
    """:class:`ScalarStepper` with the samples run by the compiled RK4 of ``flexid._kernels``.

    The compiled loop evaluates the equations of
    :func:`~flexid.envs.twin_rotor_physics.derivatives` in the RK4 of
    :func:`~flexid.envs.twin_rotor_physics.step_states`, with the model's constants divided out
    once and ``sin``, ``cos`` and ``tanh`` as polynomials within a few eps of the exact values
    (absolute error); with possible FMA contraction it differs from the reference route by
    rounding only.

    Parameters
    ----------
    params : TwinRotorParameters
        The model, handed to the compiled loop as a vector of constants.
    dt : float
        Sample time [s], > 0, as for :class:`ScalarStepper`.
    """

    def __init__(self, params: TwinRotorParameters, dt: float) -> None:
        # not ScalarStepper.__init__: the tables of the Python route are not used here
        self.params = params
        self.dt = _check_dt(dt)
        self._c = _compiled()
        self._k, self._args = _kernel_arguments(params, self.dt)
        self.n_sub = self._args[0]
        self._x = np.empty((1, 7))
        self._u = np.empty((1, 1, 2))

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        del state["_c"]  # a module does not pickle; the unpickling process finds its own
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._c = _compiled()

    def step(self, x, u1: float, u2: float) -> tuple[float, ...]:
        xb, ub = self._x, self._u
        xb[0] = x
        ub[0, 0, 0], ub[0, 0, 1] = u1, u2
        self._c.twin_rotor_run(self._k, xb, ub, None, *self._args)
        return tuple(xb[0].tolist())

    def run(self, u: np.ndarray, x0: np.ndarray) -> np.ndarray:
        n = u.shape[0]
        out = np.empty((n + 1, 7))
        out[0] = x0
        x = np.array(x0, dtype=float).reshape(1, 7)
        u3 = np.ascontiguousarray(u, dtype=float).reshape(n, 1, 2)
        self._c.twin_rotor_run(self._k, x, u3, out[1:].reshape(n, 1, 7), *self._args)
        return out


class CompiledBatchStepper(_BatchRoute):
    """:class:`BatchStepper`'s interface, the samples run by the compiled RK4.

    Parameters
    ----------
    params : TwinRotorParameters
        The model, handed to the compiled loop as a vector of constants.
    dt : float
        Sample time [s], > 0: ``round(dt / substep)`` RK4 substeps.
    batch : int
        Number of twin rotors ``B``, the rows of the state array.
    """

    _UNPICKLED = ("_c", "_angles")  # a module does not pickle: the unpickler finds its own

    def __init__(self, params: TwinRotorParameters, dt: float, batch: int) -> None:
        super().__init__(params, dt, batch)
        self._k, self._args = _kernel_arguments(params, self.dt)
        self._x = np.zeros((self.batch, 7))
        self._u = np.empty((1, self.batch, 2))
        self._bind()

    def _bind(self) -> None:
        self._c = _compiled()
        self._angles = self._x[:, 0:3:2].T  # pitch and yaw, a view
        self._angles.flags.writeable = False

    @property
    def state(self) -> np.ndarray:
        """States (B, 7) (a copy); assign to set them.  With ``lock_yaw`` the yaw rate is 0."""
        return self._x.copy()

    @state.setter
    def state(self, x: np.ndarray) -> None:
        self._x[...] = np.asarray(x, dtype=float)
        if self.params.lock_yaw:
            self._x[:, 3] = 0.0

    def reset(self, mask: np.ndarray) -> None:
        self._x[mask] = 0.0

    def outputs(self, out: np.ndarray) -> None:
        np.take(self._x, _OUTPUT_COLUMNS, axis=1, out=out[:, :4])

    def advance(self, u: np.ndarray) -> None:
        self._u[0] = u
        self._c.twin_rotor_run(self._k, self._x, self._u, None, *self._args)


def scalar_stepper(params: TwinRotorParameters, dt: float) -> ScalarStepper:
    """The fastest available route for one twin rotor.

    Parameters
    ----------
    params : TwinRotorParameters
        The model of the rotor to step.
    dt : float
        Sample time [s] of every step.

    Returns
    -------
    ScalarStepper
        A :class:`CompiledScalarStepper` when the compiled kernels run, else a
        :class:`ScalarStepper`.
    """
    if _compiled() is not None:
        return CompiledScalarStepper(params, dt)
    return ScalarStepper(params, dt)


def batch_stepper(
    params: TwinRotorParameters, dt: float, batch: int
) -> BatchStepper | CompiledBatchStepper:
    """The fastest available route for a batch of twin rotors.

    Parameters
    ----------
    params : TwinRotorParameters
        The model, shared by the whole batch.
    dt : float
        Sample time [s], the same for every rotor.
    batch : int
        Number of rotors ``B`` stepped together.

    Returns
    -------
    BatchStepper or CompiledBatchStepper
        The compiled stepper when the compiled kernels run, else the NumPy one.
    """
    if _compiled() is not None:
        return CompiledBatchStepper(params, dt, batch)
    return BatchStepper(params, dt, batch)


def simulate(
    u: Any, params: TwinRotorParameters | None = None, dt: float = 0.1, x0: Any = None
) -> np.ndarray:
    """Response of the twin rotor to sampled motor voltages (held over each sample).

    Parameters
    ----------
    u : array_like, shape (N, 2)
        Main and tail rotor voltages [V]; clipped to ``+-u_max``.  Shape (N,) drives the main
        rotor only.
    params : TwinRotorParameters, optional
        Default :class:`~flexid.envs.twin_rotor_physics.TwinRotorParameters` ``()``.
    dt : float
        Sample time [s], > 0; default 0.1.
    x0 : array_like, shape (7,), optional
        Initial state (default rest), columns
        :data:`~flexid.envs.twin_rotor_physics.STATE_NAMES`; with ``lock_yaw`` its yaw rate
        must be 0.

    Returns
    -------
    ndarray, shape (N, 4)
        :data:`~flexid.envs.twin_rotor_physics.OUTPUT_NAMES` at ``t = k dt``.

    Notes
    -----
    Computed by the compiled RK4 when the kernels run, else by :class:`ScalarStepper`;
    :func:`~flexid.envs.twin_rotor_physics.reference_trajectory` gives the same samples up
    to rounding.
    """
    p, u, dt, x = _run_arguments(u, params, dt, x0)
    return scalar_stepper(p, dt).run(u, x)[:-1, _OUTPUT_COLUMNS]
