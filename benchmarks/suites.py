"""The benchmarks as three suites, each script run in a fresh process with the arguments
that make it short, its printed figures kept, its wall time beside them.

    python benchmarks/suites.py                      # the suites, each script's first line
    python benchmarks/suites.py speed [--full]       # run one suite (speed, accuracy, trials)
    python benchmarks/suites.py speed --only chain_cost sensor_cost

- speed: what a step, a call, a run, a record costs (CPU per simulated second, us per
  step beside a matmul yardstick, instructions from callgrind, memory);
- accuracy: the estimates against their bounds and references (error/CRB, error/sigma,
  the self-calibration against the rate table, the plant against an independent solver);
- trials: the adversarial ones (fuzzers, Ctrl-C and kill -9 at random moments, bad input
  from every typed option), each counting what went wrong.

Without --full each script runs with its `QUICK` arguments below (a few minutes for a
suite); with --full, with its own defaults (the figures the docs quote: some take an
hour). Every script in benchmarks/ is in exactly one suite (tests/test_benchmarks.py). Each
script is also a plain command: `python benchmarks/<name>.py --help`.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent

#: suite -> script stem -> its quick arguments (None: the script runs only with --full,
#: its shortest run being long).
SUITES: dict[str, dict[str, list[str] | None]] = {
    "speed": {
        "chain_cost": ["--repeat", "1"],
        "inprocess_chain": ["--repeat", "1"],
        "sensor_cost": ["--seconds", "0.2", "--repeat", "1"],
        "run_overhead": ["--repeat", "1"],
        "run_outputs": None,
        "observer_step_cost": [],
        "observer_fmu_cost": ["--steps", "1000", "--repeat", "1"],
        "native_call_cost": ["--calls", "2000", "--repeat", "1"],
        "cosim_walltime": ["--repeat", "1"],
        "bench": ["--repeat", "1", "--no-memory"],
        "selfcal_engine_cost": None,
        "selfcal_record_cost": None,
    },
    "accuracy": {
        "plant_accuracy": [],
        "observer_families": ["--gyros", "2", "--seeds", "1"],
        "observer_accuracy": None,
        "observer_efficiency": ["--seeds", "2"],
        "observer_robustness": None,
        "observer_user_cases": None,
        "noise_consistency": ["--stop-time", "0.05", "--seeds", "2"],
        "tracking_bound": None,
        "sensor_seed_spread": None,
        "sensor_sway": ["--amplitudes", "0.05", "--seconds", "0.2", "--seeds", "1"],
        "robustness": None,
        "engines": None,
        "selfcal_accuracy": None,
        "selfcal_design": None,
        "selfcal_imperfections": None,
    },
    "trials": {
        "adversarial_trials": None,
        "round4_trials": None,
        "cli_fuzz_trials": ["--values", "nan", "--command", "run"],
        "fmi_call_fuzz_trials": ["--sequences", "20", "--no-pythonfmu"],
        "fuzz_native": ["--seconds", "10", "GyroPlant"],
        "fuzz_states": ["--trials", "50"],
        "fuzz_archives": None,
        "interrupt_trials": ["--runs", "2", "--sweeps", "1"],
        "kill_trials": ["--trials", "3"],
        "kill_trials_outputs": None,
    },
}
#: Modules the scripts share, not benchmarks themselves.
HELPERS = ("suites", "compiled_null", "kill_harness")


def first_line(stem: str) -> str:
    """The first line of a script's docstring."""
    import ast

    doc = ast.get_docstring(ast.parse((HERE / f"{stem}.py").read_text(encoding="utf-8")))
    return (doc or "(no docstring)").splitlines()[0]


def run(suite: str, full: bool, only: list[str] | None) -> int:
    """Run a suite's scripts; the number that failed."""
    failed = 0
    for stem, quick in SUITES[suite].items():
        if only and stem not in only:
            continue
        if quick is None and not full:
            print(f"\n## {stem}: long even at its shortest; run it with --full\n", flush=True)
            continue
        argv = [sys.executable, str(HERE / f"{stem}.py"), *([] if full else quick)]
        print(f"\n## {stem} ({' '.join(argv[1:])})\n", flush=True)
        start = time.perf_counter()
        code = subprocess.run(argv, cwd=HERE.parent).returncode
        print(f"\n-- {stem}: exit {code}, {time.perf_counter() - start:.1f} s wall", flush=True)
        failed += code != 0
    return failed


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("suite", nargs="?", choices=sorted(SUITES))
    p.add_argument("--full", action="store_true", help="each script with its own defaults")
    p.add_argument("--only", nargs="+", metavar="SCRIPT", help="these scripts of the suite")
    a = p.parse_args()
    if a.suite is None:
        for suite, scripts in SUITES.items():
            print(f"{suite}:")
            for stem in scripts:
                print(f"  {stem:<22} {first_line(stem)}")
        return 0
    unknown = sorted(set(a.only or ()) - set(SUITES[a.suite]))
    if unknown:
        p.error(f"{unknown} are not in the {a.suite} suite: {sorted(SUITES[a.suite])}")
    return 1 if run(a.suite, a.full, a.only) else 0


if __name__ == "__main__":
    sys.exit(main())
