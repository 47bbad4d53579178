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

from .carrier import CarrierSimulation
from .loops import LoopSettings
from .resonator import ResonatorParameters
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

    def summary(self) -> dict:
        return {
            "bias_rad_s": self.bias, "sigma_bias_rad_s": self.sigma_bias,
            "scale_factor_V_per_rad_s": self.scale_factor,
            "sigma_scale_factor_V_per_rad_s": self.sigma_scale_factor,
            "max_nonlinearity_rad_s": self.max_nonlinearity,
            "rates_rad_s": self.rates.tolist(), "outputs_V": self.outputs.tolist(),
            "wall_time_s": self.wall_time,
        }


def rate_table(res: ResonatorParameters, ff: FeedForward, cfg: SelfCalConfig | None = None,
               rates: tuple[float, ...] = DEFAULT_RATES, settle: float = 2.0,
               dwell: float = 1.0, average: float = 0.5) -> RateTableResult:
    """Dwell at each rate, average the last `average` seconds of the rate output."""
    cfg = cfg or SelfCalConfig()
    start = time.perf_counter()
    lo: LoopSettings = replace(cfg.loops, mode=1, sideband_index=0.0,
                               ff_xx=ff.E[0, 0], ff_xy=ff.E[0, 1], ff_yx=ff.E[1, 0],
                               ff_yy=ff.E[1, 1])
    sim = CarrierSimulation(res, lo, seed=cfg.seed + 10, step=cfg.step, Omega_z=rates[0])
    sim.run(settle)
    outputs = []
    for rate in rates:
        t_end = (sim.k * sim.step) + dwell
        rec = sim.run(dwell, record_from=t_end - average, Omega_z=rate)
        outputs.append(float(np.mean(rec["rate"][:-1])))
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
                           time.perf_counter() - start)
