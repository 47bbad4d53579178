"""Put the product's FMUs into a models folder: the native C FMUs from the package, or on
request their pythonfmu flavour built from fmu_src/, shipping the gyro_fmu package inside.

Every FMU is a native C FMU (gyro_fmu.fmu.native), built with the package (`pip install`)
and copied from it. `flavour="pythonfmu"` builds pythonfmu adapters over the same C core
instead, for the six FMUs that have a slave source in fmu_src/ (PYTHONFMU_NAMES;
GyroSensor is native only).

The slave adapters are the package `gyro_fmu.fmu_src` (the repository's top-level
fmu_src/, installed inside gyro_fmu by pyproject.toml), so an installed gyro_fmu builds
its FMUs as a checkout does. FMUs go to `models/` under the working directory unless
told otherwise: never into the installation.

Every FMU of the pythonfmu flavour ships the same gyro_fmu package (without fmu_src/:
each carries its own slave as pythonfmu's top-level script; the native FMUs ship no
Python): Python caches modules per process, so FMUs that shipped different files under
one module name would silently share the first one loaded (docs/fmi-notes.md). Slave
modules have unique names.
"""

from __future__ import annotations

import os
import shutil
import tempfile
import zipfile
from pathlib import Path

from ..cache import size_and_crc
from ..errors import GyroFmuError

PACKAGE_DIR = Path(__file__).resolve().parents[1]
#: Default folder of the built FMUs: relative, so it is models/ under the working
#: directory at the time of use.
MODELS_DIR = Path("models")


#: Capability flags, each true in fact (tests/test_fmu_quality.py holds them).
CAPABILITIES = {
    "needsExecutionTool": "false",
    "canHandleVariableCommunicationStepSize": "true",
    "canGetAndSetFMUstate": "true",
    "canSerializeFMUstate": "true",
    "canBeInstantiatedOnlyOncePerProcess": "false",
}

#: The FMUs of the product, in build order, by model identifier (= the pythonfmu slave's
#: class and source file stem). What each one needs beyond its variables (reference
#: inputs, doctor check) its declaration gives (gyro_fmu.fmu.interfaces).
FMU_NAMES = ("GyroPlant", "TwoToneDrive", "RateProfile", "GyroObserver", "GyroResonator",
             "GyroLoops", "GyroSensor", "StabilizedPlatform")
#: The native C FMUs (gyro_fmu.fmu.native), prebuilt in the package: every one.
NATIVE_NAMES = FMU_NAMES
#: The FMUs with a pythonfmu flavour too (built on request: flavour="pythonfmu"; a slave
#: source fmu_src/NAME.py each). GyroSensor is native only: its loop is the C core's;
#: StabilizedPlatform (GyroSensor's system example) too.
PYTHONFMU_NAMES = FMU_NAMES[:6]
FLAVOURS = ("native", "pythonfmu")
def prebuilt_fmu(name: str, fmi_version: int = 2) -> Path:
    """The package's prebuilt native FMU `name` (FMI 2.0 or 3.0); raises with the remedy
    when it is missing or older than the C sources."""
    from .package import PREBUILT_FMUS, prebuilt_problem

    problem = prebuilt_problem()
    path = PREBUILT_FMUS / f"fmi{fmi_version}" / f"{name}.fmu"
    if problem is None and not path.is_file():
        problem = f"{path} is missing: reinstall gyro_fmu"
    if problem:
        raise PrebuiltFmuError(problem)
    return path


class PrebuiltFmuError(GyroFmuError, FileNotFoundError):
    """The package's native FMUs are missing or older than their sources."""


def copy_fmu(source: Path, dest: Path) -> Path:
    """Copy one FMU into dest, moved into place whole."""
    dest.mkdir(parents=True, exist_ok=True)
    fd, temp = tempfile.mkstemp(suffix=".fmu", prefix=f".{source.stem}-", dir=dest)
    os.close(fd)
    try:
        shutil.copyfile(source, temp)
        os.chmod(temp, 0o644)
        os.replace(temp, dest / source.name)
    except BaseException:
        Path(temp).unlink(missing_ok=True)
        raise
    return dest / source.name


def build_fmu(name: str, dest: Path = MODELS_DIR, reference: bool = True,
              flavour: str = "native") -> Path:
    """Put FMU `name` into dest; returns the .fmu path. A native FMU is copied from the
    package (FMI 2.0); the others, and every one with flavour="pythonfmu", are built by
    pythonfmu from fmu_src/NAME.py.

    reference: also simulate its default experiment and store the result inside
    the FMU (fmi-ls-ref), for `gyro-fmu validate` in users' CI.
    """
    if flavour not in FLAVOURS:
        raise ValueError(f"flavour={flavour!r}: use one of {FLAVOURS}")
    if name in NATIVE_NAMES and flavour == "native":
        return copy_fmu(prebuilt_fmu(name), Path(dest))
    from ..pythonfmu.build import build_flavour_fmu

    return build_flavour_fmu(name, Path(dest), CAPABILITIES, FMU_NAMES,
                             finish=_finish if reference else _document)


def _finish(path: Path) -> None:
    """Reference results simulated and stored in the FMU, then its documentation."""
    from .reference import write_reference

    write_reference(path)
    _document(path)


def _document(path: Path) -> None:
    from .docs import add_documentation

    add_documentation(path)


def build_all(dest: Path = MODELS_DIR, names: tuple[str, ...] = FMU_NAMES,
              flavour: str = "native") -> list[Path]:
    """Put the named FMUs (all by default) into dest (see build_fmu)."""
    return [build_fmu(name, dest, flavour=flavour) for name in names]


def is_pythonfmu(fmu: Path) -> bool:
    """Whether fmu is of the pythonfmu flavour (it ships gyro_fmu in its resources)."""
    try:
        with zipfile.ZipFile(fmu) as z:
            return any(n.startswith("resources/gyro_fmu/") for n in z.namelist())
    except (OSError, zipfile.BadZipFile):
        return False


def ensure_current(names: tuple[str, ...] = FMU_NAMES, dest: Path = MODELS_DIR) -> list[Path]:
    """Put the named FMUs into dest where they are missing or not the prebuilt native ones;
    an FMU of the pythonfmu flavour there is kept (rebuilt in its flavour when its
    sources changed: stale_sources). Returns the paths built."""
    dest = Path(dest)
    built = []
    for name in names:
        path = dest / f"{name}.fmu"
        if path.exists() and is_pythonfmu(path):  # a flavour built on request: kept while
            from ..pythonfmu.build import stale_sources  # its sources are current

            if stale_sources(path, name):
                built.append(build_fmu(name, dest, flavour="pythonfmu"))
        elif not path.exists() or size_and_crc(path) != size_and_crc(prebuilt_fmu(name)):
            built.append(build_fmu(name, dest))
    return built
