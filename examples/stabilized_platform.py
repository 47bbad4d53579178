"""A single-axis stabilized platform that needs a gyroscope: GyroSensor.fmu in the rate
loop of a system model stepped at 1 ms, beside the same loop with an ideal sensor. Only
fmpy and the FMU at run time.

    gyro-fmu fmus --dest fmus --fmi 2        # the FMUs, once
    python examples/stabilized_platform.py --fmus fmus --stop-time 2 --figure platform.png

The platform (inertia J) sits on a vehicle whose rate w_b(t) shakes it through bearing
friction c; a motor torque holds it still in inertial space:

    J dw/dt = c (w_b - w) + tau,      theta = integral of w  (the pointing error)
    tau = -Kp w_meas - Ki integral of w_meas                 (a PI rate loop)

w_meas is the ideal sensor's w, or GyroSensor's Omega_meas with the platform's w as its
input Omega_z. The plant is integrated exactly over each 1 ms step with tau held (a
first-order system); the sensor holds w over the step, as any co-simulation master does.
Prints the RMS pointing error of both loops; exit 1 if GyroSensor's loop does not
stabilize the platform (RMS pointing error over 5 times the ideal loop's, plus the
drift its own bias explains).
"""

from __future__ import annotations

import argparse
import math
import shutil
import sys
from pathlib import Path

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

J = 2e-3  # kg m^2, the platform's inertia
C = 0.05  # N m s / rad, bearing friction to the vehicle
KP, KI = 0.15, 20.0  # the rate loop: N m s / rad, N m / rad


def vehicle_rate(t: float) -> float:
    """The vehicle's rate (rad/s): a slow sway and an engine vibration."""
    return 0.5 * math.sin(2 * math.pi * 1.5 * t) + 0.2 * math.sin(2 * math.pi * 12.0 * t)


class Sensor:
    """GyroSensor.fmu in a plain fmpy loop."""

    def __init__(self, path: Path) -> None:
        md = read_model_description(str(path))
        self.folder = extract(str(path))
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.fmu = FMU2Slave(guid=md.guid, unzipDirectory=self.folder,
                             modelIdentifier=md.coSimulation.modelIdentifier,
                             instanceName="gyro")
        self.fmu.instantiate()
        self.fmu.setupExperiment(startTime=0.0)
        self.fmu.enterInitializationMode()
        self.fmu.exitInitializationMode()

    def read(self) -> tuple[float, float]:
        return tuple(self.fmu.getReal([self.vr["Omega_meas"], self.vr["sigma_Omega_meas"]]))

    def step(self, t: float, h: float, rate: float) -> None:
        self.fmu.setReal([self.vr["Omega_z"]], [rate])
        self.fmu.doStep(t, h)

    def close(self) -> None:
        self.fmu.terminate()
        self.fmu.freeInstance()
        shutil.rmtree(self.folder, ignore_errors=True)


# --8<-- [start:simulate]
def simulate(stop: float, h: float, sensor: Sensor | None) -> dict[str, np.ndarray]:
    """The platform with the ideal sensor (None) or GyroSensor, at the host step h."""
    n = round(stop / h)
    w = theta = integral = 0.0
    out = {k: np.empty(n + 1) for k in ("t", "w", "theta", "w_meas")}
    a = math.exp(-C * h / J)  # exact over h for tau and w_b held
    for k in range(n + 1):
        t = k * h
        w_meas = w if sensor is None else sensor.read()[0]
        out["t"][k], out["w"][k], out["theta"][k], out["w_meas"][k] = t, w, theta, w_meas
        if k == n:
            break
        integral += w_meas * h
        tau = -KP * w_meas - KI * integral
        w_inf = vehicle_rate(t) + tau / C  # where w would settle with these held
        if sensor is not None:
            sensor.step(t, h, w)
        w_next = w_inf + (w - w_inf) * a
        theta += w_inf * h + (w - w_inf) * (1 - a) * J / C  # integral of w over the step
        w = w_next
    return out
# --8<-- [end:simulate]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fmus", type=Path, default=Path("fmus"), help="folder of the FMUs")
    ap.add_argument("--stop-time", type=float, default=2.0, help="s")
    ap.add_argument("--step", type=float, default=1e-3, help="the host's step, s")
    ap.add_argument("--figure", type=Path, help="write the pointing errors to this PNG")
    args = ap.parse_args()
    ideal = simulate(args.stop_time, args.step, None)
    sensor = Sensor(args.fmus / "GyroSensor.fmu")
    try:
        real = simulate(args.stop_time, args.step, sensor)
        sigma = sensor.read()[1]
    finally:
        sensor.close()
    late = ideal["t"] >= 0.5 * args.stop_time
    rms = {name: float(np.sqrt(np.mean(r["theta"][late] ** 2)))
           for name, r in (("ideal", ideal), ("GyroSensor", real))}
    err = real["w_meas"] - real["w"]
    print(f"platform on a swaying vehicle, {args.stop_time:g} s at a {args.step * 1e3:g} ms "
          "step: RMS pointing error over the second half")
    print(f"  ideal gyro: {rms['ideal'] * 1e3:.3f} mrad")
    print(f"  GyroSensor: {rms['GyroSensor'] * 1e3:.3f} mrad (its rate error: RMS "
          f"{np.sqrt(np.mean(err[late] ** 2)):.2e} rad/s, mean {np.mean(err[late]):+.2e} "
          f"rad/s; its last 1-sigma {sigma:.2e} rad/s)")
    if args.figure:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
        ax[0].plot(real["t"], real["w"], label="platform rate (true)")
        ax[0].plot(real["t"], real["w_meas"], label="GyroSensor Omega_meas", lw=0.8)
        ax[0].set_ylabel("rad/s")
        ax[0].legend(loc="upper right")
        ax[1].plot(ideal["t"], ideal["theta"] * 1e3, label="ideal gyro")
        ax[1].plot(real["t"], real["theta"] * 1e3, label="GyroSensor")
        ax[1].set_ylabel("pointing error (mrad)")
        ax[1].set_xlabel("time (s)")
        ax[1].legend(loc="upper right")
        fig.tight_layout()
        fig.savefig(args.figure, dpi=110)
        print(f"wrote {args.figure}")
    bound = 5 * rms["ideal"] + abs(np.mean(err[late])) * args.stop_time
    return 0 if rms["GyroSensor"] <= bound else 1


if __name__ == "__main__":
    sys.exit(main())
