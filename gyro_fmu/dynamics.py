"""Exact integration of the gyroscope over one communication step with held inputs.

In co-simulation every input (ux, uy and Omega_z) is held constant over a
communication step (zero-order hold). Over such a step the model of
`parameters.system_matrix` is linear time-invariant, so the step is solved
exactly with one matrix exponential. Plant and observer both use this module:
a mismatch in how they treat the input between samples biases the rate
estimate (about 0.2 rad/s for a 5e-4 input-gain mismatch, FIELD-NOTES).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import expm

from .parameters import GyroParameters, system_matrix


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
    the step (Van Loan: expm of the augmented matrix [[A, B], [0, 0]] h).
    """
    T = state_scaling(p)
    A = system_matrix(p, Omega_z) * T[:, None] / T[None, :]
    B = np.zeros((4, 2))
    B[1, 0] = T[1] / p.m
    B[3, 1] = T[3] / p.m
    M = np.zeros((6, 6))
    M[:4, :4] = A * h
    M[:4, 4:] = B * h
    E = expm(M)
    Phi = E[:4, :4] / T[:, None] * T[None, :]
    Gamma = E[:4, 4:] / T[:, None]
    return Phi, Gamma


@dataclass
class HeldInputStepper:
    """Caches the held-input maps; recomputes only when h, Omega_z or p change."""

    params: GyroParameters
    _key: tuple[float, float] | None = field(default=None, init=False, repr=False)
    _Phi: np.ndarray = field(default_factory=lambda: np.eye(4), init=False, repr=False)
    _Gamma: np.ndarray = field(default_factory=lambda: np.zeros((4, 2)), init=False, repr=False)

    def maps(self, Omega_z: float, h: float) -> tuple[np.ndarray, np.ndarray]:
        key = (Omega_z, h)
        if key != self._key:
            self._Phi, self._Gamma = held_input_maps(self.params, Omega_z, h)
            self._key = key
        return self._Phi, self._Gamma

    def step(self, s: np.ndarray, ux: float, uy: float, Omega_z: float, h: float) -> np.ndarray:
        """State at t+h from state s at t, with ux, uy (N) and Omega_z (rad/s) held."""
        Phi, Gamma = self.maps(Omega_z, h)
        return Phi @ s + Gamma @ np.array([ux, uy])


def accelerations(
    p: GyroParameters, s: np.ndarray, ux: float, uy: float, Omega_z: float
) -> tuple[float, float]:
    """Accelerations ax, ay (m/s^2) of eqs. 3-4, from the same matrix as the step."""
    ds = system_matrix(p, Omega_z) @ s
    return float(ds[1] + ux / p.m), float(ds[3] + uy / p.m)
