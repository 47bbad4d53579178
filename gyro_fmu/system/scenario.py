"""Scenarios: which gyroscope, drive, rate, noise and observer start to co-simulate.

A scenario is plain data. `fmu_system` turns it into FMU components and the
standard wiring of patent Fig. 2 (drive -> plant and observer, rate -> plant,
plant measurements -> observer) for the fmpy master.

Noise convention: `noise` is relative. Each measured signal gets white Gaussian
noise whose standard deviation is `noise` times that signal's own peak |value|
over the noise-free run (so the small y signal is not buried under a noise
floor set by the much larger x; docs/observability.md).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path

import numpy as np

from ..cosim.master import Component, Connection, check_result_memory, whole_steps
from ..model.drive import TwoToneDrive
from ..model.interfaces import SEED_MAX
from ..model.parameters import (
    DEFAULT_PRESET,
    PARAMETER_NAMES,
    PRESET_DRIVE_AMPLITUDE,
    GyroParameters,
    ParameterError,
    default_initial_guess,
    preset,
)
from ..model.plant import MEASURED, GyroPlantModel, MeasurementNoise
from ..model.rate import RateKind, RateProfile
from ..options import MAX_STEPS

#: Largest measurement noise per sample over the signal's peak a run may simulate.
NOISE_TO_PEAK_MAX = 1e6


@dataclass(frozen=True)
class Scenario:
    """Everything that defines one run. SI units throughout."""

    preset: str = DEFAULT_PRESET
    overrides: Mapping[str, float] = field(default_factory=dict)
    rate: RateProfile = field(default_factory=lambda: RateProfile(RateKind.constant, offset=1.0))
    drive: TwoToneDrive | None = None  #: None: default tones at the preset's amplitude
    stop_time: float = 0.1  #: s
    step: float = 5e-6  #: communication step, s
    noise: float = 0.0  #: relative to each measured signal's peak
    seed: int = 0
    measured_pair: int = 1  #: 1: positions x, y; 2: velocities vx, vy (claim 4)
    initial: Mapping[str, float] | None = None  #: observer guesses; None: default rule
    Omega_z_0: float = 0.0  #: observer's initial rate guess, rad/s
    tuning: Mapping[str, float] = field(default_factory=dict)  #: ObserverTuning overrides

    def __post_init__(self) -> None:
        for name, value in (("stop_time", self.stop_time), ("step", self.step)):
            if not (math.isfinite(value) and value > 0.0):
                raise ParameterError(f"{name}={value!r} s must be a finite number > 0")
        if self.stop_time / self.step > MAX_STEPS:
            raise ParameterError(
                f"stop_time={self.stop_time:g} s is {self.stop_time / self.step:.3g} steps of "
                f"{self.step:g} s, more than the {MAX_STEPS:.3g} a run may take: shorten it")
        if self.step > self.stop_time:
            raise ParameterError(
                f"step={self.step} s is longer than stop_time={self.stop_time} s"
            )
        if not (math.isfinite(self.noise) and 0.0 <= self.noise <= NOISE_TO_PEAK_MAX):
            raise ParameterError(
                f"noise={self.noise!r} must lie in [0, {NOISE_TO_PEAK_MAX:g}] (a fraction of "
                "each signal's peak: beyond it no record carries the rate)")
        if self.measured_pair not in (1, 2):
            raise ParameterError(
                f"measured_pair={self.measured_pair!r}: use 1 (positions) or 2 (velocities)"
            )
        if (isinstance(self.seed, bool) or not isinstance(self.seed, int)
                or not 0 <= self.seed <= SEED_MAX):
            raise ParameterError(
                f"seed={self.seed!r} is not an integer in [0, {SEED_MAX}], the range of "
                "GyroPlant.fmu's seed (an FMI 2.0 Integer): give such a seed")
        if not isinstance(self.Omega_z_0, int | float) or isinstance(self.Omega_z_0, bool):
            raise ParameterError(f"Omega_z_0={self.Omega_z_0!r} rad/s is not a number")
        self._check_signals()
        self._check_rates()
        self._check_tuning()
        self.n_steps  # noqa: B018 - a step that does not divide the stop time
        self.params  # noqa: B018 - fail early on a bad preset or override

    def _check_tuning(self) -> None:
        """The observer tuning, checked before any run by the observer's own rules (an
        Integer given 1.5 was truncated to 1 by the FMU path and ran)."""
        from ..estimation.observer_tuning import ObserverTuning

        try:
            ObserverTuning(**dict(self.tuning))
        except TypeError:
            known = sorted(f.name for f in fields(ObserverTuning))
            unknown = sorted(set(self.tuning) - set(known))
            raise ParameterError(f"unknown tuning name(s) {unknown}: the names are "
                                 f"{known}") from None
        except ValueError as exc:
            raise ParameterError(str(exc)) from None

    def _check_rates(self) -> None:
        """The observer's rate guess and the rate profile's largest value (over the run)
        against the fastest rate this gyro can sense (GyroParameters.rate_limit)."""
        p = self.params
        problems = [p.rate_problem("Omega_z_0", self.Omega_z_0)]
        if isinstance(self.rate, RateProfile):
            peak = p.rate_problem("Omega_z", self.rate.peak(self.stop_time))
            problems.append(peak and f"the rate profile reaches {peak}")
        problems = [q for q in problems if q]
        if problems:
            raise ParameterError("; ".join(problems))

    def _check_signals(self) -> None:
        """Refuse what gives a wrong number with no error: a tone or a sine rate at or
        above the Nyquist frequency of the step (it aliases), a sine rate of 0 Hz (it is
        its offset: say constant), a drive tone of 0 Hz (it adds nothing: one tone does
        not separate the 8 unknowns, eq. 7). The words are the C core's where it checks."""
        problems = list(self.the_drive.problems())
        signals = [self.the_drive]
        if isinstance(self.rate, RateProfile):  # a rate of the user's own kind: theirs
            problems += self.rate.problems()
            signals.append(self.rate)
        for signal in signals:
            problem = signal.sampling_problem(self.step)
            if problem:
                problems.append(problem)
        if isinstance(self.rate, RateProfile) and self.rate.kind is RateKind.sine \
                and self.rate.amplitude != 0.0 and self.rate.frequency == 0.0:
            problems.append("rate sine of frequency 0 Hz is its offset: give a frequency > 0, "
                            "or a constant rate (constant:OFFSET)")
        d = self.the_drive
        for k, (A, f) in enumerate(((d.A1, d.f1), (d.A2, d.f2)), start=1):
            if A != 0.0 and f == 0.0:
                problems.append(f"drive tone f{k}=0 Hz adds nothing (sin 0 = 0): two distinct "
                                "tones are needed to separate the 8 unknowns (eq. 7); give "
                                f"f{k} > 0")
        if problems:
            raise ParameterError("; ".join(problems))

    @property
    def params(self) -> GyroParameters:
        return preset(self.preset, **self.overrides)

    @property
    def the_drive(self) -> TwoToneDrive:
        if self.drive is not None:
            return self.drive
        amplitude = PRESET_DRIVE_AMPLITUDE.get(self.preset, PRESET_DRIVE_AMPLITUDE[DEFAULT_PRESET])
        return TwoToneDrive(A1=amplitude, A2=amplitude)

    @property
    def initial_guess(self) -> dict[str, float]:
        guess = default_initial_guess(self.params)
        if self.initial:
            unknown = sorted(set(self.initial) - set(PARAMETER_NAMES))
            if unknown:
                raise ParameterError(
                    f"unknown initial guess(es) {unknown}: names are {list(PARAMETER_NAMES)}"
                )
            guess.update({k: float(v) for k, v in self.initial.items()})
        return guess

    @property
    def n_steps(self) -> int:
        return whole_steps(self.stop_time, self.step)

    def with_(self, **changes: object) -> Scenario:
        return replace(self, **changes)

    def as_dict(self) -> dict:
        """JSON-ready settings, including the derived drive, truth and initial guess."""
        return {
            "preset": self.preset,
            "overrides": dict(self.overrides),
            "rate": {**asdict(self.rate), "kind": self.rate.kind.name,
                     "text": self.rate.describe()},
            "drive": asdict(self.the_drive),
            "stop_time": self.stop_time,
            "step": self.step,
            "noise_relative_to_peak": self.noise,
            "seed": self.seed,
            "measured_pair": self.measured_pair,
            "initial_guess": {**self.initial_guess, "Omega_z": self.Omega_z_0},
            "tuning": dict(self.tuning),
        }


#: Named scenarios of the command line.
SCENARIOS: dict[str, Scenario] = {
    # The benchmark gyroscope at a constant 1 rad/s.
    "default": Scenario(),
    # The patent's own demonstration (Table 1 with the kxy correction, Fig. 3-4).
    "patent": Scenario(
        preset="patent-table1-corrected",
        rate=RateProfile(RateKind.sine, offset=0.0, amplitude=1.0, frequency=100.0),
    ),
}


def scenario(name: str = "default", **changes: object) -> Scenario:
    try:
        base = SCENARIOS[name]
    except KeyError:
        raise ParameterError(f"unknown scenario {name!r}: choose one of {sorted(SCENARIOS)}") \
            from None
    return base.with_(**changes) if changes else base


def noise_free_run(sc: Scenario) -> np.ndarray:
    """Plant states [x, vx, y, vy] at every communication point, noise off (library only)."""
    plant = GyroPlantModel(sc.params)
    drive, rate, h = sc.the_drive, sc.rate, sc.step
    check_result_memory(sc.n_steps + 1, 4)
    out = np.empty((sc.n_steps + 1, 4))
    out[0] = plant.s
    for k in range(sc.n_steps):
        t = k * h
        plant.step(drive.ux(t), 0.0, rate.Omega_z(t), h)
        out[k + 1] = plant.s
    return out


def absolute_noise(sc: Scenario, states: np.ndarray | None = None) -> MeasurementNoise:
    """Noise standard deviations from the relative level and each signal's peak."""
    if sc.noise == 0.0:
        return MeasurementNoise()
    states = noise_free_run(sc) if states is None else states
    peaks = np.max(np.abs(states), axis=0)
    return MeasurementNoise(*(float(sc.noise * p) for p in peaks))


#: Rate model for a rate declared constant: exactly the constant the Cramer-Rao bound
#: assumes (ObserverTuning rate_model 1). The FMU's default, the adaptive rate model,
#: comes within a few percent of it on a constant rate (docs/observer-rate-model.md)
#: and also follows a moving one; a user who knows the rate is constant says so.
RATE_MODEL_CONSTANT_RATE = 1


def observer_tuning(sc: Scenario, noise: MeasurementNoise) -> dict[str, float]:
    """ObserverTuning a user would set for this scenario, overridden by sc.tuning.

    The observer is told the pick-off noise of the pair it measures (absolute stds,
    as a designer knows them from the electronics) and a rate bandwidth that suits
    the rate profile: a constant rate is modelled as exactly constant.
    """
    tuning: dict[str, float] = {}
    if not noise.is_off:
        z1, z2 = ("x", "y") if sc.measured_pair == 1 else ("vx", "vy")
        tuning["sigma_z1"], tuning["sigma_z2"] = getattr(noise, z1), getattr(noise, z2)
    if sc.rate.kind is RateKind.constant:
        tuning["rate_model"] = RATE_MODEL_CONSTANT_RATE
    return {**tuning, **dict(sc.tuning)}


#: The FMUs of the standard system, by instance name.
INSTANCE_FMUS = {
    "drive": "TwoToneDrive.fmu",
    "rate": "RateProfile.fmu",
    "plant": "GyroPlant.fmu",
    "observer": "GyroObserver.fmu",
}

#: The wiring of patent Fig. 2.
CONNECTIONS: tuple[Connection, ...] = (
    Connection("drive.ux", "plant.ux"),
    Connection("drive.uy", "plant.uy"),
    Connection("rate.Omega_z", "plant.Omega_z"),
    Connection("drive.ux", "observer.ux"),
    Connection("drive.uy", "observer.uy"),
    *(Connection(f"plant.{s}", f"observer.{s}_meas") for s in MEASURED),
)


def fmu_system(
    sc: Scenario,
    models_dir: Path,
    fmus: Mapping[str, Path] | None = None,
    noise: MeasurementNoise | None = None,
) -> tuple[list[Component], list[Connection]]:
    """Components (with the scenario's parameters) and connections of the standard system.

    fmus: instance name -> FMU path, to put a user's FMU in place of one of ours. It
    must have the same inputs and outputs; it keeps its own parameter defaults (ours
    are not pushed onto it).
    """
    paths = {name: Path(models_dir) / f for name, f in INSTANCE_FMUS.items()}
    for name, path in (fmus or {}).items():
        if name not in paths:
            raise ParameterError(f"unknown instance {name!r}: instances are {sorted(paths)}")
        paths[name] = Path(path)
    p = sc.params
    noise = absolute_noise(sc) if noise is None else noise
    rate = sc.rate
    parameters = {
        "drive": asdict(sc.the_drive),
        "rate": {"kind": int(rate.kind), "offset": rate.offset, "amplitude": rate.amplitude,
                 "frequency": rate.frequency, "slope": rate.slope, "t_start": rate.t_start},
        "plant": {**p.as_dict(), **{f"noise_{k}": v for k, v in asdict(noise).items()},
                  "seed": sc.seed},
        "observer": {**{f"{k}_0": v for k, v in sc.initial_guess.items()},
                     "Omega_z_0": sc.Omega_z_0, "measured_pair": sc.measured_pair,
                     **observer_tuning(sc, noise)},
    }
    replaced = set(fmus or {})
    components = [Component(name, paths[name], {} if name in replaced else parameters[name])
                  for name in INSTANCE_FMUS]
    return components, list(CONNECTIONS)
