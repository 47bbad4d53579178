"""GyroSensor's presets: realistic gyros as sets of its parameters, each with a datasheet
the build measures from the FMU's own output (documentation/datasheet-<name>.json).

A preset is the start values a host sets (fmpy: `simulate_fmu(..., start_values=
SENSOR_PRESETS[name])`; an SSP parameter set; the importer's parameter dialog); "consumer"
is the FMU's defaults. Each other preset is a gyro as fabricated (its drive mode, the
sense mode's split from it, Q, cross stiffness, mass) with the sensor around it as
`gyros.sensor_settings` builds it: the design values 5 % off in the stiffnesses and the
mass and 20 % in the dampings, the drive's tones at the default's ratios to the drive
mode with the default's static deflection, and a pick-off noise density scaled by `noise`
against the default's.
"""

from __future__ import annotations

import math

from .gyros import sensor_settings


def _gyro(f_drive: float, split: float, q: float, coupling: float, m: float) -> dict[str, float]:
    """kxx ... m of a gyro: drive mode f_drive (Hz), sense mode (1 + split) f_drive, both of
    quality factor q, kxy = coupling sqrt(kxx kyy), dxy 10 % of dxx, proof mass m (kg)."""
    kxx, kyy = (2 * math.pi * f_drive) ** 2, (2 * math.pi * f_drive * (1 + split)) ** 2
    dxx, dyy = math.sqrt(kxx) / q, math.sqrt(kyy) / q
    return {"kxx": kxx, "kyy": kyy, "kxy": coupling * math.sqrt(kxx * kyy), "dxx": dxx,
            "dyy": dyy, "dxy": 0.1 * dxx, "m": m}


def _preset(gyro: dict[str, float], noise: float) -> dict[str, float]:
    s = sensor_settings(gyro)
    s.pop("seed")
    s["noise_x"] *= noise
    s["noise_y"] *= noise
    return s


#: name -> GyroSensor start values. consumer: the FMU's defaults (park-horowitz: modes 3.0
#: and 3.7 kHz, Q 1,900, kxy 13 % of sqrt(kxx kyy)); high-q: a better-matched, high-Q gyro
#: with a quieter readout (modes 4.0 and 4.2 kHz, Q 4,000, coupling 2 %, noise / 3);
#: low-cost: a loosely made one (modes 2.5 and 2.75 kHz, Q 300, coupling 10 %, noise x 3).
#: (A matched gyro of Q 8,000 and a 2 % split was tried: its noise bounds varied 10 times
#: between seeds, so no datasheet holds for it; docs/datasheet.md.)
SENSOR_PRESETS: dict[str, dict[str, float]] = {
    "consumer": {},
    "high-q": _preset(_gyro(4000.0, 0.05, 4000.0, 0.02, 5e-9), 1 / 3),
    "low-cost": _preset(_gyro(2500.0, 0.10, 300.0, 0.10, 2e-8), 3.0),
}
