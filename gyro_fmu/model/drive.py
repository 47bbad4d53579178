"""The two-tone single-axis drive of patent eq. 10."""

from __future__ import annotations

import ctypes
import math
from dataclasses import dataclass

import numpy as np

from ..core.library import PickledAsFields, core_text
from ..core.library import TwoToneDrive as CDrive
from ..core.library import core as _core
from .parameters import GyroParameters, ParameterError, _c_params


class DriveFarFromModesWarning(UserWarning):
    """The drive's tones carry much less information on Omega_z than tones placed around
    the guessed modes would (drive_information_loss)."""


@dataclass(frozen=True)
class TwoToneDrive(PickledAsFields):
    """ux = A1 sin(2 pi f1 t) + A2 sin(2 pi f2 t) (eq. 10); uy = 0.

    Two distinct frequencies make W_kd of eq. 7 full rank: with one tone, x and
    its derivatives are linearly dependent and the 8 unknowns cannot be separated.
    Default tones 4000 + 1200 Hz: near, not at, the benchmark's 3759 Hz mode. Against
    2500 + 1200 Hz the Cramer-Rao bound on Omega_z drops 0.029 -> 0.0081 rad/s
    (park-horowitz, noise 1e-4, 40 ms) and the observer's Omega RMS error at noise
    1e-4 halves (measured; docs/history/observer-design-log.md).
    """

    A1: float = 1.0e-7  #: amplitude of tone 1, N
    f1: float = 4000.0  #: frequency of tone 1, Hz
    A2: float = 1.0e-7  #: amplitude of tone 2, N
    f2: float = 1200.0  #: frequency of tone 2, Hz

    def __post_init__(self) -> None:
        # the core's GyroTwoToneDrive of these values (not a field: eq, repr, replace skip it)
        object.__setattr__(self, "_c", CDrive(float(self.A1), float(self.f1),
                                              float(self.A2), float(self.f2)))

    @property
    def c_struct(self):
        """The core's GyroTwoToneDrive of these settings (for a C loop over it)."""
        return self._c

    def ux(self, t: float) -> float:
        """x-axis drive force at time t (s), N: the C core's gyro_drive_ux, as in
        TwoToneDrive.fmu."""
        return _core().gyro_drive_ux(self._c, t)

    def ux_many(self, t: np.ndarray) -> np.ndarray:
        """ux at every time of t."""
        fn, c = _core().gyro_drive_ux, self._c
        return np.array([fn(c, float(tk)) for tk in np.ravel(t)]).reshape(np.shape(t))

    def problems(self) -> list[str]:
        """Settings that make the drive useless (empty when fine): the core's check, as
        TwoToneDrive.fmu makes it."""
        problem = core_text("gyro_drive_problems", self._c)
        return [problem] if problem else []

    def sampling_problem(self, step: float) -> str | None:
        """Why a communication step of `step` s cannot carry this drive (a tone at or above
        its Nyquist frequency aliases), None if it can: the core's check, which
        TwoToneDrive.fmu logs as a warning."""
        return core_text("gyro_drive_nyquist_problem", self._c, step)


def drive_information_loss(guess: GyroParameters, drive: TwoToneDrive, Omega_z: float = 1.0,
                           h: float = 5e-6, measured_pair: int = 1
                           ) -> tuple[float, TwoToneDrive]:
    """(loss, proposal): the Cramer-Rao sigma of Omega_z over 40 ms from rest with this
    drive, divided by the best of the tones the C core places around the guess's modes
    (same amplitudes; relative noise, so the ratio depends on neither the noise level nor
    the force), and that best drive: the core's gyro_drive_information_loss, which
    GyroSensor.fmu logs from (fmu_src/core/gyro_excitation.h). About 25 ms at h = 5 us."""
    best = CDrive()
    loss = _core().gyro_drive_information_loss(_c_params(guess), drive.c_struct,
                                              float(Omega_z), float(h), int(measured_pair),
                                              ctypes.byref(best))
    if not math.isfinite(loss):
        raise ParameterError(f"no Cramer-Rao bound for guess {guess} at step h={h!r} s, "
                             f"measured_pair={measured_pair!r}: give a usable guess, a "
                             "finite step > 0 and measured_pair 1 or 2")
    return loss, TwoToneDrive(A1=best.A1, f1=best.f1, A2=best.A2, f2=best.f2)


def drive_warning(guess: GyroParameters, drive: TwoToneDrive, Omega_z: float, h: float,
                  measured_pair: int) -> str | None:
    """The words of a DriveFarFromModesWarning for this drive (the core's
    gyro_drive_warning, the text GyroSensor.fmu logs), or None when it is within the
    core's GYRO_DRIVE_LOSS_WARN (2) of tones around the guessed modes."""
    return core_text("gyro_drive_warning", _c_params(guess), drive.c_struct, float(Omega_z),
                     float(h), int(measured_pair))
