"""Imperfections of the resonator against the self-calibration: the ones the estimator
models are calibrated (within the targets of the rate table, force noise within its own
1-sigmas), the ones beyond the model are refused, never answered with a wrong number."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from gyro_fmu.model.resonator import ResonatorParameters
from gyro_fmu.selfcal.alarms import CalibrationRefusedError
from gyro_fmu.selfcal.design import design
from gyro_fmu.selfcal.ratetable import rate_table
from gyro_fmu.selfcal.sequence import FeedForward, self_calibrate

TRUE = ResonatorParameters()
SHORT = dict(settle=3.0, record=5.0, sideband_spacing=0.4, sideband_count=3,
             ff_duration=0.2, auto_record=False)


def against_table(res: ResonatorParameters) -> tuple[float, float]:
    cfg = design(res, **SHORT)
    result = self_calibrate(res, cfg)
    ff = FeedForward(result.feedthrough, result.rho, result.feedthrough * 0)
    table = rate_table(res.without_noise(), ff, cfg)
    return result.bias - table.bias, (result.scale_factor / table.scale_factor - 1) * 1e6


@pytest.mark.parametrize("beta_x, beta_y", [(1e-3, 1e-3), (5e-3, 0.0), (-2e-3, 4e-3)])
def test_non_orthogonal_pickoffs_are_calibrated(beta_x, beta_y) -> None:
    # without beta_s in the model: 1 mrad each gave +5.6e-5 rad/s and -607 ppm
    d_bias, d_sf = against_table(replace(TRUE, beta_x=beta_x, beta_y=beta_y))
    assert abs(d_bias) < 7.27e-5 / 10 and abs(d_sf) < 100 / 10


@pytest.mark.parametrize("changes", [
    {"k3x": 4.2e15, "k3y": 4.2e15},  # 0.01 Hz at 1 um: was +1.1e-4 rad/s, +5055 ppm
    {"k3x": -4.2e15, "k3y": 2e15, "k3xy": 2e14, "k3yx": -4.2e14},  # softening, cross-cubic
], ids=["cubic", "cross-cubic"])
def test_cubic_stiffness_is_calibrated(changes) -> None:
    # the linear model misfits; the cubic sideband terms (eqs. 24-27) are fitted then
    d_bias, d_sf = against_table(replace(TRUE, **changes))
    assert abs(d_bias) < 7.27e-5 / 10 and abs(d_sf) < 100 / 5


def test_force_noise_is_measured_between_the_tones_and_calibrated() -> None:
    """Thermomechanical force noise at 300 K (m_modal 1e-9 kg): concentrated in the
    mode's bandwidth, 22 times the white pick-off reference of the old misfit (refused
    then). Measured between the grid's tones and weighted in the fit, the misfit is
    near 1 and the 1-sigmas cover the error against the rate table."""
    res = replace(TRUE, m_modal=1e-9)
    # 40 s records (1-sigmas 3.7e-5 rad/s, 64 ppm: the targets would need 94 and 185 s)
    cfg = design(res, **{**SHORT, "record": 40.0}, target_bias=1e-4, target_sf_ppm=200.0)
    result = self_calibrate(res, cfg)
    assert 0.6 < result.misfit_ratio < 1.6
    assert result.fit.noise.force.min() > 0.0
    ff = FeedForward(result.feedthrough, result.rho, result.feedthrough * 0)
    table = rate_table(res.without_noise(), ff, cfg)
    assert abs(result.bias - table.bias) < 3 * result.sigma_bias
    sf_ppm = (result.scale_factor / table.scale_factor - 1) * 1e6
    assert abs(sf_ppm) < 3 * result.sigma_sf_ppm
    # the same records without it: no force noise is measured (the white floor alone)
    quiet = self_calibrate(TRUE, cfg)
    assert np.all(quiet.fit.noise.force < 1e-3 * result.fit.noise.force)


def test_a_cross_cubic_beyond_the_sideband_model_is_refused() -> None:
    # 0.03 Hz at 1 um, 0.3 of the preset's 0.1 Hz half-width: in a lot, 0.43-0.45
    # half-widths gave bias errors of 12 and 48 sigmas with a perfect misfit
    with pytest.raises(CalibrationRefusedError, match="cross-cubic stiffness shifts"):
        self_calibrate(replace(TRUE, k3yx=1.3e16), design(TRUE, **SHORT))
