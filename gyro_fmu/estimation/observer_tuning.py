"""Tuning of GyroStateObserver (the FMU's tuning parameters, with units and descriptions)."""

from __future__ import annotations

from dataclasses import fields

from ..core.observer import INTEGER_FIELDS, tuning_problem
from ..core.structs import declared
from ..core.structs.observer import TUNING


def fields_by_name() -> dict:
    """ObserverTuning's dataclass fields by name (their unit and description metadata)."""
    return {f.name: f for f in fields(ObserverTuning)}


@declared(TUNING)
class ObserverTuning:
    """Tuning of GyroStateObserver; the defaults need no knowledge of the rate or the noise.

    The rate model is adaptive and the pick-off noise is estimated from the innovations
    (above a floor of noise_rel x each signal's peak) unless sigma_z1, sigma_z2 are given.
    Its fields, their defaults, units and meaning are declared with the core's struct
    (gyro_fmu.core.structs.observer.TUNING); they become FMU parameters.
    """

    def __post_init__(self) -> None:
        """Whole numbers where the FMU has Integers, numbers elsewhere; then the core's
        rules (gyro_observer_tuning_problems, the ones GyroObserver.fmu refuses with)."""
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, bool) or not isinstance(v, int | float):
                if not (f.name == "joseph" and isinstance(v, bool)):
                    raise ValueError(f"ObserverTuning.{f.name}={v!r} must be a number")
            if f.name in INTEGER_FIELDS and isinstance(v, float) and not v.is_integer():
                raise ValueError(f"ObserverTuning.{f.name}={v!r} must be a whole number "
                                 "(an FMU Integer parameter)")
            if f.name in INTEGER_FIELDS and not -2**31 <= v < 2**31:
                raise ValueError(f"ObserverTuning.{f.name}={v!r} is out of range: see its "
                                 "description for the values it takes")
        values = {f.name: (int(getattr(self, f.name)) if f.name in INTEGER_FIELDS
                           else float(getattr(self, f.name))) for f in fields(self)}
        problem = tuning_problem(values)
        if problem:
            raise ValueError(f"ObserverTuning.{problem}")
