"""Exact integration of the gyroscope over one communication step with held inputs.

In co-simulation every input (ux, uy and Omega_z) is held constant over a
communication step (zero-order hold). Over such a step the model of
`system_matrix_of` (the one place the equations of motion are written) is
linear time-invariant, so the step is solved exactly with one matrix
exponential. Plant and observer both build their matrices with it: a mismatch
in how they treat the input between samples biases the rate estimate
(docs/observer-design.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from .parameters import GyroParameters


def state_scaling(p: GyroParameters) -> np.ndarray:
    """Diagonal of T, with T @ [x, vx, y, vy] = [x, vx/w0, y, vy/w0], w0 = sqrt(kxx).

    The unscaled A*h has entries from h (5e-6) to kxx*h (2e3): scaling the
    velocities by w0 brings every entry near w0*h and keeps expm accurate.
    """
    w0 = math.sqrt(abs(p.kxx)) or 1.0
    return np.array([1.0, 1.0 / w0, 1.0, 1.0 / w0])


@njit(cache=True)
def system_matrix_of(kxx, kyy, kxy, dxx, dyy, dxy, Omega_z):  # pragma: no cover
    """Continuous-time 4x4 matrix A of the state [x, x', y, y'] (patent eqs. 3-4).

    The printed eqs. 1-5 mix up subscripts; the model implemented is the one the
    observability matrix C1 of eq. 7 implies (k's in 1/s^2, d's in 1/s, Omega_z in rad/s):
        x'' = -kxx x - kxy y - dxx x' - dxy y' + 2 Omega_z y' + ux/m
        y'' = -kxy x - kyy y - dxy x' - dyy y' - 2 Omega_z x' + uy/m
    Compiled, so that plant and observer kernels call it; parameters.system_matrix is
    its numpy entry point.
    """
    A = np.zeros((4, 4))
    A[0, 1] = 1.0
    A[1, 0] = -kxx
    A[1, 1] = -dxx
    A[1, 2] = -kxy
    A[1, 3] = 2.0 * Omega_z - dxy
    A[2, 3] = 1.0
    A[3, 0] = -kxy
    A[3, 1] = -dxy - 2.0 * Omega_z
    A[3, 2] = -kyy
    A[3, 3] = -dyy
    return A


@njit(cache=True)
def inf_norm_rows(M, rows, cols):  # pragma: no cover
    """Infinity norm of the block M[:rows, :cols] (max absolute row sum)."""
    norm = 0.0
    for i in range(rows):
        r = 0.0
        for j in range(cols):
            r += abs(M[i, j])
        norm = max(norm, r)
    return norm


@njit(cache=True)
def _expm_held(M, E):  # pragma: no cover
    """Top 4 rows E of expm([[M], [0]]) for the 4x6 top block M of a Van Loan matrix.

    Taylor series after scaling M by 2^-s so that ||M 2^-s||_inf <= 0.5 (terms until
    the next is below 1e-17 of the sum), then s squarings. The bottom rows of every
    power are zero, so each term costs a 4x4 by 4x6 product; scaling by a power of
    two is exact and the series converges like 0.5^K / K!.
    """
    norm = inf_norm_rows(M, 4, 6)
    s = 0
    scale = 1.0
    while norm * scale > 0.5:
        scale *= 0.5
        s += 1
    Ms = np.empty((4, 6))
    T = np.empty((4, 6))
    Tn = np.empty((4, 6))
    for i in range(4):
        for j in range(6):
            Ms[i, j] = M[i, j] * scale
            T[i, j] = Ms[i, j]  # first power
            E[i, j] = Ms[i, j]
        E[i, i] += 1.0
    nrm = norm * scale
    term = nrm
    for k in range(2, 30):
        if term < 1e-17:
            break
        inv = 1.0 / k
        for i in range(4):
            for j in range(6):
                acc = 0.0
                for q in range(4):
                    acc += T[i, q] * Ms[q, j]
                Tn[i, j] = acc * inv
        for i in range(4):
            for j in range(6):
                T[i, j] = Tn[i, j]
                E[i, j] += Tn[i, j]
        term *= nrm / k
    for _ in range(s):  # [[P, G], [0, I]]^2 = [[P P, P G + G], [0, I]]
        for i in range(4):
            for j in range(6):
                acc = 0.0
                for q in range(4):
                    acc += E[i, q] * E[q, j]
                Tn[i, j] = acc + (E[i, j] if j >= 4 else 0.0)
        for i in range(4):
            for j in range(6):
                E[i, j] = Tn[i, j]


@njit(cache=True)
def _held_input_maps(kxx, kyy, kxy, dxx, dyy, dxy, m, Omega_z, h, Phi, Gamma):  # pragma: no cover
    w0 = math.sqrt(abs(kxx))
    if w0 == 0.0:
        w0 = 1.0
    T = np.array([1.0, 1.0 / w0, 1.0, 1.0 / w0])
    A = system_matrix_of(kxx, kyy, kxy, dxx, dyy, dxy, Omega_z)
    M = np.empty((4, 6))
    for i in range(4):
        for j in range(4):
            M[i, j] = A[i, j] * T[i] / T[j] * h
        M[i, 4] = 0.0
        M[i, 5] = 0.0
    M[1, 4] = T[1] / m * h
    M[3, 5] = T[3] / m * h
    E = np.empty((4, 6))
    _expm_held(M, E)
    for i in range(4):
        for j in range(4):
            Phi[i, j] = E[i, j] / T[i] * T[j]
        Gamma[i, 0] = E[i, 4] / T[i]
        Gamma[i, 1] = E[i, 5] / T[i]


@njit(cache=True)
def _apply_maps(Phi, Gamma, s, ux, uy, out):  # pragma: no cover
    for i in range(4):
        acc = 0.0
        for j in range(4):
            acc += Phi[i, j] * s[j]
        out[i] = acc + (Gamma[i, 0] * ux + Gamma[i, 1] * uy)


def held_input_maps(p: GyroParameters, Omega_z: float, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Transition Phi (4x4) and input map Gamma (4x2) of one held-input step of length h.

    s(t+h) = Phi s(t) + Gamma [ux, uy], exact for constant ux, uy, Omega_z over
    the step (Van Loan: exponential of the augmented matrix [[A, B], [0, 0]] h, in
    the scaling of state_scaling; a compiled scaled Taylor series, accurate to
    rounding: 2 us where scipy.linalg.expm took 40 us, benchmarks/PERF_NOTES.md).
    """
    Phi, Gamma = np.empty((4, 4)), np.empty((4, 2))
    _held_input_maps(float(p.kxx), float(p.kyy), float(p.kxy), float(p.dxx), float(p.dyy),
                     float(p.dxy), float(p.m), float(Omega_z), float(h), Phi, Gamma)
    return Phi, Gamma


@dataclass
class HeldInputStepper:
    """Caches the held-input maps; recomputes only when h, Omega_z or p change."""

    params: GyroParameters
    _key: tuple[float, float] | None = field(default=None, init=False, repr=False)
    _Phi: np.ndarray = field(default_factory=lambda: np.eye(4), init=False, repr=False)
    _Gamma: np.ndarray = field(default_factory=lambda: np.zeros((4, 2)), init=False, repr=False)

    def __post_init__(self) -> None:
        p = self.params
        self._p = tuple(float(v) for v in (p.kxx, p.kyy, p.kxy, p.dxx, p.dyy, p.dxy, p.m))

    def maps(self, Omega_z: float, h: float) -> tuple[np.ndarray, np.ndarray]:
        key = self._key
        if key is None or Omega_z != key[0] or h != key[1]:
            self._Phi, self._Gamma = np.empty((4, 4)), np.empty((4, 2))
            _held_input_maps(*self._p, float(Omega_z), float(h), self._Phi, self._Gamma)
            self._key = (Omega_z, h)
        return self._Phi, self._Gamma

    def step(self, s: np.ndarray, ux: float, uy: float, Omega_z: float, h: float) -> np.ndarray:
        """State at t+h from state s at t, with ux, uy (N) and Omega_z (rad/s) held."""
        Phi, Gamma = self.maps(Omega_z, h)
        out = np.empty(4)
        _apply_maps(Phi, Gamma, np.ascontiguousarray(s, dtype=float), float(ux), float(uy), out)
        return out


def accelerations(
    p: GyroParameters, s: np.ndarray, ux: float, uy: float, Omega_z: float
) -> tuple[float, float]:
    """Accelerations ax, ay (m/s^2) of eqs. 3-4: rows 1 and 3 of parameters.system_matrix."""
    x, vx, y, vy = (float(v) for v in s)
    ax = -p.kxx * x - p.dxx * vx - p.kxy * y + (2.0 * Omega_z - p.dxy) * vy
    ay = -p.kxy * x + (-p.dxy - 2.0 * Omega_z) * vx - p.kyy * y - p.dyy * vy
    return ax + ux / p.m, ay + uy / p.m
