"""Every typed option of every `gyro-fmu` subcommand with -1, 0, nan, inf, 1e300 and
text (tests/cli_fuzz.py, the fuzzer the tests run), tabulated by class.

    python benchmarks/cli_fuzz_trials.py [--values nan inf] [--command run ...] [--all]

Builds the FMUs and a short run's results.csv in a temporary folder, runs every trial in
this process (a valid value's work is cut by an alarm after a budget: exit 130), prints
the counts per class (then the file arguments given a folder, an empty, a binary, a
UTF-16 and a Latin-1 file) and every trial that is neither refused nor ran (--all: every
trial). Exit 1 if any trial is a traceback, an unclear refusal or a silent run.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import cli_fuzz


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--values", nargs="+", default=list(cli_fuzz.VALUES))
    ap.add_argument("--command", nargs="+", help="only these subcommands")
    ap.add_argument("--all", action="store_true", help="print every trial")
    args = ap.parse_args()
    from gyro_fmu.cli import main as cli_main
    from gyro_fmu.fmu.build import build_all

    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        build_all(root / "models")
        cli_main(["run", "--stop-time", "0.002", "--no-figures", "--models",
                  str(root / "models"), "--out", str(root / "run")])
        folder = root / "trials"
        cli_fuzz.prepare(folder, root / "models", root / "run" / "results.csv")
        options = [o for o in cli_fuzz.typed_options()
                   if not args.command or o[0] in args.command]
        start = time.perf_counter()
        trials = cli_fuzz.fuzz(folder, tuple(args.values), options=options)
        files = [] if args.command else cli_fuzz.fuzz_files(folder)
        wall = time.perf_counter() - start
    counts = cli_fuzz.table(trials)
    print(f"{len(trials)} trials over {len(options)} options of "
          f"{len({c for c, _ in options})} subcommands in {wall:.0f} s")
    for outcome in ("refused", "ran", "unclear", "traceback", "silent"):
        print(f"  {outcome:<10} {counts.get(outcome, 0)}")
    if files:
        print(f"{len(files)} trials over {len(cli_fuzz.FILE_ARGUMENTS)} file arguments x "
              f"{len(cli_fuzz.FILES)} careless files: {dict(cli_fuzz.table(files))}")
    trials += files
    for t in trials:
        if args.all or t.outcome not in ("refused", "ran"):
            print(f"{t.outcome:<10} {t.command} {t.option} {t.value} (exit {t.code}): "
                  f"{t.said[:160]}")
    return 1 if any(t.outcome not in ("refused", "ran") for t in trials) else 0


if __name__ == "__main__":
    sys.exit(main())
