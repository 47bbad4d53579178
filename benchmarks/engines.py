"""Each host that runs our FMUs, against the fmpy master: what it needs and how well it agrees.

    python benchmarks/engines.py [--long 0.1]

Patent scenario (Table 1 corrected, Omega_z = sin(2 pi 100 t)), 4 ms and --long s:
max |a - b| / max |b| of observer.Omega_hat and plant.y for libcosim (libcosimpy) and Ecos
(ecospy) running the SSP package, and for the container FMU through fmpy.simulate_fmu.
Then the Ecos CLI with an empty environment (PATH and TBB's folder only): wall time of
10 ms simulated (the native FMUs need nothing from the environment).
"""

from __future__ import annotations

import argparse
import subprocess
import tempfile
import time
from pathlib import Path

import fmpy
import numpy as np

from gyro_fmu.fmu.build import MODELS_DIR
from gyro_fmu.system.container import build_container, container_start_values
from gyro_fmu.system.ecos import ecos_binary, run_ssp_ecos, tbb_folder
from gyro_fmu.system.run import ensure_fmus, run_fmus
from gyro_fmu.system.scenario import scenario
from gyro_fmu.system.ssp import PARAMETER_SET, relative_differences, run_ssp_libcosim, write_ssp

SIGNALS = ("observer.Omega_hat", "plant.y")


def agreement(stop_time: float, models: Path, work: Path) -> None:
    sc = scenario("patent", stop_time=stop_time)
    ssp = write_ssp(sc, models, work / f"patent_{stop_time:g}.ssp")
    ours = run_fmus(sc, models)
    runs = {"libcosim": run_ssp_libcosim(ssp, record=SIGNALS),
            "ecospy": run_ssp_ecos(ssp, SIGNALS)}
    container = build_container(models, work / "GyroSystem.fmu")
    r = fmpy.simulate_fmu(str(container), stop_time=sc.stop_time, output_interval=sc.step,
                          start_values=container_start_values(sc, models))
    runs["container (fmpy)"] = {"observer.Omega_hat": r["Omega_hat"], "plant.y": r["y"]}
    for host, result in runs.items():
        rel = relative_differences(result, ours)
        print(f"  {stop_time * 1e3:5.0f} ms  {host:18s} " + "  ".join(
            f"{n} {rel[n]:.2e}" for n in SIGNALS))


def cli_wall(ssp: Path, work: Path, runs: int) -> list[float]:
    env = {"PATH": "/usr/bin:/bin", "LD_LIBRARY_PATH": str(tbb_folder())}
    cmd = [str(ecos_binary()), "simulate", "--path", str(ssp), "--stepSize", "5e-6",
           "--stopTime", "0.01", "--parameterSet", PARAMETER_SET, "--noParallel", "--noCsv"]
    walls = []
    for _ in range(runs):
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, cwd=work, env=env, capture_output=True, text=True)
        walls.append(time.perf_counter() - t0)
        if proc.returncode != 0:
            raise SystemExit(f"ecos failed ({proc.returncode}): {proc.stderr[-2000:]}")
    return walls


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--long", type=float, default=0.1, help="second stop time, s")
    ap.add_argument("--runs", type=int, default=3, help="Ecos CLI runs of each package")
    args = ap.parse_args()
    models = Path(MODELS_DIR)
    ensure_fmus(models)
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        print("agreement with the fmpy master, max |a - b| / max |b|, patent scenario:")
        for stop in (0.004, args.long):
            agreement(stop, models, work)
        ssp = write_ssp(scenario("patent", stop_time=0.01), models, work / "p10.ssp")
        walls = cli_wall(ssp, work, args.runs)
        print(f"Ecos CLI, empty environment, 10 ms, wall s over {args.runs} runs: median "
              f"{np.median(walls):.2f} (min {min(walls):.2f}, max {max(walls):.2f})")


if __name__ == "__main__":
    main()
