"""
Identify the flexible manipulator: the paper's figures
=======================================================

The experiment of Nasir & Tokhi on flexid's simulated Sheffield manipulator: 2,300 samples of
end-point acceleration at 1 ms under a random +-0.3 N m hub torque, an ARX(8, 8, 1) model
fitted on the first two thirds and validated on the last third. Least squares is the
reference; HBCSD searches the paper's cost in flexid's default search space (stable pole
pairs, numerator fitted for each denominator) with a budget of 5,000 function evaluations.

The figures are those of the paper: convergence, measured and model output with the error,
power spectra, the pole-zero map and the residual correlation tests with their 95 % bands.
"""

# %%
# Data and models
# ---------------
# ``generate`` simulates the plant through its measurement chain (drive amplifier,
# accelerometer, anti-aliasing filter); the same seed always gives the same record.
import flexid
from flexid.report.plots import (
    plot_convergence,
    plot_correlations,
    plot_pole_zero,
    plot_spectra,
    plot_time_response,
)

data = flexid.generate("manipulator", preset="paper-manipulator", seed=0)
ls = flexid.identify(data, na=8, nb=8, nk=1, optimiser="ls")
hb = flexid.identify(data, na=8, nb=8, nk=1, optimiser="hbcsd", budget=5_000, seed=1)
print(data)
print(f"least squares cost {ls.cost_value:.4g}, HBCSD cost {hb.cost_value:.4g} "
      f"after {hb.nfev} FE (ratio {hb.cost_value / ls.cost_value:.3f})")

# %%
# Convergence
# -----------
# The best cost found against function evaluations; the dashed line is the least-squares
# cost, the exact optimum of this (one-step) cost.
plot_convergence({"HBCSD": hb.history}, reference=hb.cost_ls)

# %%
# Time response on the validation record
# --------------------------------------
# The one-step prediction uses the measured past outputs; the simulation (free run) uses
# only the input. An eighth-order ARX model predicts one step well but does not simulate
# this record: with its measurement chain the plant has more than eight poles in the band
# that matters (see the table of fits in :doc:`/measurements/paper-character`).
val = hb.validation.arrays()
output, unit = hb.data_info["output"], hb.data_info["output_unit"]  # from the record
plot_time_response(
    val["time"], val["y"], val["y_one_step"], output=output, unit=unit,
    title=f"validation: one-step prediction, fit {hb.validation.fit_one_step:.1f} %",
)

# %%
plot_time_response(
    val["time"], val["y"], val["y_simulation"], output=output, unit=unit,
    title=f"validation: simulation, fit {hb.validation.fit_simulation:.1f} %",
)

# %%
# Frequency response: power spectra
# ---------------------------------
# Welch spectra of the measured output and of the model's simulated output.
plot_spectra(
    val["psd_frequency"],
    {"measured": val["psd_measured"], "model (simulation)": val["psd_model"]},
    unit=unit, title=f"Power spectral density of {output} (validation)",
)

# %%
# Pole-zero map
# -------------
# Every candidate of the pole-pair search space is stable, so the poles lie inside the unit
# circle.
plot_pole_zero(hb.model.poles(), hb.model.zeros(), title="HBCSD, ARX(8, 8, 1)")

# %%
# Correlation tests
# -----------------
# Autocorrelation of the residual, cross-correlation with the input and the higher-order
# tests of Billings and Voon, with the 95 % band +-1.96/sqrt(N).
plot_correlations(
    hb.validation.correlation_panels(), title="Residual correlation tests (validation)"
)

# sphinx_gallery_thumbnail_number = 2
