"""Per-call cost of the native FMUs through fmpy's FMU2Slave, against the pythonfmu
flavour of the same FMU (today's kind: an embedded interpreter over the same C core).

    python benchmarks/native_call_cost.py [--calls 20000] [--repeat 5]

Thread CPU time (time.thread_time) per fmi2DoStep, median of the repeats, for GyroPlant
(Omega_z held constant, and Omega_z changed before every step so that every step computes
a new matrix exponential; the setReal alone is timed and subtracted), TwoToneDrive and
RateProfile (a 100 Hz sine). Targets (issue "FMUs that run anywhere 1 of 2"): GyroPlant
under 2 us, TwoToneDrive and RateProfile under 1.5 us. The floor column is a do-nothing
C FMU with the same variables (benchmarks/compiled_null.py): what fmpy's FMU2Slave itself
costs per doStep on this machine, which no FMU can go under.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

from compiled_null import build_compiled_null_fmus
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

from gyro_fmu.fmu.build import build_fmu, prebuilt_fmu


def _slave(fmu: Path) -> FMU2Slave:
    md = read_model_description(str(fmu))
    s = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(fmu)),
                  modelIdentifier=md.coSimulation.modelIdentifier, instanceName="bench")
    s.instantiate()
    vr = {v.name: v.valueReference for v in md.modelVariables}
    if md.coSimulation.modelIdentifier == "RateProfile" and not fmu.stem.startswith("Compiled"):
        s.setInteger([vr["kind"]], [4])
        s.setReal([vr["amplitude"], vr["frequency"]], [1.0, 100.0])
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    s.vr = vr
    return s


def per_call_us(fmu: Path, calls: int, changing: bool) -> float:
    s = _slave(fmu)
    h = 5e-6
    t = 0.0
    if changing:
        vr = [s.vr["Omega_z"]]
        values = [1.0 + 0.5 * ((k % 200) / 200.0) for k in range(calls)]
        start = time.thread_time()
        for k in range(calls):
            s.setReal(vr, [values[k]])
            s.doStep(t, h)
            t += h
        both = time.thread_time() - start
        start = time.thread_time()
        for k in range(calls):
            s.setReal(vr, [values[k]])
        alone = time.thread_time() - start
        cost = (both - alone) / calls
    else:
        start = time.thread_time()
        for _ in range(calls):
            s.doStep(t, h)
            t += h
        cost = (time.thread_time() - start) / calls
    s.terminate()
    s.freeInstance()
    return cost * 1e6


def _folder(path: Path) -> Path:
    path.mkdir(parents=True, exist_ok=True)
    return path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--calls", type=int, default=20000)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    cases = [("GyroPlant", False), ("GyroPlant", True), ("TwoToneDrive", False),
             ("RateProfile", False)]
    names = sorted({name for name, _ in cases})  # each has a pythonfmu flavour
    with tempfile.TemporaryDirectory() as tmp:
        pythonfmu = {n: build_fmu(n, Path(tmp) / "py", reference=False, flavour="pythonfmu")
                     for n in names}
        flavours = {"native": {n: prebuilt_fmu(n) for n in names},
                    "pythonfmu": pythonfmu,
                    "floor": build_compiled_null_fmus(pythonfmu, _folder(Path(tmp) / "null"))}
        print(f"doStep through fmpy FMU2Slave, thread CPU us per call, median of {args.repeat}"
              f" x {args.calls} calls")
        print(f"{'FMU':<32}{'native':>10}{'pythonfmu':>12}{'floor':>8}{'native-floor':>14}"
              "  target")
        for name, changing in cases:
            row = {}
            for flavour, fmus in flavours.items():
                row[flavour] = statistics.median(
                    per_call_us(fmus[name], args.calls, changing) for _ in range(args.repeat))
            label = name + (" (Omega_z changing)" if changing else "")
            target = "< 2" if name == "GyroPlant" else "< 1.5"
            print(f"{label:<32}{row['native']:>10.2f}{row['pythonfmu']:>12.2f}"
                  f"{row['floor']:>8.2f}{row['native'] - row['floor']:>14.2f}  {target} us")


if __name__ == "__main__":
    main()
