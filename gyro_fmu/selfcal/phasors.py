"""Demodulation: phasors of a real record at known frequencies, by least squares.

The seed extracts "amplitude and phase by least squares, since the sideband frequency
is well known". Here the record is mixed down with a reference at omega_ref plus the
loops' smoothed NCO phase (nco_phase: smooth, so drive and pick-off phasors
stay related by the resonator's transfer function, which a jittering PLL phase would
not keep) and the phasors c_j of s(t) = Re(sum_j c_j exp(i (omega_ref + j dw) t)) are
fitted jointly with a Hann weight, which suppresses the image at -2 omega_ref and
anything off the grid. The weighted normal equations are built with two FFTs, so a
10 s record at 40 kHz takes milliseconds. carrier_shifts turns the carriers' drifts
into each record's frequency shift against the first.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
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
    return _Fit.of_signal(signal, t0, h, omega_ref, spacing, harmonics, phase).phasors


def phasors_and_variances(signal: np.ndarray, t0: float, h: float, omega_ref: float,
                          spacing: float, harmonics: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """phasors(...) and E|dc_j|^2 of each, for white noise of the variance the fit leaves.

    The noise variance is the window-weighted mean square of the residual (the record
    minus the fitted tones); the estimates' covariance is 4 G^-1 C G^-H, with G the
    weighted Gram matrix of the grid and C that of the squared weight times the noise
    variance (the same construction, FFT of w^2 instead of w).
    """
    fit = _Fit.of_signal(signal, t0, h, omega_ref, spacing, harmonics)
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
    """The weighted joint least-squares fit of phasors on a frequency grid.

    z: the record mixed down, one complex sample per dt from t0, already multiplied by
    `window` (the weight of each sample); a tone exp(i j dw t) in it has the phasor
    response[j] / 2 times its own (the real signal's half, times a filter's response)."""

    def __init__(self, z: np.ndarray, window: np.ndarray, t0: float, dt: float,
                 spacing: float, harmonics: np.ndarray, response: np.ndarray | float = 1.0
                 ) -> None:
        n = len(z)
        self.n, self.m, self.t0 = n, whole_periods(n, dt, spacing), t0
        self.harmonics = np.asarray(harmonics, dtype=int)
        self.dw = 2 * math.pi * spacing
        self.window = window
        Z = np.fft.fft(z)
        rhs = Z[(self.harmonics * self.m) % n] * np.exp(-1j * self.harmonics * self.dw * t0)
        self.gram = self.gram_of(window)
        self.phasors = 2.0 * np.linalg.solve(self.gram, rhs) / response

    @classmethod
    def of_signal(cls, signal: np.ndarray, t0: float, h: float, omega_ref: float,
                  spacing: float, harmonics: np.ndarray, phase: np.ndarray | None = None
                  ) -> _Fit:
        """The fit of a real record sampled every h from t0."""
        n = len(signal)
        window = hann_or_flat(np.arange(n), n, whole_periods(n, h, spacing))
        arg = omega_ref * (t0 + np.arange(n) * h) + (0.0 if phase is None else phase)
        return cls(signal * window * np.exp(-1j * arg), window, t0, h, spacing, harmonics)

    def gram_of(self, weight: np.ndarray) -> np.ndarray:
        """sum_k weight_k exp(-i (j - l) dw t_k) for each pair of harmonics (j, l)."""
        W = np.fft.fft(weight)
        diff = self.harmonics[None, :] - self.harmonics[:, None]  # l - j
        return np.conj(W[(diff * self.m) % self.n]) * np.exp(1j * diff * self.dw * self.t0)


def whole_periods(n: int, dt: float, spacing: float) -> int:
    """Periods of the grid in n samples of dt; refuses a record that holds no whole number."""
    periods = n * dt * spacing
    m = round(periods)
    if m < 1 or abs(periods - m) > 1e-6:
        raise PhasorError(
            f"record of {n} samples x {dt} s = {n * dt} s is not a whole number of "
            f"periods of the {spacing} Hz grid: record a multiple of {1 / spacing} s"
        )
    return m


def hann_or_flat(position: np.ndarray, n: float, periods: int) -> np.ndarray:
    """The fit's weight at sample positions (0 .. n, in samples of the record): Hann when
    the grid is at least 2 FFT bins wide (its bins are then orthogonal and its sidelobes
    fall as 1/k^3; sampled at any offset, its transform keeps 3 bins); with 1 bin per
    grid step the Hann normal equations are nearly singular, so a flat weight."""
    return np.sin(math.pi * position / n) ** 2 if periods >= 2 else np.ones(len(position))


def baseband_phasors(base: np.ndarray, t0: float, dt: float, offset: float,
                     extra: np.ndarray, spacing: float, harmonics: np.ndarray,
                     response: np.ndarray) -> np.ndarray:
    """phasors() of a record already mixed down and decimated (stream.StreamedRecord):
    base, one complex sample per dt from t0, sample b at b + offset samples into the
    record (its Hann weight: the full-rate record's at that time); extra (rad, one per
    sample): the rest of the reference's phase, mixed down here; response: the
    decimating filter's response at each harmonic, divided out."""
    n = len(base)
    window = hann_or_flat(np.arange(n) + offset, n, whole_periods(n, dt, spacing))
    return _Fit(base * window * np.exp(-1j * extra), window, t0, dt, spacing, harmonics,
                response).phasors


def baseband_off_grid(base: np.ndarray, dt: float, extra: np.ndarray, spacing: float,
                      harmonics: np.ndarray, response: Callable[[np.ndarray], np.ndarray]
                      ) -> tuple[np.ndarray, np.ndarray]:
    """The record's content between the grid's tones, from its decimated baseband (as
    baseband_phasors): (harmonic number of each FFT bin between -max and +max harmonics
    that is not on the grid, fractional; its rectangular phasor 2 Y_b / n, the filter's
    response(harmonic number) divided out). The grid's tones are exactly periodic in
    the record and leave nothing in these bins (their image at -2 omega_ref is the
    decimating filter's to reject): what is left is noise (the pick-offs', and the force
    noise and the loops' response to it), for NoiseModel. A white noise of variance s^2
    per full-rate sample gives E|2 Y_b / n|^2 = 4 s^2 / N, N the full-rate samples.
    Empty for fewer than 2 FFT bins per grid step."""
    n = len(base)
    m = whole_periods(n, dt, spacing)
    harmonics = np.asarray(harmonics, dtype=int)
    if m < 2:
        return np.zeros(0), np.zeros(0, complex)
    Y = np.fft.fft(base * np.exp(-1j * extra))
    bins = np.arange(harmonics.min() * m, harmonics.max() * m + 1)
    bins = bins[bins % m != 0]
    return bins / m, 2.0 * Y[bins % n] / n / response(bins / m)


def white_phasor_variance(n: int, periods: int) -> float:
    """E|c_j|^2 of a phasor (phasors()) per unit variance of white noise on the n
    samples: 4 sum(w^2) / sum(w)^2 for the window the fit uses (6 / n for Hann)."""
    return 6.0 / n if periods >= 2 else 4.0 / n


@dataclass(frozen=True)
class NcoPhase:
    """The loops' NCO phase over a record, smoothed (nco_phase): omega at the record's
    middle t_mid (rad/s), its relative drift d omega/dt / omega (1/s), and the phase's
    slow departure from omega t, curvature(t) = c2 u^2 + c3 u^3 with
    u = (t - t_mid) / half (rad)."""

    omega: float
    drift: float
    t_mid: float
    half: float
    c2: float
    c3: float

    def curvature(self, t: np.ndarray) -> np.ndarray:
        u = (t - self.t_mid) / self.half
        return self.c2 * u**2 + self.c3 * u**3


def nco_phase(phi: np.ndarray, t: np.ndarray, t_start: float, n: int, h: float,
              spacing: float, tones: int) -> NcoPhase:
    """Smooth the loops' unwrapped NCO phase phi, sampled at times t (s) over a record
    of n steps of h from t_start (its middle: t_start + (n - 1) h / 2).

    Every channel is demodulated on this phase, so a carrier that follows the resonator
    as the temperature moves stays on the grid (the seed: "the PLL frequency follows
    oscillator frequency modulation caused by ... stiffness variations with temperature
    ... so that demodulation yields the desired side band transfer functions
    independent of oscillator frequency"). Smoothing: a cubic in time fitted together
    with the tones at 1..tones times the spacing, which keep the sidebands' phase
    modulation out of it; only the cubic's curvature is kept. At most 20,000 samples are
    used (the phase is smooth)."""
    every = max(1, len(phi) // 20000)
    phi, t = phi[::every], t[::every]
    half = 0.5 * (n - 1) * h
    t_mid = t_start + half
    u = (t - t_mid) / half
    rel = t - t_start
    cols = [u**p for p in range(4)]
    for k in range(1, tones + 1):
        cols += [np.cos(2 * math.pi * k * spacing * rel), np.sin(2 * math.pi * k * spacing * rel)]
    coef, *_ = np.linalg.lstsq(np.stack(cols, axis=1), phi, rcond=None)
    omega = float(coef[1] / half)
    drift = float(2.0 * coef[2] / half**2 / omega)
    return NcoPhase(omega, drift, t_mid, half, float(coef[2]), float(coef[3]))


def carrier_shifts(data: list[ModeData]) -> None:
    """Set each record's frequency shift against the first (ModeData.shift), from the
    carriers' own drift: the temperature moving between the records moves both modes
    by tc_f dT, which the loops' PLL shows within each record as a relative drift r
    (nco_phase). Between the middles of two records the shift is the mean of
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
