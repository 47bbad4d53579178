"""How much GyroSensor's datasheet figures vary from seed to seed on one gyro: the
reproducer of the "tactical" preset that was dropped (docs/datasheet.md): a matched,
high-Q gyro (modes 5.0 and 5.1 kHz, Q 8,000, coupling 1 %, m 5e-9 kg, noise / 3) whose
angle random walk bound varied tenfold between seeds, against the shipped presets.

    python benchmarks/sensor_seed_spread.py [--seeds 1-8] [--gyro tactical|consumer|high-q|low-cost]

Prints, per seed, the figures of the datasheet protocol (gyro_fmu.sensor.datasheet) that
spread, and the observer's status-1 warnings; then each figure's median and range (max -
min over the median). A gyro whose range is large has no datasheet (its --check fails);
issue "An observer honest on any gyro" is where the cause is sought.
"""

from __future__ import annotations

import argparse

import numpy as np

from gyro_fmu.fmu.build import prebuilt_fmu
from gyro_fmu.sensor.datasheet import measure_datasheet
from gyro_fmu.sensor.presets import SENSOR_PRESETS, _gyro, _preset

GYROS = {**SENSOR_PRESETS,
         "tactical": _preset(_gyro(5000.0, 0.02, 8000.0, 0.01, 5e-9), 1 / 3)}
FIGURES = ("arw", "bias_instability", "noise_rms", "bias", "latency", "bandwidth")


def _seeds(text: str) -> tuple[int, ...]:
    lo, _, hi = text.partition("-")
    return tuple(range(int(lo), int(hi or lo) + 1))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=_seeds, default=_seeds("1-8"))
    ap.add_argument("--gyro", choices=sorted(GYROS), default="tactical")
    args = ap.parse_args()
    sheet = measure_datasheet(prebuilt_fmu("GyroSensor"), GYROS[args.gyro], args.seeds)
    f = sheet["figures"]
    print(f"gyro {args.gyro}, seeds {args.seeds[0]}-{args.seeds[-1]}")
    print(f"{'seed':>5} " + " ".join(f"{n:>17}" for n in FIGURES) + "  warnings")
    for i, seed in enumerate(args.seeds):
        print(f"{seed:>5} " + " ".join(f"{f[n]['seeds'][i]:>17.4g}" for n in FIGURES)
              + f"  {sheet['observer_warnings'][str(seed)]}")
    print(f"{'median':>5} " + " ".join(f"{np.median(f[n]['seeds']):>17.4g}" for n in FIGURES))
    spread = [np.ptp(f[n]["seeds"]) / np.median(np.abs(f[n]["seeds"])) for n in FIGURES]
    print(f"{'range':>5} " + " ".join(f"{r:>16.3g}x" for r in spread)
          + "  (max - min over the median |value|)")


if __name__ == "__main__":
    main()
