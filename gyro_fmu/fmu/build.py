"""Build every FMU of fmu_src/ with pythonfmu, shipping the gyro_fmu package inside.

All FMUs ship the same gyro_fmu package: Python caches modules per process,
so FMUs that shipped different files under one module name would silently
share the first one loaded (FIELD-NOTES). Slave modules have unique names.
"""

from __future__ import annotations

import functools
import os
import tempfile
import zipfile
import zlib
from pathlib import Path

from pythonfmu.builder import FmuBuilder

PACKAGE_DIR = Path(__file__).resolve().parents[1]
REPO_DIR = PACKAGE_DIR.parent
SOURCE_DIR = REPO_DIR / "fmu_src"
MODELS_DIR = REPO_DIR / "models"

#: Capability flags, each true in fact (tests/test_fmu_quality.py holds them).
CAPABILITIES = {
    "needsExecutionTool": "false",
    "canHandleVariableCommunicationStepSize": "true",
    "canGetAndSetFMUstate": "true",
    "canSerializeFMUstate": "true",
    "canBeInstantiatedOnlyOncePerProcess": "false",
}

#: The FMUs of the product, by model identifier (= slave class = source file stem).
FMU_NAMES = ("GyroPlant", "TwoToneDrive", "RateProfile", "GyroObserver", "GyroResonator",
             "GyroLoops")


def build_fmu(name: str, dest: Path = MODELS_DIR, reference: bool = True) -> Path:
    """Build one FMU from fmu_src/NAME.py into dest; returns the .fmu path.

    reference: also simulate its default experiment and store the result inside
    the FMU (fmi-ls-ref), for `gyro-fmu validate` in users' CI.
    """
    script = SOURCE_DIR / f"{name}.py"
    if not script.exists():
        raise FileNotFoundError(
            f"no FMU source {script}: the FMU names are {list(FMU_NAMES)}"
        )
    from .docs import add_documentation
    from .kernel_cache import add_to_fmu, drop_suspect_caches

    dest = Path(dest)
    dest.mkdir(parents=True, exist_ok=True)
    # Built in a folder of its own and moved into place whole: a process reading
    # dest/NAME.fmu meanwhile sees the old archive or the new one, never a partial one.
    with tempfile.TemporaryDirectory(dir=dest, prefix=f".{name}-") as tmp:
        path = Path(FmuBuilder.build_FMU(script, dest=tmp, project_files=[PACKAGE_DIR],
                                         **CAPABILITIES))
        if reference:
            from .reference import write_reference

            drop_suspect_caches(PACKAGE_DIR)
            write_reference(path)  # runs the FMU here: its kernels are compiled and cached
        add_to_fmu(path, PACKAGE_DIR)
        add_documentation(path)
        final = dest / path.name
        os.replace(path, final)
    return final


def build_all(dest: Path = MODELS_DIR, names: tuple[str, ...] = FMU_NAMES) -> list[Path]:
    """Build the named FMUs (all by default) into dest."""
    return [build_fmu(name, dest) for name in names]


def stale_sources(fmu: Path, name: str) -> list[str]:
    """The Python sources FMU `fmu` (built from fmu_src/NAME.py) ships differently from
    this tree; empty when it is current. A stale FMU would run its old slave adapter on
    the host's newer gyro_fmu (modules are cached per process) and fail obscurely.
    Compares sizes and CRC-32s (the archive stores both), so nothing is decompressed.
    Without a source tree (gyro_fmu running from inside an FMU) there is nothing to
    compare with, and the FMU counts as current."""
    source = SOURCE_DIR / f"{name}.py"
    if not source.is_file():
        return []
    tree = {f"resources/{name}.py": source}
    tree.update({f"resources/gyro_fmu/{f.relative_to(PACKAGE_DIR).as_posix()}": f
                 for f in PACKAGE_DIR.rglob("*.py")})
    try:
        with zipfile.ZipFile(fmu) as z:
            shipped = {i.filename: (i.file_size, i.CRC) for i in z.infolist()
                       if i.filename in tree or (i.filename.startswith("resources/gyro_fmu/")
                                                 and i.filename.endswith(".py"))}
    except (OSError, zipfile.BadZipFile):
        return [str(fmu)]
    return sorted(n for n in tree.keys() | shipped.keys()
                  if n not in tree or shipped.get(n) != _size_and_crc(tree[n]))


def _size_and_crc(path: Path) -> tuple[int, int]:
    stat = path.stat()
    return _size_and_crc_of(str(path), stat.st_mtime_ns, stat.st_size)


@functools.lru_cache(maxsize=1024)
def _size_and_crc_of(path: str, mtime_ns: int, size: int) -> tuple[int, int]:
    """Cached on the file's modification time: a check before every run stays cheap."""
    return size, zlib.crc32(Path(path).read_bytes())


def ensure_current(names: tuple[str, ...] = FMU_NAMES, dest: Path = MODELS_DIR) -> list[Path]:
    """Build the named FMUs that are missing from dest or stale (stale_sources)."""
    dest = Path(dest)
    built = []
    for name in names:
        path = dest / f"{name}.fmu"
        if not path.exists() or stale_sources(path, name):
            built.append(build_fmu(name, dest))
    return built
