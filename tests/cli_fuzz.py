"""The CLI fuzzer: every typed option of every `gyro-fmu` subcommand driven with -1, 0,
nan, inf, 1e300 and text, each trial through `gyro_fmu.cli.main` in this process (the
tests call it; benchmarks/cli_fuzz_trials.py prints its table).

The options come from the parser itself, so a new option is fuzzed without a word here.
Each trial runs in a fresh folder with a time budget: a value accepted as valid starts
real work, which an alarm turns into Ctrl-C (exit 130, the CLI's contract) after
`budget` seconds; the Dask-backed commands stop at the point they would submit work.

Classes of a trial:
- "refused": exit 2, no traceback, the last line of stderr an error naming the option or
  the value;
- "unclear": exit 2 without naming either;
- "traceback": an exception escaped main(), or a traceback was printed;
- "ran": exit 0, 1 or 130 with a value that may be valid (-1, 0, 1e300);
- "silent": exit 0 or 130 with nan, inf or text, which no option of ours means.
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import io
import os
import signal
import traceback
import warnings
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

VALUES = ("-1", "0", "nan", "inf", "1e300", "text")
MEANINGLESS = {"nan", "inf", "text"}
#: Arguments that make a command's valid run short (and write into the trial's folder).
BASE: dict[str, list[str]] = {
    "run": ["--stop-time", "0.0005", "--no-figures", "--out", "out"],
    "observability": ["--stop-time", "0.0005"],
    "identify": ["results.csv"],
    "design-drive": ["--stop-time", "0.0005", "--out", "out/heat.png"],
    "sweep": ["--n", "2", "--stop-time", "0.0005", "--out", "out"],
    "ssp": ["--stop-time", "0.0005", "--out", "out/system.ssp"],
    "container": ["--dest", "out/GyroSystem.fmu"],
    "selfcal": ["--record", "5", "--settle", "0.2", "--no-figures", "--out", "out"],
    "selfcal-lot": ["-n", "2", "--no-figures", "--out", "out"],
    "ratetable": ["--dwell", "0.1", "--out", "out"],
    "spec": ["--duration", "0.01", "--no-figure", "--out", "out"],
    "validate": ["models/TwoToneDrive.fmu"],
}


@dataclass(frozen=True)
class Trial:
    command: str
    option: str
    value: str
    outcome: str
    code: int | None
    said: str  #: the last line of stderr, or the traceback's last line
    warned: tuple[str, ...] = ()  #: the Python warnings the trial raised (category: text)


def typed_options() -> Iterator[tuple[str, str]]:
    """(subcommand, option) for every option whose parser converts its value (int, float
    or a custom type)."""
    from gyro_fmu.cli import parser

    sub = next(a for a in parser()._actions if isinstance(a, argparse._SubParsersAction))
    for name, sp in sub.choices.items():
        for action in sp._actions:
            if action.option_strings and action.type not in (None, str):
                yield name, max(action.option_strings, key=len)


def _option_dests() -> dict[tuple[str, str], str]:
    from gyro_fmu.cli import parser

    sub = next(a for a in parser()._actions if isinstance(a, argparse._SubParsersAction))
    return {(n, s): a.dest for n, sp in sub.choices.items() for a in sp._actions
            for s in a.option_strings}


def _argv(command: str, option: str | None, value: str, out: str) -> list[str]:
    base = [a.replace("out", out, 1) if a.startswith("out") else a
            for a in BASE.get(command, [])]
    if option is None:  # the base run alone
        return [command, *base]
    if option in base:  # the fuzzed option replaces the base's value
        i = base.index(option)
        del base[i:i + 2]
    return [command, *base, option, value]


def _invoke(argv: list[str], folder: Path, budget: float
            ) -> tuple[int | None, str, str, str | None, tuple[str, ...]]:
    """`gyro-fmu argv` in this process from `folder`, cut by an alarm after `budget` s (exit
    130): (exit code, stdout, stderr, the escaped exception or None, the warnings it
    raised)."""
    from gyro_fmu import cli

    err, out = io.StringIO(), io.StringIO()
    code: int | None = None
    escaped = None
    # what an earlier trial left for the garbage collector (a generator or a file of an
    # interrupted run, whose finalizer warns) is collected here, so that its warnings are
    # no later trial's. (The ResourceWarning of design-drive --seed 0 in stops 52-53 was
    # that trial's own: its alarm cut Pillow's PNG writer, which then left its file open;
    # outputs.save_figure now opens the file itself.) Before every trial:
    # `fuzz` froze what existed before the first one, so a collection walks only what the
    # trials made (a full one over the whole heap cost 57 ms, 45 s over every trial).
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        gc.collect()
    previous = signal.signal(signal.SIGALRM, _alarm)
    cwd = os.getcwd()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            os.chdir(folder)
            _ARMED[0] = True
            signal.setitimer(signal.ITIMER_REAL, budget)
            with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
                try:
                    code = cli.main(argv)
                except SystemExit as exc:  # argparse
                    code = exc.code if isinstance(exc.code, int) else 2
        except KeyboardInterrupt:
            code = 130
        except BaseException as exc:
            escaped = "".join(traceback.format_exception_only(type(exc), exc)).strip()
        finally:
            _disarm(previous, cwd)
    warned = tuple(f"{w.category.__name__}: {w.message}" for w in caught)
    return code, out.getvalue(), err.getvalue(), escaped, warned


def _disarm(previous: object, cwd: str) -> None:
    """End a trial's alarm. An alarm whose handler runs on entering the caller's `finally`
    (a late signal under load: Python runs handlers between bytecodes) would raise out of
    it and stop the whole test session; here it is absorbed and the disarming done again."""
    while True:
        try:
            _ARMED[0] = False  # first: an alarm from here on must not escape the trial
            signal.setitimer(signal.ITIMER_REAL, 0)
            signal.signal(signal.SIGALRM, previous)
            os.chdir(cwd)
            return
        except KeyboardInterrupt:
            continue


def run_trial(command: str, option: str | None, value: str, folder: Path, out: str = "out",
              budget: float = 1.5, base_said: str | None = None) -> Trial:
    """One trial in `folder` (which `prepare` gave models/ and a results.csv), writing
    under folder/out; option None: the command's base run. `base_said`: what the base
    run's refusal said (a trial refused with the same words ran like the base: the short
    base settings, not the fuzzed value, were refused)."""
    from gyro_fmu.studies import tasks

    argv = _argv(command, option, value, out)
    saved_tasks = tasks.run_tasks
    tasks.run_tasks = _no_dask
    try:
        code, _, text, escaped, warned = _invoke(argv, folder, budget)
    finally:
        tasks.run_tasks = saved_tasks
    lines = [ln for ln in text.splitlines() if ln.strip()]
    said = escaped or (lines[-1] if lines else "")
    if escaped or "Traceback" in text:
        outcome = "traceback"
    elif code == 2 and base_said is not None and said[:40] == base_said[:40]:
        outcome = "ran"
    elif code == 2:
        dest = _option_dests().get((command, option), "@")
        named = any(k and k in text for k in (option, value, dest, dest.replace("_", "-")))
        outcome = "refused" if ("error" in text or "refused" in text) and named else "unclear"
    elif value in MEANINGLESS and code in (0, 130):
        outcome = "silent"
    else:
        outcome = "ran"
    return Trial(command, option, value, outcome, code, said[:300], warned)


#: Whether the last trial was cut (its alarm) or escaped: the next one collects first.
#: Whether a trial is running: the alarm interrupts only then. Under load an alarm came
#: late, after the trial, and stopped the whole test session from a thread join.
_ARMED = [False]


def _alarm(signum: int, frame: object) -> None:
    if _ARMED[0]:
        _ARMED[0] = False  # once: a second interrupt would cut the CLI's own clean-up
        raise KeyboardInterrupt("trial budget")


def _no_dask(*args: object, **kwargs: object) -> object:
    raise KeyboardInterrupt("the work would be submitted to Dask here")


def prepare(folder: Path, models: Path, results: Path) -> None:
    """The trials' folder: the FMUs in models/ and a results.csv of a short run."""
    import shutil

    folder.mkdir(parents=True, exist_ok=True)
    if not (folder / "models").exists():
        shutil.copytree(models, folder / "models")
    shutil.copy2(results, folder / "results.csv")


#: Commands whose base run needs longer than the default budget to reach its verdict.
BUDGET = {"selfcal": 4.0}


def fuzz(folder: Path, values: tuple[str, ...] = VALUES, budget: float = 1.5,
         options: list[tuple[str, str]] | None = None) -> list[Trial]:
    """Every (command, option) x value, in the prepared `folder`."""
    import matplotlib.pyplot  # noqa: F401 - an alarm inside its import breaks it for good

    trials, base = [], {}
    gc.collect()
    gc.freeze()  # the collection before each trial walks only what the trials made
    try:
        for k, (command, option) in enumerate(options or list(typed_options())):
            seconds = BUDGET.get(command, budget)
            if command not in base:  # also imports its stack, which an alarm must not cut
                b = run_trial(command, None, "", folder, f"base{k}", max(seconds, 10.0))
                base[command] = b.said if b.code == 2 else None
            for j, value in enumerate(values):
                trials.append(run_trial(command, option, value, folder, f"out{k}-{j}",
                                        seconds, base[command]))
    finally:
        gc.unfreeze()
    return trials


def table(trials: list[Trial]) -> Counter:
    return Counter(t.outcome for t in trials)


#: Each file argument of the CLI, as argv with {} where the file goes (the rest short).
FILE_ARGUMENTS: dict[str, list[str]] = {
    "identify RESULTS": ["identify", "{}"],
    "validate FMU": ["validate", "{}"],
    "doctor --fmu": ["doctor", "--no-compile", "--fmu", "{}"],
    "report RUN_DIR": ["report", "{}"],
    "run --fmu plant=": ["run", "--stop-time", "0.0005", "--no-figures", "--out", "out",
                         "--fmu", "plant={}"],
    "ratetable --feedforward-from": ["ratetable", "--dwell", "0.1", "--out", "out",
                                     "--feedforward-from", "{}"],
    "run --models": ["run", "--stop-time", "0.0005", "--no-figures", "--out", "out",
                     "--models", "{}"],
}
#: Arguments that ask for a folder (which a folder may satisfy).
FOLDER_ARGUMENTS = {"run --models", "report RUN_DIR"}
#: What a careless user hands a file argument.
FILES = ("a folder", "an empty file", "a binary file", "UTF-16 text", "Latin-1 text")


def make_files(folder: Path) -> dict[str, Path]:
    folder.mkdir(parents=True, exist_ok=True)
    made = {"a folder": folder / "folder", "an empty file": folder / "empty.csv",
            "a binary file": folder / "binary.fmu", "UTF-16 text": folder / "utf16.csv",
            "Latin-1 text": folder / "latin1.csv"}
    made["a folder"].mkdir(exist_ok=True)
    made["an empty file"].write_bytes(b"")
    made["a binary file"].write_bytes(bytes(range(256)) * 64)
    text = "time,drive.ux,plant.x,plant.y\n0,0,0,0\n5e-6,1e-7,1e-9,1e-10 # \u00e9t\u00e9\n"
    made["UTF-16 text"].write_text(text, encoding="utf-16")
    made["Latin-1 text"].write_text(text, encoding="latin-1")
    return made


def file_trial(label: str, what: str, path: Path, folder: Path, budget: float = 3.0) -> Trial:
    """One file argument given `what`: refused (exit 2, or validate's exit 1 with a FAIL
    line naming the file) or a traceback; "unclear" when the refusal names neither the
    file nor the argument; "ran" only for a folder where a folder is asked for."""
    argv = [a.replace("{}", str(path)) for a in FILE_ARGUMENTS[label]]
    code, out, err, escaped, _ = _invoke(argv, folder, budget)
    text = err + out
    lines = [ln for ln in err.splitlines() if ln.strip()]
    said = escaped or (lines[-1] if lines else out.strip()[-300:])
    named = path.name in text or label.split()[-1].strip("=") in text
    if escaped or "Traceback" in text:
        outcome = "traceback"
    elif code == 2 or (label.startswith("validate") and code == 1 and "FAIL" in text):
        outcome = "refused" if named else "unclear"
    elif what == "a folder" and label in FOLDER_ARGUMENTS:
        outcome = "ran"
    else:
        outcome = "silent"
    return Trial(label, what, path.name, outcome, code, said[:300])


def fuzz_files(folder: Path) -> list[Trial]:
    """Every file argument x every careless file, in the prepared `folder`."""
    made = make_files(folder / "careless")
    return [file_trial(label, what, made[what], folder) for label in FILE_ARGUMENTS
            for what in FILES]
