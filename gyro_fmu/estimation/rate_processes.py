"""Models of a time-varying Omega_z for the tracking bound (estimation/tracking_bound.py).

Omega_k = mean_k + L_k beta: a finite linear model with unknown Gaussian coefficients
(constant_rate; sine_rate of known frequency) or a Gaussian random process sampled at
knots and held (gauss_markov_rate, integrated_random_walk_rate), with the prior
information of beta and, for a random process, a drawer of its trajectories (the Monte
Carlo of the bound's D-terms). Units: rad/s, s, Hz.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class RateProcess:
    """Omega_k = mean[k] + coef[k] . beta[col[k] : col[k] + w], held over [t_k, t_k + h].

    beta ~ N(0, info^-1): info is the prior information of the coefficients (may be
    singular: no prior along a direction; all zeros is the vanishing prior). For a random
    process (random=True) draw() gives trajectories beta of the prior, along which the
    Jacobians are evaluated (Monte Carlo of the D-terms); otherwise beta = 0: the
    Jacobians along mean, the true rate.
    """

    name: str
    mean: np.ndarray  #: (K+1,) rad/s at t_0 .. t_K
    col: np.ndarray  #: (K+1,) int: first column of row k
    coef: np.ndarray  #: (K+1, w)
    info: np.ndarray  #: (n_beta, n_beta) prior information
    random: bool = False
    draw: Callable[[np.random.Generator], np.ndarray] | None = field(default=None, repr=False)

    @property
    def n_beta(self) -> int:
        return self.info.shape[0]

    def row(self, k: int) -> np.ndarray:
        """dOmega_k / dbeta as a dense vector."""
        out = np.zeros(self.n_beta)
        c = int(self.col[k])
        out[c:c + self.coef.shape[1]] = self.coef[k]
        return out

    def trajectory(self, beta: np.ndarray | None = None) -> np.ndarray:
        """Omega_0 .. Omega_K for coefficients beta (None: the mean)."""
        if beta is None:
            return self.mean.copy()
        w = self.coef.shape[1]
        idx = self.col[:, None] + np.arange(w)[None, :]
        return self.mean + np.sum(self.coef * beta[idx], axis=1)


def _prior_info(sigmas: Sequence[float | None]) -> np.ndarray:
    """Diagonal information from 1-sigmas; None or inf: no prior."""
    return np.diag([0.0 if s is None or not math.isfinite(s) else 1.0 / s**2
                    for s in sigmas])


def constant_rate(Omega_z: float, h: float, n_steps: int,
                  sigma0: float | None = 2.0) -> RateProcess:
    """A constant Omega_z with prior N(Omega_z, sigma0^2) (None: no prior, as crb_at)."""
    K = n_steps + 1
    return RateProcess("constant", np.full(K, float(Omega_z)), np.zeros(K, int),
                     np.ones((K, 1)), _prior_info([sigma0]))


def sine_rate(h: float, n_steps: int, frequency: float, amplitude: float,
              offset: float = 0.0, phase: float = 0.0, sigma0: float | None = 2.0,
              fit_offset: bool = True) -> RateProcess:
    """Omega = offset + amplitude sin(2 pi frequency t + phase), frequency known.

    Unknown coefficients beta = [c, a, b] of c + a cos(w t) + b sin(w t) (amplitude and
    phase in linear form; c only with fit_offset), each with prior N(truth, sigma0^2).
    The harmonic oscillator with zero process noise: its PCRB is the prior-regularised
    CRB of beta mapped to Omega(t) (no Monte Carlo: the Jacobians are at the truth).
    """
    t = np.arange(n_steps + 1) * h
    w = 2.0 * math.pi * frequency
    cols = [np.cos(w * t), np.sin(w * t)]
    if fit_offset:
        cols.insert(0, np.ones_like(t))
    coef = np.column_stack(cols)
    mean = offset + amplitude * np.sin(w * t + phase)
    return RateProcess(f"sine {frequency:g} Hz", mean, np.zeros(t.size, int), coef,
                     _prior_info([sigma0] * coef.shape[1]))


def markov_chain_information(F: np.ndarray, Q: np.ndarray, P0: np.ndarray,
                             n: int) -> np.ndarray:
    """Information of r_0 .. r_{n-1} of r_{i+1} = F r_i + w_i, w_i ~ N(0, Q), r_0 ~ N(0, P0)
    (block tridiagonal; Q and P0 must be nonsingular)."""
    d = F.shape[0]
    Qi = np.linalg.inv(Q)
    J = np.zeros((n * d, n * d))
    J[:d, :d] = np.linalg.inv(P0)
    FtQi = F.T @ Qi
    for i in range(n - 1):
        a, b = slice(i * d, (i + 1) * d), slice((i + 1) * d, (i + 2) * d)
        J[a, a] += FtQi @ F
        J[a, b] -= FtQi
        J[b, a] -= FtQi.T
        J[b, b] += Qi
    return J


def _chain_drawer(F: np.ndarray, Q: np.ndarray, P0: np.ndarray, n: int):
    LQ, L0 = np.linalg.cholesky(Q), np.linalg.cholesky(P0)
    d = F.shape[0]

    def draw(rng: np.random.Generator) -> np.ndarray:
        r = np.empty((n, d))
        r[0] = L0 @ rng.standard_normal(d)
        for i in range(n - 1):
            r[i + 1] = F @ r[i] + LQ @ rng.standard_normal(d)
        return r.ravel()

    return draw


def _knots(n_steps: int, knot_step: int) -> tuple[int, np.ndarray]:
    if not (isinstance(knot_step, int) and knot_step >= 1):
        raise ValueError(f"knot_step={knot_step!r} must be an integer >= 1")
    K = n_steps + 1
    return -(-K // knot_step), np.arange(K) // knot_step


def gauss_markov_rate(h: float, n_steps: int, std: float, bandwidth: float,
                      mean: float = 0.0, knot_step: int = 20,
                      sigma0: float | None = None) -> RateProcess:
    """Omega = mean + first-order Gauss-Markov (Ornstein-Uhlenbeck) process.

    Stationary 1-sigma std (rad/s), bandwidth (Hz): autocorrelation
    exp(-2 pi bandwidth |tau|). Sampled every knot_step communication steps and held in
    between (the process this bounds); the initial knot has 1-sigma sigma0 (None: std,
    stationary).
    """
    n, knot = _knots(n_steps, knot_step)
    dt = knot_step * h
    rho = math.exp(-2.0 * math.pi * bandwidth * dt)
    q = std**2 * (1.0 - rho**2)
    s0 = std if sigma0 is None else sigma0
    F, Q, P0 = np.array([[rho]]), np.array([[q]]), np.array([[s0**2]])
    K = n_steps + 1
    return RateProcess(f"Gauss-Markov {std:g} rad/s {bandwidth:g} Hz", np.full(K, float(mean)),
                     knot, np.ones((K, 1)), markov_chain_information(F, Q, P0, n), True,
                     _chain_drawer(F, Q, P0, n))


def integrated_random_walk_rate(h: float, n_steps: int, q: float, sigma0_Omega: float,
                                sigma0_rate: float, mean: float = 0.0,
                                knot_step: int = 20) -> RateProcess:
    """Omega = mean + integrated random walk: dOmega/dt is a Wiener process of intensity
    q (rad^2/s^5), Omega(0) ~ N(0, sigma0_Omega^2), dOmega/dt(0) ~ N(0, sigma0_rate^2).

    Sampled every knot_step steps (state [Omega, dOmega/dt dt] per knot) and held.
    """
    n, knot = _knots(n_steps, knot_step)
    dt = knot_step * h
    F = np.array([[1.0, 1.0], [0.0, 1.0]])  # state [Omega, dt dOmega/dt]
    Q = q * dt**3 * np.array([[1.0 / 3.0, 0.5], [0.5, 1.0]])
    P0 = np.diag([sigma0_Omega**2, (sigma0_rate * dt) ** 2])
    K = n_steps + 1
    return RateProcess(f"integrated random walk q={q:g}", np.full(K, float(mean)), 2 * knot,
                     np.ones((K, 1)), markov_chain_information(F, Q, P0, n), True,
                     _chain_drawer(F, Q, P0, n))
