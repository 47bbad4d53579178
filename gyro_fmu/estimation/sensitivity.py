"""Exact output sensitivities of the held-input gyroscope model (the columns of eq. 7).

The sensitivity equations d/dt ds/dtheta = A ds/dtheta + (dA/dtheta) s + (dB/dtheta) u
are appended to the state and the augmented linear system is stepped with the same
exact held-input map (zero-order hold, Van Loan expm) as :mod:`gyro_fmu.model.dynamics`,
so a sensitivity is the derivative of exactly what GyroPlant computes. Used by the
observability tests, the batch identifier and the drive design (all Cramér-Rao bounds
of the package start here). docs/observability.md has the derivations and figures.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
from scipy.linalg import expm

from ..cosim.master import check_result_memory
from ..model.drive import TwoToneDrive
from ..model.dynamics import state_scaling
from ..model.measurement import UNKNOWNS, MeasuredPair
from ..model.parameters import GyroParameters, system_matrix

#: The 4 dynamic states of X (eq. 5).
STATE_NAMES: tuple[str, ...] = ("x", "vx", "y", "vy")


Tone = tuple[float, float]  # (amplitude N, frequency Hz)


def drive_tones(drive: TwoToneDrive | Sequence[Tone]) -> list[Tone]:
    """Distinct tones (amplitude N, frequency Hz) of a drive; zero tones dropped.

    Two tones at the same frequency add up to one tone.
    """
    raw = (
        [(drive.A1, drive.f1), (drive.A2, drive.f2)]
        if isinstance(drive, TwoToneDrive)
        else [(float(a), float(f)) for a, f in drive]
    )
    merged: dict[float, float] = {}
    for a, f in raw:
        if a != 0.0 and f != 0.0:
            merged[abs(f)] = merged.get(abs(f), 0.0) + (a if f > 0 else -a)
    return [(a, f) for f, a in merged.items() if a != 0.0]


def _parameter_values(p: GyroParameters, Omega_z: float) -> np.ndarray:
    return np.array([Omega_z, p.kxx, p.kyy, p.kxy, p.dxx, p.dyy, p.dxy, p.m])


def parameter_scales(p: GyroParameters, Omega_z: float) -> np.ndarray:
    """Perturbation scale c_i of each unknown: |value|, or a fallback when it is 0."""
    values = np.abs(_parameter_values(p, Omega_z))
    fallback = np.array(
        [1.0, 1.0, abs(p.kxx) or 1.0, 1e-3 * (abs(p.kxx) or 1.0), 1.0, 1.0, 1.0, 1.0]
    )
    return np.where(values > 0.0, values, fallback)


def dA_dB(p: GyroParameters) -> tuple[np.ndarray, np.ndarray]:
    """d A / d theta_i (8x4x4) and d B / d theta_i (8x4x2) of the consistent model."""
    dA = np.zeros((len(UNKNOWNS), 4, 4))
    dB = np.zeros((len(UNKNOWNS), 4, 2))
    dA[0, 1, 3], dA[0, 3, 1] = 2.0, -2.0  # Omega_z
    dA[1, 1, 0] = -1.0  # kxx
    dA[2, 3, 2] = -1.0  # kyy
    dA[3, 1, 2] = dA[3, 3, 0] = -1.0  # kxy
    dA[4, 1, 1] = -1.0  # dxx
    dA[5, 3, 3] = -1.0  # dyy
    dA[6, 1, 3] = dA[6, 3, 1] = -1.0  # dxy
    dB[7, 1, 0] = dB[7, 3, 1] = -1.0 / p.m**2  # m
    return dA, dB


def input_matrix(p: GyroParameters) -> np.ndarray:
    B = np.zeros((4, 2))
    B[1, 0] = B[3, 1] = 1.0 / p.m
    return B


@dataclass(frozen=True)
class ScaledSensitivitySystem:
    """Exact held-input step of [s, c_1 ds/dtheta_1, ..., c_8 ds/dtheta_8] (scaled)."""

    T: np.ndarray  # state scaling (4,)
    u_ref: float  # input scaling, N
    scales: np.ndarray  # c_i (8,)
    Phi: np.ndarray  # (36, 36)
    Gamma: np.ndarray  # (36, 2)

    @classmethod
    def build(cls, p: GyroParameters, Omega_z: float, h: float) -> ScaledSensitivitySystem:
        T = state_scaling(p)
        w0 = 1.0 / T[1]
        u_ref = abs(p.m) * w0**2
        scales = parameter_scales(p, Omega_z)
        A = system_matrix(p, Omega_z)
        B = input_matrix(p)
        dA, dB = dA_dB(p)
        n = 4 * (len(UNKNOWNS) + 1)

        def sc(M: np.ndarray) -> np.ndarray:
            return M * T[:, None] / T[None, :]

        Abar = np.zeros((n, n))
        Bbar = np.zeros((n, 2))
        for blk in range(len(UNKNOWNS) + 1):
            Abar[4 * blk : 4 * blk + 4, 4 * blk : 4 * blk + 4] = sc(A)
        Bbar[:4] = B * T[:, None] * u_ref
        for i in range(len(UNKNOWNS)):
            r = 4 * (i + 1)
            Abar[r : r + 4, :4] = scales[i] * sc(dA[i])
            Bbar[r : r + 4] = scales[i] * dB[i] * T[:, None] * u_ref
        M = np.zeros((n + 2, n + 2))
        M[:n, :n] = Abar * h
        M[:n, n:] = Bbar * h
        E = expm(M)
        return cls(T=T, u_ref=u_ref, scales=scales, Phi=E[:n, :n], Gamma=E[:n, n:])

    def steady_state(self, tones: Sequence[Tone], h: float) -> list[np.ndarray]:
        """Complex amplitude Sigma per tone: sigma_k = sum Im(Sigma z^k), z = e^{j w h}.

        Exact periodic solution of the sampled, held-input system driven by
        ux_k = A sin(w t_k) (discrete-time frequency response).
        """
        n = self.Phi.shape[0]
        out = []
        for a, f in tones:
            z = np.exp(1j * 2.0 * math.pi * f * h)
            rhs = self.Gamma[:, 0] * (a / self.u_ref)
            out.append(np.linalg.solve(z * np.eye(n) - self.Phi, rhs))
        return out

    def simulate(self, sigma0: np.ndarray, u: np.ndarray) -> np.ndarray:
        """sigma_k for k = 0..len(u)-1 from sigma0, with held inputs u_k = [ux, uy] (N)."""
        out = np.empty((len(u), sigma0.size))
        s = sigma0.astype(float).copy()
        Gu = (u / self.u_ref) @ self.Gamma.T
        for k in range(len(u)):
            out[k] = s
            s = self.Phi @ s + Gu[k]
        return out

    def unscale(self, sigma: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(s (..., 4), c_i ds/dtheta_i (..., 8, 4)) in SI units from scaled sigma."""
        blocks = sigma.reshape(*sigma.shape[:-1], len(UNKNOWNS) + 1, 4) / self.T
        return blocks[..., 0, :], blocks[..., 1:, :]


def window_jacobian(
    params: GyroParameters,
    drive: TwoToneDrive | Sequence[Tone],
    Omega_z: float = 1.0,
    measured_pair: int = 1,
    window: float = 0.04,
    h: float = 5e-6,
    start: Literal["steady", "rest"] = "steady",
    unknowns: Literal["parameters", "augmented"] = "parameters",
    t0: float = 0.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sampled outputs and their exact sensitivities over a window.

    Returns (z, dz, scales): z (N, 2) the measured pair at t_k = t0 + k h (SI),
    dz (N, 2, n) with dz[..., i] = c_i dz/dtheta_i for the 8 unknowns (and, with
    ``unknowns="augmented"``, then dz/ds0_j for the 4 states at t0, c_j = 1 m or
    1 m/s), and the scales c (n,). ``start="steady"``: the plant is on the
    periodic orbit of the drive; the parameter columns follow the orbit (states
    tied to the unknowns) unless ``unknowns="augmented"``, where they are
    partials at fixed initial state. ``start="rest"``: s(0) = 0 at t0 = 0.
    """
    rows = list(MeasuredPair.of(measured_pair).state_rows)
    if start not in ("steady", "rest"):
        raise ValueError(f"start must be 'steady' or 'rest', got {start!r}")
    if unknowns not in ("parameters", "augmented"):
        raise ValueError(f"unknowns must be 'parameters' or 'augmented', got {unknowns!r}")
    if not (h > 0.0 and window >= h):
        raise ValueError(f"need h > 0 and window >= h, got h={h}, window={window}")
    tones = drive_tones(drive)
    check_result_memory(window / h, 2 * 2 * 12 + 40, what=f"a window of {window:g} s at "
                        f"{h:g} s steps (its outputs and sensitivities)",
                        remedy="shorten the window (--window) or lengthen the step")
    n = round(window / h)
    model = ScaledSensitivitySystem.build(params, Omega_z, h)
    k = np.arange(n)
    if start == "rest":
        t0 = 0.0
    t = t0 + k * h
    u = np.zeros((n, 2))
    for a, f in tones:
        u[:, 0] += a * np.sin(2.0 * math.pi * f * t)
    sigma0 = np.zeros(model.Phi.shape[0])
    if start == "steady":
        for (_, f), Sig in zip(tones, model.steady_state(tones, h), strict=True):
            sigma0 += np.imag(Sig * np.exp(1j * 2.0 * math.pi * f * t0))
        if unknowns == "augmented":
            sigma0[4:] = 0.0  # partials at a fixed initial state
    sigma = model.simulate(sigma0, u)
    s, dS = model.unscale(sigma)
    z = s[:, rows]
    dz = np.moveaxis(dS[:, :, rows], 1, 2)  # (N, 2, 8)
    scales = model.scales
    if unknowns == "augmented":
        Phi4 = model.Phi[:4, :4]
        P = np.eye(4)
        dz0 = np.empty((n, 2, 4))
        for kk in range(n):
            dz0[kk] = (P / model.T[:, None] * model.T[None, :])[rows]
            P = Phi4 @ P
        dz = np.concatenate([dz, dz0], axis=2)
        scales = np.concatenate([scales, np.ones(4)])
    return z, dz, scales


def steady_state(
    params: GyroParameters,
    drive: TwoToneDrive | Sequence[Tone],
    Omega_z: float,
    t: float,
    h: float | None = 5e-6,
) -> np.ndarray:
    """State [x, x', y, y'] at time t on the periodic orbit of the drive.

    ``h`` given: the orbit of the sampled plant with the input held over steps of
    h (what the co-simulation computes, t a multiple of h); ``h=None``: the orbit
    of the continuous-time model driven by the continuous sines (the orbit the
    Lie derivatives of eq. 7 refer to). The two differ by O(w h), about 4 % at
    2500 Hz and 200 kHz, which is far larger than the 1e-4 effects of Omega_z.
    """
    tones = drive_tones(drive)
    if h is None:
        A = system_matrix(params, Omega_z)
        b = input_matrix(params)[:, 0]
        s = np.zeros(4)
        for a, f in tones:
            w = 2.0 * math.pi * f
            S = np.linalg.solve(1j * w * np.eye(4) - A, b * a)
            s += np.imag(S * np.exp(1j * w * t))
        return s
    model = ScaledSensitivitySystem.build(params, Omega_z, h)
    sigma = np.zeros(model.Phi.shape[0])
    for (_, f), Sig in zip(tones, model.steady_state(tones, h), strict=True):
        sigma += np.imag(Sig * np.exp(1j * 2.0 * math.pi * f * t))
    return model.unscale(sigma)[0]
