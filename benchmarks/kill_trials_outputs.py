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
import os
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

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
    rng = random.Random(args.seed)
    cmd = [sys.executable, "-m", "gyro_fmu.cli", *COMMANDS[args.command]]
    counts: dict[str, int] = {}
    with tempfile.TemporaryDirectory() as tmp:
        cwd = Path(tmp)
        base = cwd / "base"
        for _ in range(2):  # the first one also puts the FMUs into models/: not timed
            start = time.perf_counter()
            done = subprocess.run([*cmd, SEED[args.command], "1", "--out", str(base)],
                                  cwd=cwd, capture_output=True, text=True)
            if done.returncode != 0:
                raise SystemExit(f"the base run failed: {done.stderr[-400:]}")
            duration = time.perf_counter() - start
        old = json.dumps(json.loads((base / "summary.json").read_text()), sort_keys=True)
        for trial in range(args.trials):
            folder = cwd / f"trial{trial}"
            shutil.copytree(base, folder)
            proc = subprocess.Popen([*cmd, SEED[args.command], "2", "--out", str(folder)],
                                    cwd=cwd, stdout=subprocess.DEVNULL,
                                    stderr=subprocess.DEVNULL, start_new_session=True)
            time.sleep(rng.uniform(0.0, 1.1 * duration))
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
            verdict = classify(folder, old)
            counts[verdict] = counts.get(verdict, 0) + 1
            print(f"trial {trial:2d}: {verdict}", flush=True)
    print(f"{args.trials} kills of `gyro-fmu {args.command}` (about {duration:.1f} s each): "
          + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))


if __name__ == "__main__":
    main()
