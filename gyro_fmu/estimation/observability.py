"""Observability of the augmented gyroscope model (US 2011/0314910 A1, eq. 7, [0029]-[0030]).

The patent augments the state with the eight constant unknowns (eq. 5), measures two
of the states (eq. 6) and argues (eq. 7) that the observability matrix is full rank
"if the control input includes at least two frequencies". Two tests, on the
consistent model of :func:`gyro_fmu.model.parameters.system_matrix`:

1. the **window test**, :func:`observability_report`: the Jacobian of the sampled
   outputs with respect to the unknowns (the square root of the empirical
   observability Gramian / Fisher information), from the exact sensitivities of
   :mod:`gyro_fmu.estimation.sensitivity`; on the periodic steady state of the drive
   (``start="steady"``) or from rest (``"rest"``, as the co-simulations start);
2. the **pointwise test** of eq. 7, :func:`pointwise_report`: the 12 x 12 Jacobian
   of the output derivatives of order 0..5 at one instant (Lie derivatives) and its
   Schur complement W_kd.

One tone identifies at most 4 combinations of the 8 unknowns in steady state, two
tones all 8 (the reading of [0030]); rank counts singular values of the
column-equilibrated Jacobian above ``rtol`` (:data:`gyro_fmu.estimation.fisher.RTOL`).
The derivation and the measured ranks and conditions are in docs/observability.md.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from ..model.drive import TwoToneDrive
from ..model.measurement import UNKNOWNS, MeasuredPair
from ..model.parameters import GyroParameters, system_matrix
from . import fisher
from .sensitivity import (
    STATE_NAMES,
    Tone,
    dA_dB,
    drive_tones,
    input_matrix,
    parameter_scales,
    steady_state,
    window_jacobian,
)

__all__ = ["AUGMENTED_NAMES", "DEFAULT_RTOL", "UNKNOWNS", "ObservabilityReport",
           "drive_tones", "lie_observability_matrix", "max_identifiable_combinations",
           "observability_report", "pointwise_report", "steady_state", "w_kd",
           "window_jacobian"]

#: The 12 components of the augmented state X (eq. 5).
AUGMENTED_NAMES: tuple[str, ...] = STATE_NAMES + UNKNOWNS


#: Default relative rank tolerance on the column-equilibrated singular values.
DEFAULT_RTOL = fisher.RTOL


def max_identifiable_combinations(n_tones: int) -> int:
    """Upper bound on the identifiable combinations of the 8 unknowns in steady state.

    Each tone contributes the complex responses Hx(jw), Hy(jw): 4 real numbers.
    """
    return min(len(UNKNOWNS), 4 * n_tones)


@dataclass(frozen=True, eq=False)
class ObservabilityReport:
    """Rank and conditioning of the observability matrix (eq. 7) of one experiment.

    ``singular_values`` are those of the weighted, column-equilibrated Jacobian,
    divided by the largest; ``condition_number`` is their max/min ratio.
    """

    names: tuple[str, ...]  #: unknowns (columns) analysed
    singular_values: tuple[float, ...]  #: descending, relative to the largest
    rank: int  #: count of singular values > rtol
    rtol: float  #: relative rank tolerance
    condition_number: float  #: sigma_max / sigma_min (inf if sigma_min == 0)
    weakest_direction: tuple[tuple[str, float], ...]  #: right singular vector, largest first
    frequencies: tuple[float, ...]  #: distinct drive frequencies, Hz
    measured_pair: int  #: 1 = positions x, y; 2 = velocities x', y'
    kind: str  #: "window/steady", "window/rest" or "pointwise"
    window: float  #: window length, s (0 for pointwise)
    h: float  #: sample / communication step, s (0 for pointwise)
    jacobian: np.ndarray = field(repr=False)  #: weighted Jacobian, columns per unit c_i
    scales: np.ndarray = field(repr=False)  #: c_i: physical size of a unit column step

    @property
    def n_tones(self) -> int:
        return len(self.frequencies)

    @property
    def full_rank(self) -> bool:
        return self.rank == len(self.names)

    def cosine(self, a: str, b: str) -> float:
        """|cos| of the angle between the sensitivity columns of unknowns a and b."""
        J = self.jacobian
        i, j = self.names.index(a), self.names.index(b)
        return float(abs(J[:, i] @ J[:, j]) / (np.linalg.norm(J[:, i]) * np.linalg.norm(J[:, j])))

    def angle_deg(self, a: str, b: str) -> float:
        """Angle (degrees, 0..90) between the sensitivity columns of a and b.

        Computed from the singular values of the two unit columns (sqrt(1 +- cos))
        to stay accurate near 0.
        """
        J = self.jacobian
        cols = J[:, [self.names.index(a), self.names.index(b)]]
        cols = cols / np.linalg.norm(cols, axis=0)
        sv = np.linalg.svd(cols, compute_uv=False)
        sin_half = sv[1] / math.sqrt(2.0)  # sqrt(1 - |cos|) / sqrt(2) = sin(angle / 2)
        return 2.0 * math.degrees(math.asin(min(1.0, sin_half)))

    def one_sigma(self, noise_fraction: float) -> dict[str, float]:
        """Cramer-Rao one-sigma bound per unknown, SI units (window tests only).

        Noise convention: white, independent per sample and channel, standard
        deviation = ``noise_fraction`` times that channel's own peak over the window.
        Unknowns absent from the report's columns are taken as known.
        """
        sig = noise_fraction * fisher.standard_deviations(self.jacobian, self.rtol) * self.scales
        return dict(zip(self.names, (float(v) for v in sig), strict=True))

    def summary(self) -> str:
        weak = ", ".join(f"{n} {c:+.3f}" for n, c in self.weakest_direction[:3])
        return (
            f"{self.kind}, tones {list(self.frequencies)} Hz, pair {self.measured_pair}: "
            f"rank {self.rank}/{len(self.names)} (rtol {self.rtol:g}), "
            f"cond {self.condition_number:.3g}, weakest [{weak}]"
        )


def _report(
    J: np.ndarray,
    names: tuple[str, ...],
    scales: np.ndarray,
    rtol: float,
    **meta: object,
) -> ObservabilityReport:
    _, sv, Vt = np.linalg.svd(fisher.equilibrated(J)[0], full_matrices=False)
    rel = sv / sv[0] if sv[0] > 0.0 else sv
    rank = int(np.sum(rel > rtol))
    cond = float(sv[0] / sv[-1]) if sv[-1] > 0.0 else math.inf
    v = Vt[-1]
    v = v * np.sign(v[np.argmax(np.abs(v))])
    order = np.argsort(-np.abs(v))
    weakest = tuple((names[i], float(v[i])) for i in order)
    return ObservabilityReport(
        names=names,
        singular_values=tuple(float(s) for s in rel),
        rank=rank,
        rtol=rtol,
        condition_number=cond,
        weakest_direction=weakest,
        jacobian=J,
        scales=scales,
        **meta,  # type: ignore[arg-type]
    )


def observability_report(
    params: GyroParameters,
    drive: TwoToneDrive | Sequence[Tone],
    Omega_z: float = 1.0,
    measured_pair: int = 1,
    window: float = 0.04,
    h: float = 5e-6,
    start: Literal["steady", "rest"] = "steady",
    unknowns: Literal["parameters", "augmented"] = "parameters",
    rtol: float = DEFAULT_RTOL,
) -> ObservabilityReport:
    """Window observability test of eq. 7 (empirical Gramian of the sampled outputs).

    See the module docstring. ``unknowns="parameters"``: the 8 unknowns
    (Omega_z, kxx, kyy, kxy, dxx, dyy, dxy, m; analogue of W_kd), expected
    rank min(8, 4 * tones) at steady state; ``"augmented"``: also the 4 initial
    states (analogue of W_o), expected 4 + that.
    """
    z, dz, scales = window_jacobian(
        params, drive, Omega_z, measured_pair, window, h, start, unknowns
    )
    peak = np.max(np.abs(z), axis=0)
    peak = np.where(peak > 0.0, peak, 1.0)
    J = (dz / peak[None, :, None]).reshape(-1, dz.shape[2])
    names = UNKNOWNS + (tuple(f"{s}0" for s in STATE_NAMES) if unknowns == "augmented" else ())
    return _report(
        J,
        names,
        scales,
        rtol,
        frequencies=tuple(f for _, f in drive_tones(drive)),
        measured_pair=measured_pair,
        kind=f"window/{start}",
        window=float(window),
        h=float(h),
    )


def _input_jet(tones: Sequence[Tone], t: float, order: int) -> np.ndarray:
    """ux^(n)(t), n = 0..order, of a sum of sines (N/s^n)."""
    out = np.zeros(order + 1)
    for a, f in tones:
        w = 2.0 * math.pi * f
        for nn in range(order + 1):
            out[nn] += a * w**nn * math.sin(w * t + nn * math.pi / 2.0)
    return out


def lie_observability_matrix(
    params: GyroParameters,
    state: Sequence[float],
    Omega_z: float,
    ux_jet: Sequence[float],
    measured_pair: int = 1,
) -> np.ndarray:
    """Pointwise observability matrix W_o of eq. 7 (12 x 12), exact, SI units.

    Row pair n (n = 0..5) is d/dX of the n-th time derivative of the measured
    pair (Lie derivative along f(X) + B u, eqs. 5-6) with the input's
    derivatives ``ux_jet`` = [ux, ux', ..., ux^(4)] (N/s^n) given; columns follow
    X = [x, x', y, y', Omega_z, kxx, kyy, kxy, dxx, dyy, dxy, m].
    """
    rows = list(MeasuredPair.of(measured_pair).state_rows)
    order = 5
    jet = np.zeros(order + 1)
    jet[: min(len(ux_jet), order + 1)] = np.asarray(ux_jet, dtype=float)[: order + 1]
    A = system_matrix(params, Omega_z)
    B = input_matrix(params)
    dA, dB = dA_dB(params)
    s = np.asarray(state, dtype=float).copy()
    dS = np.zeros((4, 12))
    dS[:, :4] = np.eye(4)
    W = np.zeros((2 * (order + 1), 12))
    for nn in range(order + 1):
        W[2 * nn : 2 * nn + 2] = dS[rows]
        u = np.array([jet[nn], 0.0])
        forcing = np.stack([dA[i] @ s + dB[i] @ u for i in range(len(UNKNOWNS))], axis=1)
        dS = A @ dS
        dS[:, 4:] += forcing
        s = A @ s + B @ u
    return W


def w_kd(W_o: np.ndarray) -> np.ndarray:
    """The 8 x 8 parameter block of eq. 7 with the state columns eliminated.

    Schur complement W22 - W21 W11^-1 W12 of W_o in its 4 + 8 partition, so that
    rank W_o = 4 + rank W_kd whenever the first 4 rows fix the state (W11 = C1).
    """
    W11, W12, W21, W22 = W_o[:4, :4], W_o[:4, 4:], W_o[4:, :4], W_o[4:, 4:]
    return W22 - W21 @ np.linalg.solve(W11, W12)


def pointwise_report(
    params: GyroParameters,
    drive: TwoToneDrive | Sequence[Tone],
    Omega_z: float = 1.0,
    measured_pair: int = 1,
    t: float = 0.0,
    state: Sequence[float] | None = None,
    rtol: float = DEFAULT_RTOL,
) -> ObservabilityReport:
    """Rank of the pointwise W_o (eq. 7) at time t; state defaults to the continuous orbit.

    Rows of derivative order n are divided by w0^n (w0 = sqrt(kxx)) and by the
    peak of the channel's value; columns are equilibrated as in the window test.
    """
    tones = drive_tones(drive)
    if state is None:
        s = steady_state(params, tones, Omega_z, t, h=None)
    else:
        s = np.asarray(state, dtype=float)
    W = lie_observability_matrix(params, s, Omega_z, _input_jet(tones, t, 5), measured_pair)
    w0 = math.sqrt(abs(params.kxx)) or 1.0
    row_scale = np.repeat(w0 ** -np.arange(6.0), 2)
    rows = list(MeasuredPair.of(measured_pair).state_rows)
    mag = np.maximum(np.abs(s[rows]), 1e-300)
    if measured_pair == 1:
        mag = np.maximum(mag, np.abs(s[[1, 3]]) / w0)
    else:
        mag = np.maximum(mag, np.abs(s[[0, 2]]) * w0)
    W = W * row_scale[:, None] / np.tile(mag, 6)[:, None]
    scales = np.concatenate([np.ones(4), parameter_scales(params, Omega_z)])
    return _report(
        W * scales[None, :],
        AUGMENTED_NAMES,
        scales,
        rtol,
        frequencies=tuple(f for _, f in tones),
        measured_pair=measured_pair,
        kind="pointwise",
        window=0.0,
        h=0.0,
    )
