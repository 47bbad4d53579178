"""Wall time of the default 100 ms co-simulation through the FMUs vs the library in-process.

    python benchmarks/cosim_walltime.py [--repeat 3] [--scenario default]

Both runs compute the same numbers (tests/test_system.py holds them equal bit
for bit), so their ratio is the cost of FMI, pythonfmu and the fmpy master.
Medians over --repeat runs, interleaved so machine noise hits both alike.
"""

from __future__ import annotations

import argparse
import statistics
import time

from gyro_fmu.system.inprocess import run_inprocess
from gyro_fmu.system.run import ensure_fmus, run_fmus
from gyro_fmu.system.scenario import SCENARIOS, scenario


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--scenario", default="default", choices=sorted(SCENARIOS))
    args = ap.parse_args()
    sc = scenario(args.scenario)
    ensure_fmus()
    fmu_times, lib_times = [], []
    for _ in range(args.repeat):
        start = time.perf_counter()
        run_fmus(sc)
        fmu_times.append(time.perf_counter() - start)
        start = time.perf_counter()
        run_inprocess(sc)
        lib_times.append(time.perf_counter() - start)
    fmu, lib = statistics.median(fmu_times), statistics.median(lib_times)
    print(f"scenario {args.scenario}: {sc.n_steps} steps of {sc.step * 1e6:g} us, "
          f"median of {args.repeat}")
    print(f"{'run':<32}{'wall (s)':>10}{'per step (us)':>15}")
    print(f"{'FMUs through fmpy master':<32}{fmu:10.2f}{fmu / sc.n_steps * 1e6:15.1f}")
    print(f"{'library in-process (no FMI)':<32}{lib:10.2f}{lib / sc.n_steps * 1e6:15.1f}")
    print(f"ratio FMU / in-process: {fmu / lib:.3f}")


if __name__ == "__main__":
    main()
