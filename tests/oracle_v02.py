"""gyro_fmu 0.2.0's plant, drive and rate, frozen as the oracle of the C core's port.

The held-input step is 0.2.0's compiled kernel (gyro_fmu/model/dynamics.py at 0.2.0:
Van Loan, velocities scaled by sqrt(kxx), scaled Taylor series and squarings) in plain
Python with the same operation order, so IEEE arithmetic gives the same bits. The noise
was numpy's default_rng(seed).standard_normal(4) per communication point; the core draws
its own (xoshiro256** and the polar method), so only the noise-free part is compared bit
for bit, and the noise by its statistics.
"""

from __future__ import annotations

import math

import numpy as np


def _expm_held(M: list[list[float]]) -> list[list[float]]:
    norm = max(sum(abs(M[i][j]) for j in range(6)) for i in range(4))
    s, scale = 0, 1.0
    while norm * scale > 0.5:
        scale *= 0.5
        s += 1
    Ms = [[M[i][j] * scale for j in range(6)] for i in range(4)]
    T = [row[:] for row in Ms]
    E = [row[:] for row in Ms]
    for i in range(4):
        E[i][i] += 1.0
    nrm = norm * scale
    term = nrm
    for k in range(2, 30):
        if term < 1e-17:
            break
        inv = 1.0 / k
        Tn = [[0.0] * 6 for _ in range(4)]
        for i in range(4):
            for j in range(6):
                acc = 0.0
                for q in range(4):
                    acc += T[i][q] * Ms[q][j]
                Tn[i][j] = acc * inv
        for i in range(4):
            for j in range(6):
                T[i][j] = Tn[i][j]
                E[i][j] += Tn[i][j]
        term *= nrm / k
    for _ in range(s):
        Tn = [[0.0] * 6 for _ in range(4)]
        for i in range(4):
            for j in range(6):
                acc = 0.0
                for q in range(4):
                    acc += E[i][q] * E[q][j]
                Tn[i][j] = acc + (E[i][j] if j >= 4 else 0.0)
        E = Tn
    return E


def held_input_maps(p, Omega_z: float, h: float):
    """Phi (4x4) and Gamma (4x2) of 0.2.0's dynamics._held_input_maps."""
    w0 = math.sqrt(abs(p.kxx)) or 1.0
    T = [1.0, 1.0 / w0, 1.0, 1.0 / w0]
    A = [[0.0] * 4 for _ in range(4)]
    A[0][1] = 1.0
    A[1][0] = -p.kxx
    A[1][1] = -p.dxx
    A[1][2] = -p.kxy
    A[1][3] = 2.0 * Omega_z - p.dxy
    A[2][3] = 1.0
    A[3][0] = -p.kxy
    A[3][1] = -p.dxy - 2.0 * Omega_z
    A[3][2] = -p.kyy
    A[3][3] = -p.dyy
    M = [[A[i][j] * T[i] / T[j] * h for j in range(4)] + [0.0, 0.0] for i in range(4)]
    M[1][4] = T[1] / p.m * h
    M[3][5] = T[3] / p.m * h
    E = _expm_held(M)
    Phi = [[E[i][j] / T[i] * T[j] for j in range(4)] for i in range(4)]
    Gamma = [[E[i][4] / T[i], E[i][5] / T[i]] for i in range(4)]
    return Phi, Gamma


class Plant:
    """0.2.0's GyroPlantModel without noise: outputs x, vx, y, vy, ax, ay."""

    def __init__(self, p) -> None:
        self.p = p
        self.s = [0.0] * 4
        self.held = (0.0, 0.0, 0.0)
        self._key = None

    def step(self, ux: float, uy: float, Omega_z: float, h: float) -> None:
        if self._key != (Omega_z, h):
            self._maps = held_input_maps(self.p, Omega_z, h)
            self._key = (Omega_z, h)
        Phi, Gamma = self._maps
        out = []
        for i in range(4):
            acc = 0.0
            for j in range(4):
                acc += Phi[i][j] * self.s[j]
            out.append(acc + (Gamma[i][0] * ux + Gamma[i][1] * uy))
        self.s = out
        self.held = (ux, uy, Omega_z)

    def outputs(self) -> list[float]:
        p, (x, vx, y, vy), (ux, uy, Om) = self.p, self.s, self.held
        ax = -p.kxx * x - p.dxx * vx - p.kxy * y + (2.0 * Om - p.dxy) * vy
        ay = -p.kxy * x + (-p.dxy - 2.0 * Om) * vx - p.kyy * y - p.dyy * vy
        return [x, vx, y, vy, ax + ux / p.m, ay + uy / p.m]


def drive_ux(A1: float, f1: float, A2: float, f2: float, t: float) -> float:
    """0.2.0's TwoToneDrive.ux (eq. 10)."""
    return A1 * math.sin(2.0 * math.pi * f1 * t) + A2 * math.sin(2.0 * math.pi * f2 * t)


def rate_Omega_z(kind: int, offset: float, amplitude: float, frequency: float, slope: float,
                 t_start: float, t: float) -> float:
    """0.2.0's RateProfile.Omega_z."""
    if kind == 1 or t < t_start:
        return offset
    tau = t - t_start
    if kind == 2:
        return offset + amplitude
    if kind == 3:
        return offset + slope * tau
    return offset + amplitude * math.sin(2.0 * math.pi * frequency * tau)


def as_array(rows) -> np.ndarray:
    return np.array(rows, dtype=float)
