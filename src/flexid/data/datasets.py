"""Synthetic input-output datasets from the simulated plants, reproducible from a seed.

:func:`generate` drives a plant (``"manipulator"`` or ``"twin-rotor"``) with an excitation
signal from :mod:`flexid.data.signals`, adds white Gaussian measurement noise if asked, and returns
an :class:`~flexid.data.IOData` whose metadata records everything needed to regenerate it:
plant, physical parameters, signal and options, seed, sample time, noise, preset and flexid
version.  No timestamps: the same arguments give byte-identical files.

Presets reproduce the experiments of Nasir & Tokhi (section 4.1):

``paper-manipulator``
    2,300 samples at 1 ms, uniform random hub torque in +-0.3 N m, end-point acceleration.
``paper-twin-rotor``
    vertical channel (yaw locked), 8,000 samples at 0.1 s, uniform random +-1 V on the main
    rotor held 0.1 s (tail rotor 0 V), pitch output.

Both plants are read through their measurement and actuation chain (``sensors="lab"``,
the default; ``sensors="ideal"`` reads the plant's states exactly).  The manipulator preset
adds white noise of 1 % of the acceleration's standard deviation (the accelerometer's
analog channel); the twin rotor's pitch is an encoder count, whose quantisation is its
measurement error, so its preset adds none.  ``noise_std`` overrides either.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from .._json import jsonable
from .._validate import checked_keywords, integer, positive_real
from ..errors import DataError, UnknownNameError, plain_number
from .plants import PLANTS, Plant, all_presets, get_plant
from .records import IOData
from .signals import SIGNALS, make_signal

__all__ = ["PLANTS", "PRESETS", "generate"]

class _Presets(Mapping):
    """Every registered plant's presets by name, each with its ``plant`` (read live, so a
    plant registered later adds its own)."""

    def __getitem__(self, name: str) -> dict[str, Any]:
        return all_presets()[name]

    def __iter__(self):
        return iter(all_presets())

    def __len__(self) -> int:
        return len(all_presets())

    def __repr__(self) -> str:
        return f"PRESETS({list(self)})"


#: The presets of every plant (:attr:`flexid.data.plants.Plant.presets`), by name.
PRESETS: Mapping[str, dict[str, Any]] = _Presets()


def _indices(plant: str, kind: str, names: list[str], wanted: list[str]) -> list[int]:
    """Positions of the channels ``wanted`` among ``names`` (``kind``: "input" or "output")."""
    for name in wanted:
        if name not in names:
            raise UnknownNameError(f"{plant} {kind}", name, names)
    return [names.index(name) for name in wanted]


def _noise_levels(noise_std: Any, clean: np.ndarray) -> np.ndarray:
    """Per-output noise standard deviations from a number, a list or a "1%" string."""
    n_out = clean.shape[1]
    if noise_std is None:
        return np.zeros(n_out)
    if isinstance(noise_std, str):
        text = noise_std.strip()
        if not text.endswith("%"):
            raise DataError(f"noise_std must be a number, a list or a percentage, not {text!r}")
        try:
            fraction = float(text[:-1]) / 100.0
        except ValueError:
            raise DataError(f"noise_std {text!r} is not a percentage") from None
        if not (np.isfinite(fraction) and fraction >= 0):
            raise DataError(f"noise_std {text!r} must be a percentage >= 0")
        return fraction * clean.std(axis=0)
    levels = np.broadcast_to(np.asarray(noise_std, dtype=float), (n_out,)).copy()
    if not np.all(np.isfinite(levels) & (levels >= 0)):
        raise DataError(f"noise_std must be finite and >= 0, got {plain_number(noise_std)}")
    return levels


def _preset_settings(preset: str | None, plant: str) -> dict[str, Any]:
    """The settings of ``preset`` (none without one), checked to be for ``plant``."""
    settings: dict[str, Any] = {}
    if preset is not None:
        if preset not in PRESETS:
            raise UnknownNameError("preset", preset, PRESETS)
        settings = {k: v for k, v in PRESETS[preset].items() if k != "description"}
        if plant != settings["plant"]:
            raise DataError(f"preset {preset!r} is for the {settings['plant']}, not {plant!r}")
    return settings


def _signal_options(spec: Plant, preset: str | None, signal: str) -> dict[str, Any]:
    """The default options of ``signal``: the preset's for its own signal, the plant's
    levels for a level signal, none otherwise."""
    level_signals = ("uniform", "random", "prbs", "aprbs")
    if preset is not None and signal == PRESETS[preset]["signal"]:
        return dict(PRESETS[preset].get("signal_options", {}))
    if signal in level_signals:
        return dict(spec.signal_options)  # +-0.3 N m or +-1 V
    return {}


@checked_keywords
def generate(
    plant: str,
    *,
    signal: str | None = None,
    n_samples: int | None = None,
    seed: int = 0,
    dt: float | None = None,
    outputs: Sequence[str] | None = None,
    inputs: Sequence[str] | None = None,
    noise_std: Any = None,
    signal_options: Mapping[str, Any] | None = None,
    plant_params: Mapping[str, Any] | None = None,
    preset: str | None = None,
    sensors: str = "lab",
) -> IOData:
    """Simulate a plant under an excitation signal and return the record.

    Parameters
    ----------
    plant : str
        A registered plant (:data:`flexid.data.plants.PLANTS`): ``"manipulator"`` or
        ``"twin-rotor"``.
    signal : str, optional
        Excitation (see :func:`flexid.data.signals.describe_signals`), default ``"uniform"``.
    n_samples : int, optional
        Record length (default: the preset's, or 2,000 / 3,000 samples).
    seed : int
        One seed for the whole record: ``SeedSequence(seed)`` is split into the signal's and
        the noise's generators, so switching the noise on does not change the input.
    dt : float, optional
        Sample time in s (default 1 ms manipulator, 0.1 s twin rotor).
    outputs, inputs : list of str, optional
        Channels to keep (default all outputs; for the twin rotor the excited inputs).  For
        the twin rotor ``inputs=["main_rotor"]`` excites only the main rotor (tail at 0 V).
    noise_std : float, list or str, optional
        White Gaussian measurement noise on the outputs: one standard deviation for all, one
        per output (in output units), or ``"p%"`` of each noise-free output's standard
        deviation.  Default: none (presets: ``"1%"``).
    signal_options : mapping, optional
        Options of the signal, e.g. ``{"low": -0.3, "high": 0.3}`` or ``{"order": 10}``.
    plant_params : mapping, optional
        Physical parameter overrides, e.g. ``{"payload_mass": 0.02}`` or ``{"lock_yaw": True}``.
    preset : str, optional
        ``"paper-manipulator"`` or ``"paper-twin-rotor"``; explicit arguments override it.
    sensors : {"lab", "ideal"}
        ``"lab"`` (default): the plant read through its measurement and actuation chain
        (drive lag, sensor dynamics, anti-aliasing filter, encoder steps, tachometer noise;
        see the plant's parameters).  ``"ideal"``: the chain switched off, the plant's states
        read exactly.  ``plant_params`` apply on top of either.

    Returns
    -------
    IOData
        Inputs (N, n_u) and outputs (N, n_y) with names, units and the metadata above.
    """
    settings = _preset_settings(preset, plant)
    spec = get_plant(plant)
    explicit = {
        "signal": signal,
        "n_samples": n_samples,
        "dt": dt,
        "outputs": outputs,
        "inputs": inputs,
        "noise_std": noise_std,
    }
    for key, value in explicit.items():
        if value is not None:
            settings[key] = value
    signal = settings.get("signal", "uniform")
    if signal.replace("-", "_") not in SIGNALS:
        raise UnknownNameError("signal", signal, SIGNALS)
    options = _signal_options(spec, preset, signal)
    options.update(signal_options or {})
    params_over = dict(settings.get("plant_params", {}))
    params_over.update(plant_params or {})
    n = settings.get("n_samples", spec.n_samples)
    n = integer(n, "n_samples", error=DataError, minimum=2)
    dt = positive_real(settings.get("dt", spec.dt), "dt", error=DataError, unit="s")

    params = spec.make_parameters(params_over, sensors=sensors)
    signal_seq, noise_seq = np.random.SeedSequence(seed).spawn(2)
    signal_rng = np.random.default_rng(signal_seq)
    input_names, input_units = list(spec.input_names), list(spec.input_units)
    excited = _indices(plant, "input", input_names, list(settings.get("inputs") or input_names))
    u = np.zeros((n, len(input_names)))
    for i in excited:
        u[:, i] = make_signal(signal, n, dt, rng=signal_rng, **options)
    y_all, u = spec.simulate(spec.physics(), u, params, dt)
    y_all = spec.measure(y_all, params)
    output_names, output_units = list(spec.output_names), list(spec.output_units)
    cols = _indices(plant, "output", output_names, list(settings.get("outputs") or output_names))
    clean = y_all[:, cols]
    levels = _noise_levels(settings.get("noise_std"), clean)
    from ..envs.sensors import total_noise  # flexid.envs registers the environments

    levels = total_noise(levels, spec.noise_floor(params)[cols])
    noise_rng = np.random.default_rng(noise_seq)
    y = clean + noise_rng.standard_normal(clean.shape) * levels
    if settings.get("inputs"):
        u = u[:, excited]
        input_names = [input_names[i] for i in excited]
        input_units = [input_units[i] for i in excited]
    from .._version import __version__

    metadata = {
        "plant": plant,
        "preset": preset,
        "parameters": jsonable(dataclasses.asdict(params)),
        "signal": signal,
        "signal_options": jsonable(options),
        "seed": seed,
        "dt": dt,
        "n_samples": n,
        "noise_std": [float(v) for v in levels],
        "noise_rule": settings.get("noise_std"),
        "sensors": sensors,
        "flexid_version": __version__,
        "source": f"flexid simulated {plant}",
    }
    return IOData(
        u,
        y,
        dt=dt,
        input_names=input_names,
        output_names=[output_names[i] for i in cols],
        input_units=input_units,
        output_units=[output_units[i] for i in cols],
        metadata=metadata,
    )

