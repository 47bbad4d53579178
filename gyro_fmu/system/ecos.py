"""Run an SSP package in Ecos (ecospy, the co-simulation engine of the pythonfmu authors).

`run_ssp_ecos` returns the same {"time", "instance.variable": values} record as
`gyro_fmu.system.ssp.run_ssp_libcosim` and `run_cosimulation`, at the n + 1
communication points. Ecos applies the SSP's ParameterBindings only for the one
parameter-set name it is given; our packages name theirs `ssp.PARAMETER_SET`. It ignores
the package's stop time and step, so both are read from the package here. Its clock
adds h at every step (t += h), so t drifts from k h by about 3e-14 s over 100 ms; the
FMUs see that t. docs/engines.md lists Ecos' other traits.

Environment: ecospy's libecosc.so needs TBB (PyPI `tbb`, installed into <venv>/lib),
which is loaded here with RTLD_GLOBAL, so no LD_LIBRARY_PATH is needed in Python; pip
drops the run bit of its `ecos` and `proxyfmu` binaries, which `ecos_binary` restores.
"""

from __future__ import annotations

import ctypes
import os
import stat
import sys
from collections.abc import Iterable
from importlib.util import find_spec
from pathlib import Path

import numpy as np

from ..cosim.master import whole_steps
from .ssp import PARAMETER_SET, SSPError, package_settings, single_threaded_blas


def _ecospy_folder() -> Path:
    spec = find_spec("ecospy")
    if spec is None or spec.origin is None:
        raise SSPError("ecospy is not installed: pip install 'gyro_fmu[ecos]'")
    return Path(spec.origin).parent


def tbb_folder() -> Path | None:
    """The folder holding libtbb.so.12 (the `tbb` wheel puts it in <prefix>/lib)."""
    for folder in (Path(sys.prefix) / "lib",
                   *(Path(p) for p in os.environ.get("LD_LIBRARY_PATH", "").split(":") if p)):
        if (folder / "libtbb.so.12").exists():
            return folder
    return None


def ecos_binary(name: str = "ecos") -> Path:
    """ecospy's command-line host (or proxyfmu), with its run bit set."""
    path = _ecospy_folder() / "binaries" / name
    if not path.exists():
        raise SSPError(f"ecospy ships no {path}")
    if not os.access(path, os.X_OK):
        path.chmod(path.stat().st_mode | stat.S_IXUSR | stat.S_IXGRP | stat.S_IXOTH)
    return path


def _load_ecospy():
    folder = tbb_folder()
    if folder is None:
        raise SSPError("libtbb.so.12 not found (ecospy needs it): pip install tbb")
    ctypes.CDLL(str(folder / "libtbb.so.12"), mode=ctypes.RTLD_GLOBAL)
    from ecospy import EcosLib, EcosSimulation

    return EcosLib, EcosSimulation


def run_ssp_ecos(
    ssp_path: Path,
    record: Iterable[str],
    stop_time: float | None = None,
    step: float | None = None,
    parameter_set: str | None = PARAMETER_SET,
) -> dict[str, np.ndarray]:
    """Run the package in Ecos; returns {"time": t_k, name: values} for `record`.

    stop_time, step: s, default the package's DefaultExperiment and FixedStepAlgorithm.
    parameter_set: the set Ecos applies at initialization (None: none; the FMUs then
    run on their own defaults, which Ecos does not report).
    """
    ssp_path = Path(ssp_path)
    stop_time, step = package_settings(ssp_path, stop_time, step)
    n = whole_steps(stop_time, step)  # refuses a step that does not divide the run
    if n < 10:  # measured: the ecos library stops on a floating-point exception below
        raise SSPError(f"Ecos needs at least 10 steps; {stop_time} s at {step} s is {n}")
    ecos_lib, simulation = _load_ecospy()
    ecos_lib.set_log_level("warn")
    names = list(record)
    idents = [name.replace(".", "::", 1) for name in names]
    out = np.empty((n + 1, len(names)))
    time = np.empty(n + 1)
    with single_threaded_blas():  # Ecos may call the FMUs from TBB worker threads
        sim = simulation(step_size=step, ssp_path=str(ssp_path))
        try:
            if not sim.init(0.0, parameter_set):
                raise SSPError(f"Ecos could not initialize {ssp_path}: "
                               f"{ecos_lib.get_last_error()}")
            time[0] = sim.get_time()
            out[0] = [sim.get_real(i) for i in idents]
            for k in range(1, n + 1):
                time[k] = sim.step(1)
                out[k] = [sim.get_real(i) for i in idents]
            sim.terminate()
        finally:
            sim.free()
    return {"time": time, **{name: out[:, j] for j, name in enumerate(names)}}
