"""The two-tone single-axis drive of patent eq. 10."""

from __future__ import annotations

import math
from dataclasses import dataclass


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
        """x-axis drive force at time t (s), N."""
        return self.A1 * math.sin(2.0 * math.pi * self.f1 * t) + self.A2 * math.sin(
            2.0 * math.pi * self.f2 * t
        )

    def problems(self) -> list[str]:
        """Settings that make the drive useless (empty when fine)."""
        out = [
            f"{name}={value} must be finite"
            for name, value in vars(self).items()
            if not math.isfinite(value)
        ]
        if out:
            return out
        if self.f1 < 0 or self.f2 < 0:
            out.append(f"tone frequencies f1={self.f1}, f2={self.f2} Hz must be >= 0")
        return out
