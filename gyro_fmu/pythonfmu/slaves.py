"""The pythonfmu flavour's slave sources (fmu_src/<Model>.py), found and loaded by model
identifier at run time: what the build, the reference results and the doctor read from a
model's slave class (its reference inputs, its doctor check). Imports nothing of the fmu
layer, so each of them may import it."""

from __future__ import annotations

import functools
import sys
from importlib.util import find_spec, module_from_spec, spec_from_file_location
from pathlib import Path
from typing import Any


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


#: Prefix of the private module names `load_slave` gives the slave sources.
SLAVE_MODULE_PREFIX = "gyro_fmu_slave_"


def load_slave(name: str) -> Any | None:
    """The slave class `name` of the slave-source folder (fmu_src/NAME.py), or None
    where there is no such source (gyro_fmu running inside an FMU, a foreign FMU).

    A plugin lookup at run time, so the fmu layer imports nothing above it. The module
    is loaded from its file under the private name SLAVE_MODULE_PREFIX + NAME, never as
    the bare NAME: pythonfmu imports the slave inside an FMU as NAME, and a module of
    that name already in sys.modules would shadow the FMU's own copy. Loaded once per
    process and source file version. Errors in the slave source propagate."""
    sources = source_dir()
    path = sources / f"{name}.py" if sources else None
    if path is None or not path.is_file():
        return None
    return _load_slave_file(str(path), name, path.stat().st_mtime_ns)


@functools.lru_cache(maxsize=64)
def _load_slave_file(path: str, name: str, mtime_ns: int) -> Any | None:
    module_name = SLAVE_MODULE_PREFIX + name
    spec = spec_from_file_location(module_name, path)
    if spec is None or spec.loader is None:
        return None
    module = module_from_spec(spec)
    sys.modules[module_name] = module  # dataclasses and pickling look modules up here
    try:
        spec.loader.exec_module(module)
    except BaseException:
        sys.modules.pop(module_name, None)
        raise
    return getattr(module, name, None)
