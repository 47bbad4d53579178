"""Memory and time of one self-calibration against its record length, in process and
through the two native FMUs: `gyro-fmu selfcal --record R --engine E` in a fresh
process each, its peak RSS (ru_maxrss of the child) and wall and CPU time.

    python benchmarks/selfcal_record_cost.py [--records 10 20 40 80] [--engines inprocess fmu]
                                             [--set f_x=... ...]

Prints a table (the figures go to docs/self-calibration.md). The records are
demodulated while they run (selfcal/stream.py), so peak RSS should not grow with the
record length; the table says by how much it does.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time


def one(record: float, engine: str, sets: list[str]) -> tuple[float, float, float, int]:
    """(wall s, CPU s, peak RSS MB, exit code) of one calibration in a fresh process."""
    with tempfile.TemporaryDirectory() as out:
        argv = [sys.executable, "-m", "gyro_fmu.cli", "selfcal", "--record", f"{record:g}",
                "--engine", engine, "--no-figures", "--out", out]
        for s in sets:
            argv += ["--set", s]
        t0 = time.perf_counter()
        proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        _, status, usage = os.wait4(proc.pid, 0)  # this child's own peak RSS and CPU
        wall = time.perf_counter() - t0
    cpu = usage.ru_utime + usage.ru_stime
    return wall, cpu, usage.ru_maxrss / 1024.0, os.waitstatus_to_exitcode(status)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--records", type=float, nargs="+", default=[10.0, 20.0, 40.0, 80.0])
    ap.add_argument("--engines", nargs="+", default=["inprocess", "fmu"])
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE")
    args = ap.parse_args()
    print(f"{'record s':>9} {'engine':>10} {'wall s':>8} {'CPU s':>8} {'peak RSS MB':>12}  "
          "result")
    rows: dict[str, list[tuple[float, float, float]]] = {e: [] for e in args.engines}
    for record in args.records:
        for engine in args.engines:
            wall, cpu, rss, code = one(record, engine, args.set)
            rows[engine].append((record, cpu, rss))
            print(f"{record:9g} {engine:>10} {wall:8.1f} {cpu:8.1f} {rss:12.0f}  exit {code}",
                  flush=True)
    for engine, r in rows.items():  # growth from the shortest to the longest record
        if len(r) > 1 and r[-1][0] > r[0][0]:
            span = r[-1][0] - r[0][0]
            print(f"{engine}: {(r[-1][2] - r[0][2]) / span:.1f} MB and "
                  f"{(r[-1][1] - r[0][1]) / span:.2f} CPU s per second of record "
                  f"(each mode's record; both modes are recorded)")


if __name__ == "__main__":
    main()
