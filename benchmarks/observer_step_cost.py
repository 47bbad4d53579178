"""Cost of one GyroStateObserver step per rate model (ObserverTuning.rate_model 0-3).

5000 noise-free steps of the default scenario's data (the drive and the plant's
positions, precomputed), 7 repetitions per rate model; min and median microseconds per
step. The target is 25 us (issue 15).

    python benchmarks/observer_step_cost.py
"""

from __future__ import annotations

import statistics
import time

import numpy as np

from gyro_fmu.estimation.observer import GyroStateObserver, ObserverTuning
from gyro_fmu.model.parameters import GyroParameters
from gyro_fmu.model.plant import GyroPlantModel
from gyro_fmu.system.scenario import scenario

NAMES = {0: "adaptive (4 models)", 1: "constant", 2: "tracking", 3: "expert"}


def main(n: int = 5000, repeat: int = 7) -> None:
    sc = scenario("default")
    plant, drive, h = GyroPlantModel(sc.params), sc.the_drive, sc.step
    ux, z = np.empty(n), np.empty((n, 2))
    for k in range(n):
        ux[k] = drive.ux(k * h)
        z[k] = plant.s[[0, 2]]
        plant.step(ux[k], 0.0, 1.0, h)
    steps = [(float(ux[k]), 0.0, float(z[k, 0]), float(z[k, 1]), h) for k in range(n)]
    for rate_model, name in NAMES.items():
        times = []
        for _ in range(repeat):
            obs = GyroStateObserver(GyroParameters(**sc.initial_guess), 0.0, 1,
                                    ObserverTuning(rate_model=rate_model))
            t0 = time.perf_counter()
            for a in steps:
                obs.step(*a)
            times.append((time.perf_counter() - t0) / n * 1e6)
        print(f"rate_model {rate_model} {name:>20}: min {min(times):5.1f}  median "
              f"{statistics.median(times):5.1f} us per step")


if __name__ == "__main__":
    main()
