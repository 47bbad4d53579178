"""The main job: co-simulate a scenario through the FMUs and write results, summary, figures.

The results stream to results.csv and results.parquet (with the parquet extra) as the run
goes (`gyro_fmu.results.writer`); the summary and the figures are then made by reading the
Parquet file (or the CSV) back in chunks, so memory does not grow with the run's length.
"""

from __future__ import annotations

import json
import tempfile
import time
import uuid
import warnings
from collections.abc import Callable, Mapping
from dataclasses import asdict
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .. import __version__
from ..cache import remembered
from ..cosim.master import CoSimulationInterrupted, CoSimulationResult, run_cosimulation
from ..errors import GyroFmuError
from ..estimation.metrics import ESTIMATED, RunMetrics, summarize
from ..fmu.build import FMU_NAMES, MODELS_DIR, ensure_current
from ..interrupts import Deferral
from ..model.drive import DriveFarFromModesWarning
from ..model.parameters import GyroParameters, ParameterError, validate_for_plant
from ..model.plant import MeasurementNoise
from ..outputs import atomic_write, out_folder
from ..results.columns import OBSERVED, TRUE_RATE, estimate_column, sigma_column
from ..results.read import iter_columns
from ..results.writer import CSV, PARQUET, ResultFiles
from ..studies.progress import progress_bar
from .scenario import Scenario, absolute_noise, fmu_system, observer_tuning

if TYPE_CHECKING:
    from .figures import FigureData

__all__ = ["estimate_column", "run_and_report", "run_fmus", "summary_of"]


def ensure_fmus(models_dir: Path = MODELS_DIR) -> list[Path]:
    """Build the FMUs that are missing from models_dir or older than the sources; returns
    the paths built."""
    return ensure_current(FMU_NAMES, Path(models_dir))


#: Runs of at least this many steps show a progress bar (about 2 s of the default system).
PROGRESS_STEPS = 300_000


def run_fmus(
    sc: Scenario,
    models_dir: Path = MODELS_DIR,
    fmus: Mapping[str, Path] | None = None,
    noise: MeasurementNoise | None = None,
    ensure: bool = True,
    sink: ResultFiles | None = None,
) -> CoSimulationResult:
    """Co-simulate the scenario's standard system through the FMUs with the fmpy master.

    noise: the absolute pick-off noise, if already computed from the scenario.
    ensure: build missing or stale FMUs first (a sweep's workers leave that to the
    host, so that they never rebuild an FMU another worker is reading).
    sink: stream the rows into these files instead of keeping them (the result then
    holds the last point only).
    """
    if ensure and not fmus:
        ensure_fmus(models_dir)
    noise = absolute_noise(sc) if noise is None else noise
    components, connections = fmu_system(sc, models_dir, fmus, noise)
    with progress_bar(sc.n_steps + 1, "co-simulation", "step", PROGRESS_STEPS) as bar:
        return run_cosimulation(components, connections, sc.stop_time, sc.step,
                                progress=bar, sink=sink,
                                on_columns=None if sink is None else sink.begin)


def summary_of(sc: Scenario, result: CoSimulationResult, wall_time_s: float | None = None,
               caught: list[str] | None = None, noise: MeasurementNoise | None = None) -> dict:
    """summary.json's content for a result held in memory."""
    estimates = {n: result[estimate_column(n)] for n in ESTIMATED}
    sigmas = {n: result[sigma_column(n)] for n in ESTIMATED}
    metrics = summarize(result["time"], estimates, sigmas, sc.params, result[TRUE_RATE])
    return _summary(sc, metrics, bool(np.all(np.isfinite(result.data))), wall_time_s,
                    caught, noise)


def _summary(sc: Scenario, metrics: dict, finite: bool, wall_time_s: float | None,
             caught: list[str] | None, noise: MeasurementNoise | None) -> dict:
    noise = absolute_noise(sc) if noise is None else noise
    return {
        "gyro_fmu_version": __version__,
        "scenario": {**sc.as_dict(), "noise_std_absolute": asdict(noise),
                     "observer_tuning": observer_tuning(sc, noise)},
        "true_parameters": sc.params.as_dict(),
        "finite": finite,
        "wall_time_s": wall_time_s,
        "warnings": caught or [],
        **metrics,
    }


def read_back(path: Path, truth: GyroParameters, figures: bool = True
              ) -> tuple[RunMetrics, FigureData | None]:
    """The summary's metrics and (if figures) the figures' data of a run's results file
    (results.parquet, or results.csv of an older run), read in chunks: two passes, the
    first for the run's span and largest rate, as the tail and the rate's tolerance
    depend on them."""
    from .figures import FigureData

    metrics = RunMetrics(truth)
    for chunk in iter_columns(path, ("time", TRUE_RATE)):
        metrics.scan(chunk["time"], chunk[TRUE_RATE])
    if not metrics.rows:
        raise RunOutputError(f"{path} has a header but no rows: rerun the scenario")
    data = FigureData(truth, metrics.t0, metrics.t_end) if figures else None
    for chunk in iter_columns(path, FigureData.COLUMNS if figures else OBSERVED):
        metrics.judge(chunk["time"], {n: chunk[estimate_column(n)] for n in ESTIMATED},
                      {n: chunk[sigma_column(n)] for n in ESTIMATED}, chunk[TRUE_RATE])
        if data is not None:
            data.feed(chunk)
    return metrics, data


def replaced_run(out: Path, sc: Scenario, force: bool) -> str:
    """What an earlier run in `out` had other than sc ("" when nothing or the same): with
    other settings it is refused unless force (a second run silently replaced the first).
    A folder being written (its lock held) is left to run_and_report's own refusal."""
    from ..outputs import LOCK

    if (out / LOCK).exists():
        return ""
    try:
        old = json.loads((out / "summary.json").read_text())["scenario"]
    except (OSError, ValueError, KeyError, TypeError):
        return ""
    new = json.loads(json.dumps(sc.as_dict()))  # as summary.json holds it
    changed = [f"{k}={old.get(k)!r}" for k in sorted(new) if old.get(k, new[k]) != new[k]]
    if not changed:
        return ""
    said = ", ".join(changed[:4]) + (f" and {len(changed) - 4} more" if len(changed) > 4 else "")
    if not force:
        raise ParameterError(f"{out} holds a run with other settings ({said}): give another "
                             "--out, or --force to replace it")
    return said


def run_and_report(
    sc: Scenario,
    out_dir: Path,
    models_dir: Path = MODELS_DIR,
    fmus: Mapping[str, Path] | None = None,
    figures: bool = True,
    ensure: bool = True,
) -> dict:
    """Run the scenario and write results.csv, summary.json and the figures to out_dir.

    ensure: build missing or stale FMUs into models_dir first (False when the caller
    just did).

    The folder is made (or refused) before the run, and removed again if the run fails
    before writing into it. Ctrl-C (CoSimulationInterrupted) writes what was simulated,
    with `"interrupted"` in summary.json, and is raised again; a results file that
    cannot be written is saved to a fresh temporary folder (`write_or_rescue`).
    """
    with out_folder(Path(out_dir)) as folder:
        return _run_into(sc, folder, models_dir, fmus, figures, ensure)


def _run_into(sc: Scenario, out_dir: Path, models_dir: Path, fmus: Mapping[str, Path] | None,
              figures: bool, ensure: bool) -> dict:
    """run_and_report's work, with the folder's lock held."""
    run_id = uuid.uuid4().hex
    # from the simulation's end to summary.json, Ctrl-C waits: results never stay without
    # the summary that describes them (a second Ctrl-C stops at once)
    held = Deferral("gyro-fmu: finishing summary.json (Ctrl-C again to stop at once)")
    try:
        with ResultFiles(out_dir, run_id, expected_rows=sc.n_steps + 1) as files:  # removed
            # again if the run fails
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                validate_for_plant(sc.params)  # the growth-rate warning goes into summary
                _warn_if_drive_far(sc)
                noise = absolute_noise(sc)
                start = time.perf_counter()
                try:
                    run_fmus(sc, models_dir, fmus, noise, ensure=ensure, sink=files)
                    interrupted = None
                except CoSimulationInterrupted as exc:
                    if files.rows < 2:
                        raise
                    interrupted = exc
                wall = time.perf_counter() - start
            held.start()
            # an old summary must never sit beside new results: it goes before they come
            for name in ("summary.json", *FIGURES):  # nor an old figure
                (out_dir / name).unlink(missing_ok=True)
            record = files.close()
        written = [CSV] + ([PARQUET] if "binary" in record else [])
        metrics, data = read_back(out_dir / written[-1], sc.params,
                                  figures and interrupted is None)
        summary = _summary(sc, metrics.summary(), files.finite, wall,
                           [str(w.message) for w in caught], noise)
        summary["run_id"] = run_id
        summary["results"] = record
        if interrupted is not None:
            summary["interrupted"] = {"at_s": metrics.t_end, "message": str(interrupted)}
        write_or_rescue(lambda path: path.write_text(json.dumps(summary, indent=2)),
                        out_dir / "summary.json")
    finally:
        held.stop()
    if held.caught and interrupted is None:  # the simulation had ended: all of it is kept
        raise KeyboardInterrupt(
            f"after the simulation: {out_dir} holds {', '.join(written)} and summary.json, "
            f"complete; the figures were not drawn (`gyro-fmu report {out_dir}` draws them)")
    if interrupted is not None:
        interrupted.args = (f"{interrupted}; wrote what was simulated to {out_dir}: "
                            f"{', '.join(written)} and summary.json",)
        raise interrupted
    if data is not None:
        make_figures(data, out_dir)
    return summary


def _warn_if_drive_far(sc: Scenario) -> None:
    """DriveFarFromModesWarning (into summary.json and the CLI's warnings) when the drive
    loses more than half the information tones around the guessed modes would give.
    The bound is the C core's (gyro_excitation.c, 25 ms at 5 us; no scipy), and its
    verdict is remembered on disk (`gyro_fmu.cache`) for a run with the same guess, drive
    and step as an earlier one."""
    try:
        guess = GyroParameters(**sc.initial_guess)
    except GyroFmuError:  # a guess the bound cannot use: the run says what is wrong
        return
    Omega_z = float(sc.rate.Omega_z(0.0))

    def compute() -> str | None:
        from ..model.drive import drive_warning

        try:
            return drive_warning(guess, sc.the_drive, Omega_z, sc.step, sc.measured_pair)
        except GyroFmuError:  # a guess the bound cannot use: the run says what is wrong
            return None

    inputs = {"guess": guess.as_dict(), "drive": asdict(sc.the_drive), "Omega_z": Omega_z,
              "h": sc.step, "measured_pair": int(sc.measured_pair)}
    # the C core's bound (gyro_excitation.c) and its binding
    text = remembered("drive-warning", inputs, ("model", "core"), compute)
    if text:
        warnings.warn(text, DriveFarFromModesWarning, stacklevel=2)


def write_or_rescue(write: Callable[[Path], None], path: Path) -> Path:
    """write(path); if the OS refuses, write(same name in a fresh temporary folder) and
    raise a GyroFmuError naming both, so that computed results are never lost. Returns
    the path written."""
    try:
        return atomic_write(path, write)  # whole under its name, or not there at all
    except OSError as exc:
        rescue = Path(tempfile.mkdtemp(prefix="gyro-fmu-rescue-")) / path.name
        write(rescue)
        raise RunOutputError(
            f"could not write {path} ({exc.strerror or exc}); the results are safe in "
            f"{rescue}: free space or fix the folder's permissions, or give another --out"
        ) from exc


#: The figures `gyro-fmu run` draws from results.csv.
FIGURES = ("fig3_states.png", "fig4_estimates.png", "rate_estimate.png")


class RunOutputError(GyroFmuError):
    """An output file of a run could not be written (its content was rescued)."""


def make_figures(data: FigureData, out_dir: Path) -> list[Path]:
    """Draw FIGURES into out_dir from `read_back`'s figure data."""
    from .figures import fig3_states, fig4_estimates, fig_rate

    return [draw(data, Path(out_dir) / name)
            for draw, name in zip((fig3_states, fig4_estimates, fig_rate), FIGURES,
                                  strict=True)]


def load_results(path: Path) -> CoSimulationResult:
    """Read a results.csv written by `run_and_report`; RunOutputError if it is not one
    (no header, no rows, rows of unequal length, a cell that is not a number)."""
    path = Path(path)
    with path.open() as f:
        columns = tuple(f.readline().strip().split(","))
    if columns[:1] != ("time",):
        raise RunOutputError(f"{path} is not a results.csv of `gyro-fmu run`: its header "
                             f"starts with {columns[:1]}, not 'time'; rerun the scenario")
    try:
        with warnings.catch_warnings():  # "input contained no data": checked below
            warnings.simplefilter("ignore", UserWarning)
            data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    except ValueError as exc:
        raise RunOutputError(f"{path} is damaged ({exc}): rerun the scenario") from None
    if data.shape[0] == 0 or data.shape[1] != len(columns):
        raise RunOutputError(f"{path} holds {data.shape[0]} rows of {data.shape[1]} values "
                             f"for {len(columns)} columns: rerun the scenario")
    return CoSimulationResult(columns, data, {})
