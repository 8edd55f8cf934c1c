"""
The simulated plants: modes, measurement chain and test responses
=================================================================

What the two simulated plants do before any identification: the flexible manipulator's
modes and its frequency response from hub torque to end-point acceleration, without and with
the measurement and actuation chain; its response to the classic bang-bang torque; and the
twin rotor's pitch response to a random main-rotor voltage, with the pitch mode of the
linearised plant.
"""

# %%
# Modes of the flexible manipulator
# ---------------------------------
# The finite-difference beam (40 sections) against the exact roots of the continuous
# hub-beam's characteristic equation.
import dataclasses

import matplotlib.pyplot as plt
import numpy as np

import flexid
from flexid.data.signals import bang_bang
from flexid.envs import beam
from flexid.envs.twin_rotor_physics import pitch_linear_mode

lab = beam.BeamParameters()
ideal = beam.BeamParameters(**beam.IDEAL_SENSORS)
exact = beam.exact_frequencies(lab, n_modes=3)
fd = beam.natural_frequencies(lab, n_modes=3)
for k, (fe, ff) in enumerate(zip(exact, fd), start=1):
    print(f"mode {k}: exact {fe:7.3f} Hz, finite differences {ff:7.3f} Hz "
          f"({100 * (ff / fe - 1):+.2f} %)")

# %%
# Frequency response, torque to end-point acceleration
# ----------------------------------------------------
# The bare beam (every mode beyond the third damped like the third) and the beam seen
# through its lab chain (higher modes damped in proportion to their frequency, drive
# amplifier lag, accelerometer, anti-aliasing filter at 0.2 of the 1 kHz sampling rate); the
# dotted lines are the exact modes.
tip = beam.OUTPUT_NAMES.index("tip_acceleration")
f = np.logspace(0, np.log10(500.0), 600)  # Hz, up to the Nyquist frequency at 1 ms


def magnitude(A, B, C, D):
    """|C (j w I - A)^-1 B + D| of the end-point acceleration channel on the grid ``f``."""
    eye = np.eye(A.shape[0])
    return np.array([
        abs(C[tip] @ np.linalg.solve(2j * np.pi * fk * eye - A, B[:, 0]) + D[tip, 0])
        for fk in f
    ])


fig, ax = plt.subplots(figsize=(7.0, 4.2), layout="constrained")
ax.loglog(f, magnitude(*beam.continuous_model(ideal)), label="beam alone")
ax.loglog(f, magnitude(*beam.measured_model(lab, dt=1e-3)), label="with the lab chain")
for fk in exact:
    ax.axvline(fk, color="k", ls=":", lw=1)
ax.set_xlabel("frequency [Hz]")
ax.set_ylabel("|G| [(m/s$^2$)/(N m)]")
ax.set_title("Flexible manipulator: torque to end-point acceleration")
ax.grid(True, which="both", alpha=0.3)
ax.legend()

# %%
# Bang-bang response
# ------------------
# +0.3 N m for 0.3 s, then -0.3 N m for 0.3 s: the hub turns to about 0.55 rad and the beam
# keeps vibrating, its end-point deflection dominated by the first mode.
dt = 1e-3
torque = bang_bang(2000, dt, amplitude=0.3, width=0.3)
y = beam.simulate(torque, ideal, dt=dt)
t = np.arange(torque.size) * dt
fig, axes = plt.subplots(3, 1, sharex=True, figsize=(7.0, 6.0),
                         layout="constrained")
axes[0].plot(t, torque)
axes[0].set_ylabel("torque [N m]")
axes[1].plot(t, y[:, beam.OUTPUT_NAMES.index("hub_angle")])
axes[1].set_ylabel("hub angle [rad]")
axes[2].plot(t, 1e3 * y[:, beam.OUTPUT_NAMES.index("tip_deflection")])
axes[2].set_ylabel("tip deflection [mm]")
axes[2].set_xlabel("time [s]")
for ax in axes:
    ax.grid(True, alpha=0.3)
axes[0].set_title("Flexible manipulator, bang-bang torque (ideal sensors)")
print(f"hub angle after the manoeuvre: {y[-1, 0]:.3f} rad")

# %%
# Twin rotor: pitch under a random voltage
# ----------------------------------------
# The paper's record: a random +-1 V main-rotor voltage held for 0.1 s, yaw locked (the
# rig's one-degree-of-freedom vertical channel), pitch read by a 4,096-count encoder. Pitch
# oscillates at the lightly damped pitch mode of the gravity pendulum.
trs = flexid.generate("twin-rotor", preset="paper-twin-rotor", seed=0)
f_pitch, zeta = pitch_linear_mode()
print(f"linearised pitch mode: {f_pitch:.4f} Hz, damping ratio {zeta:.4f}")
window = slice(0, 600)  # the first minute
fig, axes = plt.subplots(2, 1, sharex=True, figsize=(7.0, 4.6),
                         layout="constrained")
axes[0].step(trs.time[window], trs.u[window, 0], where="post", lw=0.8)
axes[0].set_ylabel("main rotor [V]")
axes[1].plot(trs.time[window], trs.y[window, 0])
axes[1].set_ylabel("pitch [rad]")
axes[1].set_xlabel("time [s]")
for ax in axes:
    ax.grid(True, alpha=0.3)
axes[0].set_title(f"Twin rotor (pitch mode {f_pitch:.3f} Hz, zeta {zeta:.3f})")

# %%
# Plant variants
# --------------
# The parameters are a frozen dataclass: ``dataclasses.replace`` changes one of them, for
# example a 20 g tip payload, which lowers the modes.
heavy = dataclasses.replace(lab, payload_mass=0.02)
print("modes with a 20 g payload [Hz]:", np.round(beam.exact_frequencies(heavy), 3))
