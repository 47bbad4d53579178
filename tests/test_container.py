"""The system container FMU: one FMU, same numbers as our master, parameters that reach."""

from __future__ import annotations

from pathlib import Path

import fmpy
import numpy as np
import pytest
from fmpy.validation import validate_fmu

from gyro_fmu.cosim.master import CoSimulationResult
from gyro_fmu.estimation.observer import ObserverTuning
from gyro_fmu.model.rate import RateKind, RateProfile
from gyro_fmu.system.container import build_container, container_start_values, exposed_names
from gyro_fmu.system.run import run_fmus
from gyro_fmu.system.scenario import scenario

STOP, STEP = 0.002, 5e-6
#: Every FMU off its defaults: plant imperfections, rate profile, observer start.
SCENARIO = scenario(
    stop_time=STOP,
    overrides={"kxy": 5e7, "dxy": 3.0, "m": 2e-7},
    rate=RateProfile(RateKind.sine, offset=0.5, amplitude=2.0, frequency=300.0),
    initial={"kxx": 3.6e8},
)
ESTIMATES = ("Omega_hat", "kxx_hat", "kyy_hat", "kxy_hat", "dxx_hat", "dyy_hat", "dxy_hat",
             "m_hat")
PLANT = ("x", "vx", "y", "vy", "ax", "ay")


@pytest.fixture(scope="module")
def container(models_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_container(models_dir, tmp_path_factory.mktemp("container") / "GyroSystem.fmu")


def simulate(container: Path, start_values: dict | None = None) -> np.ndarray:
    return fmpy.simulate_fmu(str(container), stop_time=STOP, output_interval=STEP,
                             start_values=start_values or {})


def max_relative(result: np.ndarray, ref: CoSimulationResult, names: dict) -> dict[str, float]:
    """Per output: max_k |container - master| / max_k |master| (absolute if master is 0)."""
    out = {}
    for (instance, var), exposed in names.items():
        column = f"{instance}.{var}"
        if column not in ref.columns:
            continue  # a parameter
        b = ref[column]
        scale = float(np.max(np.abs(b)))
        diff = float(np.max(np.abs(result[exposed] - b)))
        out[exposed] = diff / scale if scale > 0.0 else diff
    return out


def test_the_container_exposes_parameters_and_outputs_with_units(container, models_dir):
    assert validate_fmu(str(container)) == []
    md = fmpy.read_model_description(str(container))
    assert md.fmiVersion == "2.0" and md.coSimulation is not None
    variables = {v.name: v for v in md.modelVariables}
    for name in ("kxx", "kyy", "kxy", "dxx", "dyy", "dxy", "m", "kind", "offset", "amplitude",
                 "frequency", "slope", "t_start", "A1", "f1", "A2", "f2", "kxy_0"):
        assert variables[name].causality == "parameter", name
    for name in (*ESTIMATES, *PLANT, "sigma_Omega_z", "sigma_m", "Omega_z", "ux"):
        assert variables[name].causality == "output", name
    assert variables["kxy"].unit == "1/s2" and variables["Omega_hat"].unit == "rad/s"
    assert set(exposed_names(models_dir).values()) <= set(variables)
    unitless = [v.name for v in md.modelVariables if v.type == "Real" and not v.unit]
    assert not unitless  # time and the internal links too (twotonedrive.ux, ...)


def test_the_container_runs_like_the_master(container, models_dir):
    """Same scenario, same numbers: FMUCT's parallel mode is our Jacobi step."""
    names = exposed_names(models_dir)
    result = simulate(container, container_start_values(SCENARIO, models_dir))
    ref = run_fmus(SCENARIO, models_dir)
    assert len(result) == len(ref["time"]) == round(STOP / STEP) + 1
    assert np.max(np.abs(result["time"] - ref["time"])) < 1e-18
    rel = max_relative(result, ref, names)
    assert len(rel) == len(ref.columns) - 1  # every output of every FMU is there
    assert max(rel.values()) <= 1e-12, sorted(rel.items(), key=lambda kv: -kv[1])[:3]
    # Its defaults are the FMUs' defaults: the default scenario, except the observer's
    # rate model, which the scenario makes constant for its constant rate
    # (scenario.observer_tuning).
    default = simulate(container)
    fmu_defaults = scenario(stop_time=STOP, tuning={"rate_model": ObserverTuning().rate_model})
    rel = max_relative(default, run_fmus(fmu_defaults, models_dir), names)
    assert max(rel.values()) <= 1e-12


def test_a_top_level_parameter_reaches_the_plant(container, models_dir):
    """kxy on the container alone: the plant moves as a master run with that kxy."""
    changed = simulate(container, {"kxy": 3e7})
    default = simulate(container)
    assert np.max(np.abs(changed["y"] - default["y"])) > 0.1 * np.max(np.abs(default["y"]))
    ref = run_fmus(scenario(stop_time=STOP, overrides={"kxy": 3e7}), models_dir)
    for name in PLANT:  # the plant does not depend on the observer's guesses
        assert np.max(np.abs(changed[name] - ref[f"plant.{name}"])) <= \
            1e-12 * np.max(np.abs(ref[f"plant.{name}"])), name


def test_the_container_carries_reference_results_that_validate(container, capsys):
    """`gyro-fmu container; gyro-fmu validate models/*.fmu` (the CI recipe) exited 1: the
    container had no reference results. It carries them now, and they validate."""
    from gyro_fmu.cli import main

    assert main(["validate", str(container)]) == 0
    assert "all outputs match their reference results" in capsys.readouterr().out


def test_a_scenario_the_container_cannot_initialize_is_named_before_the_run(models_dir):
    """Newcomer's defect 8: the patent scenario failed inside the container after a bare
    "damping matrix ... is indefinite" (gyro_fmu.upstream.fmu_container)."""
    from gyro_fmu.system.container import ContainerError, container_start_values
    from gyro_fmu.system.scenario import scenario

    with pytest.raises(ContainerError, match=r"damping matrix .* indefinite.*container "
                                             r"runtime.*run this scenario with `gyro-fmu run`"):
        container_start_values(scenario("patent", stop_time=0.01), models_dir)
    assert container_start_values(scenario("default", stop_time=0.01), models_dir)["kxx"] > 0


@pytest.mark.parametrize("name", ["default", "patent"])
def test_every_scenario_the_master_runs_runs_in_the_container_or_is_refused(container,
                                                                           models_dir, name):
    from gyro_fmu.system.container import ContainerError, container_start_values
    from gyro_fmu.system.scenario import scenario

    sc = scenario(name, stop_time=STOP)
    try:
        start = container_start_values(sc, models_dir)
    except ContainerError:
        return  # named above, with the remedy
    r = fmpy.simulate_fmu(str(container), stop_time=STOP, output_interval=STEP,
                          start_values=start)
    assert np.all(np.isfinite(r["Omega_hat"]))
