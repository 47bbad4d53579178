"""The calibration's default settings, in one light module: SelfCalConfig's fields take
them, and `gyro-fmu selfcal --help` prints them without importing the calibration."""

from __future__ import annotations

from ..model.resonator import EARTH_RATE

RECORD = 10.0  #: s, each sideband record of the pilot
MAX_RECORD = 120.0  #: s, longest record auto_record may choose
TARGET_BIAS = EARTH_RATE / 3  #: rad/s, bias 1-sigma to reach
TARGET_SF_PPM = 30.0  #: ppm, scale-factor 1-sigma to reach
SETTLE = 8.0  #: s, before each sideband record (5 ring-down times of the preset)
SIDEBAND_INDEX = 0.04  #: modulation index per tone (raised into the drive's headroom)
SIDEBAND_COUNT = 7  #: tones at 1..count times the spacing
KAPPA = 0.8  #: Bryant factor from the factory calibration
