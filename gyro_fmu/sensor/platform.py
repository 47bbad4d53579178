"""StabilizedPlatform.fmu's interface, declared once: the system example for GyroSensor.

A single-axis platform on a vehicle held still in inertial space by a PI rate loop on a
gyro's reading (fmu_src/core/gyro_platform.h). Wired with GyroSensor (the platform's w to
its Omega_z, its Omega_meas back to w_meas) and a vehicle (RateProfile's Omega_z to w_b)
it is the closed loop of docs/tutorials/sensor-in-system.md: `platform_system` gives
those components and connections, for the fmpy master and for an SSP package.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..core.structs.plant import PLATFORM_PARAMS
from ..cosim.system import Component, Connection
from ..model.interfaces import FmuInterface, StructCopy, Var, input_table

#: The example's platform and loop: a 2e-3 kg m2 platform, bearing friction 0.05 N m s/rad,
#: a PI rate loop of about 12 Hz crossover (Kp / J = 75 1/s) with integral action 20 N m/rad.
J, C, KP, KI = 2e-3, 0.05, 0.15, 20.0
#: The vehicle of the example: a sway of 0.5 rad/s at 2 Hz (RateProfile kind 4).
SWAY_AMPLITUDE, SWAY_FREQUENCY = 0.5, 2.0
#: The example's run: 2 s at the host's 1 ms step.
STOP_TIME, STEP = 2.0, 1e-3


def _reference_inputs(stop_time: float, step: float) -> np.ndarray:
    """The vehicle's sway as w_b; w_meas a constant 0.1 rad/s (the loop open)."""
    t = np.arange(round(stop_time / step) + 1) * step
    return input_table(t, {"w_b": SWAY_AMPLITUDE * np.sin(2 * np.pi * SWAY_FREQUENCY * t),
                           "w_meas": np.full(t.size, 0.1)})


PLATFORM = FmuInterface(
    identifier="StabilizedPlatform",
    description=(
        "Single-axis stabilized platform, the system example for GyroSensor (not of the "
        "patents): J dw/dt = c (w_b - w) + tau, tau = -Kp w_meas - Ki integral(w_meas), "
        "theta = integral(w), stepped exactly with w_b and w_meas held. Wire GyroSensor's "
        "Omega_meas to w_meas and w to its Omega_z."),
    variables=(
        Var("J", "parameter", J, "kg.m2", "the platform's inertia", min=0.0,
            min_exclusive=True),
        Var("c", "parameter", C, "N.m.s/rad", "bearing friction to the vehicle", min=0.0,
            min_exclusive=True),
        Var("Kp", "parameter", KP, "N.m.s/rad", "rate loop: proportional gain", min=0.0),
        Var("Ki", "parameter", KI, "N.m/rad", "rate loop: integral gain", min=0.0),
        Var("w_0", "parameter", 0.0, "rad/s", "the platform's initial rate"),
        Var("w_b", "input", 0.0, "rad/s", "the vehicle's rate, held over the step"),
        Var("w_meas", "input", 0.0, "rad/s", "the gyro's reading of w, held over the step"),
        Var("w", "output", 0.0, "rad/s", "the platform's inertial rate (the gyro's input)"),
        Var("theta", "output", 0.0, "rad", "the pointing error: the integral of w"),
        Var("tau", "output", 0.0, "N.m", "the motor torque over the last step"),
    ),
    doctor_check=({"w_b": 0.5, "w_meas": 0.1}, ("w", "theta", "tau")),
    reference_inputs=_reference_inputs,
    core_sources=("gyro_platform.c",),
    default_experiment=(1.0, 1e-3),
    struct_copies=(StructCopy("params_of", PLATFORM_PARAMS),),
)


def platform_system(models_dir: Path, ideal: bool = False
                    ) -> tuple[list[Component], list[Connection]]:
    """The example's closed loop as FMUs of models_dir: the vehicle (RateProfile, the
    sway) drives the platform; GyroSensor reads the platform's rate and the loop reads
    GyroSensor. ideal: no gyro, the loop reads the platform's own w."""
    models_dir = Path(models_dir)
    vehicle = Component("vehicle", models_dir / "RateProfile.fmu",
                        {"kind": 4, "offset": 0.0, "amplitude": SWAY_AMPLITUDE,
                         "frequency": SWAY_FREQUENCY, "t_start": 0.0})
    platform = Component("platform", models_dir / "StabilizedPlatform.fmu")
    links = [Connection("vehicle.Omega_z", "platform.w_b")]
    if ideal:
        return [vehicle, platform], [*links, Connection("platform.w", "platform.w_meas")]
    gyro = Component("gyro", models_dir / "GyroSensor.fmu")
    return [vehicle, platform, gyro], [*links, Connection("platform.w", "gyro.Omega_z"),
                                       Connection("gyro.Omega_meas", "platform.w_meas")]
