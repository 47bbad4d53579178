"""kill -9 at random moments of `gyro-fmu run`: does any later command accept an output
as complete when it is not?

    python benchmarks/kill_trials.py [--trials 20] [--seed 1] [--stop-time 0.02]

Each trial starts `gyro-fmu run` (noise 1e-4) into a folder that already holds a
finished run of another seed (the worst case: an old summary beside new results), kills
it with SIGKILL at a random moment between --from (0.8) and 1.1 of its usual duration,
then classifies the folder:
- "complete (seed 1)" or "(seed 2)": a matching pair, the old one (the kill came before
  the writing) or the new one (after);
- "refused": results.csv without its summary, or a pair that does not match, which
  `report` refuses (exit 2); temporaries (.part) are never under a final name;
- "ACCEPTED WRONG": `report` exits 0 on a pair whose results.csv is not the one its
  summary names, or a partial file is under a final name. The target is 0 of these.
"""

from __future__ import annotations

import argparse
import json
import random
import subprocess
import sys
from pathlib import Path

from kill_harness import kill_trials, tally

from gyro_fmu.outputs import file_digest


def gyro_fmu(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "gyro_fmu.cli", *args], cwd=cwd,
                          capture_output=True, text=True)


def classify(folder: Path, cwd: Path) -> str:
    results, summary = folder / "results.csv", folder / "summary.json"
    report = gyro_fmu("report", str(folder), cwd=cwd)
    if not summary.exists():
        return "refused" if report.returncode == 2 else "ACCEPTED WRONG"
    try:
        record = json.loads(summary.read_text())["results"]
    except (ValueError, KeyError):
        return "refused" if report.returncode == 2 else "ACCEPTED WRONG"
    matches = results.exists() and file_digest(results) == record["sha256"]
    if report.returncode == 0:
        if not matches:
            return "ACCEPTED WRONG"
        seed = json.loads(summary.read_text()).get("scenario", {}).get("seed")
        return f"complete (seed {seed})"
    return "refused" if not matches else "ACCEPTED WRONG"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=20)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--stop-time", default="0.02")
    ap.add_argument("--from", dest="start", type=float, default=0.8,
                    help="kill between this fraction of the run's duration and 1.1 (the "
                         "writing comes last: 0 spreads the kills over the whole run)")
    args = ap.parse_args()
    run = [sys.executable, "-m", "gyro_fmu.cli", "run", "--stop-time", args.stop_time,
           "--noise", "1e-4", "--no-figures"]
    counts, duration = kill_trials(lambda seed, out: [*run, "--seed", seed, "--out", str(out)],
                                   lambda folder, base: classify(folder, base.parent),
                                   args.trials, random.Random(args.seed), args.start)
    print(f"{args.trials} kills of `gyro-fmu run` (about {duration:.1f} s each): "
          + tally(counts))

if __name__ == "__main__":
    main()
