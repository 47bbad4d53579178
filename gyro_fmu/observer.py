"""Online state observer of the single-axis-drive gyroscope (US 2011/0314910 A1, eqs. 5-9).

The observer of eq. 8, x^' = f(x^) + B U + L C (X - X^), run as an extended Kalman
filter: the gain L is recomputed every step from the covariance of the augmented
state of eq. 5, X = [x, x', y, y', Omega_z, kxx, kyy, kxy, dxx, dyy, dxy, m], and the
measurement is the pair of eq. 9 / claim 4, positions (x, y) or velocities (x', y').

Design (each choice measured, see benchmarks/OBSERVER_NOTES.md):

- Same discretization as the plant. In co-simulation ux, uy and Omega_z are held over
  each step; over such a step the model is linear time-invariant and the plant
  (gyro_fmu.dynamics) integrates it exactly. The observer propagates its mean with the
  same exact map (Taylor series of expm to 1e-15, equal to the plant's step to 2e-16),
  because any mismatch in input treatment biases Omega (FIELD-NOTES: 0.2 rad/s).
- Exact sensitivities. The Jacobian of s(t+h) with respect to the parameters and
  Omega is the Frechet derivative of expm(A h) applied to [s, 1]; from the same powers
  T_j = (A h)^j / j! it is S = h sum_{j,m} j! m! / (j+m+1)! T_j G(T_m xi) (one extra
  matmul). A plain EKF with approximate Jacobians let dxx, dyy, dxy and Omega creep
  (FIELD-NOTES: dxy 3-15 % off after 80 ms); with exact ones and the scaling below all
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

from .parameters import PARAMETER_NAMES, GyroParameters, check_parameters

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


def _n_terms(norm: float) -> int:
    """Taylor terms K with norm^K / K! < 1e-15 (norm = ||A h||_inf <= 0.5)."""
    term = 1.0
    for k in range(1, _KMAX):
        term *= norm / k
        if term < 1e-15:
            return k + 1
    return _KMAX


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

    # ------------------------------------------------------------------ internals
    def _rel_R(self, j: int, nu: float, peak: float, h: float) -> float:
        """Relative-mode noise variance: (noise_rel peak)^2, floored by the innovations."""
        tun = self.tuning
        v2 = nu * nu
        e = self.nu2[j]
        e = v2 if e < 0.0 else e + min(h / tun.innov_tau, 1.0) * (v2 - e)
        self.nu2[j] = e
        return max((tun.noise_rel * peak) ** 2, tun.innov_floor * e)

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
        """
        norm = float(np.abs(Ah[:4]).sum(axis=1).max())
        if norm > _STEP_NORM:  # long step: equal sub-steps, chain the Jacobians
            nsub = math.ceil(norm / _STEP_NORM)
            xi = xi0.copy()
            Phi_t = np.eye(4)
            S_t = np.zeros((4, 8))
            for _ in range(nsub):
                s1, Phi, S = self._held_step(xi, Ah / nsub, h / nsub)
                S_t = Phi @ S_t + S
                Phi_t = Phi @ Phi_t
                xi[:4] = s1
            return xi[:4].copy(), Phi_t, S_t
        K = _n_terms(norm)
        st = self._stack
        Ahd = Ah[None, :, :] * _INV[:K - 1, None, None]
        for j in range(K - 1):
            np.matmul(st[j], Ahd[j], out=st[j + 1])
        Tk = st[:K]
        Phi_aug = np.add.reduce(Tk, axis=0)
        G = (Tk @ xi0) @ self._MgT  # (K, 16): rows 1 and 3 of G(T_m xi0)
        Gb = (_BETA[:K, :K] @ G).reshape(2 * K, 8)
        Pj = Tk[:, :4, 1::2].transpose(1, 0, 2).reshape(4, 2 * K)
        S = (Pj @ Gb) * h
        return Phi_aug[:4] @ xi0, Phi_aug[:4, :4], S

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
        tun = self.tuning
        x = self.xhat
        P = self.P
        # ---- correction (eq. 8: L C (X - X^), L from the covariance)
        sl = self._hsl
        g0, g1 = self._hg
        xs0, xs1 = x[sl].tolist()
        nu0 = z1 - g0 * xs0
        nu1 = z2 - g1 * xs1
        peak = self.peak
        if abs(z1) > peak[0]:
            peak[0] = abs(z1)
        if abs(z2) > peak[1]:
            peak[1] = abs(z2)
        if tun.sigma_z1 > 0.0:
            R0 = tun.sigma_z1 * tun.sigma_z1
        else:
            R0 = self._rel_R(0, nu0, float(peak[0]), h)
        if tun.sigma_z2 > 0.0:
            R1 = tun.sigma_z2 * tun.sigma_z2
        else:
            R1 = self._rel_R(1, nu1, float(peak[1]), h)
        (a, b_), (c, d) = P[sl, sl].tolist()
        a = a * g0 * g0 + R0
        b_ = b_ * g0 * g1
        c = c * g0 * g1
        d = d * g1 * g1 + R1
        det = a * d - b_ * c
        if det > 0.0 and a > 0.0:
            PHt = P[:, sl] * self._hgain
            K = PHt @ np.array([[d / det, -b_ / det], [-c / det, a / det]])
            x = x + K @ np.array([nu0, nu1])
            if tun.joseph:
                IKH = np.eye(self.n)
                IKH[:, sl] -= K * self._hgain
                P = IKH @ P @ IKH.T + (K * np.array([R0, R1])) @ K.T
            else:
                P = P - K @ PHt.T
        # ---- propagation to t + h (eq. 5, held ux, uy, Omega_z, exact). A is eqs. 3-4 of
        # parameters.system_matrix in the filter's scaling, filled in place for speed;
        # tests/test_observer.py holds this step equal to the plant's to 2e-16.
        if h != self._h_cached:
            self._set_h(h)
        kxx, kyy, kxy, dxx, dyy, dxy, b = (
            self.theta0 + self.scale * x[_I_PAR:_I_PAR + _N_PAR]).tolist()
        Om = float(x[_I_OM])
        wx, wy = self.wx, self.wy
        A = self._Aaug
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
        self._MgT[4, 6] = self.scale[6] * ux / wx
        self._MgT[4, 14] = self.scale[6] * uy / wy
        xi0 = np.ones(5)
        xi0[:4] = x[:4]
        s_new, Phi, Sens = self._held_step(xi0, A * h, h)
        F = self._F
        F[:4, :4] = Phi
        F[:4, 4:12] = Sens
        x_new = F @ x
        x_new[:4] = s_new
        P = F @ P @ F.T + self._Q
        self.xhat = x_new
        self.P = (P + P.T) * 0.5
        self.t += h

    def state_estimate(self) -> np.ndarray:
        """[x, vx, y, vy] at the current time (m, m/s)."""
        return self.xhat[:4] / self._Tdiag

    def _theta(self) -> np.ndarray:
        return self.theta0 + self.scale * self.xhat[_I_PAR:_I_PAR + _N_PAR]

    def estimates(self) -> dict[str, float]:
        """Current estimates of ESTIMATED (k's 1/s^2, d's 1/s, m kg, Omega_z rad/s)."""
        th = self._theta().tolist()
        out = {"Omega_z": float(self.xhat[_I_OM])}
        for i, name in enumerate(PARAMETER_NAMES[:6]):
            out[name] = th[i]
        out["m"] = 1.0 / th[6]
        return out

    def sigmas(self) -> dict[str, float]:
        """1-sigma of each ESTIMATED from the covariance (m by the delta method from 1/m)."""
        sd = np.sqrt(np.maximum(np.diag(self.P), 0.0))
        b = float(self._theta()[6])
        out = {"Omega_z": float(sd[_I_OM])}
        for i, name in enumerate(PARAMETER_NAMES[:6]):
            out[name] = float(sd[_I_PAR + i] * self.scale[i])
        out["m"] = float(sd[_I_PAR + 6] * self.scale[6] / (b * b))
        return out

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
