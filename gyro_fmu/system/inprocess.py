"""The standard system run with the library called directly, without FMI.

Same drive, rate, plant and observer objects as the FMUs wrap, same Jacobi
order, same column names: the FMI run must reproduce it bit for bit, and the
wall-time ratio of the two is the cost of FMI and the master.
"""

from __future__ import annotations

import numpy as np

from ..cosim.master import CoSimulationResult
from ..estimation.observer import GyroStateObserver, ObserverTuning
from ..estimation.observer_rate import RATE_KINDS
from ..model.parameters import GyroParameters
from ..model.plant import MEASURED, GyroPlantModel, MeasurementNoise
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
    pair = (0, 2) if sc.measured_pair == 1 else (1, 3)
    data = np.empty((sc.n_steps + 1, len(COLUMNS)))
    t_eval = 0.0  # the FMUs evaluate sources at t_prev + h, not k * h (they differ by ulps)
    for k in range(sc.n_steps + 1):
        t = k * h
        ux, Om = drive.ux(t_eval), rate.Omega_z(t_eval)
        t_eval = t + h
        z = plant.output_row()  # x, vx, y, vy measured, then ax, ay
        row = data[k]
        row[0:4] = t, ux, 0.0, Om
        row[4:10] = z
        row[10:] = [*observer.output_row(), *observer.rate_probabilities().values()]
        if k == sc.n_steps:
            break
        plant.step(ux, 0.0, Om, h)
        observer.step(ux, 0.0, z[pair[0]], z[pair[1]], h)
    return CoSimulationResult(COLUMNS, data, {})
