"""kill -9 at random moments of `gyro-fmu sweep` and `gyro-fmu selfcal`: is any output
left whole-looking when it is not, or paired with another run's?

    python benchmarks/kill_trials_outputs.py [--command selfcal|sweep] [--trials 20]

Each trial starts the command (its own process group, killed whole with SIGKILL at a
random moment of its usual duration) into a folder that holds a finished run of another
seed, then checks every file under a final name:
- summary.json parses, and where it names a table (sweep.csv) that table has its digest;
- a PNG ends in its IEND chunk; no *.part file is under a final name;
- a figure is not older than the summary beside it (an old run's figure beside a new
  summary is a wrong pair).
"complete (old)" / "complete (new)" / "nothing claimed" (no summary) are fine; anything
else is "WRONG". The target is 0 WRONG.
"""

from __future__ import annotations

import argparse
import json
import random
import sys
from pathlib import Path

from kill_harness import kill_trials, tally

from gyro_fmu.outputs import file_digest

COMMANDS = {
    "selfcal": ["selfcal", "--record", "5", "--settle", "3", "--spacing", "0.4",
                "--sidebands", "3"],
    "sweep": ["sweep", "-n", "3", "--stop-time", "0.002", "--workers", "1"],
}
SEED = {"selfcal": "--seed", "sweep": "--tolerance-seed"}


def classify(folder: Path, old_id: str | None) -> str:
    summary = folder / "summary.json"
    if not summary.exists():
        return "nothing claimed"
    try:
        s = json.loads(summary.read_text())
    except ValueError:
        return "WRONG: summary.json is partial"
    record = s.get("results")
    if isinstance(record, dict):
        table = folder / record["file"]
        if not table.exists() or file_digest(table) != record["sha256"]:
            return f"WRONG: {record['file']} is not the one summary.json names"
    for png in folder.glob("*.png"):
        if not png.read_bytes().endswith(b"IEND\xaeB`\x82"):
            return f"WRONG: {png.name} is partial"
        if png.stat().st_mtime < summary.stat().st_mtime - 1e-3:
            return f"WRONG: {png.name} is older than summary.json"
    new = json.dumps(s, sort_keys=True) != old_id
    return "complete (new)" if new else "complete (old)"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--command", choices=sorted(COMMANDS), default="selfcal")
    ap.add_argument("--trials", type=int, default=20)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    cmd = [sys.executable, "-m", "gyro_fmu.cli", *COMMANDS[args.command]]

    def old_id(base: Path) -> str:
        return json.dumps(json.loads((base / "summary.json").read_text()), sort_keys=True)

    counts, duration = kill_trials(
        lambda seed, out: [*cmd, SEED[args.command], seed, "--out", str(out)],
        lambda folder, base: classify(folder, old_id(base)), args.trials,
        random.Random(args.seed))
    print(f"{args.trials} kills of `gyro-fmu {args.command}` (about {duration:.1f} s each): "
          + tally(counts))

if __name__ == "__main__":
    main()
