"""Every typed option of every subcommand, driven with -1, 0, nan, inf, 1e300 and text
(tests/cli_fuzz.py): each trial is refused in one line that names the option or the
value (exit 2), or runs (a value that may be meant); none ends in a traceback, an
unclear refusal, or a silent run on nan, inf or text."""

from __future__ import annotations

import shutil
from pathlib import Path

import cli_fuzz
import pytest


@pytest.fixture(scope="module")
def fuzz_folder(models_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    from gyro_fmu.cli import main

    folder = tmp_path_factory.mktemp("cli-fuzz")
    run = folder / "run"
    assert main(["run", "--stop-time", "0.002", "--no-figures", "--models", str(models_dir),
                 "--out", str(run)]) == 0
    cli_fuzz.prepare(folder, models_dir, run / "results.csv")
    shutil.rmtree(run)
    return folder


def test_the_fuzzer_reaches_every_subcommand_with_typed_options():
    commands = {c for c, _ in cli_fuzz.typed_options()}
    assert set(cli_fuzz.BASE) <= commands | {"validate"}
    assert len(list(cli_fuzz.typed_options())) >= 80


def test_every_typed_option_refuses_or_runs(fuzz_folder: Path):
    trials = cli_fuzz.fuzz(fuzz_folder)
    counts = cli_fuzz.table(trials)
    bad = [t for t in trials if t.outcome not in ("refused", "ran")]
    print(f"{len(trials)} trials: {dict(counts)}")
    assert not bad, "\n".join(f"{t.outcome}: {t.command} {t.option} {t.value} (exit "
                              f"{t.code}): {t.said}" for t in bad)
    assert counts["refused"] > 0.8 * len(trials)  # nan, inf and text at least
    # numbers out of the double range on the way to a refusal (1e300 squared) are the only
    # warnings: each trial's are kept in its record, none reaches the suite's summary
    warned = [t for t in trials if t.warned]
    assert all(t.value == "1e300" and all(w.startswith("RuntimeWarning: ") for w in t.warned)
               for t in warned), [(t.command, t.option, t.value, t.warned) for t in warned]


def test_the_classifier_sees_a_traceback_and_a_silent_run(fuzz_folder: Path, monkeypatch):
    """The harness itself: an option whose check is removed is caught."""
    from gyro_fmu import options

    monkeypatch.setattr(options, "positive", float)  # main() builds its parser anew
    from gyro_fmu.system import scenario

    real = scenario.Scenario.__post_init__

    def unchecked(self):  # the scenario no longer checks its step
        try:
            real(self)
        except Exception:
            pass

    monkeypatch.setattr(scenario.Scenario, "__post_init__", unchecked)
    t = cli_fuzz.run_trial("observability", "--step", "nan", fuzz_folder, "out-check")
    assert t.outcome in ("traceback", "silent", "unclear"), t


def test_every_file_argument_refuses_what_is_not_its_file(fuzz_folder: Path):
    """Each file argument given a folder, an empty file, a binary file, UTF-16 and
    Latin-1 text: one line naming the file (validate: its FAIL line), exit 2 (1)."""
    trials = cli_fuzz.fuzz_files(fuzz_folder)
    bad = [t for t in trials if t.outcome not in ("refused", "ran")]
    print(f"{len(trials)} trials: {dict(cli_fuzz.table(trials))}")
    assert not bad, "\n".join(f"{t.outcome}: {t.command} given {t.option} (exit {t.code}): "
                              f"{t.said}" for t in bad)
    assert len(trials) == len(cli_fuzz.FILE_ARGUMENTS) * len(cli_fuzz.FILES)
