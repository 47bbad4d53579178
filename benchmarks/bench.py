"""gyro_fmu benchmark suite (issue 6): one command, one table, medians of repeats.

    python benchmarks/bench.py [--repeat 5] [--scenario default] [--no-memory]

Measured in one run, interleaved so machine noise hits all alike:
- the scenario (default: 100 ms, 20,000 steps of 5 us, 4 FMUs) through the fmpy master
  and the same computation in-process (gyro_fmu.system.inprocess, no FMI): wall time and ratio;
- the floor: the same master loop, wiring and adapter (GyroSlave) over do-nothing slaves
  with the same variables, built into a temp dir: the cost of FMI, pythonfmu and the master;
- the master alone: the same system over do-nothing FMUs compiled from C
  (compiled_null.py), so the master's own share of the floor is seen;
- the plant step (Omega_z changing every step, and constant) and the observer step alone;
- a fresh process running the scenario through the FMUs (its imports included), and the
  peak memory (ru_maxrss) of a 1 s run with every output recorded.
Machines are noisy: quote ratios from one run; `uptime` is printed with the table.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import numpy as np
from compiled_null import build_compiled_null_fmus

from gyro_fmu.cosim.master import Component, run_cosimulation
from gyro_fmu.fmu.build import PACKAGE_DIR
from gyro_fmu.system.inprocess import run_inprocess
from gyro_fmu.system.run import ensure_fmus, run_fmus
from gyro_fmu.system.scenario import CONNECTIONS, INSTANCE_FMUS, SCENARIOS, scenario

_NULL_SLAVES = {  # instance -> (class name, inputs, outputs), the variables of our FMUs
    "drive": ("NullDrive", [], ["ux", "uy"]),
    "rate": ("NullRate", [], ["Omega_z"]),
    "plant": ("NullPlant", ["ux", "uy", "Omega_z"], ["x", "vx", "y", "vy", "ax", "ay"]),
    "observer": ("NullObserver", ["ux", "uy", "x_meas", "vx_meas", "y_meas", "vy_meas"],
                 ["x_hat", "vx_hat", "y_hat", "vy_hat", "Omega_hat", "kxx_hat", "kyy_hat",
                  "kxy_hat", "dxx_hat", "dyy_hat", "dxy_hat", "m_hat", "sigma_Omega_z",
                  "sigma_kxx", "sigma_kyy", "sigma_kxy", "sigma_dxx", "sigma_dyy", "sigma_dxy",
                  "sigma_m"]),
}


def build_null_fmus(dest: Path) -> dict[str, Path]:
    """Do-nothing GyroSlave FMUs with the inputs and outputs of ours (advance() is empty)."""
    from pythonfmu.builder import FmuBuilder

    paths = {}
    for inst, (cls, inputs, outputs) in _NULL_SLAVES.items():
        variables = [f'Var("{n}", "input", 0.0, "1", "{n}")' for n in inputs]
        variables += [f'Var("{n}", "output", 0.0, "1", "{n}")' for n in outputs]
        script = dest / f"{cls}.py"
        script.write_text(textwrap.dedent(f'''\
            from gyro_fmu.pythonfmu.slave import GyroSlave, Var


            class {cls}(GyroSlave):
                """Does nothing: the floor of FMI, pythonfmu, GyroSlave and the master."""

                VARIABLES = ({", ".join(variables)},)

                def advance(self, t, h):
                    pass
            '''))
        paths[inst] = Path(FmuBuilder.build_FMU(script, dest=dest, project_files=[PACKAGE_DIR]))
    return paths


def _timed(fn) -> float:
    start = time.perf_counter()
    fn()
    return time.perf_counter() - start


def plant_step_us(sc, n: int = 20000, changing: bool = True) -> float:
    from gyro_fmu.model.plant import GyroPlantModel

    plant = GyroPlantModel(sc.params)
    drive, h = sc.the_drive, sc.step
    ux = [drive.ux(k * h) for k in range(n)]
    om = [1.0 + 0.5 * np.sin(2 * np.pi * 100 * k * h) if changing else 1.0 for k in range(n)]
    start = time.perf_counter()
    for k in range(n):
        plant.step(ux[k], 0.0, om[k], h)
    return (time.perf_counter() - start) / n * 1e6


def observer_step_us(sc, n: int = 20000, **tuning) -> float:
    from gyro_fmu.estimation.observer import GyroStateObserver, ObserverTuning
    from gyro_fmu.model.parameters import GyroParameters
    from gyro_fmu.model.plant import GyroPlantModel, MeasurementNoise
    from gyro_fmu.system.scenario import observer_tuning

    plant, drive, h = GyroPlantModel(sc.params), sc.the_drive, sc.step
    ux, z = np.empty(n), np.empty((n, 2))
    for k in range(n):
        ux[k] = drive.ux(k * h)
        z[k] = plant.s[[0, 2]]
        plant.step(ux[k], 0.0, 1.0, h)
    obs = GyroStateObserver(GyroParameters(**sc.initial_guess), sc.Omega_z_0, sc.measured_pair,
                            ObserverTuning(**{**observer_tuning(sc, MeasurementNoise()),
                                              **tuning}))
    args = [(float(ux[k]), 0.0, float(z[k, 0]), float(z[k, 1]), h) for k in range(n)]
    start = time.perf_counter()
    for a in args:
        obs.step(*a)
    return (time.perf_counter() - start) / n * 1e6


_FRESH = """
import time; t0 = time.perf_counter()
from gyro_fmu.system.run import run_fmus; from gyro_fmu.system.scenario import scenario
sc = scenario({name!r}, stop_time={stop!r})
t1 = time.perf_counter(); r = run_fmus(sc); t2 = time.perf_counter()
import resource
rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
print(t2 - t0, t2 - t1, rss, r.data.nbytes / 2**20)
"""


def fresh_process(name: str, stop: float) -> tuple[float, float, float, float, float]:
    """(process wall s, in-script wall incl. imports s, run wall s, peak RSS MB, result MB)."""
    start = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", _FRESH.format(name=name, stop=stop)],
                         check=True, capture_output=True, text=True).stdout.split()
    return (time.perf_counter() - start, *map(float, out))


def selfcal_times(repeat: int) -> tuple[float, float, float]:
    """Median wall of a whole default self-calibration in process (s), the two-FMU
    co-simulation's cost per step (us, 0.5 s run) and the implied FMU calibration (s)."""
    from gyro_fmu.model.loops import LoopSettings
    from gyro_fmu.model.resonator import ResonatorParameters
    from gyro_fmu.selfcal.run import run_fmus as run_selfcal_fmus
    from gyro_fmu.selfcal.sequence import SelfCalConfig, self_calibrate

    res, cfg = ResonatorParameters(noise=2.5e-4), SelfCalConfig()
    # no warm-up: the loops are the C core's
    walls = [_timed(lambda: self_calibrate(res, cfg)) for _ in range(repeat)]
    run_selfcal_fmus(res, LoopSettings(), 0.01)  # build if needed, load
    per_step = statistics.median(
        _timed(lambda: run_selfcal_fmus(res, LoopSettings(), 0.5))
        for _ in range(min(repeat, 3))
    ) / round(0.5 / cfg.step) * 1e6
    n_cal = round((cfg.ff_duration + 0.1 + 2 * (cfg.settle + cfg.record)) / cfg.step)
    return statistics.median(walls), per_step, per_step * 1e-6 * n_cal


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--scenario", default="default", choices=sorted(SCENARIOS))
    ap.add_argument("--no-memory", action="store_true", help="skip the 1 s memory run")
    args = ap.parse_args()
    sc = scenario(args.scenario)
    ensure_fmus()
    run_inprocess(sc.with_(stop_time=1e-3))  # load the compiled kernels before timing
    with tempfile.TemporaryDirectory() as tmp:
        nulls = build_null_fmus(Path(tmp))
        floor_system = [Component(n, nulls[n]) for n in INSTANCE_FMUS]
        compiled = build_compiled_null_fmus(nulls, Path(tmp))
        master_system = [Component(n, compiled[n]) for n in INSTANCE_FMUS]
        times: dict[str, list[float]] = {k: [] for k in ("fmu", "lib", "floor", "master",
                                                          "plant", "plant_const", "observer",
                                                          "observer_adaptive")}
        run_cosimulation(master_system, CONNECTIONS, 10 * sc.step, sc.step)  # load the loop
        for _ in range(args.repeat):
            times["fmu"].append(_timed(lambda: run_fmus(sc)))
            times["lib"].append(_timed(lambda: run_inprocess(sc)))
            times["floor"].append(_timed(lambda: run_cosimulation(
                floor_system, CONNECTIONS, sc.stop_time, sc.step)))
            times["master"].append(_timed(lambda: run_cosimulation(
                master_system, CONNECTIONS, sc.stop_time, sc.step)))
            times["plant"].append(plant_step_us(sc))
            times["plant_const"].append(plant_step_us(sc, changing=False))
            times["observer"].append(observer_step_us(sc, 5000))
            times["observer_adaptive"].append(observer_step_us(sc, 5000, rate_model=0))
    med = {k: statistics.median(v) for k, v in times.items()}
    cal_inprocess, cal_fmu_step, cal_fmu = selfcal_times(args.repeat)
    fresh = fresh_process(args.scenario, sc.stop_time)
    memory = None if args.no_memory else fresh_process(args.scenario, 1.0)
    n = sc.n_steps
    print(f"scenario {args.scenario}: {n} steps of {sc.step * 1e6:g} us; medians of "
          f"{args.repeat}; load: {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    rows = [
        ("FMUs through the fmpy master", med["fmu"], "s", med["fmu"] / n * 1e6, "<= 2 s"),
        ("library in-process (no FMI)", med["lib"], "s", med["lib"] / n * 1e6, ""),
        ("floor: same master, null slaves", med["floor"], "s", med["floor"] / n * 1e6, ""),
        ("master alone: compiled null FMUs", med["master"], "s", med["master"] / n * 1e6, ""),
        ("FMU / in-process", med["fmu"] / med["lib"], "x", None, "<= 1.15"),
        ("(FMU - floor) / in-process", (med["fmu"] - med["floor"]) / med["lib"], "x", None, ""),
        ("plant step, Omega_z changing", med["plant"], "us", None, "<= 10 us"),
        ("plant step, Omega_z constant", med["plant_const"], "us", None, ""),
        ("observer step (the scenario's rate model)", med["observer"], "us", None,
         "<= 25 us"),
        ("observer step, adaptive rate model (FMU default)", med["observer_adaptive"], "us",
         None, "<= 25 us"),
        ("fresh process: run incl. imports", fresh[1], "s", None, "<= 2 s"),
        ("fresh process: whole process", fresh[0], "s", None, ""),
    ]
    rows += [("self-calibration, in process", cal_inprocess, "s", None, "< 5 min"),
             ("self-calibration FMUs: per step", cal_fmu_step, "us", None, ""),
             ("self-calibration through FMUs", cal_fmu, "s", None, "< 5 min (implied)")]
    if memory is not None:
        rows += [("1 s run, all outputs: peak RSS", memory[3], "MB", None, "< 500 MB"),
                 ("1 s run: result array", memory[4], "MB", None, ""),
                 ("1 s run: wall (fresh process)", memory[1], "s", None, "")]
    print(f"{'measure':<36}{'value':>10} {'unit':<4}{'us/step':>10}  target")
    for label, value, unit, per_step, target in rows:
        ps = f"{per_step:10.1f}" if per_step is not None else " " * 10
        print(f"{label:<36}{value:10.3f} {unit:<4}{ps}  {target}")


if __name__ == "__main__":
    main()
