"""GyroSensor.fmu's interface, declared once: names, units, bounds, descriptions.

One FMU takes the vehicle's rate Omega_z in and gives the sensor's rate out at any
communication step the host chooses: inside, the two-tone drive, the gyro as fabricated
(with pick-off noise, on by default) and the observer that starts from the design values
run at a fixed internal step (fmu_src/core/gyro_sensor.h), then the readout filters,
clamps and quantizes the observer's rate. Names follow GyroPlant (the gyro as
fabricated), GyroObserver (the design values it starts from, its tuning) and
TwoToneDrive (the drive).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..core.structs import plant as structs
from ..core.structs.observer import TUNING
from ..estimation.interface import OBSERVER_SOURCES
from ..estimation.observer_tuning import ObserverTuning
from ..model.drive import TwoToneDrive
from ..model.interfaces import (
    FmuInterface,
    StructCopy,
    Var,
    dataclass_parameters,
    input_table,
)
from ..model.parameters import (
    DEFAULT_PRESET,
    PARAMETER_BOUNDS,
    PARAMETER_DESCRIPTIONS,
    PARAMETER_UNITS,
    PRESET_DRIVE_AMPLITUDE,
    PRESETS,
    default_initial_guess,
)
from ..options import SEED_MAX

_TRUTH = PRESETS[DEFAULT_PRESET]
_DESIGN = default_initial_guess(_TRUTH)
_AMPLITUDE = PRESET_DRIVE_AMPLITUDE[DEFAULT_PRESET]
_DRIVE = TwoToneDrive(A1=_AMPLITUDE, A2=_AMPLITUDE)

#: Pick-off noise on by default: 1e-4 of each measured position's amplitude in the
#: default drive (x 6.6e-9 m, y 4.8e-9 m) per 5 us sample, a displacement noise density
#: of about 2e-15 m/sqrt(Hz): a good capacitive readout. Given per sample at
#: NOISE_STEP; the core keeps the density at any internal step (gyro_sensor.h).
NOISE_X, NOISE_Y = 6.6e-13, 4.8e-13
NOISE_STEP = 5e-6
#: Internal step: 0 chooses it from the design's faster mode (gyro_sensor_step: at most
#: 20 us, 12.6 samples per period of that mode). Readout: a 16-bit output over
#: +-full_scale (about 2000 deg/s), 100 Hz.
INTERNAL_STEP = 0.0
STEP_MAX, OMEGA_H = 20e-6, 0.5
BANDWIDTH = 100.0
FULL_SCALE = 35.0
RESOLUTION = 2 * FULL_SCALE / 2 ** 16

#: The observer's tuning: GyroObserver's defaults (the adaptive rate model; measured on
#: the default gyro at noise 1e-4, a constant 1 rad/s then a 5 Hz sine of 0.2 rad/s: RMS
#: error 7.7e-3 / 2.3e-2 rad/s against 3.2e-2 / 3.4e-2 for the one tracking model and
#: 7.7e-3 / 7.1e-2 for the constant one; docs/gyro-sensor.md). Overridden here by name.
#: rate_model 4 (the moving bank) follows small slow sways that rate_model 0 misreads,
#: but re-converges worse after a step from rest; it is a setting, not the default
#: (docs/gyro-sensor.md, "What falls short").
TUNING_STARTS: dict[str, float] = {}
OUTPUTS = ("Omega_meas", "sigma_Omega_meas", "Omega_hat", "status", "saturated")


def _reference_inputs(stop_time: float, step: float) -> np.ndarray:
    """0 rad/s, then a step to 1 rad/s at a fifth of the run."""
    t = np.arange(round(stop_time / step) + 1) * step
    return input_table(t, {"Omega_z": np.where(t >= 0.2 * stop_time, 1.0, 0.0)})


SENSOR = FmuInterface(
    identifier="GyroSensor",
    description=(
        "MEMS vibratory gyroscope as a sensor (US 2011/0314910 A1, Fig. 2): input Omega_z, "
        "the true rate about the sense axis, held over the communication step; output "
        "Omega_meas, the sensor's rate. Inside, at a fixed internal step: the two-tone drive "
        "(eq. 10), the gyro as fabricated with pick-off noise (eqs. 3-4) and the state "
        "observer (eqs. 5-9) that starts from the design values and learns the fabrication "
        "imperfections and the rate; then the readout: a 2nd-order Butterworth output filter "
        "of the declared bandwidth, the full-scale limit and the quantization. Any "
        "communication step at least the internal step. status: 0 ok, 1 warning, 2 lost."),
    variables=(
        *(Var(n, "parameter", getattr(_TRUTH, n), PARAMETER_UNITS[n],
              f"as fabricated: {d}", **PARAMETER_BOUNDS[n])
          for n, d in PARAMETER_DESCRIPTIONS.items()),
        Var("noise_x", "parameter", NOISE_X, "m", "std of white noise on the measured x "
            "per 5 us sample (the density is kept at any internal step: per sample "
            "noise_x sqrt(5 us / internal step))", min=0.0, nominal=1e-12),
        Var("noise_y", "parameter", NOISE_Y, "m", "std of white noise on the measured y "
            "per 5 us sample (as noise_x)", min=0.0, nominal=1e-12),
        Var("seed", "parameter", 0, None, "seed of the noise generator", integer=True, min=0,
            max=SEED_MAX),
        *(Var(f"{n}_0", "parameter", _DESIGN[n], PARAMETER_UNITS[n],
              f"design value of {n}: where the observer starts", **PARAMETER_BOUNDS[n])
          for n in PARAMETER_UNITS),
        Var("Omega_z_0", "parameter", 0.0, "rad/s", "the observer's initial rate"),
        Var("A1", "parameter", _DRIVE.A1, "N", "drive: amplitude of tone 1"),
        Var("f1", "parameter", _DRIVE.f1, "Hz", "drive: frequency of tone 1", min=0.0),
        Var("A2", "parameter", _DRIVE.A2, "N", "drive: amplitude of tone 2"),
        Var("f2", "parameter", _DRIVE.f2, "Hz", "drive: frequency of tone 2", min=0.0),
        *(replace(v, start=TUNING_STARTS.get(v.name, v.start))
          for v in dataclass_parameters(ObserverTuning)),
        Var("internal_step", "parameter", INTERNAL_STEP, "s",
            "fixed step of the drive, the gyro and the observer inside; 0: chosen from the "
            "design's faster mode (0.5 / omega, at most 20 us)", min=0.0, max=1e-3),
        Var("bandwidth", "parameter", BANDWIDTH, "Hz",
            "-3 dB bandwidth of the output filter (2nd-order Butterworth)", min=0.0,
            min_exclusive=True),
        Var("full_scale", "parameter", FULL_SCALE, "rad/s",
            "output range: Omega_meas is clamped to +-full_scale", min=0.0,
            min_exclusive=True),
        Var("resolution", "parameter", RESOLUTION, "rad/s",
            "output quantization step (one least significant bit; 0: not quantized)",
            min=0.0),
        Var("Omega_z", "input", 0.0, "rad/s", "true angular rate about the sense axis, held "
            "over the communication step"),
        Var("Omega_meas", "output", 0.0, "rad/s", "the sensor's rate: the observer's estimate "
            "through the output filter, clamped to +-full_scale and quantized"),
        Var("sigma_Omega_meas", "output", 0.0, "rad/s", "1-sigma uncertainty of the rate: "
            "the observer's, with the quantization's", min=0.0),
        Var("Omega_hat", "output", 0.0, "rad/s",
            "the observer's rate estimate before the readout"),
        Var("status", "output", 0.0, "1", "0 ok; 1 warning (logged: the estimate may be off "
            "more than its sigma says); 2 lost (the step is refused with fmi2Discard, the "
            "outputs NaN)", min=0.0, max=2.0),
        Var("saturated", "output", 0.0, "1",
            "1 while Omega_meas is clamped at +-full_scale", min=0.0, max=1.0),
    ),
    doctor_check=({"Omega_z": 1.0}, OUTPUTS),
    reference_inputs=_reference_inputs,
    core_sources=("gyro_rng.c", "gyro_plant.c", *OBSERVER_SOURCES, "gyro_signals.c",
                  "gyro_linalg.c", "gyro_excitation.c", "gyro_sensor.c"),
    default_experiment=(0.05, 1e-3),
    datasheet=True,
    struct_copies=(
        StructCopy("truth_of", structs.PARAMS), StructCopy("design_of", structs.PARAMS,
                                                           {"*": "{}_0"}),
        StructCopy("noise_of", structs.PICKOFF_NOISE, {"*": "noise_{}"}, zero=("vx", "vy")),
        StructCopy("drive_of", structs.TWO_TONE_DRIVE), StructCopy("readout_of", structs.READOUT),
        StructCopy("tuning_of", TUNING)),
)
