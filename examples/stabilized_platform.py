"""A single-axis stabilized platform that needs a gyroscope: GyroSensor.fmu in the rate
loop of StabilizedPlatform.fmu, stepped at 1 ms in a plain fmpy loop, beside the same
loop with an ideal sensor. Only fmpy and the FMUs at run time.

    gyro-fmu fmus --dest fmus --fmi 2        # the FMUs, once
    python examples/stabilized_platform.py --fmus fmus --stop-time 2 --figure platform.png

The platform (inertia J) sits on a vehicle swaying at w_b(t) = 0.5 sin(2 pi 2 t) rad/s,
which shakes it through bearing friction c; a motor torque from a PI loop on the
measured rate holds it still in inertial space (StabilizedPlatform's readme):

    J dw/dt = c (w_b - w) + tau,      theta = integral of w  (the pointing error)
    tau = -Kp w_meas - Ki integral of w_meas

w_meas is the platform's own w (an ideal gyro) or GyroSensor's Omega_meas with the
platform's w as its input Omega_z. Each FMU steps from t to t + h on the other's outputs
at t, as a co-simulation master does (the same loop as an SSP package of these FMUs in
libcosim or Ecos: `gyro-fmu ssp --system platform`). Prints the RMS pointing error of
both loops; exit 1 if GyroSensor's loop does not stabilize the platform (RMS pointing
error over 5 times the ideal loop's, plus the drift its own bias explains).
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

SWAY_AMPLITUDE, SWAY_FREQUENCY = 0.5, 2.0  # rad/s, Hz: the vehicle's rate


def vehicle_rate(t: float) -> float:
    return SWAY_AMPLITUDE * math.sin(2 * math.pi * SWAY_FREQUENCY * t)


class Fmu:
    """One FMU in a plain fmpy loop: set inputs, step, get outputs by name."""

    def __init__(self, path: Path, name: str) -> None:
        md = read_model_description(str(path))
        self.folder = extract(str(path))
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.fmu = FMU2Slave(guid=md.guid, unzipDirectory=self.folder,
                             modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
        self.fmu.instantiate()
        self.fmu.setupExperiment(startTime=0.0)
        self.fmu.enterInitializationMode()
        self.fmu.exitInitializationMode()

    def get(self, *names: str) -> list[float]:
        return self.fmu.getReal([self.vr[n] for n in names])

    def step(self, t: float, h: float, **inputs: float) -> None:
        self.fmu.setReal([self.vr[n] for n in inputs], list(inputs.values()))
        self.fmu.doStep(t, h)

    def close(self) -> None:
        self.fmu.terminate()
        self.fmu.freeInstance()
        shutil.rmtree(self.folder, ignore_errors=True)


# --8<-- [start:simulate]
def simulate(stop: float, h: float, platform: Fmu, gyro: Fmu | None) -> dict[str, np.ndarray]:
    """The loop at the host step h: the ideal sensor (gyro None) or GyroSensor."""
    n = round(stop / h)
    out = {k: np.empty(n + 1) for k in ("t", "w", "theta", "w_meas")}
    for k in range(n + 1):
        t = k * h
        w, theta = platform.get("w", "theta")  # the outputs at t
        w_meas = w if gyro is None else gyro.get("Omega_meas")[0]
        out["t"][k], out["w"][k], out["theta"][k], out["w_meas"][k] = t, w, theta, w_meas
        if k == n:
            break
        platform.step(t, h, w_b=vehicle_rate(t), w_meas=w_meas)  # both on the values at t
        if gyro is not None:
            gyro.step(t, h, Omega_z=w)
    return out
# --8<-- [end:simulate]


def run(fmus: Path, stop: float, h: float, with_gyro: bool) -> tuple[dict, float | None]:
    platform = Fmu(fmus / "StabilizedPlatform.fmu", "platform")
    gyro = Fmu(fmus / "GyroSensor.fmu", "gyro") if with_gyro else None
    try:
        out = simulate(stop, h, platform, gyro)
        return out, None if gyro is None else gyro.get("sigma_Omega_meas")[0]
    finally:
        for f in (platform, gyro):
            if f is not None:
                f.close()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fmus", type=Path, default=Path("fmus"), help="folder of the FMUs")
    ap.add_argument("--stop-time", type=float, default=2.0, help="s")
    ap.add_argument("--step", type=float, default=1e-3, help="the host's step, s")
    ap.add_argument("--figure", type=Path, help="write the pointing errors to this PNG")
    args = ap.parse_args()
    ideal, _ = run(args.fmus, args.stop_time, args.step, False)
    real, sigma = run(args.fmus, args.stop_time, args.step, True)
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
