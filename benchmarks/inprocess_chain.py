"""The library's in-process run against the FMU chain, per 5 us step of the default system.

    python benchmarks/inprocess_chain.py [--repeat 5]

The default scenario (park-horowitz, constant 1 rad/s) with the observer's constant rate
model (the scenario's tuning) and with its adaptive set (rate_model 0, GyroObserver's
default): `gyro_fmu.system.inprocess.run_inprocess` (the library's objects over the C
core) and the four native FMUs under the project's master (`run_fmus`: fmpy's FMU2Slave
instances, the C stepping loop). Thread CPU time per step from two run lengths (50 and
150 ms), so that set-up cancels; min of the repeats. Target (issue "A real-time sensor
chain"): in process within 1.2x the FMU chain.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from gyro_fmu.system.inprocess import run_inprocess
from gyro_fmu.system.run import ensure_fmus, run_fmus
from gyro_fmu.system.scenario import scenario

LENGTHS = (0.05, 0.15)


def per_step(run, rate_model: int, repeat: int) -> float:
    """Thread CPU seconds per step of run(scenario), from the two lengths."""
    best = []
    for stop in LENGTHS:
        sc = scenario("default", stop_time=stop).with_(tuning={"rate_model": rate_model})
        times = []
        for _ in range(repeat):
            start = time.thread_time()
            run(sc)
            times.append(time.thread_time() - start)
        best.append((min(times), sc.n_steps))
    (t1, n1), (t2, n2) = best
    return (t2 - t1) / (n2 - n1)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeat", type=int, default=5)
    a = p.parse_args()
    with tempfile.TemporaryDirectory(prefix="gyro_fmu-chain-") as tmp:
        models = Path(tmp)
        ensure_fmus(models)
        print(f"{'observer':<22} {'in process':>11} {'FMU chain':>10} {'ratio':>6}  (us/step)")
        for label, rate_model in (("constant rate model", 1), ("adaptive (7 models)", 0)):
            lib = per_step(run_inprocess, rate_model, a.repeat)
            fmu = per_step(lambda sc: run_fmus(sc, models, ensure=False), rate_model, a.repeat)
            print(f"{label:<22} {lib * 1e6:11.2f} {fmu * 1e6:10.2f} {lib / fmu:6.2f}")


if __name__ == "__main__":
    main()
