"""The standard system run with the library called directly, without FMI.

Same drive, rate, plant and observer objects as the FMUs wrap, same Jacobi
order, same column names: the FMI run must reproduce it bit for bit, and the
wall-time ratio of the two is the cost of FMI and the master. The steps run in one
call of the C core (gyro_chain.c: no Python per step; benchmarks/inprocess_chain.py).
"""

from __future__ import annotations

import ctypes

import numpy as np

from ..cosim.master import CoSimulationResult
from ..estimation.observer import GyroStateObserver, ObserverTuning
from ..estimation.observer_rate import RATE_KINDS
from ..model.drive import TwoToneDrive
from ..model.parameters import GyroParameters
from ..model.plant import MEASURED, GyroPlantModel, MeasurementNoise
from ..model.rate import RateProfile
from .scenario import Scenario, absolute_noise, observer_tuning

ESTIMATED = GyroStateObserver.ESTIMATED


def observer_columns() -> list[str]:
    hat = {"Omega_z": "Omega_hat"}
    return [
        *(f"observer.{s}_hat" for s in MEASURED),
        *(f"observer.{hat.get(n, n + '_hat')}" for n in ESTIMATED),
        *(f"observer.sigma_{n}" for n in ESTIMATED),
        *(f"observer.p_rate_{k}" for k in RATE_KINDS),
    ]


COLUMNS = (
    "time", "drive.ux", "drive.uy", "rate.Omega_z",
    *(f"plant.{s}" for s in MEASURED), "plant.ax", "plant.ay",
    *observer_columns(),
)


def run_inprocess(sc: Scenario, noise: MeasurementNoise | None = None) -> CoSimulationResult:
    """Run the scenario in-process; returns the same columns as the FMU run."""
    drive, rate, h = sc.the_drive, sc.rate, sc.step
    noise = absolute_noise(sc) if noise is None else noise
    plant = GyroPlantModel(sc.params, noise, sc.seed)
    observer = GyroStateObserver(
        GyroParameters(**sc.initial_guess), sc.Omega_z_0, sc.measured_pair,
        ObserverTuning(**observer_tuning(sc, noise)),
    )
    data = np.empty((sc.n_steps + 1, len(COLUMNS)))
    rows, code = run_chain(drive, rate, plant, observer, sc.measured_pair, h, sc.n_steps,
                           data)
    observer.check_step(code, h)  # the lost filter's error, the coarse step's warning
    return CoSimulationResult(COLUMNS, data[:rows], {})


def run_chain(drive: TwoToneDrive, rate: RateProfile, plant: GyroPlantModel,
              observer: GyroStateObserver, pair: int, h: float, n_steps: int,
              out: np.ndarray) -> tuple[int, int]:
    """The C core's loop over the four (gyro_chain_run): rows k = 0..n_steps of COLUMNS
    into `out`, plant and observer stepped between them. (rows filled, the last observer
    step's result code): fewer rows when the filter was lost."""
    from ..core.observer import observer_core

    if out.shape != (n_steps + 1, len(COLUMNS)) or not out.flags.c_contiguous \
            or out.dtype != np.float64:
        raise ValueError(f"out must be a C-contiguous float64 array of {n_steps + 1} x "
                         f"{len(COLUMNS)}")
    code, msg = ctypes.c_int(0), observer.message_buffer
    rows = observer_core().gyro_chain_run(
        ctypes.byref(drive.c_struct), ctypes.byref(rate.c_struct), plant.c_pointer,
        ctypes.byref(observer.c_struct), int(pair), float(h), int(n_steps),
        out.ctypes.data_as(ctypes.POINTER(ctypes.c_double)), ctypes.byref(code), msg,
        len(msg))
    return int(rows), code.value
