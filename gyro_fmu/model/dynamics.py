"""Exact integration of the gyroscope over one communication step with held inputs.

In co-simulation every input (ux, uy and Omega_z) is held constant over a
communication step (zero-order hold). Over such a step the model of
the C core's gyro_system_matrix (the one place the equations of motion are written) is
linear time-invariant, so the step is solved exactly with one matrix
exponential. Plant and observer both build their matrices with it: a mismatch
in how they treat the input between samples biases the rate estimate
(docs/observer-design.md).
"""

from __future__ import annotations

import ctypes
import math
from dataclasses import dataclass, field

import numpy as np

from ..core.library import Params, core
from .parameters import GyroParameters


def state_scaling(p: GyroParameters) -> np.ndarray:
    """Diagonal of T, with T @ [x, vx, y, vy] = [x, vx/w0, y, vy/w0], w0 = sqrt(kxx).

    The unscaled A*h has entries from h (5e-6) to kxx*h (2e3): scaling the
    velocities by w0 brings every entry near w0*h and keeps expm accurate.
    """
    w0 = math.sqrt(abs(p.kxx)) or 1.0
    return np.array([1.0, 1.0 / w0, 1.0, 1.0 / w0])


def held_input_maps(p: GyroParameters, Omega_z: float, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Transition Phi (4x4) and input map Gamma (4x2) of one held-input step of length h.

    s(t+h) = Phi s(t) + Gamma [ux, uy], exact for constant ux, uy, Omega_z over
    the step: the C core's gyro_held_input_maps (fmu_src/core/gyro_plant.c), the step
    GyroPlant.fmu takes (Van Loan exponential in the scaling of state_scaling).
    """
    Phi, Gamma = np.empty((4, 4)), np.empty((4, 2))
    core().gyro_held_input_maps(
        ctypes.byref(Params(float(p.kxx), float(p.kyy), float(p.kxy), float(p.dxx),
                            float(p.dyy), float(p.dxy), float(p.m))),
        float(Omega_z), float(h), Phi.ctypes.data_as(_DOUBLE_P),
        Gamma.ctypes.data_as(_DOUBLE_P))
    return Phi, Gamma


_DOUBLE_P = ctypes.POINTER(ctypes.c_double)


@dataclass
class HeldInputStepper:
    """Caches the held-input maps; recomputes only when h, Omega_z or p change."""

    params: GyroParameters
    _key: tuple[float, float] | None = field(default=None, init=False, repr=False)
    _Phi: np.ndarray = field(default_factory=lambda: np.eye(4), init=False, repr=False)
    _Gamma: np.ndarray = field(default_factory=lambda: np.zeros((4, 2)), init=False, repr=False)

    def maps(self, Omega_z: float, h: float) -> tuple[np.ndarray, np.ndarray]:
        key = self._key
        if key is None or Omega_z != key[0] or h != key[1]:
            self._Phi, self._Gamma = held_input_maps(self.params, Omega_z, h)
            self._key = (Omega_z, h)
        return self._Phi, self._Gamma

    def step(self, s: np.ndarray, ux: float, uy: float, Omega_z: float, h: float) -> np.ndarray:
        """State at t+h from state s at t, with ux, uy (N) and Omega_z (rad/s) held."""
        Phi, Gamma = self.maps(Omega_z, h)
        return Phi @ np.asarray(s, dtype=float) + Gamma @ np.array([ux, uy], dtype=float)


def accelerations(
    p: GyroParameters, s: np.ndarray, ux: float, uy: float, Omega_z: float
) -> tuple[float, float]:
    """Accelerations ax, ay (m/s^2) of eqs. 3-4: rows 1 and 3 of parameters.system_matrix."""
    x, vx, y, vy = (float(v) for v in s)
    ax = -p.kxx * x - p.dxx * vx - p.kxy * y + (2.0 * Omega_z - p.dxy) * vy
    ay = -p.kxy * x + (-p.dxy - 2.0 * Omega_z) * vx - p.kyy * y - p.dyy * vy
    return ax + ux / p.m, ay + uy / p.m
