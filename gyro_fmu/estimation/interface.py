"""GyroObserver.fmu's interface, declared once: names, units, bounds, descriptions.

Like gyro_fmu.model.interfaces (the physics' FMUs), this generates the native FMU's
variables.h and model descriptions (gyro_fmu.fmu.native), its documentation page and the
pythonfmu flavour's variables (fmu_src/GyroObserver.py). The tuning parameters are the
fields of ObserverTuning, with the units and descriptions of their metadata.
"""

from __future__ import annotations

import numpy as np

from ..core.structs.observer import TUNING
from ..core.structs.plant import PARAMS
from ..model.drive import TwoToneDrive
from ..model.interfaces import FmuInterface, StructCopy, Var, dataclass_parameters
from ..model.parameters import (
    DEFAULT_PRESET,
    PARAMETER_BOUNDS,
    PARAMETER_UNITS,
    PRESET_DRIVE_AMPLITUDE,
    PRESETS,
    default_initial_guess,
)
from ..model.plant import GyroPlantModel
from .observer_rate import RATE_KINDS
from .observer_tuning import ObserverTuning

_GUESS = default_initial_guess(PRESETS[DEFAULT_PRESET])
_UNITS = {**PARAMETER_UNITS, "Omega_z": "rad/s"}
#: The unknowns in the order of the outputs (GyroStateObserver.output_row()).
ESTIMATED = ("Omega_z", "kxx", "kyy", "kxy", "dxx", "dyy", "dxy", "m")
HAT = {"Omega_z": "Omega_hat"}  # the patent's Omega_z' is published as Omega_hat
#: What each of observer_rate.RATE_KINDS means, for the p_rate_* descriptions.
RATE_KIND_MEANINGS = {
    "constant": "Omega_z held",
    "rough": ("Omega_z wandering (random walks of four graded intensities, from what a "
              "tenth of rate_bandwidth needs to 100 times it)"),
    "slow": "Omega_z moving smoothly at up to a tenth of rate_bandwidth",
    "agile": "Omega_z moving smoothly at up to rate_bandwidth"}
#: The outputs in the order of GyroStateObserver.output_row().
OUTPUTS = ("x_hat", "vx_hat", "y_hat", "vy_hat", *(HAT.get(n, f"{n}_hat") for n in ESTIMATED),
           *(f"sigma_{n}" for n in ESTIMATED))


def _reference_inputs(stop_time: float, step: float) -> np.ndarray:
    """The default scenario's two-tone drive and the noise-free measurements of its plant
    (default preset, 1 rad/s)."""
    amplitude = PRESET_DRIVE_AMPLITUDE[DEFAULT_PRESET]
    drive = TwoToneDrive(A1=amplitude, A2=amplitude)
    n = round(stop_time / step)
    t = np.arange(n + 1) * step
    ux = drive.ux_many(t)
    plant = GyroPlantModel(PRESETS[DEFAULT_PRESET])
    s = np.empty((n + 1, 4))
    s[0] = plant.s
    for k in range(n):
        plant.step(float(ux[k]), 0.0, 1.0, step)
        s[k + 1] = plant.s
    out = np.zeros(t.size, dtype=[("time", float)] + [(c, float) for c in (
        "ux", "uy", "x_meas", "vx_meas", "y_meas", "vy_meas")])
    out["time"], out["ux"] = t, ux
    for j, name in enumerate(("x_meas", "vx_meas", "y_meas", "vy_meas")):
        out[name] = s[:, j]
    return out


#: The observer's C files (fmu_src/core/, one per idea: gyro_observer_internal.h lists them).
OBSERVER_SOURCES = ("gyro_observer.c", "gyro_observer_held.c", "gyro_observer_correct.c",
                    "gyro_observer_refit.c", "gyro_observer_imm.c", "gyro_observer_rates.c",
                    "gyro_observer_monitor.c")


OBSERVER = FmuInterface(
    identifier="GyroObserver",
    description=(
        "State observer of the single-axis-control-input gyroscope (US 2011/0314910 A1, "
        "eqs. 5-9): from the drive ux, uy and two measured signals (measured_pair 1: x, y; "
        "2: vx, vy) it estimates the states and the 8 unknowns kxx, kyy, kxy, dxx, dyy, dxy, "
        "m and Omega_z with 1-sigma uncertainties. Inputs are held over each communication "
        "step exactly as GyroPlant holds them; outputs at t+h are predictions from data up to "
        "t. Output status: 0 ok, 1 warning, 2 lost (then the step is refused with fmi2Discard "
        "and the cause logged)."),
    variables=(
        *(Var(f"{n}_0", "parameter", _GUESS[n], PARAMETER_UNITS[n], f"initial guess of {n}",
              **PARAMETER_BOUNDS[n]) for n in PARAMETER_UNITS),
        Var("Omega_z_0", "parameter", 0.0, "rad/s", "initial guess of Omega_z"),
        Var("measured_pair", "parameter", 1, None,
            "measured signals used: 1 positions x, y; 2 velocities vx, vy",
            integer=True, min=1, max=2),
        *(Var(f, "parameter", 0.0, "Hz",
              f"the drive's tone {f[1]} (TwoToneDrive's {f}), if known: with both tones set, "
              "the first step warns when they leave the rate weakly observable (their "
              "Cramer-Rao bound on Omega_z over 40 ms more than twice that of tones around "
              "the guessed modes); 0: not known, no check", min=0.0) for f in ("f1", "f2")),
        *dataclass_parameters(ObserverTuning),
        Var("ux", "input", 0.0, "N", "x-axis drive force, held over the step"),
        Var("uy", "input", 0.0, "N", "y-axis drive force, held over the step"),
        Var("x_meas", "input", 0.0, "m", "measured x-axis position"),
        Var("vx_meas", "input", 0.0, "m/s", "measured x-axis velocity"),
        Var("y_meas", "input", 0.0, "m", "measured y-axis position"),
        Var("vy_meas", "input", 0.0, "m/s", "measured y-axis velocity"),
        Var("x_hat", "output", 0.0, "m", "estimated x-axis position"),
        Var("vx_hat", "output", 0.0, "m/s", "estimated x-axis velocity"),
        Var("y_hat", "output", 0.0, "m", "estimated y-axis position"),
        Var("vy_hat", "output", 0.0, "m/s", "estimated y-axis velocity"),
        *(Var(HAT.get(n, f"{n}_hat"), "output", 0.0, _UNITS[n], f"estimate of {n}")
          for n in ESTIMATED),
        *(Var(f"sigma_{n}", "output", 0.0, _UNITS[n], f"1-sigma uncertainty of {n}", min=0.0)
          for n in ESTIMATED),
        *(Var(f"p_rate_{k}", "output", 1.0 / len(RATE_KINDS), "1",
              f"probability that the rate is {k} ({RATE_KIND_MEANINGS[k]}; adaptive rate "
              "model; a fixed one: 1 for its kind, 0 else)", min=0.0, max=1.0)
          for k in RATE_KINDS),
        Var("status", "output", 0.0, "1",
            "observer health: 0 ok; 1 warning (innovations outside their band, logged: the "
            "estimates may be off more than their sigmas say); 2 lost (the filter diverged "
            "or lost its numerical footing: the step is refused with fmi2Discard and the "
            "cause logged, every other output NaN). A Real so that hosts reading every "
            "output as Real get it", min=0.0, max=2.0),
    ),
    doctor_check=({}, OUTPUTS),
    reference_inputs=_reference_inputs,
    core_sources=("gyro_rng.c", "gyro_plant.c", *OBSERVER_SOURCES, "gyro_signals.c",
                  "gyro_linalg.c", "gyro_excitation.c"),
    struct_copies=(StructCopy("guess_of", PARAMS, {"*": "{}_0"}),
                   StructCopy("tuning_of", TUNING)),
)
