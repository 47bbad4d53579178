"""GyroSensor's observer under a slow sway: is its sigma honest when the rate moves a little?

    python benchmarks/sensor_sway.py [--amplitudes 0 0.05 0.5 1] [--frequency 2]
                                     [--seconds 1] [--seeds 3] [--set NAME=VALUE ...]

The sensor's own chain in process (gyro_fmu.sensor.inprocess: its drive, plant and
observer on the C core, at GyroSensor's defaults and internal step), Omega_z = A sin(2 pi
f t), judged over the second half of the run: per amplitude the RMS error of the
observer's rate (rad/s), the RMS of error / sigma (1: honest), the re-fit test's restarts
and the share of samples with a non-zero status, over the seeds (GyroSensor's `seed`).
docs/gyro-sensor.md ("What falls short") quotes it.
"""

from __future__ import annotations

import argparse
import math
import warnings

import numpy as np

from gyro_fmu.sensor.inprocess import chain_parts


def one_run(settings: dict, amplitude: float, frequency: float, seconds: float,
            seed: int) -> tuple[float, float, int, float]:
    """(RMS error, RMS error/sigma, restarts, flagged share) over the second half."""
    plant, observer, drive, h = chain_parts({**settings, "seed": seed})
    n = round(seconds / h)
    err, ratio, flagged = [], [], 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the re-fit's warnings are counted, not printed
        for k in range(n):
            t = k * h
            ux = drive.ux(t)
            z = plant.output_row()
            observer.step(ux, 0.0, z[0], z[2], h)
            plant.step(ux, 0.0, amplitude * math.sin(2 * math.pi * frequency * t), h)
            if t >= seconds / 2:
                e = observer.estimates()["Omega_z"] - amplitude * math.sin(
                    2 * math.pi * frequency * (t + h))
                err.append(e)
                ratio.append(e / observer.sigmas()["Omega_z"])
                flagged += observer.status != 0
    err, ratio = np.array(err), np.array(ratio)
    return (float(np.sqrt(np.mean(err**2))), float(np.sqrt(np.mean(ratio**2))),
            observer.restarts, flagged / len(err))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--amplitudes", type=float, nargs="+", default=[0.0, 0.05, 0.5, 1.0])
    p.add_argument("--frequency", type=float, default=2.0, help="Hz")
    p.add_argument("--seconds", type=float, default=1.0)
    p.add_argument("--seeds", type=int, default=3)
    p.add_argument("--set", nargs="*", default=[], metavar="NAME=VALUE",
                   help="GyroSensor parameters (e.g. rate_model=1)")
    a = p.parse_args()
    settings = {k: float(v) for k, v in (item.split("=", 1) for item in a.set)}
    print(f"GyroSensor's chain in process, Omega_z = A sin(2 pi {a.frequency:g} t), "
          f"{a.seconds:g} s judged from {a.seconds / 2:g} s, seeds 0-{a.seeds - 1}")
    print(f"{'A (rad/s)':>9} {'RMS error':>10} {'error/sigma':>11} {'restarts':>8} "
          f"{'flagged':>8}")
    for amplitude in a.amplitudes:
        runs = [one_run(settings, amplitude, a.frequency, a.seconds, seed)
                for seed in range(a.seeds)]
        e, r, restarts, flagged = (np.array(x) for x in zip(*runs, strict=True))
        print(f"{amplitude:>9g} {np.sqrt(np.mean(e**2)):>10.3g} {np.sqrt(np.mean(r**2)):>11.2f} "
              f"{int(restarts.sum()):>8} {flagged.mean():>8.1%}")


if __name__ == "__main__":
    main()
