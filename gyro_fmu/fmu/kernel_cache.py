"""Ship numba's compiled kernels inside the FMUs, so a non-Python importer does not
compile them in every process.

A Python host runs its own gyro_fmu (modules are cached per process), whose kernels are
cached next to its sources. A non-Python host (libcosim, OMSimulator, a C master) runs
the copy an FMU carries, unpacked to a fresh folder: numba found no cache there and
compiled the observer's kernels in every process (13.7 s for 200 steps of
GyroObserver.fmu in the C host of `gyro-fmu doctor`, docs/performance.md).

numba keys a cache on the SHA-256 of the function's own source file, its own version,
the function's bytecode and the CPU, not on paths. So the build adds to the FMU the
cache files that are current for the sources it ships, beside them
(resources/gyro_fmu/**/__pycache__). On another CPU or numba version the entries do not
match and numba compiles, as before.

numba does not look at the other files a kernel calls into (observer's kernels inline
dynamics.inf_norm_rows; carrier._run inlines loops_step and resonator_step): after an
edit of a callee it loads the caller's old code. The build therefore first drops every
cache file older than the newest source that holds kernels, so that the reference run
compiles them afresh, and ships only files at least that new.
"""

from __future__ import annotations

import hashlib
import pickle
import zipfile
from pathlib import Path


def newest_kernel_source(package_dir: Path) -> int:
    """mtime (ns) of the newest source file of the package that defines numba kernels."""
    return max((f.stat().st_mtime_ns for f in package_dir.rglob("*.py")
                if "@njit" in f.read_text(encoding="utf-8", errors="replace")), default=0)


def drop_suspect_caches(package_dir: Path) -> int:
    """Delete cache files older than the newest kernel source (they may hold an inlined
    callee that has changed since); returns how many were deleted."""
    newest = newest_kernel_source(package_dir)
    dropped = 0
    for f in [*package_dir.rglob("__pycache__/*.nbi"), *package_dir.rglob("__pycache__/*.nbc")]:
        if f.stat().st_mtime_ns < newest:
            f.unlink(missing_ok=True)
            dropped += 1
    return dropped


def current_cache_files(package_dir: Path) -> list[Path]:
    """The package's numba cache files (index and data) made for its sources as they are
    and no older than its newest kernel source."""
    import numba

    newest = newest_kernel_source(package_dir)
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
        if (version == numba.__version__ and stamp == digest
                and all(f.is_file() and f.stat().st_mtime_ns >= newest for f in [index, *data])):
            files += [index, *data]
    return files


def missing_from(fmu: Path, package_dir: Path,
                 prefix: str = "resources/gyro_fmu") -> dict[str, Path]:
    """The current cache files the FMU does not carry yet, by their name in the archive."""
    files = {f"{prefix}/{f.relative_to(package_dir).as_posix()}": f
             for f in current_cache_files(package_dir)}
    with zipfile.ZipFile(fmu) as z:
        present = set(z.namelist())
    return {name: f for name, f in files.items() if name not in present}


def add_to_fmu(fmu: Path, package_dir: Path, prefix: str = "resources/gyro_fmu") -> int:
    """Append the current cache files to the FMU beside the sources; returns how many.
    Appends in place: for an FMU nobody may be reading (one being built)."""
    added = missing_from(fmu, package_dir, prefix)
    with zipfile.ZipFile(fmu, "a", zipfile.ZIP_DEFLATED) as z:
        for name, f in added.items():
            z.write(f, name)
    return len(added)
