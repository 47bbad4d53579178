"""The self-calibration in process against through its two FMUs (issue: FMUs that run
anywhere, 2 of 2): `gyro-fmu selfcal` with `--engine inprocess` and `--engine fmu`, each
in a fresh process, CPU and wall time; plus the carrier step itself (resonator + loops)
in process and through the project's master over the native FMUs.

    python benchmarks/selfcal_engine_cost.py [--repeat 3]

Prints a table; the figures go to docs/native-fmus.md.
"""

from __future__ import annotations

import argparse
import resource
import subprocess
import sys
import tempfile
import time


def _cli(engine: str, out: str) -> tuple[float, float]:
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "gyro_fmu.cli", "selfcal", "--engine", engine,
                           "--out", out], capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise SystemExit(f"selfcal --engine {engine} failed ({proc.returncode}):\n"
                         f"{proc.stdout[-2000:]}\n{proc.stderr[-2000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def _carrier(duration: float) -> tuple[float, float]:
    from gyro_fmu.model.loops import LoopSettings
    from gyro_fmu.model.resonator import ResonatorParameters
    from gyro_fmu.selfcal.inprocess import CarrierSimulation
    from gyro_fmu.selfcal.run import run_fmus

    res, lo = ResonatorParameters(noise=1e-4), LoopSettings()
    t0 = time.process_time()
    CarrierSimulation(res, lo, seed=1).run(duration)
    inproc = time.process_time() - t0
    run_fmus(res, lo, 0.01, seed=1)  # warm: FMUs unpacked, libraries loaded
    t0 = time.process_time()
    run_fmus(res, lo, duration, seed=1)
    fmu = time.process_time() - t0
    return inproc, fmu


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    rows = {}
    with tempfile.TemporaryDirectory() as tmp:
        for engine in ("inprocess", "fmu"):
            runs = [_cli(engine, f"{tmp}/{engine}{k}") for k in range(args.repeat)]
            rows[engine] = min(runs, key=lambda r: r[1])
    duration, h = 2.0, 25e-6
    inproc, fmu = _carrier(duration)
    n = round(duration / h)
    print("| run | wall (s) | CPU (s) |")
    print("|---|---|---|")
    for engine, (wall, cpu) in rows.items():
        print(f"| gyro-fmu selfcal --engine {engine} (fresh process, best of {args.repeat}) "
              f"| {wall:.2f} | {cpu:.2f} |")
    print(f"\nselfcal --engine fmu / inprocess: {rows['fmu'][1] / rows['inprocess'][1]:.2f}x CPU, "
          f"{rows['fmu'][0] / rows['inprocess'][0]:.2f}x wall")
    print(f"carrier step, {n} steps: in process {inproc / n * 1e6:.3f} us, through the "
          f"native FMUs {fmu / n * 1e6:.3f} us ({fmu / inproc:.1f}x)")


if __name__ == "__main__":
    main()
