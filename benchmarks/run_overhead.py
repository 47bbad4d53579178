"""What `gyro-fmu run` costs beyond its simulation, in a fresh process as a user runs it.

    python benchmarks/run_overhead.py [--repeat 5] [--stop-time 0.1]

For the default scenario (100 ms at 5 us): the process's CPU seconds (user + system, the
OS's accounting of the finished child), the simulation's share (summary.json's
wall_time_s: the FMUs' set-up and stepping), and the rest, which is the overhead: with and
without figures, with the drive check remembered (a second run) and not (the cache off:
a first run). Medians of the repeats. Then `python -X importtime`'s largest imports of a
run without figures. Target (issue "A real-time sensor chain"): the default run with
figures under 0.5 s of the process's own time beyond the simulation.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path


def one_run(folder: Path, args: list[str], env: dict) -> tuple[float, float]:
    """(CPU s of the whole process, the simulation's wall s)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run([sys.executable, "-m", "gyro_fmu.cli", "run", "--out", "r", "--force",
                    *args], cwd=folder, env=env, check=True, capture_output=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    sim = json.loads((folder / "r" / "summary.json").read_text())["wall_time_s"]
    return cpu, sim


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeat", type=int, default=5)
    p.add_argument("--stop-time", default="0.1")
    a = p.parse_args()
    with tempfile.TemporaryDirectory(prefix="gyro_fmu-overhead-") as tmp:
        folder = Path(tmp)
        cache = folder / "cache"  # the first run copies the FMUs into models/
        one_run(folder, ["--stop-time", a.stop_time, "--no-figures"],
                {**os.environ, "GYRO_FMU_CACHE_DIR": str(cache)})
        print(f"gyro-fmu run --stop-time {a.stop_time}, median of {a.repeat} fresh "
              "processes (CPU s)")
        print(f"{'case':<34} {'process':>8} {'simulation':>11} {'beyond':>8}")
        for label, args, setting in (
                ("no figures, check remembered", ["--no-figures"], str(cache)),
                ("no figures, first run (cache off)", ["--no-figures"], "off"),
                ("figures, check remembered", [], str(cache)),
                ("figures, first run (cache off)", [], "off")):
            env = {**os.environ, "GYRO_FMU_CACHE_DIR": setting}
            runs = [one_run(folder, ["--stop-time", a.stop_time, *args], env)
                    for _ in range(a.repeat)]
            cpu = statistics.median(r[0] for r in runs)
            sim = statistics.median(r[1] for r in runs)
            print(f"{label:<34} {cpu:8.3f} {sim:11.3f} {cpu - sim:8.3f}")
        out = subprocess.run([sys.executable, "-X", "importtime", "-m", "gyro_fmu.cli", "run",
                              "--out", "r", "--force", "--stop-time", a.stop_time,
                              "--no-figures"], cwd=folder, capture_output=True, text=True,
                             env={**os.environ, "GYRO_FMU_CACHE_DIR": str(cache)})
        rows = []
        for line in out.stderr.splitlines():
            m = re.match(r"import time:\s+(\d+) \|\s+(\d+) \|( *)(\S+)", line)
            if m and len(m.group(3)) <= 3:
                rows.append((int(m.group(2)) / 1e6, m.group(4)))
        print("largest imports (cumulative s, -X importtime, no figures):")
        for seconds, name in sorted(rows, reverse=True)[:8]:
            print(f"  {seconds:6.3f}  {name}")


if __name__ == "__main__":
    main()
