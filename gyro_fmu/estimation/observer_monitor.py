"""Divergence monitor of GyroStateObserver: what it judges, and the errors it raises.

The check (obs_monitor_check in fmu_src/core/gyro_observer_monitor.c; its thresholds in
gyro_observer_internal.h) runs after every step and judges:

- the estimate and covariance are finite;
- the covariance has a Cholesky factor (is symmetric positive definite);
- the parameters stay physical (kxx, kyy, 1/m > 0, K positive definite) and within a
  factor RATIO of the guess (kxx, kyy, 1/m), |d| <= D_MAX, |Omega_z| below the guessed
  natural frequency (a gyro's rate is far below its resonance);
- the innovations over blocks of BLOCK corrections: with absolute noise stds given
  (sigma_z1, sigma_z2), the mean normalized innovation squared (NIS, chi-square with 2
  dof per correction: mean 2) against its chi-square band: above the 0.9999 quantile a
  warning (status 1), above NIS_LOST lost; in relative mode (R adapts to the innovations,
  so NIS says little) the RMS innovation relative to each signal's running peak at the
  end of the block (early in a run the signal is still building up):
  above REL_LOST lost (the one-step predictions miss by that
  fraction of the signal), a warning above REL_WARN.

A lost filter raises ObserverDivergedError (a GyroFmuError) naming the cause and the
remedies; every later step raises it again. Thresholds and measurements:
docs/observer-soundness.md.
"""

from __future__ import annotations

from ..errors import GyroFmuError


class ObserverDivergedError(GyroFmuError):
    """The observer lost its numerical footing or the gyro: its estimates are meaningless.

    The message names the check that tripped and the remedies; the observer refuses
    every later step (restore an earlier state or build a new one).
    """


class CoarseStepWarning(UserWarning):
    """A step the observer takes that is coarse for the guessed resonance (omega h above
    1.2, below the refusal at 2.5): the estimates and sigmas degrade (the core's words)."""


class ObserverStepError(GyroFmuError, ValueError):
    """A communication step the observer cannot use (too coarse for the gyro's resonance);
    the observer is unchanged: a smaller step goes on (in the FMU: fmi2Discard)."""
