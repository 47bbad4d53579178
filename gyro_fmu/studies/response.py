"""A rate response from stepped sines (IEEE Std 1431-2004 clause 12.15, transfer function):
the gain and phase of one sine, the -3 dB bandwidth of a set. Shared by `gyro-fmu spec`
and GyroSensor's datasheet."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np


def sine_gain(tau: np.ndarray, y: np.ndarray, f: float, amplitude: float) -> dict:
    """Gain and phase of the response y at times tau (s, the input sine's own clock:
    input amplitude sin(2 pi f tau)) by a least-squares fit of a sin + b cos + c."""
    w = 2.0 * math.pi * f
    X = np.column_stack([np.sin(w * tau), np.cos(w * tau), np.ones(tau.size)])
    coef, *_ = np.linalg.lstsq(X, y, rcond=None)
    g = complex(coef[0], coef[1]) / amplitude
    return {"f_hz": f, "gain": abs(g), "gain_db": 20.0 * math.log10(max(abs(g), 1e-12)),
            "phase_deg": math.degrees(math.atan2(g.imag, g.real))}


def bandwidth_3db(response: Sequence[dict]) -> dict:
    """-3 dB bandwidth (Hz): the lowest frequency at which the gain, relative to the
    lowest frequency's gain, falls through -3 dB (linear interpolation of dB in log f).
    "below"/"above": the gain was already under -3 dB at the lowest / never fell under
    it up to the highest frequency tested; the value is then that frequency."""
    f = np.array([r["f_hz"] for r in response])
    g = np.array([r["gain_db"] for r in response])
    ref = g[0]
    rel = g - ref
    peak = float(rel.max())
    if ref < -3.0:
        return {"f_3db_hz": float(f[0]), "bound": "below", "peaking_db": peak,
                "reference_gain_db": float(ref)}
    below = np.flatnonzero(rel < -3.0)
    if below.size == 0:
        return {"f_3db_hz": float(f[-1]), "bound": "above", "peaking_db": peak,
                "reference_gain_db": float(ref)}
    j = int(below[0])
    x0, x1 = math.log(f[j - 1]), math.log(f[j])
    y0, y1 = rel[j - 1], rel[j]
    x = x0 + (-3.0 - y0) * (x1 - x0) / (y1 - y0)
    return {"f_3db_hz": float(math.exp(x)), "bound": None, "peaking_db": peak,
            "reference_gain_db": float(ref)}
