"""The observer's model of Omega_z(t): fixed, or adaptive by interacting multiple models.

A user cannot know q_Omega (rad^2/s^5); the observer's innovations tell whether the
rate moves. The adaptive rate model (the default) runs seven filters that differ only
in how Omega_z may move, mixed by the IMM algorithm (Blom & Bar-Shalom, IEEE Trans. AC
33(8) 1988; Bar-Shalom, Li & Kirubarajan, "Estimation with Applications to Tracking and
Navigation", 2001, sec. 11.6.6, eqs. 11.6.6-1 to -22):

- constant: Omega_z constant (the Cramer-Rao bound's model);
- rough: random walk sized to follow rate_span at rate_bandwidth / 10 (a rate that
  wanders without a smooth derivative, e.g. a Gauss-Markov process);
- slow: integrated random walk sized to follow rate_span at rate_bandwidth / 10;
- agile: twice-integrated random walk sized to follow rate_span at rate_bandwidth;
- rough x3, x10, x100: random walks of 3, 10 and 100 times the rough model's intensity
  (ROUGH_GRADES in fmu_src/core/gyro_observer_internal.h), so that the likelihood chooses a
  wandering rate's intensity: with the rough model alone, Gauss-Markov rates of 10-50 Hz
  had error/sigma 1.2-2.7 and 2-23 % of the samples beyond 3 sigma; with the grades
  0.84-1.0 and under 0.3 % (benchmarks/observer_families.py; their probabilities count
  as "rough").

Sizing rule: a white noise of intensity q on the r-th derivative of Omega_z, with
q = rate_span^2 (2 pi f)^(2 r - 1) / (2 pi), follows a sine of amplitude rate_span at f
(Hz); it reproduces the best fixed tunings measured by hand (order 2, 10 Hz: 3.9e4
against 1e4-1e5; order 3, 100 Hz: 1.6e13 against ~1e13; docs/observer-rate-model.md).

The filters share the plant's linearization (the held step of eq. 5 about the
combined estimate), so a step costs one held step, seven corrections and seven covariance
propagations; the computation is the C core's (fmu_src/core/gyro_observer_imm.c and
gyro_observer_rates.c), this module names the models and sizes them. A fixed rate model
(constant, tracking at rate_bandwidth, or the expert q_Omega / omega_order) is the same code
with one model.

rate_model 4 (a setting, for vehicles that sway) moves the rough and slow intensities
instead of grading them: rough models at c x {1/10, 1, 10} of the rough intensity and the
slow one at min(c, 1) of its own, with c following the slope of the likelihood across
the rough ones (BANK_* in gyro_observer_internal.h). A slow sway far below the fixed
grades (0.05 rad/s at 2 Hz: error/sigma 3.9 with rate_model 0) is followed honestly
(0.97); but on the honest-observer benchmark's Gauss-Markov rates at noise 1e-5 it is
over-confident (error/sigma 1.24-1.26) and after steps from rest it restarts more, so
neither FMU defaults to it (docs/observer-rate-model.md).
"""

from __future__ import annotations

from enum import IntEnum


class RateModel(IntEnum):
    """ObserverTuning.rate_model (the FMU's Integer-valued parameter)."""

    adaptive = 0  #: IMM over constant / rough (graded) / slow / agile (the default)
    constant = 1  #: Omega_z constant (as the Cramer-Rao bound assumes)
    tracking = 2  #: one agile model at rate_bandwidth
    expert = 3  #: one model: q_Omega on the omega_order-th derivative
    moving = 4  #: IMM as adaptive, its rough and slow intensities a moving bank


#: The adaptive set's models (rate_probabilities, the FMU's p_rate_* outputs).
RATE_KINDS = ("constant", "rough", "slow", "agile")


def rate_block_size(tuning) -> int:
    """States of the rate block: Omega_z and the derivatives its models use."""
    kind = RateModel(int(tuning.rate_model))
    if kind is RateModel.constant:
        return 1
    if kind is RateModel.expert:
        return int(tuning.omega_order)
    return 3


def model_names(tuning) -> tuple[str, ...]:
    """Names of the rate models the observer runs (the FMU's p_rate_* outputs)."""
    kind = RateModel(int(tuning.rate_model))
    if kind is RateModel.adaptive:
        from ..core.observer import rough_grades

        return RATE_KINDS + tuple(f"rough x{g:g}" for g in rough_grades())
    if kind is RateModel.moving:
        return (*RATE_KINDS, "rough low", "rough high")
    return (kind.name,)
