"""Build every FMU of fmu_src/ with pythonfmu, shipping the gyro_fmu package inside.

All FMUs ship the same gyro_fmu package: Python caches modules per process,
so FMUs that shipped different files under one module name would silently
share the first one loaded (FIELD-NOTES). Slave modules have unique names.
"""

from __future__ import annotations

from pathlib import Path

from pythonfmu.builder import FmuBuilder

PACKAGE_DIR = Path(__file__).resolve().parent
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
    dest.mkdir(parents=True, exist_ok=True)
    path = Path(FmuBuilder.build_FMU(script, dest=dest, project_files=[PACKAGE_DIR],
                                     **CAPABILITIES))
    if reference:
        from .reference import write_reference

        write_reference(path)
    return path


def build_all(dest: Path = MODELS_DIR, names: tuple[str, ...] = FMU_NAMES) -> list[Path]:
    """Build the named FMUs (all by default) into dest."""
    return [build_fmu(name, dest) for name in names]
