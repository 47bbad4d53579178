"""The tracking bound of a Scenario (estimation/tracking_bound.py): its gyro, drive, step,
stop time, measured pair, noise and rate profile (docs/tracking-bound.md)."""

from __future__ import annotations

import math

from ..estimation.observer import ObserverTuning
from ..estimation.rate_processes import RateProcess, constant_rate, sine_rate
from ..estimation.tracking_bound import TrackingBound, tracking_bound
from ..model.measurement import MeasuredPair
from ..model.parameters import GyroParameters
from ..model.rate import RateKind
from .scenario import absolute_noise


def rate_model_for(sc, sigma0: float | None = None) -> RateProcess:
    """The deterministic rate model of a Scenario's RateProfile: constant -> constant_rate;
    sine -> sine_rate (offset, amplitude and phase unknown, frequency known), prior 1-sigma
    sigma0 (None: ObserverTuning().sigma0_Omega) on each coefficient."""
    s0 = ObserverTuning().sigma0_Omega if sigma0 is None else sigma0
    r = sc.rate
    if r.kind is RateKind.constant:
        return constant_rate(r.offset, sc.step, sc.n_steps, s0)
    if r.kind is RateKind.sine and r.t_start <= 0.0:
        return sine_rate(sc.step, sc.n_steps, r.frequency, r.amplitude, r.offset,
                         -2.0 * math.pi * r.frequency * r.t_start, s0)
    raise ValueError(f"no rate model for {r.describe()}: give a RateProcess to tracking_bound")


def tracking_bound_for_scenario(sc, tuning: ObserverTuning | None = None,
                                rate: RateProcess | None = None, **kwargs) -> TrackingBound:
    """tracking_bound for a gyro_fmu.system.scenario.Scenario: its gyro, drive, step, stop
    time, measured pair and absolute noise (absolute_noise), the observer's guess as the
    scale of the parameter prior, the prior on Omega from tuning.sigma0_Omega."""
    tun = ObserverTuning() if tuning is None else tuning
    noise = absolute_noise(sc)
    z = MeasuredPair.of(sc.measured_pair).plant_outputs
    std = (getattr(noise, z[0]), getattr(noise, z[1]))
    if not (std[0] > 0.0 and std[1] > 0.0):
        raise ValueError("the bound needs measurement noise: give the scenario noise > 0")
    model = rate if rate is not None else rate_model_for(sc, tun.sigma0_Omega)
    return tracking_bound(sc.params, sc.the_drive, model, std, sc.step, sc.n_steps, tun,
                          GyroParameters(**sc.initial_guess), sc.measured_pair, **kwargs)
