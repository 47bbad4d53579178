"""The two-tone single-axis drive of patent eq. 10."""

from __future__ import annotations

import ctypes
import functools
from dataclasses import dataclass

import numpy as np

from ..core.library import TwoToneDrive as CDrive
from ..core.library import core as _core
from ..core.library import message_buffer


@dataclass(frozen=True)
class TwoToneDrive:
    """ux = A1 sin(2 pi f1 t) + A2 sin(2 pi f2 t) (eq. 10); uy = 0.

    Two distinct frequencies make W_kd of eq. 7 full rank: with one tone, x and
    its derivatives are linearly dependent and the 8 unknowns cannot be separated.
    Default tones 4000 + 1200 Hz: near, not at, the benchmark's 3759 Hz mode. Against
    2500 + 1200 Hz the Cramer-Rao bound on Omega_z drops 0.029 -> 0.0081 rad/s
    (park-horowitz, noise 1e-4, 40 ms) and the observer's Omega RMS error at noise
    1e-4 halves (measured; benchmarks/OBSERVER_NOTES.md).
    """

    A1: float = 1.0e-7  #: amplitude of tone 1, N
    f1: float = 4000.0  #: frequency of tone 1, Hz
    A2: float = 1.0e-7  #: amplitude of tone 2, N
    f2: float = 1200.0  #: frequency of tone 2, Hz

    def ux(self, t: float) -> float:
        """x-axis drive force at time t (s), N: the C core's gyro_drive_ux, as in
        TwoToneDrive.fmu."""
        return _core().gyro_drive_ux(_c_drive(self.A1, self.f1, self.A2, self.f2), t)

    def ux_many(self, t: np.ndarray) -> np.ndarray:
        """ux at every time of t."""
        fn, c = _core().gyro_drive_ux, _c_drive(self.A1, self.f1, self.A2, self.f2)
        return np.array([fn(c, float(tk)) for tk in np.ravel(t)]).reshape(np.shape(t))

    def problems(self) -> list[str]:
        """Settings that make the drive useless (empty when fine): the core's check, as
        TwoToneDrive.fmu makes it."""
        msg = message_buffer()
        if _core().gyro_drive_problems(_c_drive(self.A1, self.f1, self.A2, self.f2), msg,
                                       len(msg)):
            return [msg.value.decode()]
        return []


@functools.lru_cache(maxsize=256)
def _c_drive(A1: float, f1: float, A2: float, f2: float) -> object:
    """The core's GyroTwoToneDrive, passed by reference."""
    return ctypes.byref(CDrive(float(A1), float(f1), float(A2), float(f2)))
