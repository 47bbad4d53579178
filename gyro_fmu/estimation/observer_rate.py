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
"""

from __future__ import annotations

from enum import IntEnum


class RateModel(IntEnum):
    """ObserverTuning.rate_model (the FMU's Integer-valued parameter)."""

    adaptive = 0  #: IMM over constant / rough (graded) / slow / agile (the default)
    constant = 1  #: Omega_z constant (as the Cramer-Rao bound assumes)
    tracking = 2  #: one agile model at rate_bandwidth
    expert = 3  #: one model: q_Omega on the omega_order-th derivative


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
    return (kind.name,)
