"""Overlapping Allan deviation of a rate record: how gyro noise is specified (IEEE 952).

Its slope on log axes names the noise: -1 for white phase (angle) noise, -1/2 for
white rate noise (angle random walk, read off at tau = 1 s), 0 for bias instability.
Written here, not imported: it is one cumulative sum and a difference.
"""

from __future__ import annotations

import numpy as np


def allan_deviation(rate: np.ndarray, h: float, taus: np.ndarray) -> np.ndarray:
    """Overlapping Allan deviation (units of `rate`) at each averaging time in taus (s).

    rate: uniformly sampled with step h (s). Each tau is rounded to a whole number m of
    samples, 1 <= m <= N/2; sigma^2(tau) = <(theta_{k+2m} - 2 theta_{k+m} + theta_k)^2>
    / (2 tau^2) with theta the integrated rate (angle).
    """
    rate = np.asarray(rate, dtype=float)
    taus = np.atleast_1d(np.asarray(taus, dtype=float))
    n = len(rate)
    if not (h > 0.0) or n < 2:
        raise ValueError(f"need h > 0 and at least 2 samples, got h={h!r}, {n} samples")
    m = np.rint(taus / h).astype(int)
    if np.any(m < 1) or np.any(2 * m > n):
        raise ValueError(f"averaging times {taus.tolist()} s must lie between the step "
                         f"{h:g} s and half the record ({n * h / 2:g} s)")
    theta = np.concatenate([[0.0], np.cumsum(rate)]) * h
    out = np.empty(len(m))
    for i, mi in enumerate(m):
        d = theta[2 * mi:] - 2.0 * theta[mi:-mi] + theta[:-2 * mi]
        out[i] = np.sqrt(np.mean(d**2) / (2.0 * (mi * h) ** 2))
    return out
