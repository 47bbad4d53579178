"""The kill trials' shared loop (kill_trials.py, kill_trials_outputs.py): a finished run
into base/, then per trial a copy of it overwritten by a second run that is killed with
SIGKILL at a random moment, and the folder classified."""

from __future__ import annotations

import os
import random
import shutil
import signal
import subprocess
import tempfile
import time
from collections.abc import Callable
from pathlib import Path


def kill_trials(argv: Callable[[str, Path], list[str]], classify: Callable[[Path, Path], str],
                trials: int, rng: random.Random, start: float = 0.0) -> tuple[dict, float]:
    """argv(seed, out) is the command for a seed into a folder; classify(folder, base)
    names what a killed run left. Kills fall between start and 1.1 of the base run's
    duration (the second of two: the first also puts the FMUs into models/). The command
    runs in its own process group, killed whole. Returns (verdict counts, duration s)."""
    counts: dict[str, int] = {}
    with tempfile.TemporaryDirectory() as tmp:
        cwd = Path(tmp)
        base = cwd / "base"
        for _ in range(2):
            began = time.perf_counter()
            done = subprocess.run(argv("1", base), cwd=cwd, capture_output=True, text=True)
            if done.returncode != 0:
                raise SystemExit(f"the base run failed: {done.stderr[-400:]}")
            duration = time.perf_counter() - began
        for trial in range(trials):
            folder = cwd / f"trial{trial}"
            shutil.copytree(base, folder)
            proc = subprocess.Popen(argv("2", folder), cwd=cwd, stdout=subprocess.DEVNULL,
                                    stderr=subprocess.DEVNULL, start_new_session=True)
            time.sleep(rng.uniform(start * duration, 1.1 * duration))
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
            verdict = classify(folder, base)
            counts[verdict] = counts.get(verdict, 0) + 1
            print(f"trial {trial:2d}: {verdict}", flush=True)
    return counts, duration


def tally(counts: dict[str, int]) -> str:
    return ", ".join(f"{k} {v}" for k, v in sorted(counts.items()))
