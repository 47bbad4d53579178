"""GyroSensor's chain computed in-process, as its independent check: the library's drive,
plant and observer (the C core through ctypes, stepped from Python) at the internal step,
then the readout with scipy (a Butterworth designed by scipy.signal.butter, run by
lfilter from rest at the initial rate, clamped and quantized with numpy).

`run_chain(settings, Omega_z, times)` gives what GyroSensor.fmu outputs at `times` for a
rate Omega_z(t) held over each interval between them.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from ..estimation.observer import GyroStateObserver
from ..estimation.observer_tuning import ObserverTuning
from ..model.drive import TwoToneDrive
from ..model.parameters import PARAMETER_UNITS, GyroParameters
from ..model.plant import GyroPlantModel, MeasurementNoise
from .interface import NOISE_STEP, OMEGA_H, SENSOR, STEP_MAX


def internal_step(settings: Mapping[str, float]) -> float:
    """The step the sensor runs at: internal_step, or for 0 the auto rule (the faster
    design mode sampled at omega h = 0.5, at most 20 us)."""
    if settings["internal_step"] > 0:
        return float(settings["internal_step"])
    omega = max(settings["kxx_0"], settings["kyy_0"]) ** 0.5
    return min(STEP_MAX, OMEGA_H / omega)


def defaults() -> dict[str, float]:
    """Every parameter of GyroSensor.fmu at its start value."""
    return {v.name: v.start for v in SENSOR.variables if v.is_parameter}


@dataclass
class ChainResult:
    time: np.ndarray
    Omega_hat: np.ndarray  #: the observer's rate at each time (before the readout)
    filtered: np.ndarray  #: the output filter's value (before clamp and quantization)
    Omega_meas: np.ndarray
    sigma_Omega_z: np.ndarray  #: the observer's 1-sigma of the rate
    status: np.ndarray


def chain_parts(settings: Mapping[str, float]
                ) -> tuple[GyroPlantModel, GyroStateObserver, TwoToneDrive, float]:
    """The sensor's plant (its noise density kept at the internal step), observer and drive
    at `settings` (the FMU's parameters; the rest at their start values), and the step."""
    s = {**defaults(), **settings}
    truth = GyroParameters(**{n: float(s[n]) for n in PARAMETER_UNITS})
    design = GyroParameters(**{n: float(s[f"{n}_0"]) for n in PARAMETER_UNITS})
    tuning = ObserverTuning(**{f: s[f] for f in ObserverTuning.__dataclass_fields__})
    h = internal_step(s)
    f = (NOISE_STEP / h) ** 0.5  # the same noise density at any step
    plant = GyroPlantModel(truth, MeasurementNoise(x=s["noise_x"] * f, y=s["noise_y"] * f),
                           int(s["seed"]))
    observer = GyroStateObserver(design, float(s["Omega_z_0"]), 1, tuning)
    drive = TwoToneDrive(A1=s["A1"], f1=s["f1"], A2=s["A2"], f2=s["f2"])
    return plant, observer, drive, h


def run_chain(settings: Mapping[str, float], Omega_z: Callable[[float], float],
              times: np.ndarray) -> ChainResult:
    """The chain from t = 0 to each of `times` (increasing), with Omega_z(t_i) held over
    [t_i, t_i+1): outputs at the last internal step at or before each time."""
    from scipy.signal import butter, lfilter, lfilter_zi

    s = {**defaults(), **settings}
    plant, observer, drive, h = chain_parts(s)
    n_times = len(times)
    hats, sigmas, status = np.empty(n_times), np.empty(n_times), np.empty(n_times)
    k = 0
    rates: list[float] = []
    marks = []
    for i, t_end in enumerate(times):
        steps = int(np.floor((t_end - k * h) / h * (1.0 + 1e-12) + 1e-9))
        rate = Omega_z(times[i - 1]) if i else 0.0
        for _ in range(max(steps, 0)):
            t = k * h
            ux = drive.ux(t)
            z = plant.output_row()
            observer.step(ux, 0.0, z[0], z[2], h)
            plant.step(ux, 0.0, rate, h)
            rates.append(observer.estimates()["Omega_z"])
            k += 1
        marks.append(k)
        est, sig = observer.estimates(), observer.sigmas()
        hats[i], sigmas[i], status[i] = est["Omega_z"], sig["Omega_z"], observer.status
    hat = np.asarray(rates)
    b, a = butter(2, float(s["bandwidth"]), fs=1.0 / h)
    x0 = float(s["Omega_z_0"])
    y, _ = lfilter(b, a, hat, zi=lfilter_zi(b, a) * x0)
    y = np.concatenate([[x0], y])  # y[k]: after k internal steps
    filtered = y[np.asarray(marks)]
    fs, q = float(s["full_scale"]), float(s["resolution"])
    meas = np.clip(filtered, -fs, fs)
    if q > 0:
        meas = q * np.round(meas / q)
    return ChainResult(np.asarray(times, float), hats, filtered, meas, sigmas, status)
