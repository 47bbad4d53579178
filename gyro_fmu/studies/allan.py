"""The overlapping Allan deviation of a rate record and the figures read off it, as
gyro noise is specified (IEEE Std 952-1997 Annex C): its slope on log axes names the
noise (-1 white angle noise, -1/2 white rate noise, the angle random walk read at
tau = 1 s, 0 bias instability). Shared by the self-calibration, `gyro-fmu spec` and
GyroSensor's datasheet. Written here, not imported: it is one cumulative sum and a
difference (`allantools` would add a dependency for ten lines).
"""

from __future__ import annotations

import math

import numpy as np

#: sigma = B sqrt(2 ln 2 / pi) on the Allan deviation's flat part (IEEE 952 Annex C).
BIAS_INSTABILITY_FACTOR = math.sqrt(2.0 * math.log(2.0) / math.pi)  # 0.664
#: Longest averaging time of allan_taus, as a fraction of the record.
TAU_MAX_FRACTION = 0.2


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


def allan_taus(n: int, h: float, per_decade: int = 10,
               max_fraction: float = TAU_MAX_FRACTION) -> np.ndarray:
    """Averaging times (s): whole multiples m h of the step, log-spaced, from h up to
    max_fraction of the record of n samples (unique m)."""
    m_max = max(1, int(max_fraction * n))
    count = max(2, int(per_decade * math.log10(max(m_max, 10))))
    m = np.unique(np.rint(np.geomspace(1, m_max, count))).astype(int)
    return m * h


def adev_uncertainty(n: int, h: float, taus: np.ndarray) -> np.ndarray:
    """Relative 1-sigma error of an Allan deviation estimate at each tau from n samples:
    1 / sqrt(2 (n / m - 1)) with m = tau / h samples per cluster (IEEE 952 Annex C);
    conservative for the overlapping estimator."""
    clusters = n / np.rint(np.asarray(taus) / h)
    return 1.0 / np.sqrt(2.0 * np.maximum(clusters - 1.0, 1.0))


def local_slopes(taus: np.ndarray, adev: np.ndarray) -> np.ndarray:
    """d log(adev) / d log(tau) at each tau (central differences, one-sided at the ends)."""
    return np.gradient(np.log(adev), np.log(taus))


def bias_instability(taus: np.ndarray, adev: np.ndarray) -> dict:
    """Bias instability B (rad/s) = the Allan deviation's flat minimum / 0.664
    (sigma = B sqrt(2 ln 2 / pi) on the flat part; IEEE 952 Annex C).

    The minimum is sought beyond the deviation's first maximum: below it the output is
    smoothed by the observer's own bandwidth (the deviation rises with tau there, a
    filter's signature, not a bias). "resolved" is True when the minimum lies inside
    the tau range (not in its last two points) with a local slope within +-0.25 there;
    otherwise the record is too short (the deviation still falls) and B is an upper
    bound: the last deviation / 0.664.
    """
    falls = np.flatnonzero(np.diff(adev) < 0.0)
    i0 = int(falls[0]) if falls.size else 0
    i = i0 + int(np.argmin(adev[i0:]))
    slopes = local_slopes(taus, adev)
    resolved = i < len(adev) - 2 and abs(slopes[i]) <= 0.25
    return {"B": float(adev[i] / BIAS_INSTABILITY_FACTOR), "tau_min": float(taus[i]),
            "adev_min": float(adev[i]), "resolved": bool(resolved),
            "slope_at_min": float(slopes[i])}
