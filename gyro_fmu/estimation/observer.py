"""Online state observer of the single-axis-drive gyroscope (US 2011/0314910 A1, eqs. 5-9).

The observer of eq. 8, x^' = f(x^) + B U + L C (X - X^), run as an extended Kalman
filter: the gain L is recomputed every step from the covariance of the augmented
state of eq. 5, X = [x, x', y, y', Omega_z, kxx, kyy, kxy, dxx, dyy, dxy, m], and the
measurement is the pair of eq. 9 / claim 4, positions (x, y) or velocities (x', y').

Design (each choice measured, see benchmarks/OBSERVER_NOTES.md):

- Same discretization as the plant. In co-simulation ux, uy and Omega_z are held over
  each step; over such a step the model is linear time-invariant and the plant
  (gyro_fmu.model.dynamics) integrates it exactly. The observer propagates its mean with the
  same exact map (Taylor series of expm to 1e-15, equal to the plant's step to 2e-16),
  because any mismatch in input treatment biases Omega (0.2 rad/s for a 5e-4 gain
  mismatch, docs/observability.md).
- Exact sensitivities. The Jacobian of s(t+h) with respect to the parameters and
  Omega is the Frechet derivative of expm(A h) applied to [s, 1]; from the same powers
  T_j = (A h)^j / j! it is S = h sum_{j,m} j! m! / (j+m+1)! T_j G(T_m xi) (one extra
  matmul). A plain EKF with approximate Jacobians let dxx, dyy, dxy and Omega creep
  (a plain EKF: dxy 3-15 % off after 80 ms); with exact ones and the scaling below all
  seven parameters are within 1 % in under 1 ms (noise-free).
- Scaling. Parameters are relative deviations from the initial guess, theta = theta_0 +
  scale p (scale = |theta_0|; damping coefficients share max |d_0| so a zero dyy is fine);
  the input gain b = 1/m is estimated instead of m, since the model is linear in b.
  Velocities are scaled per axis, vx / sqrt(kxx_0) and vy / sqrt(kyy_0), so that every
  entry of A h is about omega h ~ 0.1 (well-conditioned Taylor series and covariance).
- Omega model: integrated random walk (Omega, dOmega/dt) driven by white noise of
  spectral density q_Omega, so a 100 Hz sine is tracked without the lag a random walk
  has. q_Omega is the bandwidth / noise trade-off: q ~ (rms d2Omega/dt2)^2 / omega, about
  1e8 for the patent's unit 100 Hz sine; the default 1e9 leaves a factor-3 margin on the
  tracking error of that sine. Lower it for slowly varying rates and noisy signals.
- Measurement noise. Either absolute stds (sigma_z1, sigma_z2), or relative
  (noise_rel x running peak |z| of each signal: the convention of the benchmarks, noise
  std = level x that signal's own peak). Early in a run the running peak is still
  small (at t = 0 it is the noise itself) and would make R far too small; the filter
  then fits the noise and diverges (measured). Hence in relative mode R is floored by
  innov_floor x a short EWMA of the squared innovations, which in a consistent filter
  (E nu^2 = H P H' + R) stays below R once converged.
- Joseph-form updates gave identical figures; the cheaper P - K H P is the default.
- Efficiency: with constant Omega and q_Omega = 1e2, noise 1e-4, 40 ms (park-horowitz),
  the filter's sigmas are 1.1-1.3x the Cramer-Rao bound (Omega 0.037 vs 0.029 rad/s).
  Rejected alternatives: UKF (25 propagations per step: too slow), iterated EKF (the
  measurement is linear; nothing to iterate), covariance resetting (not needed once the
  sensitivities are exact).

Conventions: normalized k's in 1/s^2, d's in 1/s (parameters.py), m in kg, Omega_z in
rad/s. step(ux, uy, z1, z2, h) first corrects with the measurement at t, then
propagates to t + h with ux, uy and Omega_z held, as the plant does.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields

import numpy as np
from numba import njit

from ..model.dynamics import inf_norm_rows
from ..model.parameters import GyroParameters, check_parameters

_N_PAR = 7  # kxx, kyy, kxy, dxx, dyy, dxy, b = 1/m
_I_PAR = 4  # index of the first parameter in the filter state
_I_OM = 11  # index of Omega_z
_KMAX = 24  # most Taylor terms (||A h|| <= 0.5 needs 18)
_STEP_NORM = 0.5  # longer steps are split into equal sub-steps
_J = np.arange(_KMAX)
_FACT = np.array([math.factorial(k) for k in range(2 * _KMAX + 2)], dtype=float)
#: beta[j, m] = j! m! / (j + m + 1)!: weights of the Frechet series of expm.
_BETA = _FACT[_J][:, None] * _FACT[_J][None, :] / _FACT[_J[:, None] + _J[None, :] + 1]
_INV = 1.0 / np.arange(1, _KMAX + 1)
_STATE_VERSION = 1
#: Outputs of output_row(): state estimate, ESTIMATED, their 1-sigmas.
N_OUTPUTS = 4 + 8 + 8


# ---------------------------------------------------------------- compiled kernels
# One EKF step is ~40 small (5x5 .. 13x13) linear-algebra operations: in numpy each costs
# 1-3 us of call overhead (120 us per step, benchmarks/PERF_NOTES.md); compiled with numba
# the whole step takes a few us. The arithmetic is that of the numpy formulation it
# replaced, written as loops (no fastmath: IEEE operations, no contraction).
@njit(cache=True)
def _n_terms(norm: float) -> int:
    """Taylor terms K with norm^K / K! < 1e-15 (norm = ||A h||_inf <= 0.5)."""
    term = 1.0
    for k in range(1, _KMAX):
        term *= norm / k
        if term < 1e-15:
            return k + 1
    return _KMAX


@njit(cache=True)
def _held_step_single(xi0, Ah, h, MgT, beta, st, G, Gb, s1, Phi, S):  # pragma: no cover
    """Taylor powers st[j] = (A h)^j / j!, their sum, and the Frechet series S (see _held_step)."""
    norm = inf_norm_rows(Ah, 4, 5)
    K = _n_terms(norm)
    for j in range(K - 1):
        inv = 1.0 / (j + 1)
        for a in range(5):
            for c in range(5):
                acc = 0.0
                for b in range(5):
                    acc += st[j, a, b] * (Ah[b, c] * inv)
                st[j + 1, a, c] = acc
    for i in range(4):
        for c in range(4):
            acc = 0.0
            for j in range(K):
                acc += st[j, i, c]
            Phi[i, c] = acc
        acc = 0.0
        for c in range(5):
            e = 0.0
            for j in range(K):
                e += st[j, i, c]
            acc += e * xi0[c]
        s1[i] = acc
    # G[m] = (T_m xi0) MgT: rows 1 and 3 of dA/d(p, Omega) (T_m xi0)
    for m in range(K):
        for q in range(16):
            G[m, q] = 0.0
        for a in range(5):
            txi = 0.0
            for b in range(5):
                txi += st[m, a, b] * xi0[b]
            for q in range(16):
                G[m, q] += txi * MgT[a, q]
    for j in range(K):
        for q in range(16):
            acc = 0.0
            for m in range(K):
                acc += beta[j, m] * G[m, q]
            Gb[j, q] = acc
    for i in range(4):
        for q in range(8):
            acc = 0.0
            for j in range(K):
                acc += st[j, i, 1] * Gb[j, q] + st[j, i, 3] * Gb[j, 8 + q]
            S[i, q] = acc * h


@njit(cache=True)
def _held_step_kernel(xi0, Ah, h, MgT, beta, st, G, Gb, s1, Phi, S):  # pragma: no cover
    """s1 = s(t+h), Phi = ds1/ds, S = ds1/d(p, Omega); long steps in equal sub-steps."""
    norm = inf_norm_rows(Ah, 4, 5)
    if norm <= _STEP_NORM:
        _held_step_single(xi0, Ah, h, MgT, beta, st, G, Gb, s1, Phi, S)
        return
    nsub = math.ceil(norm / _STEP_NORM)
    Ahs = Ah / nsub
    xi = xi0.copy()
    Phi_t = np.eye(4)
    S_t = np.zeros((4, 8))
    Phi1 = np.empty((4, 4))
    S1 = np.empty((4, 8))
    s_1 = np.empty(4)
    for _ in range(nsub):
        _held_step_single(xi, Ahs, h / nsub, MgT, beta, st, G, Gb, s_1, Phi1, S1)
        S_t = Phi1 @ S_t + S1
        Phi_t = Phi1 @ Phi_t
        xi[:4] = s_1
    s1[:] = xi[:4]
    Phi[:, :] = Phi_t
    S[:, :] = S_t


@njit(cache=True)
def _rel_R(nu2, j, nu, peak, h, noise_rel, innov_floor, innov_tau):  # pragma: no cover
    """Relative-mode noise variance: (noise_rel peak)^2, floored by the innovations."""
    v2 = nu * nu
    e = nu2[j]
    e = v2 if e < 0.0 else e + min(h / innov_tau, 1.0) * (v2 - e)
    nu2[j] = e
    return max((noise_rel * peak) ** 2, innov_floor * e)


@njit(cache=True)
def _ekf_step(x, P, peak, nu2, F, Q, MgT, A, theta0, scale, hgain, i0, wx, wy,
              ux, uy, z1, z2, h, sz1, sz2, noise_rel, innov_floor, innov_tau, joseph,
              beta, st, G, Gb):  # pragma: no cover
    """Correct x, P with (z1, z2) at t, then propagate them to t + h, in place."""
    n = x.shape[0]
    i1 = i0 + 2
    g0 = hgain[0]
    g1 = hgain[1]
    # ---- correction (eq. 8: L C (X - X^), L from the covariance)
    nu0 = z1 - g0 * x[i0]
    nu1 = z2 - g1 * x[i1]
    if abs(z1) > peak[0]:
        peak[0] = abs(z1)
    if abs(z2) > peak[1]:
        peak[1] = abs(z2)
    if sz1 > 0.0:
        R0 = sz1 * sz1
    else:
        R0 = _rel_R(nu2, 0, nu0, peak[0], h, noise_rel, innov_floor, innov_tau)
    if sz2 > 0.0:
        R1 = sz2 * sz2
    else:
        R1 = _rel_R(nu2, 1, nu1, peak[1], h, noise_rel, innov_floor, innov_tau)
    a = P[i0, i0] * g0 * g0 + R0
    b_ = P[i0, i1] * g0 * g1
    c = P[i1, i0] * g0 * g1
    d = P[i1, i1] * g1 * g1 + R1
    det = a * d - b_ * c
    if det > 0.0 and a > 0.0:
        s00, s01, s10, s11 = d / det, -b_ / det, -c / det, a / det
        PHt = np.empty((n, 2))
        K = np.empty((n, 2))
        for i in range(n):
            PHt[i, 0] = P[i, i0] * g0
            PHt[i, 1] = P[i, i1] * g1
        for i in range(n):
            K[i, 0] = PHt[i, 0] * s00 + PHt[i, 1] * s10
            K[i, 1] = PHt[i, 0] * s01 + PHt[i, 1] * s11
            x[i] = x[i] + (K[i, 0] * nu0 + K[i, 1] * nu1)
        if joseph:
            IKH = np.eye(n)
            for i in range(n):
                IKH[i, i0] -= K[i, 0] * g0
                IKH[i, i1] -= K[i, 1] * g1
            KR = np.empty((n, 2))
            for i in range(n):
                KR[i, 0] = K[i, 0] * R0
                KR[i, 1] = K[i, 1] * R1
            P[:, :] = IKH @ P @ IKH.T + KR @ K.T
        else:
            for i in range(n):
                for j in range(n):
                    P[i, j] -= K[i, 0] * PHt[j, 0] + K[i, 1] * PHt[j, 1]
    # ---- propagation to t + h (eq. 5, held ux, uy, Omega_z, exact). A is eqs. 3-4 of
    # parameters.system_matrix in the filter's scaling; tests/test_observer.py holds
    # this step equal to the plant's.
    kxx = theta0[0] + scale[0] * x[4]
    kyy = theta0[1] + scale[1] * x[5]
    kxy = theta0[2] + scale[2] * x[6]
    dxx = theta0[3] + scale[3] * x[7]
    dyy = theta0[4] + scale[4] * x[8]
    dxy = theta0[5] + scale[5] * x[9]
    b = theta0[6] + scale[6] * x[10]
    Om = x[11]
    A[1, 0] = -kxx / wx
    A[1, 1] = -dxx
    A[1, 2] = -kxy / wx
    A[1, 3] = (2.0 * Om - dxy) * wy / wx
    A[1, 4] = b * ux / wx
    A[3, 0] = -kxy / wy
    A[3, 1] = -(dxy + 2.0 * Om) * wx / wy
    A[3, 2] = -kyy / wy
    A[3, 3] = -dyy
    A[3, 4] = b * uy / wy
    MgT[4, 6] = scale[6] * ux / wx
    MgT[4, 14] = scale[6] * uy / wy
    xi0 = np.ones(5)
    xi0[:4] = x[:4]
    s1 = np.empty(4)
    Phi = np.empty((4, 4))
    S = np.empty((4, 8))
    _held_step_kernel(xi0, A * h, h, MgT, beta, st, G, Gb, s1, Phi, S)
    for i in range(4):
        for j in range(4):
            F[i, j] = Phi[i, j]
        for j in range(8):
            F[i, 4 + j] = S[i, j]
    x_new = np.empty(n)
    for i in range(n):
        acc = 0.0
        for j in range(n):
            acc += F[i, j] * x[j]
        x_new[i] = acc
    x_new[:4] = s1
    x[:] = x_new
    FP = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            acc = 0.0
            for k in range(n):
                acc += F[i, k] * P[k, j]
            FP[i, j] = acc
    Pn = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            acc = 0.0
            for k in range(n):
                acc += FP[i, k] * F[j, k]
            Pn[i, j] = acc + Q[i, j]
    for i in range(n):
        for j in range(n):
            P[i, j] = (Pn[i, j] + Pn[j, i]) * 0.5


@njit(cache=True)
def _output_row(x, P, theta0, scale, Tdiag, out):  # pragma: no cover
    """[x, vx, y, vy], ESTIMATED, their 1-sigmas (m by the delta method from b = 1/m)."""
    for i in range(4):
        out[i] = x[i] / Tdiag[i]
    out[4] = x[_I_OM]
    for i in range(6):
        out[5 + i] = theta0[i] + scale[i] * x[_I_PAR + i]
    b = theta0[6] + scale[6] * x[_I_PAR + 6]
    out[11] = 1.0 / b
    out[12] = math.sqrt(max(P[_I_OM, _I_OM], 0.0))
    for i in range(6):
        out[13 + i] = math.sqrt(max(P[_I_PAR + i, _I_PAR + i], 0.0)) * scale[i]
    out[19] = math.sqrt(max(P[_I_PAR + 6, _I_PAR + 6], 0.0)) * scale[6] / (b * b)


@dataclass(frozen=True)
class ObserverTuning:
    """Tuning of GyroStateObserver; the defaults meet the issue's noise-free targets.

    Noise convention of noise_rel: white noise with std = noise_rel x the signal's peak.
    """

    noise_rel: float = 1.0e-6  #: noise std / running peak |z| (-); a floor for noise-free data
    sigma_z1: float = 0.0  #: absolute noise std of z1 (m, or m/s for velocities); > 0 overrides
    sigma_z2: float = 0.0  #: absolute noise std of z2 (m, or m/s for velocities); > 0 overrides
    innov_floor: float = 0.5  #: relative mode: R >= innov_floor x EWMA(innovation^2) (-)
    innov_tau: float = 1.0e-4  #: time constant of that innovation EWMA (s)
    q_Omega: float = 1.0e9  #: white-noise density of dOmega/dt's derivative ((rad/s^2)^2 s)
    omega_order: int = 2  #: Omega model: 1 random walk, 2 integrated RW, 3 twice integrated (-)
    q_param_rel: float = 0.0  #: random-walk density of the relative parameter deviations (1/s)
    sigma0_k_rel: float = 0.1  #: initial 1-sigma of kxx, kyy, kxy relative to the guess (-)
    sigma0_d_rel: float = 0.5  #: initial 1-sigma of dxx, dyy, dxy relative to max |d_0| (-)
    sigma0_m_rel: float = 0.1  #: initial 1-sigma of m relative to the guess (-)
    sigma0_Omega: float = 2.0  #: initial 1-sigma of Omega_z (rad/s)
    sigma0_Omega_rate: float = 1.0e3  #: initial 1-sigma of dOmega_z/dt (rad/s^2)
    sigma0_Omega_acc: float = 1.0e6  #: initial 1-sigma of d2Omega_z/dt2, order 3 only (rad/s^3)
    sigma0_position: float = 1.0e-10  #: initial 1-sigma of x and y (m)
    sigma0_velocity: float = 1.0e-6  #: initial 1-sigma of vx and vy (m/s)
    joseph: bool = False  #: Joseph-form covariance update (same figures measured, 13 us dearer)

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name in ("joseph", "omega_order"):
                continue
            if not (isinstance(v, int | float) and math.isfinite(v) and v >= 0.0):
                raise ValueError(
                    f"ObserverTuning.{f.name}={v!r} must be a finite number >= 0"
                )
        if self.omega_order not in (1, 2, 3):
            raise ValueError(
                f"ObserverTuning.omega_order={self.omega_order!r}: use 1 (random walk), "
                "2 (integrated random walk) or 3"
            )
        if self.noise_rel <= 0.0 and (self.sigma_z1 <= 0.0 or self.sigma_z2 <= 0.0):
            raise ValueError(
                f"ObserverTuning.noise_rel={self.noise_rel!r}: give noise_rel > 0 "
                "(e.g. 1e-6 for noise-free data) or both sigma_z1 and sigma_z2 > 0"
            )
        if self.innov_tau <= 0.0:
            raise ValueError(f"ObserverTuning.innov_tau={self.innov_tau!r} s must be > 0")
        for name in ("sigma0_k_rel", "sigma0_d_rel", "sigma0_m_rel", "sigma0_Omega"):
            if getattr(self, name) <= 0.0:
                raise ValueError(
                    f"ObserverTuning.{name}={getattr(self, name)!r} must be > 0: a zero "
                    "initial uncertainty freezes that estimate"
                )


class GyroStateObserver:
    """EKF form of the patent's state observer (eq. 8): Omega_z and the 7 parameters online.

    Filter state: [x, vx/wx, y, vy/wy, p_kxx, p_kyy, p_kxy, p_dxx, p_dyy, p_dxy, p_b,
    Omega_z, dOmega_z/dt (order >= 2), d2Omega_z/dt2 (order 3)], where wx = sqrt(kxx_0),
    wy = sqrt(kyy_0), theta = theta_0 + scale p and b = 1/m.
    """

    ESTIMATED: tuple[str, ...] = ("Omega_z", "kxx", "kyy", "kxy", "dxx", "dyy", "dxy", "m")

    def __init__(
        self,
        initial: GyroParameters,
        Omega_z_0: float = 0.0,
        measured_pair: int = 1,
        tuning: ObserverTuning | None = None,
    ) -> None:
        if measured_pair not in (1, 2) or isinstance(measured_pair, bool):
            raise ValueError(
                f"measured_pair={measured_pair!r} is invalid: use 1 for positions (x, y) "
                "or 2 for velocities (vx, vy) (patent claim 4)"
            )
        if not isinstance(initial, GyroParameters):
            raise ValueError(
                f"initial={initial!r} must be a GyroParameters (e.g. parameters.preset(...))"
            )
        problems = check_parameters(initial)
        if initial.kyy <= 0.0 and not problems:
            problems.append(f"kyy={initial.kyy} must be > 0")
        if problems:
            raise ValueError(
                "initial parameter guess is unusable: " + "; ".join(problems)
                + ". Give a physical guess (positive m, positive definite K)"
            )
        if not (isinstance(Omega_z_0, int | float) and math.isfinite(Omega_z_0)):
            raise ValueError(f"Omega_z_0={Omega_z_0!r} rad/s must be a finite number")
        tun = tuning if tuning is not None else ObserverTuning()
        if not isinstance(tun, ObserverTuning):
            raise ValueError(f"tuning={tun!r} must be an ObserverTuning or None")
        self.tuning = tun
        self.measured_pair = measured_pair
        self.order = int(tun.omega_order)
        self.n = 4 + _N_PAR + self.order
        wx = math.sqrt(initial.kxx)
        wy = math.sqrt(initial.kyy)
        theta0 = np.array([initial.kxx, initial.kyy, initial.kxy, initial.dxx, initial.dyy,
                           initial.dxy, 1.0 / initial.m])
        d_scale = max(abs(initial.dxx), abs(initial.dyy), abs(initial.dxy), 1e-3)
        kxy_scale = max(abs(initial.kxy), 1e-2 * math.sqrt(initial.kxx * initial.kyy))
        scale = np.array([initial.kxx, initial.kyy, kxy_scale, d_scale, d_scale, d_scale,
                          1.0 / initial.m])
        self._build(wx, wy, theta0, scale)
        xhat = np.zeros(self.n)
        xhat[_I_OM] = Omega_z_0
        sig = np.zeros(self.n)
        sig[[0, 2]] = tun.sigma0_position
        sig[1] = tun.sigma0_velocity / wx
        sig[3] = tun.sigma0_velocity / wy
        sig[4:7] = tun.sigma0_k_rel * np.abs(theta0[:3]) / scale[:3]
        sig[7:10] = tun.sigma0_d_rel
        sig[10] = tun.sigma0_m_rel
        sig[_I_OM] = tun.sigma0_Omega
        if self.order >= 2:
            sig[_I_OM + 1] = tun.sigma0_Omega_rate
        if self.order >= 3:
            sig[_I_OM + 2] = tun.sigma0_Omega_acc
        self.xhat = xhat
        self.P = np.diag(sig**2)
        self.peak = np.zeros(2)  # running peak |z1|, |z2|
        self.nu2 = np.full(2, -1.0)  # EWMA of squared innovations (< 0: not started)
        self.t = 0.0  # s since construction

    def _build(self, wx: float, wy: float, theta0: np.ndarray, scale: np.ndarray) -> None:
        """Caches that depend only on the scaling (rebuilt by set_state)."""
        self.wx, self.wy = wx, wy
        self.theta0 = theta0
        self.scale = scale
        n = self.n
        r = wy / wx
        # d(A_aug xi)/d(p, Omega): rows 1 and 3 are Mg[0] @ xi and Mg[1] @ xi, xi = [s, 1]
        Mg = np.zeros((2, 8, 5))
        Mg[0, 0, 0] = -scale[0] / wx
        Mg[1, 1, 2] = -scale[1] / wy
        Mg[0, 2, 2] = -scale[2] / wx
        Mg[1, 2, 0] = -scale[2] / wy
        Mg[0, 3, 1] = -scale[3]
        Mg[1, 4, 3] = -scale[4]
        Mg[0, 5, 3] = -scale[5] * r
        Mg[1, 5, 1] = -scale[5] / r
        Mg[0, 7, 3] = 2.0 * r
        Mg[1, 7, 1] = -2.0 / r
        self._MgT = Mg.reshape(16, 5).T.copy()  # entries [4, 6], [4, 14] (input gain) per step
        self._Aaug = np.zeros((5, 5))
        self._Aaug[0, 1] = wx
        self._Aaug[2, 3] = wy
        self._stack = np.zeros((_KMAX, 5, 5))
        self._stack[0] = np.eye(5)
        self._F = np.eye(n)
        self._Q = np.zeros((n, n))
        self._h_cached = -1.0
        self._Tdiag = np.array([1.0, 1.0 / wx, 1.0, 1.0 / wy])
        if self.measured_pair == 1:
            self._hsl = slice(0, 3, 2)
            self._hgain = np.array([1.0, 1.0])
        else:
            self._hsl = slice(1, 4, 2)
            self._hgain = np.array([wx, wy])
        self._hg = tuple(self._hgain.tolist())
        self._i0 = self._hsl.start
        self._G = np.zeros((_KMAX, 16))
        self._Gb = np.zeros((_KMAX, 16))
        self._out = np.empty(N_OUTPUTS)
        tun = self.tuning
        self._kargs = (float(tun.sigma_z1), float(tun.sigma_z2), float(tun.noise_rel),
                       float(tun.innov_floor), float(tun.innov_tau), bool(tun.joseph))

    # ------------------------------------------------------------------ internals
    def _set_h(self, h: float) -> None:
        """Omega-model transition and process noise of a step h (cached: h rarely changes)."""
        tun = self.tuning
        n, r = self.n, self.order
        F = self._F
        Q = np.zeros((n, n))
        for a in range(r):
            for c in range(a + 1, r):
                F[_I_OM + a, _I_OM + c] = h ** (c - a) / math.factorial(c - a)
        for a in range(r):  # white noise on the r-th derivative of Omega
            for c in range(r):
                pa, pc = r - 1 - a, r - 1 - c
                Q[_I_OM + a, _I_OM + c] = tun.q_Omega * h ** (pa + pc + 1) / (
                    math.factorial(pa) * math.factorial(pc) * (pa + pc + 1))
        for i in range(_N_PAR):
            Q[_I_PAR + i, _I_PAR + i] = tun.q_param_rel * h
        self._Q = Q
        self._h_cached = h

    def _held_step(self, xi0: np.ndarray, Ah: np.ndarray, h: float
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One exact held-input step (eq. 5): s(t+h), Phi = ds+/ds, S = ds+/d(p, Omega).

        Taylor powers T_j = (A h)^j / j! give Phi_aug = sum T_j = expm(A_aug h) and the
        Frechet series S = h sum_{j,m} j! m! / (j+m+1)! T_j G(T_m xi0), G(xi) = dA/dtheta xi.
        Steps with ||A h|| > 0.5 are split into equal sub-steps (Jacobians chained).
        The same kernel runs inside step().
        """
        s1, Phi, S = np.empty(4), np.empty((4, 4)), np.empty((4, 8))
        _held_step_kernel(np.ascontiguousarray(xi0, dtype=float),
                          np.ascontiguousarray(Ah, dtype=float), float(h), self._MgT, _BETA,
                          self._stack, self._G, self._Gb, s1, Phi, S)
        return s1, Phi, S

    # ------------------------------------------------------------------ API
    def step(self, ux: float, uy: float, z1: float, z2: float, h: float) -> None:
        """Correct with the measured pair (z1, z2) at t, then propagate to t + h.

        ux, uy (N) are the drive force at t, held over [t, t+h] as the plant holds it;
        Omega_z is likewise held at its estimate over the step. h (s) may vary.
        """
        if not (h > 0.0 and math.isfinite(h)):
            raise ValueError(f"step h={h!r} s must be finite and > 0")
        if not (math.isfinite(ux) and math.isfinite(uy) and math.isfinite(z1)
                and math.isfinite(z2)):
            raise ValueError(
                f"non-finite input ux={ux!r}, uy={uy!r}, z1={z1!r}, z2={z2!r}: "
                "pass finite forces (N) and measurements"
            )
        if h != self._h_cached:
            self._set_h(h)
        sz1, sz2, noise_rel, innov_floor, innov_tau, joseph = self._kargs
        _ekf_step(self.xhat, self.P, self.peak, self.nu2, self._F, self._Q, self._MgT,
                  self._Aaug, self.theta0, self.scale, self._hgain, self._i0, self.wx, self.wy,
                  float(ux), float(uy), float(z1), float(z2), float(h), sz1, sz2, noise_rel,
                  innov_floor, innov_tau, joseph, _BETA, self._stack, self._G, self._Gb)
        self.t += h

    def output_row(self) -> list[float]:
        """[x, vx, y, vy] (m, m/s), ESTIMATED, then their 1-sigmas: what the FMU publishes."""
        _output_row(self.xhat, self.P, self.theta0, self.scale, self._Tdiag, self._out)
        return self._out.tolist()

    def state_estimate(self) -> np.ndarray:
        """[x, vx, y, vy] at the current time (m, m/s)."""
        return np.array(self.output_row()[:4])

    def _theta(self) -> np.ndarray:
        return self.theta0 + self.scale * self.xhat[_I_PAR:_I_PAR + _N_PAR]

    def estimates(self) -> dict[str, float]:
        """Current estimates of ESTIMATED (k's 1/s^2, d's 1/s, m kg, Omega_z rad/s)."""
        return dict(zip(self.ESTIMATED, self.output_row()[4:12], strict=True))

    def sigmas(self) -> dict[str, float]:
        """1-sigma of each ESTIMATED from the covariance (m by the delta method from 1/m)."""
        return dict(zip(self.ESTIMATED, self.output_row()[12:20], strict=True))

    def get_state(self) -> dict:
        """Everything internal as plain floats / lists (JSON-serializable)."""
        return {
            "version": _STATE_VERSION,
            "measured_pair": self.measured_pair,
            "tuning": asdict(self.tuning),
            "wx": self.wx,
            "wy": self.wy,
            "theta0": self.theta0.tolist(),
            "scale": self.scale.tolist(),
            "xhat": self.xhat.tolist(),
            "P": self.P.tolist(),
            "peak": self.peak.tolist(),
            "nu2": self.nu2.tolist(),
            "t": self.t,
        }

    def set_state(self, state: dict) -> None:
        """Restore a get_state() snapshot (also into an observer built differently)."""
        if not isinstance(state, dict) or state.get("version") != _STATE_VERSION:
            raise ValueError(
                f"observer state must be a dict from get_state() with version "
                f"{_STATE_VERSION}; got {type(state).__name__} "
                f"version {state.get('version') if isinstance(state, dict) else None!r}"
            )
        tuning = ObserverTuning(**state["tuning"])
        n = 4 + _N_PAR + tuning.omega_order
        xhat = np.array(state["xhat"], dtype=float)
        P = np.array(state["P"], dtype=float)
        if xhat.shape != (n,) or P.shape != (n, n):
            raise ValueError(
                f"observer state has xhat {xhat.shape} and P {P.shape}; expected ({n},) and "
                f"({n}, {n}) for omega_order={tuning.omega_order}"
            )
        self.tuning = tuning
        self.measured_pair = int(state["measured_pair"])
        self.order = tuning.omega_order
        self.n = n
        self._build(float(state["wx"]), float(state["wy"]),
                    np.array(state["theta0"], dtype=float), np.array(state["scale"], dtype=float))
        self.xhat = xhat
        self.P = P
        self.peak = np.array(state["peak"], dtype=float)
        self.nu2 = np.array(state["nu2"], dtype=float)
        self.t = float(state["t"])
