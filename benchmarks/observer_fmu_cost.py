"""GyroObserver.fmu's doStep through fmpy's FMU2Slave against the same observer step in
process (GyroStateObserver.step, the C core through ctypes), per rate model.

    python benchmarks/observer_fmu_cost.py [--steps 5000] [--repeat 5]

Thread CPU time per step, median of the repeats, on the default scenario's data (two-tone
drive, noise-free measurements of the default plant at 1 rad/s, 5 us steps; the same
numbers in both). FMU: one fmi2SetReal of the 6 inputs and one fmi2DoStep per step, as
the master makes them; in process: one step() call. The floor is the do-nothing C FMU
(benchmarks/compiled_null.py): what fmpy's FMU2Slave costs per setReal + doStep here.
Target (issue "FMUs that run anywhere 2 of 2"): the FMU within 1.3x of in process.
"""

from __future__ import annotations

import argparse
import statistics
import time

from compiled_null import build_compiled_null_fmus
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

from gyro_fmu.estimation.interface import OBSERVER
from gyro_fmu.estimation.observer import GyroStateObserver, ObserverTuning
from gyro_fmu.fmu.build import prebuilt_fmu
from gyro_fmu.model.parameters import GyroParameters

H = 5e-6
INPUTS = ("ux", "uy", "x_meas", "vx_meas", "y_meas", "vy_meas")


def _data(steps: int):
    table = OBSERVER.reference_inputs(steps * H, H)
    return [[float(table[n][k]) for n in INPUTS] for k in range(steps)]


def _guess() -> GyroParameters:
    v = {x.name: x.start for x in OBSERVER.variables}
    return GyroParameters(*(v[f"{n}_0"] for n in ("kxx", "kyy", "kxy", "dxx", "dyy", "dxy",
                                                   "m")))


def in_process_us(rows, rate_model: int) -> float:
    obs = GyroStateObserver(_guess(), tuning=ObserverTuning(rate_model=rate_model))
    step = obs.step
    start = time.thread_time()
    for ux, uy, x, _vx, y, _vy in rows:
        step(ux, uy, x, y, H)
    return (time.thread_time() - start) / len(rows) * 1e6


def fmu_us(fmu, rows, rate_model: int) -> float:
    md = read_model_description(str(fmu))
    s = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(fmu)),
                  modelIdentifier=md.coSimulation.modelIdentifier, instanceName="bench")
    s.instantiate()
    vr = {v.name: v.valueReference for v in md.modelVariables}
    if not fmu.stem.startswith("Compiled"):  # the do-nothing FMU has Reals only
        s.setInteger([vr["rate_model"]], [rate_model])
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    vrs = [vr[n] for n in INPUTS]
    set_real, do_step = s.setReal, s.doStep
    t = 0.0
    start = time.thread_time()
    for row in rows:
        set_real(vrs, row)
        do_step(t, H)
        t += H
    cost = (time.thread_time() - start) / len(rows) * 1e6
    s.terminate()
    s.freeInstance()
    return cost


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=5000)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    rows = _data(args.steps)
    fmu = prebuilt_fmu("GyroObserver")
    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory() as tmp:
        null = build_compiled_null_fmus({"observer": fmu}, Path(tmp))["observer"]
        floor = statistics.median(fmu_us(null, rows, 0) for _ in range(args.repeat))
        print(f"floor (do-nothing C FMU, setReal + doStep): {floor:.2f} us")
        print("rate model        in process   FMU (native)   ratio   FMU - floor")
        for rate_model, name in ((0, "adaptive"), (1, "constant")):
            lib, ext = [], []
            for _ in range(args.repeat):  # interleaved: machine noise hits both alike
                lib.append(in_process_us(rows, rate_model))
                ext.append(fmu_us(fmu, rows, rate_model))
            a, b = statistics.median(lib), statistics.median(ext)
            print(f"{rate_model} {name:<14} {a:9.2f} us {b:11.2f} us {b / a:8.2f} "
                  f"{b - floor:10.2f} us")


if __name__ == "__main__":
    main()
