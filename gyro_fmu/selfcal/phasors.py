"""Demodulation: phasors of a real record at known frequencies, by least squares.

The seed extracts "amplitude and phase by least squares, since the sideband frequency
is well known". Here the record is mixed down with a reference at omega_ref plus the
loops' smoothed NCO phase (smoothed_nco_phase: smooth, so drive and pick-off phasors
stay related by the resonator's transfer function, which a jittering PLL phase would
not keep) and the phasors c_j of s(t) = Re(sum_j c_j exp(i (omega_ref + j dw) t)) are
fitted jointly with a Hann weight, which suppresses the image at -2 omega_ref and
anything off the grid. The weighted normal equations are built with two FFTs, so a
10 s record at 40 kHz takes milliseconds. carrier_shifts turns the carriers' drifts
into each record's frequency shift against the first.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from ..errors import GyroFmuError

if TYPE_CHECKING:
    from .estimator import ModeData


class PhasorError(GyroFmuError, ValueError):
    """The record does not fit the frequency grid; the message says what to change."""


def phasors(signal: np.ndarray, t0: float, h: float, omega_ref: float, spacing: float,
            harmonics: np.ndarray, phase: np.ndarray | None = None) -> np.ndarray:
    """Complex phasors at omega_ref + j * 2 pi * spacing for each integer j in harmonics.

    signal: uniformly sampled from t0 with step h; its duration N h must hold a whole
    number of periods 1/spacing (the grid is then orthogonal over the record); two or
    more periods give the Hann weight. phase (rad, one per sample): the reference's
    slow departure from omega_ref t (the loops' own smoothed NCO phase: the carrier
    drifting with the temperature), mixed down with the rest.
    """
    return _Fit(signal, t0, h, omega_ref, spacing, harmonics, phase).phasors


def phasors_and_variances(signal: np.ndarray, t0: float, h: float, omega_ref: float,
                          spacing: float, harmonics: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """phasors(...) and E|dc_j|^2 of each, for white noise of the variance the fit leaves.

    The noise variance is the window-weighted mean square of the residual (the record
    minus the fitted tones); the estimates' covariance is 4 G^-1 C G^-H, with G the
    weighted Gram matrix of the grid and C that of the squared weight times the noise
    variance (the same construction, FFT of w^2 instead of w).
    """
    fit = _Fit(signal, t0, h, omega_ref, spacing, harmonics)
    k = np.arange(len(signal))
    t = t0 + k * h
    model = np.zeros(len(signal))
    for j, c in zip(fit.harmonics, fit.phasors, strict=True):
        model += np.real(c * np.exp(1j * (omega_ref + j * fit.dw) * t))
    dof = max(len(signal) - 2 * len(fit.harmonics), 1)
    noise_var = float(np.sum(fit.window * (signal - model) ** 2) / np.sum(fit.window)
                      * len(signal) / dof)
    C = noise_var * fit.gram_of(fit.window ** 2)
    G_inv = np.linalg.inv(fit.gram)
    cov = 4.0 * G_inv @ C @ G_inv.conj().T
    return fit.phasors, np.real(np.diag(cov)).copy()


class _Fit:
    """The weighted joint least-squares fit of phasors on a frequency grid."""

    def __init__(self, signal: np.ndarray, t0: float, h: float, omega_ref: float,
                 spacing: float, harmonics: np.ndarray,
                 phase: np.ndarray | None = None) -> None:
        n = len(signal)
        periods = n * h * spacing
        m = round(periods)
        if m < 1 or abs(periods - m) > 1e-6:
            raise PhasorError(
                f"record of {n} samples x {h} s = {n * h} s is not a whole number of "
                f"periods of the {spacing} Hz grid: record a multiple of {1 / spacing} s"
            )
        self.n, self.m, self.t0 = n, m, t0
        self.harmonics = np.asarray(harmonics, dtype=int)
        self.dw = 2 * math.pi * spacing
        k = np.arange(n)
        # Hann when the grid is at least 2 FFT bins wide: its bins are then orthogonal and
        # its sidelobes fall as 1/k^3. With 1 bin per grid step the Hann normal equations
        # are nearly singular, so a rectangular (exactly orthogonal) weight is used.
        self.window = np.sin(math.pi * k / n) ** 2 if m >= 2 else np.ones(n)
        arg = omega_ref * (t0 + k * h) + (0.0 if phase is None else phase)
        z = signal * self.window * np.exp(-1j * arg)
        Z = np.fft.fft(z)
        rhs = Z[(self.harmonics * m) % n] * np.exp(-1j * self.harmonics * self.dw * t0)
        self.gram = self.gram_of(self.window)
        self.phasors = 2.0 * np.linalg.solve(self.gram, rhs)

    def gram_of(self, weight: np.ndarray) -> np.ndarray:
        """sum_k weight_k exp(-i (j - l) dw t_k) for each pair of harmonics (j, l)."""
        W = np.fft.fft(weight)
        diff = self.harmonics[None, :] - self.harmonics[:, None]  # l - j
        return np.conj(W[(diff * self.m) % self.n]) * np.exp(1j * diff * self.dw * self.t0)


def off_grid(signal: np.ndarray, t0: float, h: float, omega_ref: float, spacing: float,
             harmonics: np.ndarray, c: np.ndarray, phase: np.ndarray | None = None
             ) -> tuple[np.ndarray, np.ndarray]:
    """The record's content between the grid's tones: (harmonic number of each FFT bin
    between -max and +max harmonics that is not on the grid, fractional; its rectangular
    phasor 2 Y_b / n). The fitted tones c (phasors() on the same grid and phase) are
    exactly periodic in the record, so they leave nothing in these bins once their
    image at -2 omega_ref is removed: what is left is noise (the pick-offs', and the
    force noise and the loops' response to it), for NoiseModel. A white noise of
    variance s^2 per sample gives E|2 Y_b / n|^2 = 4 s^2 / n. Empty for fewer than 2
    FFT bins per grid step."""
    n = len(signal)
    m = round(n * h * spacing)
    harmonics = np.asarray(harmonics, dtype=int)
    if m < 2:
        return np.zeros(0), np.zeros(0, complex)
    dw = 2 * math.pi * spacing
    tones = np.zeros(n, complex)  # j dw t_k = 2 pi j m k / n + j dw t0
    tones[(harmonics * m) % n] = c * np.exp(1j * harmonics * dw * t0)
    P = np.fft.ifft(tones) * n  # sum_j c_j exp(i j dw t)
    e = np.exp(-1j * (omega_ref * (t0 + np.arange(n) * h) + (0.0 if phase is None else phase)))
    Y = np.fft.fft(signal * e - 0.5 * np.conj(P) * e * e)
    bins = np.arange(harmonics.min() * m, harmonics.max() * m + 1)
    bins = bins[bins % m != 0]
    return bins / m, 2.0 * Y[bins % n] / n


def white_phasor_variance(n: int, periods: int) -> float:
    """E|c_j|^2 of a phasor (phasors()) per unit variance of white noise on the n
    samples: 4 sum(w^2) / sum(w)^2 for the window the fit uses (6 / n for Hann)."""
    return 6.0 / n if periods >= 2 else 4.0 / n


def smoothed_nco_phase(theta: np.ndarray, h: float, spacing: float,
                       tones: int) -> tuple[float, float, np.ndarray]:
    """The loops' NCO phase over a record, smoothed: (omega at the record's middle,
    rad/s; its relative drift d omega/dt / omega, 1/s; the phase's departure from
    omega t, rad, one per sample).

    Every channel is demodulated on this phase, so a carrier that follows the resonator
    as the temperature moves stays on the grid (the seed: "the PLL frequency follows
    oscillator frequency modulation caused by ... stiffness variations with temperature
    ... so that demodulation yields the desired side band transfer functions
    independent of oscillator frequency"). Smoothing: a cubic in time fitted together
    with the tones at 1..tones times the spacing, which keep the sidebands' phase
    modulation out of it; only the cubic's curvature is kept."""
    phi = np.unwrap(theta)
    n = len(phi)
    half = 0.5 * (n - 1) * h
    u = (np.arange(n) * h - half) / half
    every = max(1, n // 20000)  # the phase is smooth: fit on a subsample (memory flat)
    t = np.arange(0, n, every) * h
    cols = [u[::every] ** p for p in range(4)]
    for k in range(1, tones + 1):
        cols += [np.cos(2 * math.pi * k * spacing * t), np.sin(2 * math.pi * k * spacing * t)]
    coef, *_ = np.linalg.lstsq(np.stack(cols, axis=1), phi[::every], rcond=None)
    omega = float(coef[1] / half)
    drift = float(2.0 * coef[2] / half**2 / omega)
    return omega, drift, coef[2] * u**2 + coef[3] * u**3


def carrier_shifts(data: list[ModeData]) -> None:
    """Set each record's frequency shift against the first (ModeData.shift), from the
    carriers' own drift: the temperature moving between the records moves both modes
    by tc_f dT, which the loops' PLL shows within each record as a relative drift r
    (smoothed_nco_phase). Between the middles of two records the shift is the mean of
    their drifts times the time between them (exact for a steady ramp, and for a rate
    changing linearly); its uncertainty is half their difference times that time (the
    bound for a rate that changes monotonically between the records), carried into
    the 1-sigmas by a refit (estimate). The dampings are not shifted: the amplitude
    loop's gain, their natural witness, moves 2 %/s in a record from its settling and
    the sidebands (measured), far more than a tc_Q does."""
    first = data[0]
    for md in data[1:]:
        dt = md.t_center - first.t_center
        md.shift = math.expm1(0.5 * (first.drift + md.drift) * dt)
        md.sigma_shift = 0.5 * abs(first.drift - md.drift) * abs(dt)
