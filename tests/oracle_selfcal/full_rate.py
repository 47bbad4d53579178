"""The full-record demodulation the self-calibration used before it streamed (gyro_fmu
0.3.0 to 188631b): the whole record held, every channel mixed down at full rate on the
loops' smoothed NCO phase, phasors by the Hann-weighted least squares of
gyro_fmu.selfcal.phasors, the noise between the tones from a rectangular FFT with the
fitted tones' image removed. The oracle of gyro_fmu.selfcal.stream (tests/
test_selfcal_stream.py); copied with only its imports changed, the NCO smoothing
expressed through the library's nco_phase (same fit, same samples).
"""

from __future__ import annotations

import math

import numpy as np

from gyro_fmu.selfcal.estimator import ModeData
from gyro_fmu.selfcal.inprocess import CarrierRecord
from gyro_fmu.selfcal.phasors import nco_phase, phasors


def off_grid(signal: np.ndarray, t0: float, h: float, omega_ref: float, spacing: float,
             harmonics: np.ndarray, c: np.ndarray, phase: np.ndarray | None = None
             ) -> tuple[np.ndarray, np.ndarray]:
    n = len(signal)
    m = round(n * h * spacing)
    harmonics = np.asarray(harmonics, dtype=int)
    if m < 2:
        return np.zeros(0), np.zeros(0, complex)
    dw = 2 * math.pi * spacing
    tones = np.zeros(n, complex)
    tones[(harmonics * m) % n] = c * np.exp(1j * harmonics * dw * t0)
    P = np.fft.ifft(tones) * n
    e = np.exp(-1j * (omega_ref * (t0 + np.arange(n) * h) + (0.0 if phase is None else phase)))
    Y = np.fft.fft(signal * e - 0.5 * np.conj(P) * e * e)
    bins = np.arange(harmonics.min() * m, harmonics.max() * m + 1)
    bins = bins[bins % m != 0]
    return bins / m, 2.0 * Y[bins % n] / n


def mode_phasors(rec: CarrierRecord, mode: int, E: np.ndarray, spacing: float,
                 count: int) -> ModeData:
    h = rec.step
    cols = CarrierRecord(rec.data[:-1], h)
    t0 = cols.time[0]
    n = len(cols.time)
    harm = np.arange(-3 * count, 3 * count + 1)
    phi = np.unwrap(cols["theta"])
    nco = nco_phase(phi, t0 + np.arange(n) * h, t0, n, h, spacing, 3 * count)
    slow = nco.curvature(t0 + np.arange(n) * h)
    omega = nco.omega + harm * 2 * math.pi * spacing
    names = ("Vx", "Vy", "Vpx", "Vpy")
    ph = {k: phasors(cols[k], t0, h, nco.omega, spacing, harm, slow) for k in names}
    off = {k: off_grid(cols[k], t0, h, nco.omega, spacing, harm, ph[k], slow) for k in names}
    off_omega = nco.omega + off["Vx"][0] * 2 * math.pi * spacing

    def corrected(ph: dict, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        D = np.stack([ph["Vx"], ph["Vy"]], axis=1)
        PO = np.stack([ph["Vpx"], ph["Vpy"]], axis=1)
        return D, PO - np.einsum("ij,nj->ni", E, D) * np.exp(-1j * w * h)[:, None]

    D, PO = corrected(ph, omega)
    off_D, off_PO = corrected({k: v for k, (_, v) in off.items()}, off_omega)
    amp = float(np.abs(PO[harm == 0, mode - 1][0]))
    return ModeData(mode, omega, D, PO, nco.omega, amp, drift=nco.drift, off_omega=off_omega,
                    off_D=off_D, off_PO=off_PO)
