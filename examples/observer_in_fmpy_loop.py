"""GyroObserver.fmu estimating the rate of GyroPlant.fmu driven by TwoToneDrive.fmu, in a
plain fmpy loop: no gyro_fmu at run time, only fmpy and the three native FMUs.

    gyro-fmu fmus --dest fmus --fmi 2        # the FMUs, once
    python examples/observer_in_fmpy_loop.py --fmus fmus --rate 1.0 --stop-time 0.1

The loop is what any co-simulation master does (Jacobi): read every output at t, set
the inputs, step every FMU from t to t + h. The plant turns at --rate rad/s; the
observer starts from its own default guesses (5 % off the plant's parameters) and is
told nothing else. Exit 1 if its estimate ends more than 4 of its own sigmas off.
"""

from __future__ import annotations

import argparse
import shutil
import sys
from pathlib import Path

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave


class Unit:
    """One FMU instance with its variables by name."""

    def __init__(self, path: Path, start: dict[str, float] | None = None) -> None:
        self.md = read_model_description(str(path))
        self.folder = extract(str(path))
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=self.folder,
                             modelIdentifier=self.md.coSimulation.modelIdentifier,
                             instanceName=path.stem)
        self.fmu.instantiate()
        self.fmu.setupExperiment(startTime=0.0)
        for name, value in (start or {}).items():
            self.set(name, value)
        self.fmu.enterInitializationMode()
        self.fmu.exitInitializationMode()

    def get(self, *names: str) -> list[float]:
        return self.fmu.getReal([self.vr[n] for n in names])

    def set(self, name: str, value: float) -> None:
        self.fmu.setReal([self.vr[name]], [value])

    def close(self) -> None:
        self.fmu.terminate()
        self.fmu.freeInstance()
        shutil.rmtree(self.folder, ignore_errors=True)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fmus", type=Path, default=Path("fmus"), help="folder of the FMI 2.0 FMUs")
    ap.add_argument("--rate", type=float, default=1.0, help="Omega_z, rad/s")
    ap.add_argument("--stop-time", type=float, default=0.1, help="s")
    ap.add_argument("--step", type=float, default=5e-6, help="communication step, s")
    args = ap.parse_args()
    drive = Unit(args.fmus / "TwoToneDrive.fmu")
    plant = Unit(args.fmus / "GyroPlant.fmu")
    observer = Unit(args.fmus / "GyroObserver.fmu")
    plant.set("Omega_z", args.rate)  # an input no unit drives: it holds this value
    h, n = args.step, round(args.stop_time / args.step)
    try:
        for k in range(n):
            t = k * h
            ux, uy = drive.get("ux", "uy")
            x, vx, y, vy = plant.get("x", "vx", "y", "vy")
            plant.set("ux", ux), plant.set("uy", uy)
            for name, value in zip(("ux", "uy", "x_meas", "vx_meas", "y_meas", "vy_meas"),
                                   (ux, uy, x, vx, y, vy), strict=True):
                observer.set(name, value)
            for unit in (drive, plant, observer):
                unit.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=h)
        rate, sigma, status = observer.get("Omega_hat", "sigma_Omega_z", "status")
    finally:
        for unit in (drive, plant, observer):
            unit.close()
    print(f"Omega_z {args.rate:g} rad/s: Omega_hat {rate:.6f} rad/s, 1-sigma {sigma:.2g}, "
          f"status {status:g} after {n * h:g} s")
    return 0 if abs(rate - args.rate) <= 4 * sigma else 1


if __name__ == "__main__":
    sys.exit(main())
