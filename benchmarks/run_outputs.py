"""What `gyro-fmu run` costs in wall time, peak memory and disk as the run grows, and
how long its figures take.

    python benchmarks/run_outputs.py [--stop-times 0.001 0.5 5 20] [--models models]

Each run is `gyro-fmu run --stop-time T` in a fresh process in an empty folder (peak RSS
from the child's getrusage); the figures are timed apart, drawn again from the run's
results.parquet in this process (warm: matplotlib imported). Targets (docs/results/
performance.md): peak RSS under 300 MB whatever T, figures under 1 s.
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from gyro_fmu.system.run import make_figures, read_back
from gyro_fmu.system.scenario import scenario


def one_run(stop: float, models: Path) -> tuple[float, float, dict[str, int], Path]:
    folder = Path(tempfile.mkdtemp(prefix="run-outputs-"))
    before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "gyro_fmu.cli", "run", "--stop-time", str(stop),
                    "--models", str(models), "--out", str(folder / "run")], check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=folder)
    wall = time.perf_counter() - start
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    if peak <= before:
        print(f"  (peak RSS of T={stop} below an earlier run's {before / 1e3:.0f} MB: "
              "run it alone for its figure)")
    sizes = {p.name: p.stat().st_size for p in (folder / "run").iterdir()}
    return wall, peak / 1e3, sizes, folder / "run"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--stop-times", type=float, nargs="+", default=[0.001, 0.5, 5.0, 20.0])
    ap.add_argument("--models", type=Path, default=Path("models"))
    args = ap.parse_args()
    truth = scenario().params
    print(f"{'stop s':>8} {'rows':>10} {'wall s':>8} {'peak MB':>8} {'csv MB':>8} "
          f"{'parquet MB':>10} {'read s':>7} {'figures s':>9}")
    # smallest first: ru_maxrss of children is the largest so far, so each longer run
    # shows its own peak only if it is the highest yet
    for stop in sorted(args.stop_times):
        wall, peak, sizes, run = one_run(stop, args.models.resolve())
        start = time.perf_counter()
        _, data = read_back(run / "results.parquet", truth)
        read = time.perf_counter() - start
        start = time.perf_counter()
        make_figures(data, Path(tempfile.mkdtemp()))
        figures = time.perf_counter() - start
        rows = round(stop / scenario().step) + 1
        print(f"{stop:8g} {rows:10d} {wall:8.2f} {peak:8.0f} "
              f"{sizes['results.csv'] / 1e6:8.1f} {sizes['results.parquet'] / 1e6:10.1f} "
              f"{read:7.2f} {figures:9.2f}", flush=True)
        for p in run.iterdir():
            p.unlink()
    print(f"cores: {os.cpu_count()}")


if __name__ == "__main__":
    main()
