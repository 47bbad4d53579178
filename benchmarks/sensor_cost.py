"""GyroSensor.fmu's cost: CPU seconds per simulated second at a 1 ms host step, per preset
and per rate model, and the instructions per internal step under callgrind (repeatable
under load, where CPU time is not).

    python benchmarks/sensor_cost.py [--seconds 2] [--repeat 3] [--callgrind]

The FMU (FMI 2.0, the package's) stepped by fmpy's FMU2Slave, one setReal and one doStep
per 1 ms host step, a 1 rad/s step at 50 ms; thread CPU time over the run, min and
median of the repeats; beside them the yardstick of chain_cost.py measured in the same
run (a naive 14x14 double matmul, cc -O2), so that the figure holds across machines and
loads. Target (issue "The gyroscope as a sensor"): <= 1.0 at the defaults; the issue on
the chain's speed aims at 0.25, set when the yardstick read 0.915 us: 5.5 matmuls per 20 us
internal step.
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from chain_cost import matmul_seconds  # the yardstick, from this folder
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
from fmpy.simulation import apply_start_values

from gyro_fmu.cosim.instances import LogCollector, fmi2_callbacks
from gyro_fmu.fmu.build import prebuilt_fmu
from gyro_fmu.sensor.presets import SENSOR_PRESETS

H = 1e-3
#: The window of the converged instruction count (s): the 1 rad/s step at 50 ms settled.
CONVERGED = (0.3, 0.4)


def cpu_per_second(folder: str, start: dict, seconds: float) -> float:
    md = read_model_description(folder)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=folder, modelIdentifier="GyroSensor",
                    instanceName="cost")
    log = LogCollector()  # the observer's warnings (a constant rate model at a step) kept
    callbacks = fmi2_callbacks(log)
    fmu.instantiate(callbacks=callbacks)
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    apply_start_values(fmu, md, start)
    fmu.exitInitializationMode()
    t, c = 0.0, time.thread_time()
    for k in range(round(seconds / H)):
        fmu.setReal([vr["Omega_z"]], [1.0 if k * H >= 0.05 else 0.0])
        fmu.doStep(t, H)
        t = (k + 1) * H
    cpu = time.thread_time() - c
    fmu.terminate()
    fmu.freeInstance()
    return cpu / seconds


def _instructions(folder: str, seconds: float) -> int:
    """callgrind's count of the FMU binary's instructions over a run of `seconds`."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "cg.out"
        code = (f"import sys; sys.path.insert(0, {str(Path(__file__).parent)!r}); "
                "from sensor_cost import cpu_per_second; "
                f"cpu_per_second({str(folder)!r}, {{}}, {seconds!r})")
        subprocess.run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}",
                        sys.executable, "-c", code], check=True, capture_output=True)
        text = subprocess.run(["callgrind_annotate", str(out)], check=True,
                              capture_output=True, text=True).stdout
    return sum(int(line.split()[0].replace(",", "")) for line in text.splitlines()
               if "GyroSensor.so" in line and line.strip()[:1].isdigit())


def instructions_per_step(folder: str, window: tuple[float, float] = (0.03, 0.06)
                          ) -> tuple[float, float]:
    """(per internal step, at start-up): the FMU binary's instructions from runs of
    window[0] and window[1] s (20 us internal steps at the defaults): their difference over
    the steps between them, so that start-up (the drive check: gyro_excitation.c) cancels,
    and what the shorter run spent beyond its steps."""
    short, long_ = _instructions(folder, window[0]), _instructions(folder, window[1])
    per_step = (long_ - short) / ((window[1] - window[0]) / 20e-6)
    return per_step, short - per_step * (window[0] / 20e-6)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=2.0)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--callgrind", action="store_true", help="also count instructions")
    args = ap.parse_args()
    folder = str(extract(str(prebuilt_fmu("GyroSensor"))))
    try:
        cases = {f"preset {name}": dict(s) for name, s in SENSOR_PRESETS.items()}
        cases.update({f"consumer, rate_model {m}": {"rate_model": m} for m in (1, 2, 4)})
        print(f"GyroSensor.fmu, {args.seconds:g} s at a {H * 1e3:g} ms host step: CPU s per "
              "simulated s (min / median of", args.repeat, "runs)")
        defaults_runs = None  # the first case: the consumer preset, GyroSensor's defaults
        for name, start in cases.items():
            runs = [cpu_per_second(folder, start, args.seconds) for _ in range(args.repeat)]
            defaults_runs = defaults_runs or runs
            print(f"  {name:28s} {min(runs):.3f} / {statistics.median(runs):.3f}")
        mm = matmul_seconds(Path(folder), 5)
        per_matmul = min(defaults_runs) / 50e3 / mm
        print(f"  yardstick: a 14x14 double matmul (cc -O2) takes {mm * 1e6:.3f} us here; the "
              f"defaults' min is {per_matmul:.2f} matmuls per 20 us internal step")
        if args.callgrind:
            per_step, start_up = instructions_per_step(folder)
            print(f"  instructions per internal step (defaults, callgrind): {per_step:,.0f} "
                  f"at 0.03-0.06 s (at rest, converging); at start-up (the drive check, "
                  f"set-up): {start_up:,.0f}")
            per_step, _ = instructions_per_step(folder, CONVERGED)
            print(f"  instructions per internal step at {CONVERGED[0]:g}-{CONVERGED[1]:g} s "
                  f"(1 rad/s, converged): {per_step:,.0f}")
    finally:
        shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    main()
