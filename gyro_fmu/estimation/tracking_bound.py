"""Posterior (Bayesian) Cramér-Rao bound for tracking a time-varying Omega_z.

The batch bound of identify.crb_at holds for a constant rate only. This module bounds the
mean-square error of ANY estimator of Omega_z(t_k) (the observer's output at t_k, which
has used the samples z_0 .. z_{k-1}) when Omega_z follows a given model:

- a finite linear model with unknown Gaussian coefficients: a constant (constant_rate),
  or a sine of known frequency with unknown amplitude, phase and offset (sine_rate,
  Omega = c + a cos w t + b sin w t): the harmonic-oscillator state with zero process
  noise, for which the PCRB is the ordinary (prior-regularised) CRB of (c, a, b) mapped
  to Omega(t);
- a Gaussian random process (gauss_markov_rate: first-order Gauss-Markov of a given
  bandwidth; integrated_random_walk_rate), sampled at knots every knot_step steps and
  held between them.

The 7 parameters are unknown constants with the observer's own Gaussian prior
(ObserverTuning sigma0_k_rel, sigma0_d_rel, sigma0_m_rel, in physical units of the
observer's initial guess, centred on the truth); the plant starts from rest with the
observer's prior on [x, vx, y, vy]; the positions (or velocities) are measured every h
with white Gaussian noise of the given absolute std per channel.

Formulation (Tichavský, Muravchik & Nehorai, IEEE Trans. SP 46(5), 1998, "TMN"). The
PCRB of TMN is the Van Trees bound E[(x^ - x)(x^ - x)^T] >= J^-1 (TMN eq. 1-2) for the
Bayesian information J of the joint density of states and measurements; TMN eq. 21
(J_{k+1} = D22 - D21 (J_k + D11)^-1 D12, D-terms eqs. 22-24) computes its last block
recursively. That recursion needs a density p(x_{k+1} | x_k): with the plant state and
the parameters propagated without process noise (Q singular) it does not exist, and
regularising Q = eps I does not help when the Jacobians are random (the D-terms then
give J ~ Var(F) / eps: a bound that vanishes as eps -> 0). So the Van Trees bound is
applied to the variables that do have a density,

    theta = [s_0 (the free components), p (7), beta (the rate model's coefficients or
             knot values)],   prior N(theta_true, J_prior^-1),

with every state a deterministic function of theta: s_{k+1} = f(s_k, p, Omega_k; u_k)
(GyroStateObserver.held_step: the exact held-input step and its Jacobians Phi, S) and
Omega_k = mean_k + L_k beta (linear). The Bayesian information is

    J_k = J_prior + E_beta[ sum_{j<k} G_j^T R^-1 G_j ],   G_j = H ds_j/dtheta,

(the D-term of the measurements, TMN eq. 24's E[grad h R^-1 grad h^T], averaged over
Monte Carlo draws of the rate trajectory as TMN do for random Jacobians) and the bound on
Omega_k = mean_k + L_k beta is L_k J_k^-1 L_k^T (exact for a linear function of theta).
For a deterministic rate model (constant, sine) the Jacobians are evaluated at the truth
and are not random: J_k^-1 is then the covariance of the Kalman filter of the linearised
(about the truth) system, i.e. the covariance-form Riccati, which is the PCRB for
additive Gaussian noise and non-random Jacobians (TMN section on linear systems). The
Jacobians with respect to s_0 and p are always evaluated at the truth (the observer's
priors are narrow; averaging over them as well would bound a different, mixed problem).

Units: Omega rad/s, k's 1/s^2, d's 1/s, m kg, time s. The rate models are in
rate_processes.py; a Scenario's bound is gyro_fmu.system.tracking. docs/tracking-bound.md
explains and measures it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from ..core.observer import prior_fraction
from ..model.drive import TwoToneDrive
from ..model.measurement import MeasuredPair
from ..model.parameters import PARAMETER_NAMES, GyroParameters
from .fisher import RTOL
from .observer import I_PAR, N_PAR, GyroStateObserver, ObserverTuning
from .rate_processes import (
    RateProcess,
    constant_rate,
    gauss_markov_rate,
    integrated_random_walk_rate,
    markov_chain_information,
    sine_rate,
)

__all__ = [
    "RateProcess",
    "TrackingBound",
    "bayesian_information",
    "constant_rate",
    "gauss_markov_rate",
    "integrated_random_walk_rate",
    "markov_chain_information",
    "sine_rate",
    "tracking_bound",
]

#: Measurements accumulated per BLAS update of the information matrix.
_CHUNK = 256


# --------------------------------------------------------------------------- core


#: step(k, s, Omega) -> (s(t_k+1), ds'/ds (n_s x n_s), ds'/dp (n_s x n_p), ds'/dOmega (n_s,))
StepFunction = Callable[[int, np.ndarray, float], tuple[np.ndarray, np.ndarray, np.ndarray,
                                                        np.ndarray]]


def bayesian_information(step: StepFunction, s0: np.ndarray, n_p: int, rate: RateProcess,
                         H: np.ndarray, noise_std: Sequence[float], eval_steps: Sequence[int],
                         s0_free: np.ndarray | None = None, n_draws: int = 8,
                         seed: int = 0, filtered: bool = False) -> np.ndarray:
    """Measurement part of the Bayesian information at each of eval_steps.

    Unknowns theta = [s_0[s0_free], p (n_p), beta (rate.n_beta)]; s_{k+1} = step(k, s_k,
    Omega_k) from s_0 at the truth, z_k = H s_k + v_k, v_k ~ N(0, diag(noise_std^2)).
    Returns M (len(eval_steps), n, n) with M[e] = E[sum_j G_j^T R^-1 G_j] over the
    measurements j < eval_steps[e] (j <= with filtered), averaged over n_draws Monte Carlo
    trajectories of a random rate (one pass along rate.mean otherwise). The steps are
    evaluated in increasing order; the last one sets the horizon.
    """
    s0 = np.asarray(s0, float)
    ns = s0.size
    free = np.ones(ns, bool) if s0_free is None else np.asarray(s0_free, bool)
    n_a = int(free.sum()) + n_p
    n = n_a + rate.n_beta
    ev = [int(k) for k in eval_steps]
    if sorted(ev) != ev or not ev or ev[0] < 0 or ev[-1] > rate.mean.size - 1:
        raise ValueError(f"eval_steps must increase within 0 .. {rate.mean.size - 1}")
    Hw = np.asarray(H, float) / np.asarray(noise_std, float)[:, None]
    w = rate.coef.shape[1]
    draws = max(1, int(n_draws)) if rate.random else 1
    rng = np.random.default_rng(seed)
    out = np.zeros((len(ev), n, n))
    last = ev[-1] + (1 if filtered else 0)
    for _ in range(draws):
        beta = rate.draw(rng) if rate.random and rate.draw is not None else None
        omega = rate.trajectory(beta)
        Sig = np.zeros((ns, n))
        Sig[np.flatnonzero(free), np.arange(int(free.sum()))] = 1.0
        ncol = n_a
        M = np.zeros((n, n))
        rows: list[np.ndarray] = []
        s = s0.copy()
        e = 0
        for k in range(last):
            # measurements j < k are in M (+ rows) here; z_k is added below
            while e < len(ev) and ev[e] + (1 if filtered else 0) == k:
                _flush(M, rows)
                out[e] += M
                e += 1
            rows.append(Hw @ Sig[:, :ncol])
            if len(rows) * Hw.shape[0] >= _CHUNK:
                _flush(M, rows)
            s1, Phi, Sp, Som = step(k, s, float(omega[k]))
            c0 = n_a + int(rate.col[k])
            ncol = max(ncol, c0 + w)
            Sig[:, :ncol] = Phi @ Sig[:, :ncol]
            Sig[:, n_a - n_p:n_a] += Sp
            Sig[:, c0:c0 + w] += np.outer(Som, rate.coef[k])
            s = s1
        while e < len(ev):
            _flush(M, rows)
            out[e] += M
            e += 1
    return out / draws


def _flush(M: np.ndarray, rows: list[np.ndarray]) -> None:
    """M += B^T B for the whitened rows G_j collected since the last flush (one BLAS call;
    rows are as wide as the columns active when they were taken)."""
    if not rows:
        return
    m = max(r.shape[1] for r in rows)
    B = np.zeros((sum(r.shape[0] for r in rows), m))
    i = 0
    for r in rows:
        B[i:i + r.shape[0], :r.shape[1]] = r
        i += r.shape[0]
    M[:m, :m] += B.T @ B
    rows.clear()


def _inverse_parts(J: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """diag(T J^-1 T^T) for the rows T of targets; inf along unidentifiable directions
    (the rank rule of fisher: eigenvalues of the equilibrated J below RTOL^2 x largest)."""
    d = np.sqrt(np.diag(J))
    d = np.where(d > 0.0, d, 1.0)
    Jn = J / d[:, None] / d[None, :]
    Tn = targets / d[None, :]
    try:
        c = sla.cho_factor(Jn, lower=True, check_finite=False)
        dl = np.abs(np.diag(c[0]))
        if dl.min() > RTOL * dl.max():  # well away from the rank rule's threshold
            X = sla.cho_solve(c, Tn.T, check_finite=False)
            var = np.einsum("ij,ji->i", Tn, X)
            if np.all(np.isfinite(var)) and np.all(var >= 0.0):
                return var
    except (np.linalg.LinAlgError, ValueError):
        pass
    ww, V = np.linalg.eigh(Jn)
    keep = ww > RTOL**2 * ww[-1]
    proj = Tn @ V
    var = np.sum(proj[:, keep] ** 2 / ww[keep], axis=1)
    null = np.sum(proj[:, ~keep] ** 2, axis=1) > 1e-12 * np.sum(proj**2, axis=1)
    return np.where(null, math.inf, var)


# --------------------------------------------------------------------------- the gyro


@dataclass(frozen=True)
class TrackingBound:
    """The bound at the evaluation times (all 1-sigmas: sqrt of the bound's diagonal)."""

    time: np.ndarray  #: s, t_k of each evaluation
    steps: np.ndarray  #: k of each evaluation (the bound uses z_0 .. z_{k-1})
    Omega_true: np.ndarray  #: rad/s, the rate model's mean at t_k (the truth if not random)
    sigma_Omega: np.ndarray  #: rad/s, bound on the RMS error of any estimate of Omega_z(t_k)
    sigma_params: dict[str, np.ndarray]  #: PARAMETER_NAMES -> 1-sigma (SI) at each time
    rate: str  #: the rate model's name
    n_draws: int  #: Monte Carlo trajectories behind the D-terms (1: deterministic model)
    noise_std: tuple[float, float]

    def rms_sigma(self, t_from: float, t_to: float) -> float:
        """sqrt(mean sigma_Omega^2) over t_from <= t <= t_to: the bound on an RMS error."""
        sel = (self.time >= t_from - 1e-12) & (self.time <= t_to + 1e-12)
        return float(np.sqrt(np.mean(self.sigma_Omega[sel] ** 2)))


def _prior_sigmas(initial: GyroParameters, tuning: ObserverTuning) -> np.ndarray:
    """The observer's prior 1-sigma of theta = [kxx, kyy, kxy, dxx, dyy, dxy, 1/m] in SI
    (as GyroStateObserver.__init__ sets it from the guess `initial`)."""
    ref = GyroStateObserver(initial, 0.0, 1, tuning)
    p_sig = np.sqrt(np.diag(ref.P)[I_PAR:I_PAR + N_PAR])
    return p_sig * ref.scale


def _state_prior(initial: GyroParameters, tuning: ObserverTuning, u1: float) -> np.ndarray:
    """1-sigma of s_0 = [x, vx, y, vy]: the tuning's, or the observer's auto prior
    (the core's prior fraction of the guessed static deflection of the first drive sample u1)."""
    wx, wy = math.sqrt(initial.kxx), math.sqrt(initial.kyy)
    if tuning.sigma0_position > 0.0 and tuning.sigma0_velocity > 0.0:
        sp, sv = tuning.sigma0_position, tuning.sigma0_velocity
        return np.array([sp, sv, sp, sv])
    size = prior_fraction() * abs(u1) / initial.m / initial.kxx
    return np.array([size, size * wx, size, size * wy])


def tracking_bound(
    params: GyroParameters,
    drive: TwoToneDrive,
    rate: RateProcess,
    noise_std: Sequence[float],
    h: float,
    n_steps: int,
    tuning: ObserverTuning | None = None,
    initial: GyroParameters | None = None,
    measured_pair: int = 1,
    eval_every: int = 200,
    t_eval: Sequence[float] | None = None,
    n_draws: int = 8,
    seed: int = 0,
    param_prior: bool = True,
    state_prior: bool = True,
    filtered: bool = False,
) -> TrackingBound:
    """PCRB of Omega_z(t_k) and of the 7 parameters for the gyro `params` (the truth).

    The plant starts from rest, driven by ux = drive.ux(k h), uy = 0 (held over each
    step, as GyroPlantModel steps); rate gives Omega_k (built for the same h and
    n_steps); noise_std = absolute std of the two measured signals (m, or m/s for
    measured_pair 2), e.g. scenario.absolute_noise. Priors: the observer's (tuning,
    default ObserverTuning()) in physical units of its guess `initial` (default: the
    truth), centred on the truth; param_prior=False: no prior on the parameters;
    state_prior=False: s_0 = 0 known (what crb_at assumes). Evaluated every eval_every
    steps (or at the steps nearest t_eval), the bound at t_k from z_0 .. z_{k-1} (what the
    observer's output at t_k has used; filtered: z_0 .. z_k).
    """
    tun = ObserverTuning() if tuning is None else tuning
    guess = params if initial is None else initial
    pair = MeasuredPair.of(measured_pair)
    if rate.mean.size != n_steps + 1:
        raise ValueError(f"rate model has {rate.mean.size} samples; n_steps + 1 = "
                         f"{n_steps + 1} expected (build it with the same h, n_steps)")
    obs = GyroStateObserver(params, 0.0, int(pair), tun)  # p-scaling at the truth
    theta = obs.theta0.copy()
    u = np.array([drive.ux(k * h) for k in range(n_steps + 1)])

    def step(k: int, s: np.ndarray, om: float):
        s1, Phi, S = obs.held_step(s, u[k], 0.0, h, theta=theta, Omega_z=om)
        return s1, Phi, S[:, :7], S[:, 7]

    sig_s0 = _state_prior(guess, tun, next((v for v in u if v != 0.0), 0.0))
    free = (sig_s0 > 0.0) if state_prior else np.zeros(4, bool)
    if t_eval is not None:
        steps = sorted({round(t / h) for t in t_eval})
    else:
        steps = list(range(eval_every, n_steps + 1, eval_every))
    H = np.zeros((2, 4))
    H[0, pair.state_rows[0]] = H[1, pair.state_rows[1]] = 1.0
    M = bayesian_information(step, np.zeros(4), 7, rate, H, noise_std, steps, free,
                             n_draws, seed, filtered)
    nf = int(free.sum())
    n_a = nf + 7
    J0 = np.zeros(M.shape[1:])
    J0[:nf, :nf] = np.diag(1.0 / sig_s0[free] ** 2)
    if param_prior:
        J0[nf:n_a, nf:n_a] = np.diag((obs.scale / _prior_sigmas(guess, tun)) ** 2)
    J0[n_a:, n_a:] = rate.info
    sig_om = np.empty(len(steps))
    sig_par = np.empty((len(steps), 7))
    targets = np.zeros((8, M.shape[1]))
    targets[1:, nf:n_a] = np.eye(7)
    for e, k in enumerate(steps):
        targets[0, n_a:] = rate.row(k)
        var = _inverse_parts(J0 + M[e], targets)
        sig_om[e] = math.sqrt(var[0])
        sig_par[e] = np.sqrt(var[1:]) * obs.scale
    sig_par[:, 6] *= params.m**2  # delta method, m = 1/b (as the observer reports it)
    return TrackingBound(
        time=np.array(steps) * h, steps=np.array(steps), Omega_true=rate.mean[steps],
        sigma_Omega=sig_om,
        sigma_params={n: sig_par[:, i] for i, n in enumerate(PARAMETER_NAMES)},
        rate=rate.name, n_draws=max(1, n_draws) if rate.random else 1,
        noise_std=(float(noise_std[0]), float(noise_std[1])))
