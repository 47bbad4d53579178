"""`gyro-fmu doctor`: what a non-Python importer needs to load our FMUs, checked for real.

``environment`` finds the settings (libpython, PYTHONHOME, PYTHONPATH, glibc, compiler),
``host`` runs the compiled C host on an FMU, ``report`` puts both together. The public
names, imported on first use: ``doctor``, ``DoctorReport``, ``main``.
"""

from __future__ import annotations

import importlib

_EXPORTS = {
    "doctor": "gyro_fmu.doctor.report",
    "DoctorReport": "gyro_fmu.doctor.report",
    "main": "gyro_fmu.doctor.report",
}

__all__ = list(_EXPORTS)


def __getattr__(name: str) -> object:
    if name in _EXPORTS:
        value = getattr(importlib.import_module(_EXPORTS[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'gyro_fmu.doctor' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted([*__all__, "environment", "host", "report"])
