"""gyro_fmu: MEMS vibratory gyroscope FMUs and estimators (US 2011/0314910 A1)."""

__version__ = "0.1.0"
