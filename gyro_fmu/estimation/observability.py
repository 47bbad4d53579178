"""Observability of the augmented gyroscope model (US 2011/0314910 A1, eq. 7, [0029]-[0030]).

The patent augments the state with the eight constant unknowns,
X = [x, x', y, y', Omega_z, kxx, kyy, kxy, dxx, dyy, dxy, m] (eq. 5), measures
two of the states (eq. 6; here ``measured_pair`` 1 = positions x, y, 2 =
velocities x', y') and argues (eq. 7) that the observability matrix
W_o = [[C1, 0], [0, W_kd]] is full rank "if the control input includes at least
two frequencies". The printed eq. 7 is schematic (its C1 drops the damping terms,
the off-diagonal blocks are not zero, W_kd's entries have typos); this module
evaluates the exact quantities of the consistent model of
:func:`gyro_fmu.model.parameters.system_matrix`.

Two tests are implemented.

1. **Window test (the informative one)**, :func:`observability_report`: the
   Jacobian of the sampled outputs z_k, k = 0..N-1 (N = window / h) with respect
   to the unknowns, i.e. the square root of the empirical observability Gramian
   / Fisher information. Sensitivities are exact: the sensitivity equations
   d/dt ds/dtheta = A ds/dtheta + (dA/dtheta) s + (dB/dtheta) u are appended to
   the state and the augmented linear system is stepped with the same exact
   held-input (zero-order hold, Van Loan expm) map as
   :mod:`gyro_fmu.model.dynamics`, so the result is the derivative of exactly what the
   plant FMU computes. ``unknowns="parameters"`` analyses the 8 unknowns with
   the trajectory determined by them (the analogue of W_kd);
   ``unknowns="augmented"`` adds the 4 initial states of the window (the
   analogue of the full 12 x 12 W_o).

   ``start="steady"`` (default) places the window on the periodic steady state
   of the drive (computed in closed form from the discrete-time frequency
   response of the held-input map); ``start="rest"`` starts the plant from
   rest at t = 0, as the co-simulations do.

2. **Pointwise test** of eq. 7, :func:`lie_observability_matrix` /
   :func:`pointwise_report`: the 12 x 12 Jacobian of the output derivatives of
   order 0..5 with respect to X at one instant (Lie derivatives along
   f(X) + B u, with the known input's time derivatives), and its 8 x 8 Schur
   complement W_kd (the parameter block after eliminating the 4 state columns;
   rank W_o = 4 + rank W_kd when the first 4 rows determine the state).

What the numbers show, and why. In periodic steady state a tone of frequency
w makes x and y single sinusoids: the data are then fully described by the
complex frequency responses Hx(jw), Hy(jw), i.e. 4 real numbers, whatever the
window length. With transfer functions
Hx = (s^2 + dyy s + kyy) / (m Delta), Hy = -(kxy + (dxy + 2 Omega_z) s) / (m Delta),
Delta = det(s^2 I + (D + G) s + K), G = [[0, -2 Omega_z], [2 Omega_z, 0]],
at most **4 combinations** of the 8 unknowns are identifiable from one tone
(rank 4 of 8; 8 of 12 with the initial state), and 4 per distinct tone in
general, so two tones give 8 numbers for 8 unknowns: **rank 8** (12 of 12).
This is the correct reading of [0030]: on the steady orbit of one tone
x'' = -w^2 x, x^(4) = w^4 x, ... so columns of W_kd built from x, x'', x^(4)
are collinear. The pointwise test agrees *on the steady orbit* of the
continuous sines (one tone: rank 8 of 12), but at a state carrying a transient
(e.g. the plant started from rest; the free modes decay only at about
dxx/2 = 5 1/s) the free oscillations at the natural frequencies act as extra
tones and even one tone gives full rank; the window test with
``start="rest"`` shows the same.

Two tones are full rank but not necessarily well conditioned: Omega_z enters
Hx only through 4 Omega_z^2 in Delta (so x is blind to it to first order) and
Hy through dxy + 2 Omega_z; separating Omega_z from dxy relies on the weaker
Delta terms (dDelta/ddxy = -2 s (kxy + dxy s) versus dDelta/dOmega_z =
8 Omega_z s^2). For park-horowitz the weakest direction is essentially
(Omega_z, dxy), whose sensitivity columns are 14 degrees apart
(:meth:`ObservabilityReport.angle_deg`); for Table 1 corrected they are 60
degrees apart and the weakest direction is (m, kxx, kyy).

Conventions. Each output channel is divided by its own peak over the window
(noise proportional to each signal's own peak, the convention of
:meth:`ObservabilityReport.one_sigma`); each unknown's column is then scaled
to unit norm (column equilibration), so rank and condition number do not
depend on units or nominal values. Rank counts singular values above
``rtol`` times the largest (default ``DEFAULT_RTOL`` = 1e-8: exact rank
deficiencies come out below 1e-10 in the window test and 1e-15 pointwise,
the weakest genuine directions of the presets above 1e-5).

Measured (Omega_z = 1 rad/s, positions, 40 ms at h = 5 us, default drive
2500 + 1200 Hz with PRESET_DRIVE_AMPLITUDE, 8 unknowns):

=======================  ===========  ======================  =================
preset                   drive        steady: rank, cond      rest: rank, cond
=======================  ===========  ======================  =================
park-horowitz            two tones    8, 561                  8, 361
park-horowitz            2500 Hz      4, 2.6e14 (deficient)   8, 335
patent-table1-corrected  two tones    8, 10.4                 8, 290
patent-table1-corrected  2500 Hz      4, 5.8e13 (deficient)   8, 332
=======================  ===========  ======================  =================

With ``start="rest"`` the Cramer-Rao bounds at noise 1e-4 of each channel's
peak reproduce FIELD-NOTES (Omega_z 0.029 rad/s, dxy 0.052 1/s for
park-horowitz; 0.033 and 0.059 for Table 1 corrected); on the steady orbit
park-horowitz gives Omega_z 0.62 rad/s: most of its information on Omega_z is
in the free transient at the natural frequencies, not in the off-resonance tones.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from scipy.linalg import expm

from ..model.drive import TwoToneDrive
from ..model.dynamics import state_scaling
from ..model.parameters import GyroParameters, system_matrix

#: The 4 dynamic states of X (eq. 5).
STATE_NAMES: tuple[str, ...] = ("x", "vx", "y", "vy")
#: The 8 constant unknowns of X, in the patent's order (eq. 5).
UNKNOWN_NAMES: tuple[str, ...] = ("Omega_z", "kxx", "kyy", "kxy", "dxx", "dyy", "dxy", "m")
#: The 12 components of the augmented state X (eq. 5).
AUGMENTED_NAMES: tuple[str, ...] = STATE_NAMES + UNKNOWN_NAMES
#: Default relative rank tolerance on the column-equilibrated singular values.
DEFAULT_RTOL = 1e-8

_MEASURED_ROWS = {1: (0, 2), 2: (1, 3)}
_N_PAR = len(UNKNOWN_NAMES)

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


def max_identifiable_combinations(n_tones: int) -> int:
    """Upper bound on the identifiable combinations of the 8 unknowns in steady state.

    Each tone contributes the complex responses Hx(jw), Hy(jw): 4 real numbers.
    """
    return min(_N_PAR, 4 * n_tones)


def _parameter_values(p: GyroParameters, Omega_z: float) -> np.ndarray:
    return np.array([Omega_z, p.kxx, p.kyy, p.kxy, p.dxx, p.dyy, p.dxy, p.m])


def _parameter_scales(p: GyroParameters, Omega_z: float) -> np.ndarray:
    """Perturbation scale c_i of each unknown: |value|, or a fallback when it is 0."""
    values = np.abs(_parameter_values(p, Omega_z))
    fallback = np.array(
        [1.0, 1.0, abs(p.kxx) or 1.0, 1e-3 * (abs(p.kxx) or 1.0), 1.0, 1.0, 1.0, 1.0]
    )
    return np.where(values > 0.0, values, fallback)


def _dA_dB(p: GyroParameters) -> tuple[np.ndarray, np.ndarray]:
    """d A / d theta_i (8x4x4) and d B / d theta_i (8x4x2) of the consistent model."""
    dA = np.zeros((_N_PAR, 4, 4))
    dB = np.zeros((_N_PAR, 4, 2))
    dA[0, 1, 3], dA[0, 3, 1] = 2.0, -2.0  # Omega_z
    dA[1, 1, 0] = -1.0  # kxx
    dA[2, 3, 2] = -1.0  # kyy
    dA[3, 1, 2] = dA[3, 3, 0] = -1.0  # kxy
    dA[4, 1, 1] = -1.0  # dxx
    dA[5, 3, 3] = -1.0  # dyy
    dA[6, 1, 3] = dA[6, 3, 1] = -1.0  # dxy
    dB[7, 1, 0] = dB[7, 3, 1] = -1.0 / p.m**2  # m
    return dA, dB


def _input_matrix(p: GyroParameters) -> np.ndarray:
    B = np.zeros((4, 2))
    B[1, 0] = B[3, 1] = 1.0 / p.m
    return B


@dataclass(frozen=True)
class _ScaledSensitivitySystem:
    """Exact held-input step of [s, c_1 ds/dtheta_1, ..., c_8 ds/dtheta_8] (scaled)."""

    T: np.ndarray  # state scaling (4,)
    u_ref: float  # input scaling, N
    scales: np.ndarray  # c_i (8,)
    Phi: np.ndarray  # (36, 36)
    Gamma: np.ndarray  # (36, 2)

    @classmethod
    def build(cls, p: GyroParameters, Omega_z: float, h: float) -> _ScaledSensitivitySystem:
        T = state_scaling(p)
        w0 = 1.0 / T[1]
        u_ref = abs(p.m) * w0**2
        scales = _parameter_scales(p, Omega_z)
        A = system_matrix(p, Omega_z)
        B = _input_matrix(p)
        dA, dB = _dA_dB(p)
        n = 4 * (_N_PAR + 1)

        def sc(M: np.ndarray) -> np.ndarray:
            return M * T[:, None] / T[None, :]

        Abar = np.zeros((n, n))
        Bbar = np.zeros((n, 2))
        for blk in range(_N_PAR + 1):
            Abar[4 * blk : 4 * blk + 4, 4 * blk : 4 * blk + 4] = sc(A)
        Bbar[:4] = B * T[:, None] * u_ref
        for i in range(_N_PAR):
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
        blocks = sigma.reshape(*sigma.shape[:-1], _N_PAR + 1, 4) / self.T
        return blocks[..., 0, :], blocks[..., 1:, :]


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
        J = self.jacobian
        norms = np.linalg.norm(J, axis=0)
        norms = np.where(norms > 0.0, norms, 1.0)
        _, sv, Vt = np.linalg.svd(J / norms, full_matrices=False)
        keep = sv > self.rtol * sv[0]
        # covariance of the equilibrated unknowns restricted to the observable subspace
        V = Vt[keep].T
        var = (V**2) @ (1.0 / sv[keep] ** 2)
        # an unknown with a component in the unobservable subspace has no finite bound
        null = Vt[~keep].T
        unobservable = np.sum(null**2, axis=1) > 1e-12 if null.size else np.zeros(len(sv), bool)
        sig = noise_fraction * np.sqrt(var) / norms * self.scales
        sig = np.where(unobservable, math.inf, sig)
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
    norms = np.linalg.norm(J, axis=0)
    norms = np.where(norms > 0.0, norms, 1.0)
    _, sv, Vt = np.linalg.svd(J / norms, full_matrices=False)
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
    if measured_pair not in _MEASURED_ROWS:
        raise ValueError(f"measured_pair must be 1 (x, y) or 2 (x', y'), got {measured_pair!r}")
    if start not in ("steady", "rest"):
        raise ValueError(f"start must be 'steady' or 'rest', got {start!r}")
    if unknowns not in ("parameters", "augmented"):
        raise ValueError(f"unknowns must be 'parameters' or 'augmented', got {unknowns!r}")
    if not (h > 0.0 and window >= h):
        raise ValueError(f"need h > 0 and window >= h, got h={h}, window={window}")
    tones = drive_tones(drive)
    n = round(window / h)
    model = _ScaledSensitivitySystem.build(params, Omega_z, h)
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
    rows = list(_MEASURED_ROWS[measured_pair])
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
    names = UNKNOWN_NAMES + (tuple(f"{s}0" for s in STATE_NAMES) if unknowns == "augmented" else ())
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
    if measured_pair not in _MEASURED_ROWS:
        raise ValueError(f"measured_pair must be 1 or 2, got {measured_pair!r}")
    rows = list(_MEASURED_ROWS[measured_pair])
    order = 5
    jet = np.zeros(order + 1)
    jet[: min(len(ux_jet), order + 1)] = np.asarray(ux_jet, dtype=float)[: order + 1]
    A = system_matrix(params, Omega_z)
    B = _input_matrix(params)
    dA, dB = _dA_dB(params)
    s = np.asarray(state, dtype=float).copy()
    dS = np.zeros((4, 12))
    dS[:, :4] = np.eye(4)
    W = np.zeros((2 * (order + 1), 12))
    for nn in range(order + 1):
        W[2 * nn : 2 * nn + 2] = dS[rows]
        u = np.array([jet[nn], 0.0])
        forcing = np.stack([dA[i] @ s + dB[i] @ u for i in range(_N_PAR)], axis=1)
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
        b = _input_matrix(params)[:, 0]
        s = np.zeros(4)
        for a, f in tones:
            w = 2.0 * math.pi * f
            S = np.linalg.solve(1j * w * np.eye(4) - A, b * a)
            s += np.imag(S * np.exp(1j * w * t))
        return s
    model = _ScaledSensitivitySystem.build(params, Omega_z, h)
    sigma = np.zeros(model.Phi.shape[0])
    for (_, f), Sig in zip(tones, model.steady_state(tones, h), strict=True):
        sigma += np.imag(Sig * np.exp(1j * 2.0 * math.pi * f * t))
    return model.unscale(sigma)[0]


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
    rows = list(_MEASURED_ROWS[measured_pair])
    mag = np.maximum(np.abs(s[rows]), 1e-300)
    if measured_pair == 1:
        mag = np.maximum(mag, np.abs(s[[1, 3]]) / w0)
    else:
        mag = np.maximum(mag, np.abs(s[[0, 2]]) * w0)
    W = W * row_scale[:, None] / np.tile(mag, 6)[:, None]
    scales = np.concatenate([np.ones(4), _parameter_scales(params, Omega_z)])
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
