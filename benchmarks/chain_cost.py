"""The chain drive + rate + plant + observer per 5 us step in C, no Python per step, beside a
yardstick measured in the same run: a 14x14 double matmul compiled here at -O2.

    python benchmarks/chain_cost.py [--repeat 5] [--callgrind]

The default system (park-horowitz, constant 1 rad/s, pick-off noise 1e-4) stepped by the
C core's loop (gyro_chain.c, what `run_inprocess` calls once) with the observer's
constant rate model and with its adaptive set of 7 (GyroObserver's default). Thread CPU
per step from two run lengths (so that set-up cancels), min of the repeats, in two
windows: while the filter converges (steps 4,000-16,000: 20-80 ms) and once converged
(40,000-100,000: 0.2-0.5 s), where the held step's maps are reused
(docs/results/performance.md); the same per naive 14x14 matmul (cc -O2, so that the
figure holds across machines). --callgrind adds the instructions per step in the C
core's library (valgrind, two lengths: 4,000-16,000 and 40,000-44,000). Targets (issue
"A real-time sensor chain"): adaptive <= 3.0 us, constant <= 0.8 us here (about 3.3 and
0.9 matmuls).
"""

from __future__ import annotations

import argparse
import ctypes
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from gyro_fmu.estimation.observer import GyroStateObserver, ObserverTuning
from gyro_fmu.model.parameters import GyroParameters
from gyro_fmu.model.plant import GyroPlantModel
from gyro_fmu.system.inprocess import COLUMNS, run_chain
from gyro_fmu.system.scenario import absolute_noise, observer_tuning, scenario

#: Windows of steps: (label, the two run lengths timed, the two under callgrind).
WINDOWS = (("converging", (4000, 16000), (4000, 16000)),
           ("converged", (40000, 100000), (40000, 44000)))
MATMUL = r"""
void matmul14(int reps, const double *a, const double *b, double *c) {
    for (int r = 0; r < reps; r++)
        for (int i = 0; i < 14; i++)
            for (int j = 0; j < 14; j++) {
                double s = 0.0;
                for (int k = 0; k < 14; k++) s += a[14 * i + k] * b[14 * k + j];
                c[14 * i + j] = s + 1e-300 * c[14 * i + j];  /* each rep depends on the last */
            }
}
"""


def chain_seconds(rate_model: int, steps: int) -> float:
    """Thread CPU seconds of one gyro_chain_run call of `steps` steps."""
    sc = scenario("default", stop_time=steps * 5e-6, noise=1e-4).with_(
        tuning={"rate_model": rate_model})
    noise = absolute_noise(sc)
    plant = GyroPlantModel(sc.params, noise, sc.seed)
    observer = GyroStateObserver(GyroParameters(**sc.initial_guess), sc.Omega_z_0,
                                 sc.measured_pair, ObserverTuning(**observer_tuning(sc, noise)))
    out = np.empty((sc.n_steps + 1, len(COLUMNS)))
    start = time.thread_time()
    rows, code = run_chain(sc.the_drive, sc.rate, plant, observer, sc.measured_pair, sc.step,
                           sc.n_steps, out)
    spent = time.thread_time() - start
    if rows != sc.n_steps + 1 or code < 0:
        raise SystemExit(f"the chain stopped after {rows} rows (code {code})")
    return spent


def per_step(rate_model: int, repeat: int, lengths: tuple[int, int]) -> float:
    t1, t2 = (min(chain_seconds(rate_model, n) for _ in range(repeat)) for n in lengths)
    return (t2 - t1) / (lengths[1] - lengths[0])


def matmul_seconds(folder: Path, repeat: int) -> float:
    cc = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
    if cc is None:
        raise SystemExit("no C compiler for the yardstick (cc, gcc or clang)")
    (folder / "mm.c").write_text(MATMUL)
    subprocess.run([cc, "-O2", "-shared", "-fPIC", "-o", str(folder / "mm.so"),
                    str(folder / "mm.c")], check=True)
    lib = ctypes.CDLL(str(folder / "mm.so"))
    ptr = ctypes.POINTER(ctypes.c_double)
    a, b, c = (np.random.default_rng(i).random((14, 14)) for i in range(3))
    args = [x.ctypes.data_as(ptr) for x in (a, b, c)]
    reps = 20000
    best = []
    for _ in range(repeat):
        start = time.thread_time()
        lib.matmul14(reps, *args)
        best.append((time.thread_time() - start) / reps)
    return min(best)


def instructions(rate_model: int, lengths: tuple[int, int]) -> float:
    """Instructions per chain step under callgrind, from the two lengths: only those in
    the C core's library (the scenario's set-up in Python grows with the length too)."""
    counts = []
    with tempfile.TemporaryDirectory(prefix="gyro_fmu-callgrind-") as tmp:
        for n in lengths:
            code = (f"import sys; sys.path.insert(0, {str(Path(__file__).parent)!r}); "
                    f"import chain_cost; chain_cost.chain_seconds({rate_model}, {n})")
            data = Path(tmp) / f"cg.{n}"
            out = subprocess.run(["valgrind", "--tool=callgrind",
                                  f"--callgrind-out-file={data}", sys.executable, "-c", code],
                                 capture_output=True, text=True)
            if not data.exists():
                raise SystemExit(f"callgrind said: {out.stderr[-500:]}")
            table = subprocess.run(["callgrind_annotate", "--threshold=100", str(data)],
                                   capture_output=True, text=True, check=True).stdout
            counts.append(sum(int(m.group(1).replace(",", "")) for m in re.finditer(
                r"^\s*([\d,]+) .*gyro_core", table, re.MULTILINE)))
    return (counts[1] - counts[0]) / (lengths[1] - lengths[0])


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeat", type=int, default=5)
    p.add_argument("--callgrind", action="store_true")
    a = p.parse_args()
    with tempfile.TemporaryDirectory(prefix="gyro_fmu-chain-") as tmp:
        mm = matmul_seconds(Path(tmp), a.repeat)
    print(f"yardstick: a 14x14 double matmul (cc -O2) takes {mm * 1e6:.3f} us here")
    print(f"{'observer':<22} {'window':<11} {'us/step':>8} {'matmuls':>8} {'target':>8}"
          + (f" {'instructions':>13}" if a.callgrind else ""))
    for label, rate_model, target in (("constant rate model", 1, 0.8),
                                      ("adaptive (7 models)", 0, 3.0)):
        for window, lengths, counted in WINDOWS:
            t = per_step(rate_model, a.repeat, lengths)
            line = f"{label:<22} {window:<11} {t * 1e6:8.2f} {t / mm:8.2f} {target:8.1f}"
            if a.callgrind:
                line += f" {instructions(rate_model, counted):13,.0f}"
            print(line, flush=True)


if __name__ == "__main__":
    main()
