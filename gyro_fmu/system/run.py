"""The main job: co-simulate a scenario through the FMUs and write results, summary, figures."""

from __future__ import annotations

import json
import time
import warnings
from collections.abc import Mapping
from dataclasses import asdict
from pathlib import Path

import numpy as np

from .. import __version__
from ..cosim.master import CoSimulationResult, run_cosimulation
from ..estimation.metrics import ESTIMATED, summarize
from ..fmu.build import FMU_NAMES, MODELS_DIR, ensure_current
from ..model.parameters import GyroParameters, validate_for_plant
from ..model.plant import MeasurementNoise
from .scenario import Scenario, absolute_noise, fmu_system, observer_tuning

HAT = {"Omega_z": "Omega_hat"}


def estimate_column(name: str) -> str:
    return f"observer.{HAT.get(name, name + '_hat')}"


def ensure_fmus(models_dir: Path = MODELS_DIR) -> list[Path]:
    """Build the FMUs that are missing from models_dir or older than the sources; returns
    the paths built."""
    return ensure_current(FMU_NAMES, Path(models_dir))


def run_fmus(
    sc: Scenario,
    models_dir: Path = MODELS_DIR,
    fmus: Mapping[str, Path] | None = None,
    noise: MeasurementNoise | None = None,
    ensure: bool = True,
) -> CoSimulationResult:
    """Co-simulate the scenario's standard system through the FMUs with the fmpy master.

    noise: the absolute pick-off noise, if already computed from the scenario.
    ensure: build missing or stale FMUs first (a sweep's workers leave that to the
    host, so that they never rebuild an FMU another worker is reading).
    """
    if ensure and not fmus:
        ensure_fmus(models_dir)
    noise = absolute_noise(sc) if noise is None else noise
    components, connections = fmu_system(sc, models_dir, fmus, noise)
    return run_cosimulation(components, connections, sc.stop_time, sc.step)


def summary_of(sc: Scenario, result: CoSimulationResult, wall_time_s: float | None = None,
               caught: list[str] | None = None, noise: MeasurementNoise | None = None) -> dict:
    truth: GyroParameters = sc.params
    estimates = {n: result[estimate_column(n)] for n in ESTIMATED}
    sigmas = {n: result[f"observer.sigma_{n}"] for n in ESTIMATED}
    metrics = summarize(result["time"], estimates, sigmas, truth, result["rate.Omega_z"])
    finite = bool(np.all(np.isfinite(result.data)))
    noise = absolute_noise(sc) if noise is None else noise
    return {
        "gyro_fmu_version": __version__,
        "scenario": {**sc.as_dict(), "noise_std_absolute": asdict(noise),
                     "observer_tuning": observer_tuning(sc, noise)},
        "true_parameters": truth.as_dict(),
        "finite": finite,
        "wall_time_s": wall_time_s,
        "warnings": caught or [],
        **metrics,
    }


def run_and_report(
    sc: Scenario,
    out_dir: Path,
    models_dir: Path = MODELS_DIR,
    fmus: Mapping[str, Path] | None = None,
    figures: bool = True,
) -> dict:
    """Run the scenario and write results.csv, summary.json and the figures to out_dir."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        validate_for_plant(sc.params)  # the growth-rate warning goes into summary.json
        noise = absolute_noise(sc)
        start = time.perf_counter()
        result = run_fmus(sc, models_dir, fmus, noise)
        wall = time.perf_counter() - start
    messages = [str(w.message) for w in caught]
    result.write_csv(out_dir / "results.csv")
    summary = summary_of(sc, result, wall, messages, noise)
    (out_dir / "summary.json").write_text(json.dumps(summary, indent=2))
    if figures:
        make_figures(result, sc.params, out_dir)
    return summary


def make_figures(result: CoSimulationResult, truth: GyroParameters, out_dir: Path) -> list[Path]:
    from .figures import fig3_states, fig4_estimates

    return [
        fig3_states(result, Path(out_dir) / "fig3_states.png"),
        fig4_estimates(result, truth, Path(out_dir) / "fig4_estimates.png"),
    ]


def load_results(path: Path) -> CoSimulationResult:
    """Read a results.csv written by `run_and_report`."""
    path = Path(path)
    with path.open() as f:
        columns = tuple(f.readline().strip().split(","))
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    return CoSimulationResult(columns, data, {})
