"""gyro-fmu spec: its configuration, the pick-off noise and the in-process record.

Definitions and measurements: docs/gyro-spec.md.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field, fields

import numpy as np

from ..cosim.master import check_result_memory
from ..errors import GyroFmuError
from ..estimation.observer import GyroStateObserver, ObserverDivergedError, ObserverTuning
from ..model.measurement import UNKNOWNS
from ..model.parameters import DEFAULT_PRESET, GyroParameters, ParameterError
from ..model.plant import GyroPlantModel, MeasurementNoise
from ..system.scenario import (
    NOISE_TO_PEAK_MAX,
    Scenario,
    absolute_noise,
    default_initial_guess,
    noise_free_run,
)

ARW_DEG_PER_SQRT_H = math.degrees(1.0) * 60.0


DEG_PER_H = math.degrees(1.0) * 3600.0


ARW_SLOPE_TOLERANCE = 0.15


STARTUP_SIGMAS = 6.0


STATIONARITY_RATIO = 1.3


PROBABILITY_EVERY = 100


_I_OMEGA = 4 + UNKNOWNS.index("Omega_z")


_TUNING_NAMES = tuple(f.name for f in fields(ObserverTuning))


class SpecError(GyroFmuError):
    """A spec that cannot be measured from this run: the message names the cause and
    the remedy (the observer was lost, or its estimate never settled)."""


def default_bw_frequencies() -> tuple[float, ...]:
    """16 log-spaced rate frequencies, 10 Hz to 5 kHz (Hz)."""
    return tuple(float(f) for f in np.round(np.geomspace(10.0, 5000.0, 16), 1))


@dataclass(frozen=True)
class SpecConfig:
    """What to measure and how. SI units (s, rad/s, Hz, m/sqrt(Hz)).

    Noise: `noise_density` (m/sqrt(Hz), one-sided, on x and y alike) when given, else
    `noise` relative to each measured signal's peak (the project's convention,
    system/scenario.py). The per-sample std of a density D at step h is D / sqrt(2 h):
    white noise of one-sided density D band-limited to the Nyquist frequency 1/(2 h).
    """

    preset: str = DEFAULT_PRESET
    overrides: dict[str, float] = field(default_factory=dict)
    tuning: dict[str, float] = field(default_factory=dict)
    noise: float = 1e-4
    noise_density: float | None = None
    seed: int = 0
    step: float = 5e-6
    duration: float = 20.0  #: Allan record (constant rate), s
    rate: float = 0.0  #: constant rate of the Allan and start-up run, rad/s
    full_scale: float = 5.0  #: rad/s; the scale-factor rates span +-full_scale
    sf_points: int = 11
    sf_record: float = 0.2  #: averaging time per scale-factor rate, s (after settling)
    bw_frequencies: tuple[float, ...] = field(default_factory=default_bw_frequencies)
    bw_amplitude: float = 1.0  #: rad/s, about `rate`
    bw_segment: float = 0.1  #: s per frequency (at least 5 periods)
    startup_band: float | None = None  #: rad/s; None: 1 % of full scale
    startup_window: float | None = None  #: s; None: chosen from the noise (STARTUP_SIGMAS)

    def __post_init__(self) -> None:
        positive = {"step": self.step, "duration": self.duration,
                    "full_scale": self.full_scale, "sf_record": self.sf_record,
                    "bw_amplitude": self.bw_amplitude, "bw_segment": self.bw_segment}
        for name in ("startup_band", "startup_window", "noise_density"):
            if getattr(self, name) is not None:
                positive[name] = getattr(self, name)
        for name, value in positive.items():
            if not (math.isfinite(value) and value > 0.0):
                raise ParameterError(f"{name}={value!r} must be a finite number > 0")
        if not (math.isfinite(self.noise) and self.noise >= 0.0):
            raise ParameterError(f"noise={self.noise!r} must be >= 0 (fraction of peak)")
        if not math.isfinite(self.rate):
            raise ParameterError(f"rate={self.rate!r} rad/s must be finite")
        if self.sf_points < 3:
            raise ParameterError(f"sf_points={self.sf_points} must be >= 3 for a line and "
                                 "its residuals")
        if self.duration < 200 * self.step:
            raise ParameterError(f"duration={self.duration:g} s is shorter than 200 steps of "
                                 f"step={self.step:g} s: lengthen the duration or shorten "
                                 "the step")
        if self.startup_window is not None and self.startup_window >= self.duration:
            raise ParameterError(f"startup_window={self.startup_window:g} s is not shorter "
                                 f"than the record (duration={self.duration:g} s): give a "
                                 "shorter window or a longer duration")
        for name, record in (("duration", self.duration), ("sf_record", self.sf_record),
                             ("bw_segment", self.bw_segment * len(self.bw_frequencies))):
            check_result_memory(record / self.step, 3, what=f"a record of {record:g} s "
                                f"({name}) at {self.step:g} s steps",
                                remedy=f"shorten {name} or lengthen the step")
        if len(self.bw_frequencies) < 2 or any(
                not (math.isfinite(f) and 0.0 < f < 0.25 / self.step)
                for f in self.bw_frequencies):
            raise ParameterError(
                f"bw_frequencies {list(self.bw_frequencies)} Hz: give at least 2, each > 0 "
                f"and below a quarter of the sampling rate ({0.25 / self.step:g} Hz)")
        unknown = sorted(set(self.tuning) - set(_TUNING_NAMES))
        if unknown:
            raise ParameterError(f"unknown observer tuning {unknown}: names are "
                                 f"{', '.join(_TUNING_NAMES)}")
        sc = self.scenario  # a bad preset or override fails here
        for name, value in (("rate", self.rate), ("full_scale", self.full_scale),
                            ("rate + bw_amplitude", abs(self.rate) + self.bw_amplitude)):
            problem = sc.params.rate_problem(name, value)
            if problem:
                raise ParameterError(problem)
        if self.band > self.full_scale:
            raise ParameterError(f"startup_band={self.band:g} rad/s is wider than the full "
                                 f"scale ({self.full_scale:g} rad/s): every estimate would be "
                                 "'settled'; give a narrower band")
        if self.noise_density is not None:
            std = density_to_std(self.noise_density, self.step)
            peak = float(np.max(np.abs(noise_free_run(sc)[:, 0])))
            if not std < NOISE_TO_PEAK_MAX * peak:
                raise ParameterError(
                    f"noise_density={self.noise_density:g} m/sqrt(Hz) is {std:.3g} m per "
                    f"{self.step:g} s sample, more than {NOISE_TO_PEAK_MAX:g} times the "
                    f"signal's peak ({peak:.3g} m): no record carries the rate through "
                    "that; give a pick-off noise of physical size")

    @property
    def scenario(self) -> Scenario:
        """The project scenario of this gyro (preset, overrides, step; drive and initial
        guess by the project's rules). Its default stop time (0.1 s) is the record
        over which `noise` finds each signal's peak, as `gyro-fmu run --noise` does."""
        return Scenario(preset=self.preset, overrides=dict(self.overrides), step=self.step,
                        noise=self.noise, seed=self.seed)

    @property
    def band(self) -> float:
        return self.startup_band if self.startup_band is not None else 0.01 * self.full_scale


def density_to_std(density: float, h: float) -> float:
    """Per-sample std (m) of white noise of one-sided density `density` (m/sqrt(Hz))
    sampled every h s: density / sqrt(2 h) (variance = density^2 x Nyquist band 1/(2h))."""
    return density / math.sqrt(2.0 * h)


def pickoff_noise(cfg: SpecConfig) -> MeasurementNoise:
    """Std of the position pick-off noise (m) the plant adds to x and y. Velocities get
    none: the observer measures positions here (measured pair 1)."""
    if cfg.noise_density is not None:
        s = density_to_std(cfg.noise_density, cfg.step)
        return MeasurementNoise(x=s, y=s)
    if cfg.noise == 0.0:
        return MeasurementNoise()
    rel = absolute_noise(cfg.scenario)
    return MeasurementNoise(x=rel.x, y=rel.y)


def observer_tuning(cfg: SpecConfig, noise: MeasurementNoise) -> dict[str, float]:
    """The observer's tuning: its defaults, told the pick-off noise (sigma_z1, sigma_z2),
    then cfg.tuning. Unlike system.scenario.observer_tuning the rate is NOT declared
    constant: a gyro under test does not know its rate (docs/gyro-spec.md)."""
    base: dict[str, float] = {}
    if not noise.is_off:
        base = {"sigma_z1": noise.x, "sigma_z2": noise.y}
    return {**base, **cfg.tuning}


@dataclass
class Record:
    """One run: times t (s) of the estimates, the estimate Omega_hat and the true rate
    (rad/s) at those times, and the observer's warnings (time, text)."""

    t: np.ndarray
    omega_hat: np.ndarray
    omega_true: np.ndarray
    warnings: list[tuple[float, str]]
    wall_s: float
    #: rate models of an adaptive observer, and their probabilities every
    #: PROBABILITY_EVERY steps (rows), from the first step; empty without them
    rate_models: list[str] = field(default_factory=list)
    rate_probabilities: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))

    @property
    def error(self) -> np.ndarray:
        return self.omega_hat - self.omega_true


def simulate(cfg: SpecConfig, rate: Callable[[float], float], duration: float,
             what: str, seed: int | None = None) -> Record:
    """Run plant + observer for `duration` s under the rate profile rate(t) (rad/s).

    Same loop as system/inprocess.py: at each step the plant's measured x, y at t enter
    the observer, which corrects and predicts to t + h; the plant moves to t + h with the
    drive and rate at t held. The estimate after the step is Omega_hat(t + h); it is
    recorded with the true rate held over that step. Raises SpecError if the observer
    is lost (status 2, ObserverDivergedError), naming the run `what`.
    """
    sc = cfg.scenario
    h = cfg.step
    noise = pickoff_noise(cfg)
    plant = GyroPlantModel(sc.params, noise, cfg.seed if seed is None else seed)
    try:
        tuning = ObserverTuning(**observer_tuning(cfg, noise))
    except (TypeError, ValueError) as exc:
        raise ParameterError(f"observer tuning: {exc}") from None
    observer = GyroStateObserver(GyroParameters(**default_initial_guess(sc.params)),
                                 0.0, 1, tuning)
    drive = sc.the_drive
    n = round(duration / h)
    om_hat = np.empty(n)
    om_true = np.empty(n)
    warned: list[tuple[float, str]] = []
    # an adaptive observer's rate-model probabilities, sampled (where it has them)
    probs: list[list[float]] | None = [] if hasattr(observer, "rate_probabilities") else None
    status = 0
    start = time.perf_counter()
    t = 0.0
    k = 0
    try:
        for k in range(n):
            t = k * h
            ux = drive.ux(t)
            om = rate(t)
            z = plant.measured()
            observer.step(ux, 0.0, z[0], z[2], h)
            plant.step(ux, 0.0, om, h)
            om_hat[k] = observer.output_row()[_I_OMEGA]
            om_true[k] = om
            if probs is not None and k % PROBABILITY_EVERY == 0:
                probs.append(list(observer.rate_probabilities().values()))
            if observer.status != status:
                status = observer.status
                if status == 1:
                    warned.append((t + h, observer.warning or "innovations above their band"))
    except ObserverDivergedError as exc:
        raise SpecError(
            f"{what}: the observer was lost at t = {t:.4g} s (status 2): {exc}. No spec "
            "from this gyro at these settings: lower the noise, give a smaller --step, or "
            "loosen the observer (--tuning)") from None
    names = list(observer.rate_probabilities()) if probs is not None else []
    return Record((np.arange(n) + 1) * h, om_hat, om_true, warned,
                  time.perf_counter() - start, names,
                  np.array(probs) if probs else np.zeros((0, len(names))))
