"""Compiled kernels of GyroStateObserver (US 2011/0314910 A1, eqs. 5-9).

- held_step: one exact held-input step of the augmented model (eq. 5) with the exact
  sensitivities of the new state to the parameters and Omega_z.
- noise_variances, correct_with, monitor_innovations: the measurement update of eq. 8,
  x^ += L (Z - C x^), L from the covariance, and what the monitor records of it.
- linearize, predict_about: propagation of x^ and P to t + h with ux, uy and Omega_z
  held, about a given estimate (the rate models of observer_rate share one).

The filter works in a scaled state (see docs/observer-design.md); the constant data of
one observer are an ObserverModel, its noise settings a NoiseModel. One EKF step is
~40 small linear-algebra operations, written as loops because numpy's per-call overhead
would cost 120 us per step; IEEE arithmetic throughout (no fastmath).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from .dynamics import inf_norm_rows, system_matrix_of

N_PAR = 7  #: kxx, kyy, kxy, dxx, dyy, dxy, b = 1/m
I_PAR = 4  #: index of the first parameter in the filter state
I_OM = 11  #: index of Omega_z in the filter state
KMAX = 24  #: most Taylor terms (||A h|| <= 0.5 needs 18)
_STEP_NORM = 0.5  # longer steps are split into equal sub-steps
#: Monitor accumulators and results (the observer's `mon` array).
(M_NIS, M_COUNT, M_STATUS, M_CAUSE, M_WHICH, M_VALUE, M_BLOCK, M_LAST_NIS, M_LAST_REL, M_PREV,
 M_AC, M_SQ, M_LAST_CORR) = (0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 11, 13, 15)
N_MON = 16  #: M_PREV, M_AC, M_SQ: two entries each (z1, z2)
#: Monitor verdicts (observer_monitor.check): 0 ok, 1 warning, >= 2 lost, by cause.
C_OK, C_WARN, C_NONFINITE, C_NOT_SPD, C_BOUNDS, C_INNOVATIONS = range(6)
_J = np.arange(KMAX)
_FACT = np.array([math.factorial(k) for k in range(2 * KMAX + 2)], dtype=float)
#: BETA[j, m] = j! m! / (j + m + 1)!: weights of the Frechet series of expm.
BETA = _FACT[_J][:, None] * _FACT[_J][None, :] / _FACT[_J[:, None] + _J[None, :] + 1]


class ObserverModel(NamedTuple):
    """Constant data of one observer and its scratch arrays (built by GyroStateObserver).

    Filter state x = [x, vx/wx, y, vy/wy, p (7), Omega_z, its derivatives]; the
    parameters are theta = theta0 + scale p with theta = [kxx, kyy, kxy, dxx, dyy, dxy, 1/m].
    """

    theta0: np.ndarray  #: initial guess of theta (1/s^2, 1/s, 1/kg)
    scale: np.ndarray  #: scale of each parameter deviation (units of theta)
    wx: float  #: sqrt(kxx_0), rad/s: vx is scaled by 1/wx
    wy: float  #: sqrt(kyy_0), rad/s: vy is scaled by 1/wy
    i0: int  #: filter-state row of z1 (0: positions x, y; 1: velocities); z2 is row i0 + 2
    hgain: np.ndarray  #: z = hgain * (x[i0], x[i0 + 2]): [1, 1] or [wx, wy]
    A: np.ndarray  #: 5x5 scratch: A_aug of [s, 1] in the filter's scaling
    MgT: np.ndarray  #: 5x16 d(A_aug xi)/d(p, Omega_z) rows 1 and 3; [4, 6], [4, 14] per step
    stack: np.ndarray  #: KMAX x 5 x 5 scratch, stack[0] = I: Taylor powers (A h)^j / j!
    G: np.ndarray  #: KMAX x 16 scratch of the Frechet series
    Gb: np.ndarray  #: KMAX x 16 scratch of the Frechet series


class NoiseModel(NamedTuple):
    """Measurement-noise settings (ObserverTuning): absolute stds, or relative mode."""

    sigma_z1: float  #: > 0: std of z1; else relative mode
    sigma_z2: float  #: > 0: std of z2; else relative mode
    noise_rel: float  #: relative mode: std = noise_rel x running peak |z|
    innov_floor: float  #: relative mode: R >= innov_floor x EWMA(innovation^2)
    innov_tau: float  #: time constant of that EWMA, s
    joseph: bool  #: Joseph-form covariance update


@njit(cache=True)
def _n_terms(norm: float) -> int:
    """Taylor terms K with norm^K / K! < 1e-15 (norm = ||A h||_inf <= 0.5)."""
    term = 1.0
    for k in range(1, KMAX):
        term *= norm / k
        if term < 1e-15:
            return k + 1
    return KMAX


@njit(cache=True)
def _held_step_single(xi0, Ah, h, MgT, beta, st, G, Gb, s1, Phi, S):  # pragma: no cover
    """Taylor powers st[j] = (A h)^j / j!, their sum, and the Frechet series S."""
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
def _held_step_split(xi0, Ah, h, MgT, beta, st, G, Gb, s1, Phi, S):  # pragma: no cover
    """_held_step_single, with steps of ||A h|| > 0.5 in equal sub-steps (Jacobians chained)."""
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
        S_n = np.empty((4, 8))
        P_n = np.empty((4, 4))
        for i in range(4):
            for q in range(8):
                acc = 0.0
                for c in range(4):
                    acc += Phi1[i, c] * S_t[c, q]
                S_n[i, q] = acc + S1[i, q]
            for q in range(4):
                acc = 0.0
                for c in range(4):
                    acc += Phi1[i, c] * Phi_t[c, q]
                P_n[i, q] = acc
        S_t = S_n
        Phi_t = P_n
        xi[:4] = s_1
    s1[:] = xi[:4]
    Phi[:, :] = Phi_t
    S[:, :] = S_t


@njit(cache=True)
def held_step(model, theta, Omega_z, s, ux, uy, h):  # pragma: no cover
    """One exact held-input step of the scaled plant state s (eq. 5, as the plant steps).

    theta = [kxx, kyy, kxy, dxx, dyy, dxy, 1/m], Omega_z, ux, uy held over h. Returns
    (s(t+h), Phi = ds(t+h)/ds, S = ds(t+h)/d(p, Omega_z)), 4, 4x4 and 4x8, in the
    filter's scaling. From the Taylor powers T_j = (A h)^j / j! of A_aug (the system
    matrix with the input column) Phi_aug = sum T_j = expm(A_aug h), and S is the
    Frechet series h sum_{j,m} j! m! / (j+m+1)! T_j G(T_m xi0) with xi0 = [s, 1].
    """
    wx = model.wx
    wy = model.wy
    b = theta[6]
    Ap = system_matrix_of(theta[0], theta[1], theta[2], theta[3], theta[4], theta[5], Omega_z)
    A = model.A  # rows 0 and 2 ([0, 1] = wx, [2, 3] = wy) are constant
    A[1, 0] = Ap[1, 0] / wx
    A[1, 1] = Ap[1, 1]
    A[1, 2] = Ap[1, 2] / wx
    A[1, 3] = Ap[1, 3] * wy / wx
    A[1, 4] = b * ux / wx
    A[3, 0] = Ap[3, 0] / wy
    A[3, 1] = Ap[3, 1] * wx / wy
    A[3, 2] = Ap[3, 2] / wy
    A[3, 3] = Ap[3, 3]
    A[3, 4] = b * uy / wy
    MgT = model.MgT
    MgT[4, 6] = model.scale[6] * ux / wx
    MgT[4, 14] = model.scale[6] * uy / wy
    xi0 = np.ones(5)
    xi0[:4] = s
    s1 = np.empty(4)
    Phi = np.empty((4, 4))
    S = np.empty((4, 8))
    _held_step_split(xi0, A * h, h, MgT, BETA, model.stack, model.G, model.Gb, s1, Phi, S)
    return s1, Phi, S


@njit(cache=True)
def _rel_R(nu2, j, nu, peak, w, noise_rel, innov_floor):  # pragma: no cover
    """Relative-mode noise variances (the gain's, the covariance's): (noise_rel peak)^2,
    floored by the innovations' EWMA; the covariance's is the larger of that and the same
    EWMA started from 0 over the weight it has taken in (nu2[2 + j] / nu2[4])."""
    v2 = nu * nu
    e = nu2[j]
    e = v2 if e < 0.0 else e + w * (v2 - e)
    nu2[j] = e
    nu2[2 + j] += w * (v2 - nu2[2 + j])
    R = max((noise_rel * peak) ** 2, innov_floor * e)
    mass = nu2[4] + w * (1.0 - nu2[4])
    return R, max(R, innov_floor * nu2[2 + j] / mass)


@njit(cache=True)
def noise_variances(model, noise, x, peak, nu2, z1, z2, h):  # pragma: no cover
    """Noise variances of the measured pair at t, the gain's (R0, R1) and the
    covariance's (Rc0, Rc1), and the innovations of x.

    x is the (combined) prediction; peak (running |z|) and nu2 (the innovation EWMA, < 0
    before the first, [2:4] the same started from 0, [4] the weight those took in) are
    updated for the relative noise mode; h (s) is the step that follows, the EWMA's time
    base. Returns (R0, R1, Rc0, Rc1, nu0, nu1).
    """
    i0 = model.i0
    nu0 = z1 - model.hgain[0] * x[i0]
    nu1 = z2 - model.hgain[1] * x[i0 + 2]
    if abs(z1) > peak[0]:
        peak[0] = abs(z1)
    if abs(z2) > peak[1]:
        peak[1] = abs(z2)
    w = min(h / noise.innov_tau, 1.0)
    if noise.sigma_z1 > 0.0:
        R0 = Rc0 = noise.sigma_z1 * noise.sigma_z1
    else:
        R0, Rc0 = _rel_R(nu2, 0, nu0, peak[0], w, noise.noise_rel, noise.innov_floor)
    if noise.sigma_z2 > 0.0:
        R1 = Rc1 = noise.sigma_z2 * noise.sigma_z2
    else:
        R1, Rc1 = _rel_R(nu2, 1, nu1, peak[1], w, noise.noise_rel, noise.innov_floor)
    if not (noise.sigma_z1 > 0.0 and noise.sigma_z2 > 0.0):
        nu2[4] += w * (1.0 - nu2[4])
    return R0, R1, Rc0, Rc1, nu0, nu1


@njit(cache=True)
def correct_with(model, joseph, x, P, z1, z2, R0, R1, Rc0, Rc1):  # pragma: no cover
    """Measurement update (eq. 8) of one filter's x, P in place, noise variances given.

    Returns (NIS, log det S) of its innovation nu = z - H x (S = H P H' + R, 2 dof): the
    log-likelihood of the measurement under this filter is -(NIS + log det S)/2 - log 2 pi.
    NIS < 0: no update (S singular: nothing to learn).
    """
    n = x.shape[0]
    i0 = model.i0
    i1 = i0 + 2
    g0 = model.hgain[0]
    g1 = model.hgain[1]
    nu0 = z1 - g0 * x[i0]
    nu1 = z2 - g1 * x[i1]
    a = P[i0, i0] * g0 * g0 + R0
    b_ = P[i0, i1] * g0 * g1
    c = P[i1, i0] * g0 * g1
    d = P[i1, i1] * g1 * g1 + R1
    det = a * d - b_ * c
    if not (det > 0.0 and a > 0.0):
        return -1.0, 0.0
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
    if joseph:  # (I - K H) P (I - K H)' + K R K', in O(n^2): H picks rows i0, i1
        M = np.empty((n, n))
        for i in range(n):
            k0 = K[i, 0] * g0
            k1 = K[i, 1] * g1
            for j in range(n):
                M[i, j] = P[i, j] - (k0 * P[i0, j] + k1 * P[i1, j])
        for i in range(n):
            m0 = M[i, i0] * g0
            m1 = M[i, i1] * g1
            kr0 = K[i, 0] * Rc0
            kr1 = K[i, 1] * Rc1
            for j in range(n):
                P[i, j] = (M[i, j] - (m0 * K[j, 0] + m1 * K[j, 1])) + (kr0 * K[j, 0]
                                                                       + kr1 * K[j, 1])
        for i in range(n):  # symmetric to the last bit
            for j in range(i):
                v = 0.5 * (P[i, j] + P[j, i])
                P[i, j] = v
                P[j, i] = v
    else:
        for i in range(n):
            for j in range(n):
                P[i, j] -= K[i, 0] * PHt[j, 0] + K[i, 1] * PHt[j, 1]
    nis = nu0 * (s00 * nu0 + s01 * nu1) + nu1 * (s10 * nu0 + s11 * nu1)
    return nis, math.log(det)


@njit(cache=True)
def monitor_innovations(model, mon, P, nu0, nu1, R0, R1):  # pragma: no cover
    """Add one correction's innovations (of the combined prediction, covariance P) to the
    monitor's block accumulators: NIS (2 dof), lag-1 products, squares."""
    i0 = model.i0
    i1 = i0 + 2
    g0 = model.hgain[0]
    g1 = model.hgain[1]
    a = P[i0, i0] * g0 * g0 + R0
    b_ = P[i0, i1] * g0 * g1
    d = P[i1, i1] * g1 * g1 + R1
    det = a * d - b_ * b_
    if not (det > 0.0 and a > 0.0):
        return
    mon[M_NIS] += (d * nu0 * nu0 - 2.0 * b_ * nu0 * nu1 + a * nu1 * nu1) / det
    mon[M_AC] += nu0 * mon[M_PREV]  # lag-1 autocorrelation of each innovation sequence
    mon[M_AC + 1] += nu1 * mon[M_PREV + 1]
    mon[M_SQ] += nu0 * nu0
    mon[M_SQ + 1] += nu1 * nu1
    mon[M_PREV] = nu0
    mon[M_PREV + 1] = nu1
    mon[M_COUNT] += 1.0


@njit(cache=True)
def linearize(model, x, ux, uy, h):  # pragma: no cover
    """The held step (eq. 5) of x's plant state at x's parameters and Omega_z: (s1, Phi, S)."""
    theta = np.empty(N_PAR)
    for i in range(N_PAR):
        theta[i] = model.theta0[i] + model.scale[i] * x[I_PAR + i]
    return held_step(model, theta, x[I_OM], x[:4], ux, uy, h)


@njit(cache=True)
def predict_about(xbar, s1, Phi, S, x, P, Fr, Qr, qpar, q0, q1):  # pragma: no cover
    """Propagate one filter's x, P in place to t + h, linearized about xbar.

    (s1, Phi, S) is the held step of xbar (linearize): x[:4] -> s1 + Phi (x[:4] -
    xbar[:4]) + S (x[4:12] - xbar[4:12]), process noise q0 on x, vx and q1 on y, vy;
    the parameters are constant (random walk of variance qpar per step); the rate block
    x[I_OM:] -> Fr x[I_OM:] with process noise Qr. P -> F P F' + Q with F's structure
    used (rows 4..10 are the identity), symmetrized. For xbar = x this is the EKF
    prediction.
    """
    n = x.shape[0]
    r = n - I_OM
    d = np.empty(12)
    for c in range(12):
        d[c] = x[c] - xbar[c]
    for i in range(4):
        acc = s1[i]
        for c in range(4):
            acc += Phi[i, c] * d[c]
        for c in range(8):
            acc += S[i, c] * d[4 + c]
        x[i] = acc
    om = np.empty(r)
    for a in range(r):
        acc = 0.0
        for c in range(r):
            acc += Fr[a, c] * x[I_OM + c]
        om[a] = acc
    for a in range(r):
        x[I_OM + a] = om[a]
    A = np.empty((n, n))  # F P
    for k in range(n):
        for i in range(4):
            acc = 0.0
            for c in range(4):
                acc += Phi[i, c] * P[c, k]
            for c in range(8):
                acc += S[i, c] * P[4 + c, k]
            A[i, k] = acc
        for i in range(4, I_OM):
            A[i, k] = P[i, k]
        for a in range(r):
            acc = 0.0
            for c in range(r):
                acc += Fr[a, c] * P[I_OM + c, k]
            A[I_OM + a, k] = acc
    B = np.empty((n, n))  # (F P) F'
    for i in range(n):
        for j in range(4):
            acc = 0.0
            for c in range(4):
                acc += A[i, c] * Phi[j, c]
            for c in range(8):
                acc += A[i, 4 + c] * S[j, c]
            B[i, j] = acc
        for j in range(4, I_OM):
            B[i, j] = A[i, j]
        for a in range(r):
            acc = 0.0
            for c in range(r):
                acc += A[i, I_OM + c] * Fr[a, c]
            B[i, I_OM + a] = acc
    B[0, 0] += q0
    B[1, 1] += q0
    B[2, 2] += q1
    B[3, 3] += q1
    for i in range(I_PAR, I_OM):
        B[i, i] += qpar
    for a in range(r):
        for c in range(r):
            B[I_OM + a, I_OM + c] += Qr[a, c]
    for i in range(n):
        P[i, i] = B[i, i]
        for j in range(i):
            v = 0.5 * (B[i, j] + B[j, i])
            P[i, j] = v
            P[j, i] = v


@njit(cache=True)
def output_row(theta0, scale, x, P, Tdiag, out):  # pragma: no cover
    """out = [x, vx, y, vy], UNKNOWNS, their 1-sigmas (m by the delta method from 1/m).

    theta0, scale as in ObserverModel; Tdiag = [1, 1/wx, 1, 1/wy] unscales the state.
    """
    for i in range(4):
        out[i] = x[i] / Tdiag[i]
    out[4] = x[I_OM]
    for i in range(6):
        out[5 + i] = theta0[i] + scale[i] * x[I_PAR + i]
    b = theta0[6] + scale[6] * x[I_PAR + 6]
    out[11] = 1.0 / b
    out[12] = math.sqrt(max(P[I_OM, I_OM], 0.0))
    for i in range(6):
        out[13 + i] = math.sqrt(max(P[I_PAR + i, I_PAR + i], 0.0)) * scale[i]
    out[19] = math.sqrt(max(P[I_PAR + 6, I_PAR + 6], 0.0)) * scale[6] / (b * b)
