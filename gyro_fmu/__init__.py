"""gyro_fmu: MEMS vibratory gyroscope FMUs and estimators (US 2011/0314910 A1, US 9,482,553).

The public API, imported on first use (``import gyro_fmu`` stays cheap, also inside
each FMU, which ships this package):

- ``scenario``, ``Scenario``, ``fmu_system``: a gyroscope experiment and its FMU system;
  ``ensure_fmus(folder)``: the native FMUs copied there (where missing or stale);
- ``run_cosimulation``, ``Component``, ``Connection``: the FMI 2.0 co-simulation master;
- ``preset``, ``GyroParameters``: the gyroscope's parameters;
- ``GyroStateObserver``, ``ObserverTuning``: the augmented-state observer (eqs. 5-9);
- ``read_results``, ``read_dataframe``, ``read_arrow``: a run's results.parquet or
  results.csv as a structured array (fmpy's form), a pandas DataFrame or an Arrow table,
  the last two with each column's unit (``df.attrs["units"]``, field metadata "unit").

Subpackages, lowest first: ``core`` (the C core), ``model`` (physics) and ``cosim``
(master); ``estimation`` and ``results`` (a run's files); ``fmu`` (FMU builds); ``doctor``;
``system`` and ``selfcal``; ``cli``.
"""

from __future__ import annotations

import importlib
import os

__version__ = "0.4.0"

# Many FMUs in one process, each shipping this package (the pythonfmu flavour's, whose
# resources/ hold a copy): pythonfmu/shipped_copies.py. An installed package needs no hook.
if os.path.basename(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))) == "resources":
    importlib.import_module("gyro_fmu.pythonfmu.shipped_copies").install()

_EXPORTS = {
    "scenario": "gyro_fmu.system.scenario",
    "Scenario": "gyro_fmu.system.scenario",
    "fmu_system": "gyro_fmu.system.scenario",
    "ensure_fmus": "gyro_fmu.system.run",
    "run_cosimulation": "gyro_fmu.cosim.master",
    "Component": "gyro_fmu.cosim.master",
    "Connection": "gyro_fmu.cosim.master",
    "preset": "gyro_fmu.model.parameters",
    "GyroParameters": "gyro_fmu.model.parameters",
    "GyroStateObserver": "gyro_fmu.estimation.observer",
    "ObserverTuning": "gyro_fmu.estimation.observer",
    "read_results": "gyro_fmu.results.read",
    "read_dataframe": "gyro_fmu.results.read",
    "read_arrow": "gyro_fmu.results.read",
}

__all__ = ["__version__", *_EXPORTS]


def __getattr__(name: str) -> object:
    if name in _EXPORTS:
        value = getattr(importlib.import_module(_EXPORTS[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'gyro_fmu' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)
