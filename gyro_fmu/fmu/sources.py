"""Where the FMUs' sources are and which Python files declare their variables: what the
prebuilt FMUs' stamp hashes (package.py) and the native build compiles (native.py),
without importing the declarations (the check before every run stays light)."""

from __future__ import annotations

from pathlib import Path

REPO_SOURCES = Path(__file__).resolve().parents[2] / "fmu_src"


def sources_root() -> Path:
    """The fmu_src/ beside the imported gyro_fmu: gyro_fmu/fmu_src of an installation, or
    fmu_src/ of the checkout it was imported from. Only then what the import system maps
    gyro_fmu.fmu_src to: an editable install maps it to its own checkout, so a second
    checkout (a git worktree) imported first compiled the first one's C sources."""
    from importlib.util import find_spec

    for root in (Path(__file__).resolve().parents[1] / "fmu_src", REPO_SOURCES):
        if (root / "core").is_dir():
            return root
    spec = find_spec("gyro_fmu.fmu_src")
    if spec is not None and spec.submodule_search_locations:
        root = Path(next(iter(spec.submodule_search_locations)))
        if (root / "core").is_dir():
            return root
    return REPO_SOURCES


#: The modules the declarations come from (the prebuilt FMUs' staleness stamp hashes them).
DECLARATION_FILES = ("core/structs/__init__.py", "core/structs/base.py", "core/structs/plant.py",
                     "core/structs/observer.py", "core/structs/selfcal.py",
                     "core/structs/master.py", "core/structs/tables.py",
                     "model/interfaces.py", "fmu/interfaces.py", "model/selfcal_interfaces.py",
                     "model/resonator.py",
                     "model/loops.py", "estimation/interface.py",
                     "estimation/observer_tuning.py", "estimation/observer_rate.py",
                     "sensor/interface.py", "sensor/platform.py")
