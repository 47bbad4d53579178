"""gyro-fmu spec: noise figures from the Allan deviation of Omega_hat (IEEE Std 952-1997 Annex C,
IEEE Std 1431-2004 clause 12.11) and the start-up time (clauses 12.5, 12.6)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ..studies.allan import (
    adev_uncertainty,
    allan_deviation,
    allan_taus,
    bias_instability,
    local_slopes,
)
from .config import (
    _TUNING_NAMES,
    ARW_DEG_PER_SQRT_H,
    ARW_SLOPE_TOLERANCE,
    DEG_PER_H,
    STARTUP_SIGMAS,
    STATIONARITY_RATIO,
    Record,
    SpecConfig,
    SpecError,
)


def angle_random_walk(taus: np.ndarray, adev: np.ndarray, n: int, h: float) -> dict:
    """Angle random walk N (rad/s/sqrt(Hz) = rad/sqrt(s)): the -1/2-slope line
    sigma(tau) = N / sqrt(tau) read at tau = 1 s (IEEE 952 Annex C).

    The line is fitted to the taus whose local slope is -1/2 +- ARW_SLOPE_TOLERANCE
    (white rate noise), weighting each sigma sqrt(tau) by its inverse variance
    (adev_uncertainty). Returns {"N": ..., "tau_range": [lo, hi], "points": k}; N is None
    when no tau shows white rate noise.
    """
    slopes = local_slopes(taus, adev)
    sel = np.abs(slopes + 0.5) <= ARW_SLOPE_TOLERANCE
    if not sel.any():
        return {"N": None, "tau_range": None, "points": 0}
    w = 1.0 / adev_uncertainty(n, h, taus[sel]) ** 2
    log_n = np.sum(w * np.log(adev[sel] * np.sqrt(taus[sel]))) / np.sum(w)
    return {"N": float(np.exp(log_n)), "tau_range": [float(taus[sel][0]), float(taus[sel][-1])],
            "points": int(sel.sum())}


def moving_mean(x: np.ndarray, m: int) -> np.ndarray:
    """Trailing mean over m samples; element j is the mean of x[j : j + m]."""
    c = np.concatenate([[0.0], np.cumsum(x)])
    return (c[m:] - c[:-m]) / m


def startup_time(t: np.ndarray, error: np.ndarray, band: float, window: float,
                 h: float) -> float | None:
    """Start-up time to spec (s): the earliest time from which the error Omega_hat -
    Omega, averaged over the trailing `window` s, stays within +-band to the end of the
    record (IEEE 1431 12.5/12.6: turn-on and warm-up time). None if the last window is
    outside the band (the estimate never settles to it). The result is at least
    `window` (the first average is complete then)."""
    m = max(1, round(window / h))
    avg = moving_mean(error, m)  # the average ending at t[j + m - 1]
    outside = np.flatnonzero(np.abs(avg) > band)
    if outside.size == 0:
        return float(t[m - 1])
    j = int(outside[-1])
    if j == len(avg) - 1:
        return None
    return float(t[j + m])


def check_stationary(error: np.ndarray, h: float, taus: Sequence[float]) -> dict:
    """Compare the white-noise level (sigma(tau) sqrt(tau), median over taus) of the first
    and second half of the settled record. A ratio beyond STATIONARITY_RATIO (or its
    inverse) means a non-stationary output: an estimate whose bandwidth keeps shrinking
    (a constant-rate model averages forever) or grows; its Allan deviation is no noise
    figure."""
    half = len(error) // 2
    taus = np.asarray([tau for tau in taus if 2 * round(tau / h) <= half // 10] or [h])
    a = allan_deviation(error[:half], h, taus) * np.sqrt(taus)
    b = allan_deviation(error[half:], h, taus) * np.sqrt(taus)
    ratio = float(np.median(a) / np.median(b)) if np.median(b) > 0 else math.inf
    ok = 1.0 / STATIONARITY_RATIO <= ratio <= STATIONARITY_RATIO
    return {"ratio_first_to_second_half": ratio, "stationary": bool(ok),
            "taus": [float(x) for x in taus]}


def allan_study(rec: Record, cfg: SpecConfig) -> dict:
    """ARW, bias instability, bias and start-up time of a constant-rate record.

    The start-up part is cut before the Allan deviation: first a provisional 10 % of the
    record, then the measured start-up time if longer. The start-up window (unless
    given) is the one whose noise-only average stays inside the band at STARTUP_SIGMAS
    sigma: window = (STARTUP_SIGMAS N / band)^2, at least 1 ms, at most a tenth of the
    record. Raises SpecError when the estimate never settles into the band.
    """
    h = cfg.step
    err = rec.error
    n_all = len(err)

    def adev_after(k0: int) -> tuple[np.ndarray, np.ndarray, int]:
        e = err[k0:]
        taus = allan_taus(len(e), h)
        return taus, allan_deviation(e, h, taus), len(e)

    k0 = int(0.1 * n_all)
    taus, adev, n = adev_after(k0)
    arw = angle_random_walk(taus, adev, n, h)
    band = cfg.band
    N = arw["N"]
    if cfg.startup_window is not None:
        window = cfg.startup_window
    elif N is None:
        window = 0.01
    else:
        window = min(max((STARTUP_SIGMAS * N / band) ** 2, 1e-3), 0.1 * cfg.duration)
    t_on = startup_time(rec.t, err, band, window, h)
    if t_on is None:
        final = float(np.mean(err[-max(1, round(window / h)):]))
        raise SpecError(
            f"start-up run: the rate estimate never settles within +-{band:g} rad/s of the "
            f"true {cfg.rate:g} rad/s (averaged over {window:g} s, the last average is "
            f"{final:+.3g} rad/s off after {cfg.duration:g} s); no spec from this run. "
            "Cause: a bias beyond the band or noise too large for it; remedy: a wider "
            "--startup-band, a longer --startup-window, less noise, or another --tuning")
    k_on = round(t_on / h)
    if k_on > k0:
        if n_all - k_on < 400:
            raise SpecError(
                f"start-up run: settled only at {t_on:.3g} s of {cfg.duration:g} s, too "
                "little record for an Allan deviation: give a longer --duration")
        k0 = k_on
        taus, adev, n = adev_after(k0)
        arw = angle_random_walk(taus, adev, n, h)
    settled = err[k0:]
    bi = bias_instability(taus, adev)
    stat = check_stationary(settled, h, [tau for tau in taus if tau >= 1e-3][:6])
    N = arw["N"]
    remedy = ("--tuning rate_model=2 --tuning rate_bandwidth=HZ (a tracking model of stated "
              "bandwidth)" if "rate_model" in _TUNING_NAMES else
              "--tuning q_Omega=Q (a tracking model, omega_order 2)")
    refused = None
    if not stat["stationary"]:
        refused = (
            "the settled output is not stationary (white-noise level of the first / second "
            f"half {stat['ratio_first_to_second_half']:.3g}): the observer's rate bandwidth "
            "changes during the record (a constant rate model, or an adaptive one settling "
            "into it, averages ever longer), so its Allan deviation describes this record, "
            f"not a noise of the gyro. For noise figures at a stated bandwidth: {remedy}")
    elif N is None:
        refused = ("no white-rate-noise (-1/2) region in the Allan deviation of this record: "
                   f"give a longer --duration or a rate model of stated bandwidth: {remedy}")
    if refused:
        N = None
    sigma_bias = (N / math.sqrt(len(settled) * h)) if N else None
    B = None if refused else bi["B"]
    return {
        "rate_rad_s": cfg.rate,
        "record_s": cfg.duration,
        "settled_from_s": float(k0 * h),
        "bias_rad_s": float(np.mean(settled)),
        "bias_sigma_rad_s": sigma_bias,
        "std_rad_s": float(np.std(settled)),
        "arw_rad_s_per_sqrt_hz": N,
        "arw_deg_per_sqrt_h": None if N is None else N * ARW_DEG_PER_SQRT_H,
        "arw_tau_range_s": arw["tau_range"],
        "adev_at_1s_rad_s": None if N is None else N,
        "noise_figures_refused": refused,
        # properties of this record's Allan deviation, whether or not it is a noise figure
        "record_adev_min_rad_s": bi["adev_min"],
        "record_adev_min_tau_s": bi["tau_min"],
        "record_adev_at_1s_rad_s": (float(np.interp(0.0, np.log(taus), adev))
                                    if taus[0] <= 1.0 <= taus[-1] else None),
        "bias_instability_rad_s": B,
        "bias_instability_deg_h": None if B is None else B * DEG_PER_H,
        "bias_instability_resolved": bi["resolved"],
        "bias_instability_tau_s": bi["tau_min"],
        "adev_slope_at_min": bi["slope_at_min"],
        "stationarity": stat,
        "startup_time_s": t_on,
        "startup_band_rad_s": band,
        "startup_window_s": window,
        "settled_by_s": max(0.0, t_on - window),
        "taus_s": taus.tolist(),
        "adev_rad_s": adev.tolist(),
        "adev_rel_sigma": adev_uncertainty(n, h, taus).tolist(),
    }
