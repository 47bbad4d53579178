"""Ship numba's compiled kernels inside the FMUs, so a non-Python importer does not
compile them in every process.

A Python host runs its own gyro_fmu (modules are cached per process), whose kernels are
cached next to its sources. A non-Python host (libcosim, OMSimulator, a C master) runs
the copy an FMU carries, unpacked to a fresh folder: numba found no cache there and
compiled the observer's kernels in every process (13.7 s for 200 steps of
GyroObserver.fmu in the C host of `gyro-fmu doctor`, benchmarks/PERF_NOTES.md).

numba keys a cache on the SHA-256 of the source file, its own version, the function's
bytecode and the CPU, not on paths. So the build adds to the FMU the cache files that
are current for the sources it ships, beside them (resources/gyro_fmu/**/__pycache__).
On another CPU or numba version the entries do not match and numba compiles, as before.
"""

from __future__ import annotations

import hashlib
import pickle
import zipfile
from pathlib import Path


def current_cache_files(package_dir: Path) -> list[Path]:
    """The package's numba cache files (index and data) made for its sources as they are."""
    import numba

    files: list[Path] = []
    for index in sorted(package_dir.rglob("__pycache__/*.nbi")):
        source = index.parent.parent / f"{index.name.split('.', 1)[0]}.py"
        try:
            with index.open("rb") as f:
                version = pickle.load(f)
                stamp, overloads = pickle.loads(f.read())
            digest = hashlib.sha256(source.read_bytes()).digest()
        except Exception:  # unreadable or orphaned index: not shipped
            continue
        data = [index.parent / name for name in overloads.values()]
        if version == numba.__version__ and stamp == digest and all(d.is_file() for d in data):
            files += [index, *data]
    return files


def add_to_fmu(fmu: Path, package_dir: Path, prefix: str = "resources/gyro_fmu") -> int:
    """Append the current cache files to the FMU beside the sources; returns how many."""
    files = current_cache_files(package_dir)
    with zipfile.ZipFile(fmu, "a", zipfile.ZIP_DEFLATED) as z:
        present = set(z.namelist())
        added = [f for f in files
                 if f"{prefix}/{f.relative_to(package_dir).as_posix()}" not in present]
        for f in added:
            z.write(f, f"{prefix}/{f.relative_to(package_dir).as_posix()}")
    return len(added)
