"""Calibration during a warm-up: bias and scale factor against temperature.

The patent's point is to calibrate in the field, without a turntable. Here the
instrument warms (temperature_rate, warmup_span, warmup_tau) while calibrations run
back to back, each starting where the last one's sequence ended on the same
temperature history (ResonatorParameters.later), until the temperature has risen by
the span. Each is
checked against a rate table of the instrument held at the temperature of its mode-1
record (ratetable.table_at_readout), so the curve of the calibrations can be laid
beside the rate table's at the same temperatures.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

from ..errors import GyroFmuError
from ..model.resonator import ResonatorParameters
from .alarms import CalibrationRefusedError
from .lot import BIAS_TOLERANCE, SF_TOLERANCE_PPM


class WarmupError(GyroFmuError, ValueError):
    """The warm-up cannot be run as asked; the message names the value and the remedy."""


@dataclass(frozen=True)
class CurvePoint:
    """One calibration of the warm-up and the rate table at its temperature."""

    start: float  #: s, when its sequence began on the warm-up's clock
    temperature: float  #: K, in the middle of its mode-1 record (the read-out's)
    status: str  #: "good", "refused" (reasons named) or "WRONG" (outside the targets, exit 0)
    reason: str
    bias: float = math.nan  #: rad/s (the untrusted value when refused)
    sigma_bias: float = math.nan
    sf_ppm: float = math.nan  #: scale factor, ppm from the first point's table
    sigma_sf_ppm: float = math.nan
    table_bias: float = math.nan  #: rad/s, the rate table's at the same temperature
    table_sf_ppm: float = math.nan  #: ppm from the first point's table
    record: float = math.nan  #: s per mode record

    @property
    def d_bias(self) -> float:
        return self.bias - self.table_bias

    @property
    def d_sf_ppm(self) -> float:
        return self.sf_ppm - self.table_sf_ppm


def warmup_curve(instrument: ResonatorParameters, cfg: object, span: float,
                 progress: Callable[[CurvePoint], None] | None = None) -> list[CurvePoint]:
    """Calibrate back to back while the temperature rises by span (K) on the
    instrument's temperature history (its ramp and exponential warm-up; cfg: a
    SelfCalConfig); one CurvePoint each."""
    from .ratetable import table_at_readout
    from .sequence import MAX_SEED, self_calibrate

    rate, rise = instrument.temperature_rate, instrument.warmup_span
    if not (math.isfinite(span) and span > 0.0):
        raise WarmupError(f"span {span!r} K must be a positive number of kelvins")
    if not (rate > 0.0 or rise > span):
        raise WarmupError(f"temperature_rate {rate!r} K/s and warmup_span {rise!r} K never "
                          f"warm the resonator by the span {span:g} K: a warm-up needs a "
                          "positive ramp (--set temperature_rate=0.01) or an exponential "
                          "rise beyond the span (--set warmup_span=K --set warmup_tau=S)")
    points: list[CurvePoint] = []
    t, sf_ref = 0.0, None
    nominal = cfg.ff_duration + 0.1 + len(cfg.modes) * (cfg.settle + cfg.record)
    while instrument.temperature_offset(t) < span:
        start = instrument.later(t)
        # fresh noise for each calibration (a sequence draws seeds seed + 0..10)
        each = replace(cfg, seed=(cfg.seed + 11 * len(points)) % (MAX_SEED + 1))
        try:
            result, status, reason = self_calibrate(start, each), "good", ""
        except CalibrationRefusedError as exc:
            result, status, reason = exc.result, "refused", " | ".join(exc.problems)
        if result is None:  # the loops did not hold: no record to time, no number
            points.append(CurvePoint(t, start.temperature, status, reason))
            t += nominal
            continue
        table = table_at_readout(start, result, each)
        sf_ref = sf_ref or table.scale_factor
        point = CurvePoint(
            t, start.later(result.modes[0].t_center).temperature, status, reason,
            result.bias, result.sigma_bias, (result.scale_factor / sf_ref - 1) * 1e6,
            result.sigma_sf_ppm, table.bias, (table.scale_factor / sf_ref - 1) * 1e6,
            result.record)
        if status == "good" and not (abs(point.d_bias) < BIAS_TOLERANCE
                                     and abs(point.d_sf_ppm) < SF_TOLERANCE_PPM):
            point = replace(point, status="WRONG")
        points.append(point)
        if progress:
            progress(point)
        last = result.modes[-1]
        t += last.t_center + result.record / 2  # where its sequence ended
    return points


def write_curve(points: list[CurvePoint], out: object, summary: dict,
                figure: bool = True) -> list:
    """warmup.csv (one row per calibration), summary.json naming it, warmup.png."""
    import csv
    from dataclasses import asdict
    from pathlib import Path

    from ..outputs import write_table_and_summary

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    columns = [*asdict(points[0]), "d_bias", "d_sf_ppm"] if points else ["start"]

    def write_csv(path: Path) -> int:
        with path.open("w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=columns)
            w.writeheader()
            w.writerows({**asdict(p), "d_bias": p.d_bias, "d_sf_ppm": p.d_sf_ppm}
                        for p in points)
        return len(points)

    paths = list(write_table_and_summary(out, "warmup.csv", write_csv, summary,
                                         ("warmup.png",)))
    if figure and points:
        paths.append(curve_figure(points, out / "warmup.png"))
    return paths


def curve_figure(points: list[CurvePoint], path: object) -> object:
    """Bias and scale factor against temperature, the calibrations (1-sigma bars) on
    the rate table's curve, and their differences against the targets."""
    from ..extras import pyplot

    plt = pyplot()
    import numpy as np

    from ..outputs import save_figure

    T = np.array([p.temperature for p in points])
    good = np.array([p.status == "good" for p in points])
    fig, ax = plt.subplots(2, 2, figsize=(11, 6.5), sharex=True)
    for col, (value, sigma, table, diff, tol, unit) in enumerate((
            ("bias", "sigma_bias", "table_bias", "d_bias", BIAS_TOLERANCE, "rad/s"),
            ("sf_ppm", "sigma_sf_ppm", "table_sf_ppm", "d_sf_ppm", SF_TOLERANCE_PPM,
             "ppm"))):
        v = np.array([getattr(p, value) for p in points])
        s = np.array([getattr(p, sigma) for p in points])
        t = np.array([getattr(p, table) for p in points])
        d = np.array([getattr(p, diff) for p in points])
        top, bottom = ax[0, col], ax[1, col]
        top.plot(T, t, "k-", lw=1.5, label="rate table at the same temperature,\n"
                 "with that calibration's feed-forward")
        top.errorbar(T[good], v[good], s[good], fmt="o", ms=3, capsize=2, color="C0",
                     label="self-calibration (1 sigma)")
        if (~good).any():
            top.plot(T[~good], v[~good], "x", color="C3", label="refused / wrong")
        bottom.errorbar(T[good], d[good], s[good], fmt="o", ms=3, capsize=2, color="C0")
        for sign in (-1, 1):
            bottom.axhline(sign * tol, color="k", ls="--", lw=1)
        bottom.axhline(0.0, color="0.6", lw=0.8)
        name = "bias" if col == 0 else "scale factor from the first table"
        top.set_ylabel(f"{name} ({unit})")
        bottom.set_ylabel(f"self-calibration - table ({unit})")
        bottom.set_xlabel("temperature in the mode-1 record (K)")
        top.legend(fontsize=8)
    fig.suptitle(f"calibration during a warm-up: {int(good.sum())} of {len(points)} in "
                 f"spec, {T[0]:.2f}-{T[-1]:.2f} K")
    fig.tight_layout()
    path = save_figure(fig, path, dpi=110)
    plt.close(fig)
    return path
