"""
Identify the twin rotor: optimisers on one problem
==================================================

The paper's second experiment on flexid's simulated twin rotor MIMO system: 8,000 samples
of pitch at 0.1 s under a random +-1 V main-rotor voltage (vertical channel), an ARX(5, 5, 1)
model. Three optimisers (HBCSD, BFA and DE) search the same problem from the same seed with
the same budget of 3,000 function evaluations; least squares is the reference.
"""

# %%
import matplotlib.pyplot as plt
import numpy as np

import flexid
from flexid.envs.twin_rotor_physics import pitch_linear_mode
from flexid.report.plots import plot_convergence, plot_pole_zero, plot_spectra, plot_time_response

data = flexid.generate("twin-rotor", preset="paper-twin-rotor", seed=0)
fits = {
    name: flexid.identify(data, na=5, nb=5, nk=1, optimiser=name, budget=3_000, seed=1)
    for name in ("hbcsd", "bfa", "de")
}
reference = fits["de"].cost_ls
for name, ident in fits.items():
    print(f"{name:6} cost / least squares = {ident.cost_value / reference:.4f}, "
          f"simulation fit on validation {ident.validation.fit_simulation:.1f} %")

# %%
# Convergence
# -----------
plot_convergence({name.upper(): ident.history for name, ident in fits.items()},
                 reference=reference)

# %%
# Time response of the best model
# -------------------------------
# The free-run simulation of the held-out third of the record.
best = min(fits.values(), key=lambda ident: ident.cost_value)
val = best.validation.arrays()
output, unit = best.data_info["output"], best.data_info["output_unit"]  # from the record
window = val["time"] < val["time"][0] + 120.0  # two minutes, to see the oscillations
plot_time_response(
    val["time"][window], val["y"][window], val["y_simulation"][window],
    output=output, unit=unit,
    title=f"{best.optimiser}: simulation, fit {best.validation.fit_simulation:.1f} %",
)

# %%
# Frequency response
# ------------------
# The spectra of measured and simulated pitch, and the model's frequency response from
# the main-rotor voltage to pitch; the pitch mode of the linearised plant is marked.
f_pitch, zeta = pitch_linear_mode()
fig = plot_spectra(
    val["psd_frequency"],
    {"measured": val["psd_measured"], "model (simulation)": val["psd_model"]},
    unit=unit, title=f"Power spectral density of {output} (validation)",
)
fig.axes[0].axvline(f_pitch, color="k", ls=":", lw=1)

# %%
f = np.linspace(0.01, 5.0, 500)  # Hz, up to the Nyquist frequency of 0.1 s sampling
_, response = best.model.to_dlti().freqresp(w=2 * np.pi * f * data.dt)  # w in rad/sample
fig, ax = plt.subplots(figsize=(6.4, 4.0), layout="constrained")
ax.loglog(f, np.abs(response))
ax.axvline(f_pitch, color="k", ls=":", lw=1, label=f"linearised pitch mode {f_pitch:.3f} Hz")
ax.set_xlabel("frequency [Hz]")
ax.set_ylabel("|G| [rad/V]")
ax.set_title(f"{best.optimiser}, ARX(5, 5, 1): frequency response")
ax.grid(True, which="both", alpha=0.3)
ax.legend()

# %%
# Pole-zero map
# -------------
plot_pole_zero(best.model.poles(), best.model.zeros(), title=f"{best.optimiser}, ARX(5, 5, 1)")

# sphinx_gallery_thumbnail_number = 2
