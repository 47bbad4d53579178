"""Cost of one GyroStateObserver step per rate model (ObserverTuning.rate_model 0-3).

bench.py's observer_step_us (5000 noise-free steps of the default scenario's data,
precomputed) for each rate model, 7 repetitions; min and median microseconds per step.
The target is 25 us (issue 15).

    python benchmarks/observer_step_cost.py
"""

from __future__ import annotations

import statistics

from bench import observer_step_us

from gyro_fmu.system.scenario import scenario

NAMES = {0: "adaptive (7 models)", 1: "constant", 2: "tracking", 3: "expert"}


def main(repeat: int = 7) -> None:
    sc = scenario("default")
    for rate_model, name in NAMES.items():
        times = [observer_step_us(sc, 5000, rate_model=rate_model) for _ in range(repeat)]
        print(f"rate_model {rate_model} {name:>20}: min {min(times):5.1f}  median "
              f"{statistics.median(times):5.1f} us per step")


if __name__ == "__main__":
    main()
