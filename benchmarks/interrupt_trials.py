"""Ctrl-C at random moments of `gyro-fmu run` and `gyro-fmu sweep`, as a terminal sends it.

    python benchmarks/interrupt_trials.py [--runs 10] [--sweeps 10] [--seed 0]

Each trial starts the command in a process group of its own (SIGINT at its default, as
in a shell), sends SIGINT to the whole group after a random delay within the job's own
length (a run's is measured first; imports, start-up, the FMUs' steps, a sweep's Dask
workers: every moment is a candidate) and checks that

- the exit code is 130 and stderr ends in one `gyro-fmu: interrupted...` line, no traceback;
- the work so far is on disk: a run's results.csv holds every point up to the time its
  summary.json records as interrupted; a sweep's sweep.csv holds as many gyros as its
  summary; or, interrupted before anything was simulated, no output folder at all.

Prints one row per trial and the totals; exit 1 if any trial failed.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

STEP = 5e-6


def trial(command: list[str], delay: float, out: Path) -> dict:
    proc = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            text=True, start_new_session=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    time.sleep(delay)
    sent = time.perf_counter()
    finished_before = proc.poll() is not None
    if not finished_before:
        os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=300)
    exit_s = time.perf_counter() - sent
    lines = [line for line in err.splitlines() if line.strip()]
    last = lines[-1] if lines else ""
    problems = []
    kept = on_disk(out)
    # killed by the signal itself (-2: it came while Python was exiting, after the work)
    # is what a shell also reports as 130; it is fine when everything was written
    at_exit = proc.returncode == -signal.SIGINT and kept.startswith("complete")
    if finished_before:
        problems.append("finished before the signal: pick a longer job")
    if proc.returncode != 130 and not at_exit:
        problems.append(f"exit {proc.returncode}")
    if "Traceback" in err:
        problems.append("traceback")
    if not last.startswith("gyro-fmu: interrupted") and not at_exit:
        problems.append(f"last line {last[:80]!r}")
    if kept.startswith("BAD"):
        problems.append(kept)
    return {"delay_s": delay, "exit": proc.returncode, "exit_after_s": exit_s, "kept": kept,
            "problems": problems, "line": last[:110]}


def on_disk(out: Path) -> str:
    """What the interrupted command left, or 'BAD: ...' when it is inconsistent."""
    if not out.exists():
        return "nothing (before the first step)"
    summary_path = out / "summary.json"
    if not summary_path.exists():
        return f"BAD: {out} without summary.json: {sorted(p.name for p in out.iterdir())}"
    summary = json.loads(summary_path.read_text())
    if (out / "results.csv").exists():  # a run
        rows = sum(1 for _ in (out / "results.csv").open()) - 1
        at = summary.get("interrupted", {}).get("at_s")
        if at is None:  # Ctrl-C after the simulation: the whole run is kept, described
            stop = summary["scenario"]["stop_time"]
            if rows != round(stop / STEP) + 1:
                return f"BAD: not marked interrupted, {rows} rows for a run to {stop} s"
            return f"complete: {rows} rows to t = {stop * 1e3:.2f} ms"
        if rows != round(at / STEP) + 1:
            return f"BAD: {rows} rows for t = {at} s"
        return f"{rows} rows to t = {at * 1e3:.2f} ms"
    rows = sum(1 for _ in (out / "sweep.csv").open()) - 1
    if not summary.get("interrupted") or rows != summary["n"]:
        return (f"BAD: sweep.csv {rows} rows, summary {summary.get('n')}, "
                f"{summary.get('interrupted')}")
    return f"{rows} of {summary['n_requested']} gyros"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=10)
    ap.add_argument("--sweeps", type=int, default=10)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--models", default="models")
    args = ap.parse_args()
    rng = random.Random(args.seed)
    models = str(Path(args.models).resolve())
    subprocess.run(["gyro-fmu", "build", "--dest", models], check=True,
                   stdout=subprocess.DEVNULL) if not Path(models).is_dir() else None
    gyro_fmu = [str(Path(sys.executable).with_name("gyro-fmu"))]  # the console script
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        run = [*gyro_fmu, "run", "--stop-time", "1", "--no-figures", "--models", models]
        began = time.perf_counter()  # the run's own length: every SIGINT falls within it
        subprocess.run([*run, "--out", str(Path(tmp) / "timed")], check=True,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        run_s = time.perf_counter() - began
        print(f"an uninterrupted run takes {run_s:.2f} s: SIGINT between 0.1 s and "
              f"{0.9 * run_s:.2f} s", flush=True)
        for k in range(args.runs + args.sweeps):
            out = Path(tmp) / f"trial{k}"
            if k < args.runs:
                kind, delay = "run", rng.uniform(0.1, 0.9 * run_s)
                command = [*run, "--out", str(out)]
            else:
                kind, delay = "sweep", rng.uniform(0.5, 25.0)
                command = [*gyro_fmu, "sweep", "-n", "300", "--stop-time", "0.05",
                           "--no-figures", "--models", models, "--out", str(out)]
            r = {"trial": k, "kind": kind, **trial(command, delay, out)}
            rows.append(r)
            print(f"{k:>3} {kind:<5} SIGINT at {r['delay_s']:5.2f} s  exit {r['exit']:>4} "
                  f"{r['exit_after_s']:5.2f} s later  kept: {r['kept']:<32} "
                  f"{'OK' if not r['problems'] else 'FAIL ' + '; '.join(r['problems'])}",
                  flush=True)
    bad = [r for r in rows if r["problems"]]
    slowest = max(r["exit_after_s"] for r in rows)
    print(f"{len(rows)} trials: {len(rows) - len(bad)} exited 130 with the work so far on "
          f"disk, {len(bad)} failed; slowest exit {slowest:.2f} s after SIGINT")
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())
