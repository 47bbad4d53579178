"""Demodulation: phasors of a real record at known frequencies, by least squares.

The seed extracts "amplitude and phase by least squares, since the sideband frequency
is well known". Here the record is mixed down with a constant-frequency reference
omega_ref (a constant reference keeps drive and pick-off phasors related by the
resonator's transfer function exactly, which a jittering PLL phase would not) and the
phasors c_j of s(t) = Re(sum_j c_j exp(i (omega_ref + j dw) t)) are fitted jointly
with a Hann weight, which suppresses the image at -2 omega_ref and anything off the
grid. The weighted normal equations are built with two FFTs, so a 10 s record at
40 kHz takes milliseconds.
"""

from __future__ import annotations

import math

import numpy as np


class PhasorError(ValueError):
    """The record does not fit the frequency grid; the message says what to change."""


def phasors(signal: np.ndarray, t0: float, h: float, omega_ref: float, spacing: float,
            harmonics: np.ndarray) -> np.ndarray:
    """Complex phasors at omega_ref + j * 2 pi * spacing for each integer j in harmonics.

    signal: uniformly sampled from t0 with step h; its duration N h must hold a whole
    number of periods 1/spacing (the grid is then orthogonal over the record); two or
    more periods give the Hann weight.
    """
    n = len(signal)
    periods = n * h * spacing
    m = round(periods)
    if m < 1 or abs(periods - m) > 1e-6:
        raise PhasorError(
            f"record of {n} samples x {h} s = {n * h} s is not a whole number of periods "
            f"of the {spacing} Hz grid: record a multiple of {1 / spacing} s"
        )
    harmonics = np.asarray(harmonics, dtype=int)
    k = np.arange(n)
    # Hann when the grid is at least 2 FFT bins wide: its bins are then orthogonal and
    # its sidelobes fall as 1/k^3. With 1 bin per grid step the Hann normal equations
    # are nearly singular, so a rectangular (exactly orthogonal) weight is used.
    window = np.sin(math.pi * k / n) ** 2 if m >= 2 else np.ones(n)
    z = signal * window * np.exp(-1j * omega_ref * (t0 + k * h))
    Z = np.fft.fft(z)
    W = np.fft.fft(window)
    dw = 2 * math.pi * spacing
    rhs = Z[(harmonics * m) % n] * np.exp(-1j * harmonics * dw * t0)
    diff = harmonics[None, :] - harmonics[:, None]  # l - j
    gram = np.conj(W[(diff * m) % n]) * np.exp(1j * diff * dw * t0)
    return 2.0 * np.linalg.solve(gram, rhs)
