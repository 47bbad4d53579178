"""Angular-rate profiles Omega_z(t) that drive the plant's Coriolis coupling."""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

import numpy as np

from ..core.library import PickledAsFields, core_text
from ..core.library import RateProfile as CRate
from ..core.library import core as _core


class RateKind(IntEnum):
    """Shape of the rate profile (the Integer `kind` of RateProfile.fmu)."""

    constant = 1
    step = 2
    ramp = 3
    sine = 4


@dataclass(frozen=True)
class RateProfile(PickledAsFields):
    """Omega_z(t) in rad/s.

    - constant: offset
    - step:     offset, plus amplitude from t_start on
    - ramp:     offset, plus slope * (t - t_start) from t_start on
    - sine:     offset + amplitude sin(2 pi frequency (t - t_start)) from t_start on;
                the patent's Table 1 case is amplitude 1, frequency 100 Hz.
    """

    kind: RateKind = RateKind.constant
    offset: float = 1.0  #: rad/s
    amplitude: float = 0.0  #: rad/s
    frequency: float = 0.0  #: Hz
    slope: float = 0.0  #: rad/s^2
    t_start: float = 0.0  #: s

    def __post_init__(self) -> None:
        object.__setattr__(self, "kind", RateKind(self.kind))
        # the core's GyroRateProfile of these values (not a field: eq, repr, replace skip it)
        object.__setattr__(self, "_c", CRate(int(self.kind), 0, float(self.offset),
                                             float(self.amplitude), float(self.frequency),
                                             float(self.slope), float(self.t_start)))

    @property
    def c_struct(self):
        """The core's GyroRateProfile of these settings (for a C loop over it)."""
        return self._c

    def Omega_z(self, t: float) -> float:
        """Omega_z at time t (s), rad/s: the C core's gyro_rate_Omega_z, as in
        RateProfile.fmu."""
        return _core().gyro_rate_Omega_z(self._c, t)

    def peak(self, t_end: float) -> float:
        """The largest |Omega_z| over [0, t_end], rad/s (a sine counted at its crest)."""
        ends = [abs(self.Omega_z(t)) for t in (0.0, self.t_start, t_end) if 0.0 <= t <= t_end]
        if self.kind is RateKind.sine and self.t_start <= t_end:
            ends.append(abs(self.offset) + abs(self.amplitude))
        return max(ends)

    def Omega_z_many(self, t: np.ndarray) -> np.ndarray:
        fn, c = _core().gyro_rate_Omega_z, self._c
        return np.array([fn(c, float(tk)) for tk in np.ravel(t)]).reshape(np.shape(t))

    def sampling_problem(self, step: float) -> str | None:
        """Why a communication step of `step` s cannot carry this rate (a sine at or above
        its Nyquist frequency aliases), None if it can: the core's check, which
        RateProfile.fmu logs as a warning."""
        return core_text("gyro_rate_nyquist_problem", self._c, step)

    def problems(self) -> list[str]:
        """Settings RateProfile.fmu refuses (empty when fine): the core's check."""
        problem = core_text("gyro_rate_problems", self._c)
        return [problem] if problem else []


    @classmethod
    def parse(cls, text: str) -> RateProfile:
        """Build from 'constant:1', 'sine:1:100', 'step:0.5:0.01', 'ramp:100:0' texts.

        Forms: constant:OFFSET | step:AMPLITUDE:T_START[:OFFSET] |
        ramp:SLOPE:T_START[:OFFSET] | sine:AMPLITUDE:FREQUENCY[:OFFSET].
        """
        kind, *rest = text.split(":")
        try:
            values = [float(v) for v in rest]
        except ValueError:
            raise ValueError(f"rate profile {text!r}: values must be numbers") from None
        try:
            k = RateKind[kind]
        except KeyError:
            raise ValueError(
                f"rate profile {text!r}: kind must be one of {[r.name for r in RateKind]}"
            ) from None
        need = {RateKind.constant: (1, 1), RateKind.step: (2, 3), RateKind.ramp: (2, 3),
                RateKind.sine: (2, 3)}[k]
        if not need[0] <= len(values) <= need[1]:
            raise ValueError(f"rate profile {text!r}: see RateProfile.parse for the forms")
        if k is RateKind.constant:
            return cls(k, offset=values[0])
        offset = values[2] if len(values) == 3 else 0.0
        if k is RateKind.step:
            return cls(k, offset=offset, amplitude=values[0], t_start=values[1])
        if k is RateKind.ramp:
            return cls(k, offset=offset, slope=values[0], t_start=values[1])
        return cls(k, offset=offset, amplitude=values[0], frequency=values[1])

    def describe(self) -> str:
        return {
            RateKind.constant: f"constant:{self.offset:g}",
            RateKind.step: f"step:{self.amplitude:g}:{self.t_start:g}:{self.offset:g}",
            RateKind.ramp: f"ramp:{self.slope:g}:{self.t_start:g}:{self.offset:g}",
            RateKind.sine: f"sine:{self.amplitude:g}:{self.frequency:g}:{self.offset:g}",
        }[self.kind]

