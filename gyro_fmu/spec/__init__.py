"""gyro-fmu spec: the observer-based gyro judged as a gyroscope (IEEE Std 1431-2004, 952-1997).

- config: what to measure (SpecConfig), the pick-off noise, the in-process record;
- noise: angle random walk and bias instability from the Allan deviation, start-up time;
- response: rate bandwidth (stepped sine) and scale factor (least-squares line);
- measure: measure_spec, the whole datasheet; cli: the `gyro-fmu spec` command.

Definitions, citations and the measured default spec: docs/gyro-spec.md.
"""

from .config import (
    Record,
    SpecConfig,
    SpecError,
    density_to_std,
    observer_tuning,
    pickoff_noise,
    simulate,
)
from .measure import measure_spec
from .noise import (
    adev_uncertainty,
    allan_study,
    allan_taus,
    angle_random_walk,
    bias_instability,
    check_stationary,
    local_slopes,
    startup_time,
)
from .response import bandwidth_3db, scale_factor_fit, scale_factor_study

__all__ = [
    "Record", "SpecConfig", "SpecError", "adev_uncertainty", "allan_study", "allan_taus",
    "angle_random_walk", "bandwidth_3db", "bias_instability", "check_stationary",
    "density_to_std", "local_slopes", "measure_spec", "observer_tuning", "pickoff_noise",
    "scale_factor_fit", "scale_factor_study", "simulate", "startup_time",
]
