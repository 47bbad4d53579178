"""Where the pythonfmu flavour's slave sources are (fmu_src/<Model>.py, installed as
gyro_fmu.fmu_src): what that flavour's build and staleness check read. What an FMU needs
beyond its variables (reference inputs, doctor check) comes from its declaration
(gyro_fmu.fmu.interfaces), not from its slave."""

from __future__ import annotations

from importlib.util import find_spec
from pathlib import Path


def source_dir() -> Path | None:
    """Folder of the slave sources (package gyro_fmu.fmu_src), or None where gyro_fmu runs
    without them (from inside an FMU)."""
    try:
        spec = find_spec("gyro_fmu.fmu_src")
    except ImportError:
        return None
    if spec is None or not spec.submodule_search_locations:
        return None
    return Path(next(iter(spec.submodule_search_locations))).resolve()
