"""gyro-fmu spec: rate response (stepped sine, IEEE 1431 clause 12.15) and scale factor
(least-squares line, clause 12.9)."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..studies.response import bandwidth_3db as bandwidth_3db  # gyro_fmu.spec.bandwidth_3db
from ..studies.response import sine_gain
from .config import Record, SpecConfig, simulate


@dataclass(frozen=True)
class SineSegment:
    t0: float  #: s
    length: float  #: s, whole periods
    f: float  #: Hz


def sine_plan(cfg: SpecConfig, t_start: float) -> list[SineSegment]:
    """One segment per frequency, back to back from t_start: at least cfg.bw_segment s
    and 5 periods, rounded up to whole periods."""
    out, t = [], t_start
    for f in sorted(cfg.bw_frequencies):
        length = math.ceil(max(cfg.bw_segment, 5.0 / f) * f) / f
        out.append(SineSegment(t, length, f))
        t += length
    return out


def stepped_sine_rate(base: float, amplitude: float,
                      plan: Sequence[SineSegment]) -> Callable[[float], float]:
    """Omega(t) = base + amplitude sin(2 pi f (t - t0)) in each segment, base outside."""
    starts = np.array([s.t0 for s in plan])

    def rate(t: float) -> float:
        i = int(np.searchsorted(starts, t, side="right")) - 1
        if i < 0:
            return base
        s = plan[i]
        if t >= s.t0 + s.length:
            return base
        return base + amplitude * math.sin(2.0 * math.pi * s.f * (t - s.t0))
    return rate


def sine_response(rec: Record, plan: Sequence[SineSegment], amplitude: float,
                  h: float, discard: float = 0.3) -> list[dict]:
    """Complex gain Omega_hat / Omega at each segment's frequency: a least-squares fit of
    a sin + b cos + c to Omega_hat over the segment's last (1 - discard) part (the
    transient of the frequency change dropped). The true rate over step k is held at
    its value at t_k, so a held sine lags half a step; that lag is taken out so that
    the phase is the observer's own."""
    out = []
    t_in = rec.t - h  # the rate over the step ending at rec.t started at rec.t - h
    for s in plan:
        sel = (t_in >= s.t0 + discard * s.length) & (t_in < s.t0 + s.length)
        # the estimate at rec.t responds to the held input; compare with the continuous
        # sine at the middle of the hold (a ZOH delays by h / 2)
        tau = rec.t[sel] - s.t0 - 0.5 * h
        out.append(sine_gain(tau, rec.omega_hat[sel], s.f, amplitude))
    return out




def scale_factor_fit(rates: Sequence[float], outputs: Sequence[float],
                     full_scale: float) -> dict:
    """Least-squares line outputs = SF rates + offset (IEEE 1431 12.9).

    Returns the scale factor SF (1: Omega_hat is in rad/s), its error (SF - 1) in ppm,
    the offset (rad/s), the residuals (rad/s and ppm of full scale) and the
    nonlinearity: the largest |residual| in ppm of full scale.
    """
    r = np.asarray(rates, dtype=float)
    y = np.asarray(outputs, dtype=float)
    if r.size < 3 or np.ptp(r) == 0.0:
        raise ValueError("need at least 3 distinct rates for a line and its residuals")
    X = np.column_stack([r, np.ones_like(r)])
    (sf, offset), *_ = np.linalg.lstsq(X, y, rcond=None)
    res = y - (sf * r + offset)
    res_ppm = res / full_scale * 1e6
    return {"scale_factor": float(sf), "sf_error_ppm": float((sf - 1.0) * 1e6),
            "offset_rad_s": float(offset), "rates_rad_s": r.tolist(),
            "outputs_rad_s": y.tolist(), "residuals_rad_s": res.tolist(),
            "residuals_ppm_fs": res_ppm.tolist(),
            "nonlinearity_ppm_fs": float(np.max(np.abs(res_ppm)))}


def scale_factor_study(cfg: SpecConfig, settle: float,
                       progress: Callable[[str], None]) -> dict:
    """One run per rate in +-full scale, each from power-on with the same noise seed
    (common random numbers: the noise, which enters the estimate almost independently
    of the rate, cancels in the line, leaving the rate-dependent error), averaging
    Omega_hat over sf_record s after `settle` s. A plateau whose two halves differ by
    more than 6 sigma of noise plus 1 % of the band has not settled: SpecError."""
    rates = np.linspace(-cfg.full_scale, cfg.full_scale, cfg.sf_points)
    h = cfg.step
    means, drifts = [], []
    for i, om in enumerate(rates):
        rec = simulate(cfg, lambda t, om=float(om): om, settle + cfg.sf_record,
                       f"scale-factor run at {om:+g} rad/s")
        e = rec.omega_hat[round(settle / h):]
        half = len(e) // 2
        a, b = float(np.mean(e[:half])), float(np.mean(e[half:]))
        means.append(float(np.mean(e)))
        drifts.append(b - a)
        progress(f"  rate {om:+8.4g} rad/s: mean Omega_hat {means[-1]:+.7g} rad/s "
                 f"({i + 1}/{len(rates)}, {rec.wall_s:.1f} s)")
    fit = scale_factor_fit(rates, means, cfg.full_scale)
    fit["settle_s"] = settle
    fit["record_s"] = cfg.sf_record
    # a drift common to all rates (the same noise, the same convergence) moves only the
    # offset; what differs between rates would move the line
    common = float(np.mean(drifts))
    i = int(np.argmax(np.abs(np.array(drifts) - common)))
    fit["half_record_drift_rad_s"] = drifts
    fit["common_drift_rad_s"] = common
    fit["worst_drift"] = {"rate_rad_s": float(rates[i]), "drift_rad_s": drifts[i] - common}
    return fit
