"""What one self-calibration found (sequence.self_calibrate), with its 1-sigmas."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .estimator import ModeData, SidebandFit


@dataclass
class SelfCalResult:
    """Everything the calibration found, with 1-sigma uncertainties.

    sigma_bias and sigma_scale_factor are the totals: the sideband fit's own (delta
    method) and rho's (step 1's measurement error carried through a refit), which
    are independent; the *_rho fields give rho's part alone.
    """

    bias: float  #: rad/s
    scale_factor: float  #: V/(rad/s)
    sigma_bias: float
    sigma_scale_factor: float
    sigma_bias_rho: float
    sigma_scale_factor_rho: float
    physical: dict[str, float]
    rho: complex
    feedthrough: np.ndarray
    omega_r: float  #: rad/s, mode-1 oscillation frequency
    amplitude: float
    rms_residual: float
    wall_time: float
    fit: SidebandFit
    modes: list[ModeData]
    record: float = math.nan  #: s, length of each sideband record used
    misfit_ratio: float = math.nan  #: rms residual / what the pick-off noise leaves
    pickoff_noise: float = math.nan  #: V per sample, estimated from the records
    cubic: bool = False  #: the cubic terms of eqs. 24-27 were fitted
    #: the parts of the 1-sigmas from the shift between the records (phasors.carrier_shifts)
    sigma_bias_shift: float = 0.0
    sigma_scale_factor_shift: float = 0.0
    sideband_index: float = math.nan  #: the modulation index of each tone used
    #: the drive gain's largest excursion about its mean, as a fraction of its room
    #: (sequence.drive_use; the larger of the two modes')
    drive_use: float = math.nan

    @property
    def sigma_sf_ppm(self) -> float:
        """1-sigma of the scale factor relative to it, ppm."""
        return abs(self.sigma_scale_factor / self.scale_factor) * 1e6

    def summary(self) -> dict:
        return {
            "record_s": self.record, "misfit_ratio": self.misfit_ratio,
            "sideband_index": self.sideband_index, "drive_use": self.drive_use,
            "cubic_terms_fitted": self.cubic,
            "pickoff_noise_estimate_V": self.pickoff_noise,
            "bias_rad_s": self.bias, "sigma_bias_rad_s": self.sigma_bias,
            "scale_factor_V_per_rad_s": self.scale_factor,
            "sigma_scale_factor_V_per_rad_s": self.sigma_scale_factor,
            "sigma_bias_from_rho_rad_s": self.sigma_bias_rho,
            "sigma_scale_factor_from_rho_V_per_rad_s": self.sigma_scale_factor_rho,
            "sigma_bias_from_carrier_shift_rad_s": self.sigma_bias_shift,
            "sigma_scale_factor_from_carrier_shift_V_per_rad_s": self.sigma_scale_factor_shift,
            "carrier_drift_per_s": [md.drift for md in self.modes],
            "carrier_shift": [md.shift for md in self.modes],
            "record_middle_s": [md.t_center for md in self.modes],
            "relative_pickoff_gain": abs(self.rho),
            "relative_pickoff_phase_rad": float(np.angle(self.rho)),
            "feedthrough_V_per_V": self.feedthrough.tolist(),
            "oscillation_frequency_Hz": self.omega_r / (2 * math.pi),
            "rms_residual_V": self.rms_residual, "wall_time_s": self.wall_time,
            **self.physical,
        }
