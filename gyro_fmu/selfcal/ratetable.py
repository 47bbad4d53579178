"""The conventional calibration the self-calibration must reproduce: a rate table.

The same closed-loop gyroscope (mode 1, the same feed-forward correction) sits on a
simulated table turning at a set of constant rates of both signs; the mean rate
output at each is fitted with a straight line, output = SF (Omega + bias), by linear
least squares. No earth rate: the table's rates are the only rotation.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace

import numpy as np

from ..errors import GyroFmuError
from ..model.loops import LoopsError, LoopSettings
from ..model.resonator import ResonatorParameters
from . import alarms
from .inprocess import MAX_STEPS, CarrierSimulation
from .sequence import FeedForward, SelfCalConfig

#: Table rates, rad/s (about +-6, 29 and 57 deg/s, and zero).
DEFAULT_RATES = (-1.0, -0.5, -0.1, 0.0, 0.1, 0.5, 1.0)


@dataclass
class RateTableResult:
    rates: np.ndarray  #: rad/s
    outputs: np.ndarray  #: V, mean rate output at each rate
    bias: float  #: rad/s
    scale_factor: float  #: V/(rad/s)
    sigma_bias: float
    sigma_scale_factor: float
    max_nonlinearity: float  #: rad/s, largest residual of the line
    wall_time: float
    #: rad/s: the largest change of the mean output between the two halves of an
    #: averaging window; well above the noise, the dwell was too short for the loops
    unsettled: float = 0.0

    def summary(self) -> dict:
        return {
            "bias_rad_s": self.bias, "sigma_bias_rad_s": self.sigma_bias,
            "scale_factor_V_per_rad_s": self.scale_factor,
            "sigma_scale_factor_V_per_rad_s": self.sigma_scale_factor,
            "max_nonlinearity_rad_s": self.max_nonlinearity,
            "unsettled_rad_s": self.unsettled,
            "rates_rad_s": self.rates.tolist(), "outputs_V": self.outputs.tolist(),
            "wall_time_s": self.wall_time,
        }


class RateTableError(GyroFmuError, ValueError):
    """A rate-table setting that cannot work; the message names it and the remedy."""


def settling_time(lo: LoopSettings) -> float:
    """Seconds the closed loops need after a rate step: 3 / (slowest loop bandwidth),
    1 s with the default loops, where the AGC (3 Hz) is the slowest. A rate step moves
    the drive amplitude, which the AGC restores: with a 0.5 Hz AGC, 1 s dwells gave a
    table 737 ppm off its settled scale factor (benchmarks/selfcal_accuracy.py)."""
    return 3.0 / min(lo.agc_bandwidth, lo.pll_bandwidth, lo.rebalance_bandwidth)


def rate_table(res: ResonatorParameters, ff: FeedForward, cfg: SelfCalConfig | None = None,
               rates: tuple[float, ...] = DEFAULT_RATES, settle: float | None = None,
               dwell: float | None = None, average: float | None = None) -> RateTableResult:
    """Dwell at each rate, average the last `average` seconds of the rate output.

    Defaults follow the loops: settle max(2, 2 T) s from rest, dwell max(1, T) s per
    rate and average its second half, T = settling_time(loops).
    """
    cfg = cfg or SelfCalConfig()
    start = time.perf_counter()
    lo: LoopSettings = replace(cfg.loops, mode=1, sideband_index=0.0,
                               ff_xx=ff.E[0, 0], ff_xy=ff.E[0, 1], ff_yx=ff.E[1, 0],
                               ff_yy=ff.E[1, 1])
    problems = lo.problems()
    if problems:
        raise LoopsError("; ".join(problems))
    T = settling_time(lo)
    settle = max(2.0, 2.0 * T) if settle is None else settle
    dwell = max(1.0, T) if dwell is None else dwell
    average = dwell / 2 if average is None else average
    if not (math.isfinite(settle) and settle >= 0.0):
        raise RateTableError(f"settle={settle!r} s: give a finite time >= 0")
    if not (math.isfinite(dwell) and dwell >= 10 * cfg.step):
        raise RateTableError(f"dwell={dwell!r} s: give a finite time of at least "
                             f"{10 * cfg.step:g} s (10 steps); {max(1.0, T):g} s settles "
                             "these loops")
    if (settle + len(rates) * dwell) / cfg.step > MAX_STEPS:
        raise RateTableError(f"settle={settle:g} s and {len(rates)} dwells of {dwell:g} s "
                             f"are more than the {MAX_STEPS:.3g} steps of {cfg.step:g} s a "
                             "run may take: shorten the dwell or the settle")
    if not (math.isfinite(average) and 2 * cfg.step <= average <= dwell):
        raise RateTableError(f"average={average!r} s must lie between {2 * cfg.step:g} s "
                             f"and the dwell ({dwell:g} s)")
    sim = CarrierSimulation(res, lo, seed=cfg.seed + 10, step=cfg.step, Omega_z=rates[0])
    sim.run(settle)
    outputs, drifts = [], []
    for rate in rates:
        t_end = (sim.k * sim.step) + dwell
        rec = sim.run(dwell, record_from=t_end - average, Omega_z=rate)
        stats = alarms.lock_statistics(rec["phase_error"], rec["amplitude"], rec["gain"],
                                       lo.drive_limit)
        problems = alarms.lock_problems(1, *stats, 0.0, lo.amplitude, lo.drive_limit)
        out = rec["rate"][:-1]
        if problems or not np.all(np.isfinite(out)):
            raise RateTableError(
                f"rate table refused at {rate:g} rad/s (pick-off noise {res.noise:g} V per "
                f"sample on a {lo.amplitude:g} V carrier): "
                + "; ".join(problems or ["the rate output is not finite"]))
        outputs.append(float(np.mean(out)))
        half = len(out) // 2
        drifts.append(abs(float(np.mean(out[half:]) - np.mean(out[:half]))))
    r, y = np.asarray(rates, float), np.asarray(outputs)
    A = np.stack([r, np.ones_like(r)], axis=1)
    coef, *_ = np.linalg.lstsq(A, y, rcond=None)
    sf, b0 = coef
    resid = y - A @ coef
    dof = max(len(r) - 2, 1)
    s2 = float(resid @ resid) / dof
    cov = s2 * np.linalg.inv(A.T @ A)
    bias = b0 / sf
    s_bias = math.sqrt(cov[1, 1]) / abs(sf)
    return RateTableResult(r, y, bias, sf, s_bias, math.sqrt(cov[0, 0]),
                           float(np.max(np.abs(resid))) / abs(sf),
                           time.perf_counter() - start, max(drifts) / abs(sf))


def table_at_readout(instrument: ResonatorParameters, result: object,
                     cfg: SelfCalConfig) -> RateTableResult:
    """The rate table a calibration is judged against: the instrument as it was in the
    calibration's mode-1 record (the read-out's), held at that temperature, noise-free,
    with the calibration's own feed-forward (result: a SelfCalResult)."""
    ff = FeedForward(result.feedthrough, result.rho, result.feedthrough * 0)
    held = replace(instrument.later(result.modes[0].t_center).without_noise(),
                   temperature_rate=0.0)
    return rate_table(held, ff, cfg)
