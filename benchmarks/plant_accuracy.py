"""GyroPlant.fmu through fmpy vs an independent DOP853 solution of the held-input ODE.

    python benchmarks/plant_accuracy.py

Prints, per measured signal, max |FMU - reference| / max |reference| over 100 ms
for the park-horowitz preset with constant and with sine Omega_z (the figure
tests/test_plant_fmu.py holds below 1e-8).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from gyro_fmu.cosim.master import Component, Connection, run_cosimulation
from gyro_fmu.fmu.build import MODELS_DIR
from gyro_fmu.model.parameters import preset
from gyro_fmu.system.run import ensure_fmus

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from reference import held_input_reference

H = 5e-6


def main() -> None:
    ensure_fmus()
    print(f"{'rate':<10}{'x':>11}{'vx':>11}{'y':>11}{'vy':>11}  (max error / peak, 100 ms)")
    for label, rate in (("constant", {"kind": 1, "offset": 1.0}),
                        ("sine", {"kind": 4, "offset": 0.0, "amplitude": 1.0,
                                  "frequency": 100.0})):
        comps = [Component("drive", MODELS_DIR / "TwoToneDrive.fmu"),
                 Component("rate", MODELS_DIR / "RateProfile.fmu", rate),
                 Component("plant", MODELS_DIR / "GyroPlant.fmu")]
        conns = [Connection("drive.ux", "plant.ux"),
                 Connection("rate.Omega_z", "plant.Omega_z")]
        r = run_cosimulation(comps, conns, 0.1, H)
        got = np.column_stack([r[f"plant.{s}"] for s in ("x", "vx", "y", "vy")])
        ref = held_input_reference(preset(), r["drive.ux"][:-1], r["rate.Omega_z"][:-1], H)
        rel = np.max(np.abs(got - ref), axis=0) / np.max(np.abs(ref), axis=0)
        print(f"{label:<10}" + "".join(f"{v:11.2e}" for v in rel))


if __name__ == "__main__":
    main()
