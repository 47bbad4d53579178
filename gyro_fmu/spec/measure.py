"""The observer-based gyro judged as a gyroscope: the figures of an inertial-sensor datasheet.

`measure_spec(cfg)` runs the plant and the observer in-process (the same library the
FMUs wrap, as system/inprocess.py does) and measures, from the rate estimate Omega_hat:

- angle random walk and bias instability from the overlapping Allan deviation of a
  record of `cfg.duration` seconds at a constant rate (IEEE Std 952-1997 Annex C;
  IEEE Std 1431-2004 clause 12.11, drift rate test series), and the bias (mean error);
- the start-up time to spec: when the output, averaged over a stated window, enters a
  stated band around the true rate for good (IEEE 1431 clauses 12.5 and 12.6);
- the rate bandwidth: the -3 dB point of the response to a stepped sine of the input
  rate (one sine at a time, IEEE 1431 clause 12.15, transfer function);
- scale-factor error and nonlinearity: least-squares line of the settled Omega_hat
  against the true rate over +-full scale (IEEE 1431 clause 12.9).

Definitions, citations and the measured default spec: docs/gyro-spec.md. Every function
states its contract; they raise SpecError (exit 2 on the command line) rather than
return a figure from a run that cannot be trusted (a lost observer, an estimate that
never settles).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import asdict

import numpy as np

from ..estimation.observer import ObserverTuning
from ..studies.response import bandwidth_3db
from ..system.scenario import default_initial_guess
from .config import (
    PROBABILITY_EVERY,
    Record,
    SpecConfig,
    SpecError,
    observer_tuning,
    pickoff_noise,
    simulate,
)
from .noise import allan_study, moving_mean
from .response import scale_factor_study, sine_plan, sine_response, stepped_sine_rate


def measure_spec(cfg: SpecConfig, progress: Callable[[str], None] = lambda s: None) -> dict:
    """The datasheet of this gyro + observer (a JSON-ready dict). SpecError if a run
    cannot be trusted (see the module docstring)."""
    start = time.perf_counter()
    noise = pickoff_noise(cfg)
    tuning = observer_tuning(cfg, noise)
    tun = ObserverTuning(**tuning)
    h = cfg.step
    progress(f"allan/start-up run: {cfg.duration:g} s at {cfg.rate:g} rad/s "
             f"({round(cfg.duration / h):,} steps)")
    rec = simulate(cfg, lambda t: cfg.rate, cfg.duration, "Allan/start-up run")
    progress(f"  done in {rec.wall_s:.1f} s")
    allan = allan_study(rec, cfg)
    allan["rate_model_probabilities"] = (
        probability_summary(rec, allan["settled_from_s"], h)
        if int(getattr(tun, "rate_model", -1)) in (0, 4) else None)  # only the IMMs mix
    trace = startup_trace(rec, allan["startup_window_s"], h)
    warnings_ = warning_summary("Allan/start-up run", rec)
    del rec

    settle = max(0.05, 2.0 * allan["startup_time_s"])
    plan = sine_plan(cfg, settle)
    t_end = plan[-1].t0 + plan[-1].length
    progress(f"rate-response run: {len(plan)} sines of {cfg.bw_amplitude:g} rad/s, "
             f"{plan[0].f:g}-{plan[-1].f:g} Hz, {t_end:.3g} s")
    rec = simulate(cfg, stepped_sine_rate(cfg.rate, cfg.bw_amplitude, plan), t_end,
                   "rate-response run", seed=cfg.seed + 1)
    progress(f"  done in {rec.wall_s:.1f} s")
    response = sine_response(rec, plan, cfg.bw_amplitude, h)
    bw = bandwidth_3db(response)
    warnings_ += warning_summary("rate-response run", rec)
    del rec

    progress(f"scale-factor runs: {cfg.sf_points} rates in +-{cfg.full_scale:g} rad/s, "
             f"{settle:.3g} s settling + {cfg.sf_record:g} s each")
    sf = scale_factor_study(cfg, settle, progress)
    noise_sigma = (allan["arw_rad_s_per_sqrt_hz"] or 0.0) / math.sqrt(cfg.sf_record)
    limit = 6.0 * 2.0 * noise_sigma + 0.01 * cfg.band  # 6 sigma of a difference of halves
    worst = sf["worst_drift"]
    if abs(worst["drift_rad_s"]) > limit:
        raise SpecError(
            f"scale-factor run at {worst['rate_rad_s']:+g} rad/s: Omega_hat still drifts by "
            f"{worst['drift_rad_s']:+.3g} rad/s more than the other rates' runs between the two "
            f"halves of its {cfg.sf_record:g} s plateau after {settle:.3g} s of settling (noise "
            f"allows {limit:.3g}, 6 sigma + 1 % of the start-up band): the estimate has not "
            "settled, its mean is no scale-factor point. Remedy: a longer --sf-record, a wider "
            "--startup-band, or another --tuning")

    p = cfg.scenario.params
    return {
        "what": "gyro-fmu spec: the observer-based gyro measured as a gyroscope "
                "(docs/gyro-spec.md)",
        "gyro": {"preset": cfg.preset, "overrides": dict(cfg.overrides),
                 "parameters": p.as_dict(), "drive": asdict(cfg.scenario.the_drive),
                 "initial_guess": default_initial_guess(p)},
        "noise": {"relative_to_peak": None if cfg.noise_density is not None else cfg.noise,
                  "density_m_per_sqrt_hz": cfg.noise_density,
                  "std_x_m": noise.x, "std_y_m": noise.y,
                  "density_x_m_per_sqrt_hz": noise.x * math.sqrt(2.0 * h),
                  "density_y_m_per_sqrt_hz": noise.y * math.sqrt(2.0 * h),
                  "convention": "std = density / sqrt(2 step): one-sided density, white "
                                "to the Nyquist frequency"},
        "observer_tuning": asdict(tun),
        "rate_model": rate_model_text(tun),
        "step_s": h,
        "seed": cfg.seed,
        "allan": allan,
        "rate_response": {"amplitude_rad_s": cfg.bw_amplitude, "about_rad_s": cfg.rate,
                          "method": "stepped sine, one frequency at a time",
                          "points": response, **bw},
        "scale_factor": {**sf, "full_scale_rad_s": cfg.full_scale,
                         "method": "one run per rate, same noise seed, mean of the "
                                   "settled estimate; least-squares line"},
        "warnings": warnings_,
        "wall_time_s": time.perf_counter() - start,
        "_startup_trace": trace,  # for the figure; not written to summary.json
    }


def probability_summary(rec: Record, t_from: float, h: float) -> dict | None:
    """Mean over the settled record and final probability of each rate model of an
    adaptive observer (None for an observer without them)."""
    if not rec.rate_models or rec.rate_probabilities.size == 0:
        return None
    p = rec.rate_probabilities
    k0 = min(len(p) - 1, int(t_from / (h * PROBABILITY_EVERY)))
    return {name: {"mean": float(np.mean(p[k0:, j])), "final": float(p[-1, j])}
            for j, name in enumerate(rec.rate_models)}


def warning_summary(what: str, rec: Record) -> list[str]:
    """One line per run with status-1 episodes of the observer (innovations above their
    chi-square band): how many, and the first one in words."""
    if not rec.warnings:
        return []
    t, text = rec.warnings[0]
    return [f"{what}: {len(rec.warnings)} innovation warning(s) (status 1) in "
            f"{rec.t[-1]:.3g} s; the first at t = {t:.4g} s: {text}"]


def startup_trace(rec: Record, window: float, h: float, points: int = 400) -> dict:
    """The trailing-window mean of the error at log-spaced times (for the figure)."""
    out = {}
    for key, w in (("", window), ("_1ms", 1e-3)):
        m = max(1, round(w / h))
        avg = moving_mean(rec.error, m)
        j = np.unique(np.geomspace(1, len(avg), points).astype(int) - 1)
        out[f"t_s{key}"] = rec.t[j + m - 1].tolist()
        out[f"error_rad_s{key}"] = avg[j].tolist()
    return out


def rate_model_text(tun: ObserverTuning) -> str:
    """The observer's rate model in words, for the ObserverTuning at hand: with a
    rate_model field (0 adaptive, 1 constant, 2 tracking, 3 expert, 4 moving bank) or
    without one
    (q_Omega on the omega_order-th derivative only)."""
    d = asdict(tun)
    if "rate_model" not in d:
        return f"q_Omega {d['q_Omega']:g}, omega_order {d['omega_order']:g}"
    kind = int(d["rate_model"])
    follow = (f"rate_bandwidth {d.get('rate_bandwidth', float('nan')):g} Hz, "
              f"rate_span {d.get('rate_span', float('nan')):g} rad/s")
    if kind == 0:
        return (f"rate_model 0 (adaptive: constant/rough/slow/agile mixed), {follow}, "
                f"rate_dwell {d.get('rate_dwell', float('nan')):g} s")
    if kind == 4:
        return (f"rate_model 4 (adaptive, a moving bank of intensities), {follow}, "
                f"rate_dwell {d.get('rate_dwell', float('nan')):g} s")
    if kind == 1:
        return "rate_model 1 (constant)"
    if kind == 2:
        return f"rate_model 2 (tracking), {follow}"
    return f"rate_model {kind} (expert), q_Omega {d['q_Omega']:g}, omega_order {d['omega_order']:g}"
