"""Start-up of the FMUs in a non-Python host: the C host of `gyro-fmu doctor`.

    python benchmarks/c_host_start.py [--steps 200]

For GyroPlant.fmu and GyroObserver.fmu as built (numba kernels shipped inside, see
gyro_fmu/fmu/kernel_cache.py) and for a copy with those kernels removed (what the C host
met before: numba compiles in every process), the wall time of one C-host process that
loads the FMU and runs `steps` steps of 5 us. Needs Linux and a C compiler.
"""

from __future__ import annotations

import argparse
import tempfile
import time
import zipfile
from pathlib import Path

from gyro_fmu.doctor import environment, host
from gyro_fmu.doctor import report as doc
from gyro_fmu.fmu.build import MODELS_DIR
from gyro_fmu.system.run import ensure_fmus


def without_kernels(fmu: Path, dest: Path) -> Path:
    """A copy of the FMU without the numba cache files."""
    out = dest / fmu.name
    with zipfile.ZipFile(fmu) as src, zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as z:
        for item in src.infolist():
            if not item.filename.endswith((".nbi", ".nbc")):
                z.writestr(item, src.read(item.filename))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=200)
    args = ap.parse_args()
    compiler = environment.find_compiler()
    if compiler is None:
        raise SystemExit("no C compiler (cc, gcc, clang or $CC): nothing to measure")
    ensure_fmus()
    env = doc.doctor(compile_host=False).environment()
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        exe, log = host.compile_host(work, compiler)
        if exe is None:
            raise SystemExit(f"compiling the C host failed:\n{log}")
        print(f"{'FMU':<20} {'kernels':<9} {'wall s':>7}  result")
        for name in ("GyroPlant", "GyroObserver"):
            built = MODELS_DIR / f"{name}.fmu"
            stripped_dir = work / f"stripped_{name}"
            stripped_dir.mkdir()
            for label, fmu in (("shipped", built),
                               ("removed", without_kernels(built, stripped_dir))):
                info = host.unpack_fmu(fmu, work / f"{name}_{label}")
                start = time.perf_counter()
                run = host.run_host(exe, info, env, label, steps=args.steps, step=5e-6)
                wall = time.perf_counter() - start
                print(f"{name + '.fmu':<20} {label:<9} {wall:7.2f}  {run.verdict()[:60]}")


if __name__ == "__main__":
    main()
