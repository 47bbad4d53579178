"""gyro-fmu spec: the observer-based gyro judged as a gyroscope (IEEE Std 1431-2004, 952-1997).

- config: what to measure (SpecConfig), the pick-off noise, the in-process record;
- noise: angle random walk and bias instability from the Allan deviation, start-up time;
- response: rate bandwidth (stepped sine) and scale factor (least-squares line);
- measure: measure_spec, the whole datasheet; cli: the `gyro-fmu spec` command.

Definitions, citations and the measured default spec: docs/gyro-spec.md.
"""

import importlib

#: The public names, imported on first use (the CLI's parser imports gyro_fmu.spec.cli,
#: which must not pull in the measurement stack).
_EXPORTS = {
    **dict.fromkeys(("Record", "SpecConfig", "SpecError", "density_to_std", "observer_tuning",
                     "pickoff_noise", "simulate"), "config"),
    "measure_spec": "measure",
    **dict.fromkeys(("adev_uncertainty", "allan_study", "allan_taus", "angle_random_walk",
                     "bias_instability", "check_stationary", "local_slopes", "startup_time"),
                    "noise"),
    **dict.fromkeys(("bandwidth_3db", "scale_factor_fit", "scale_factor_study"), "response"),
}
__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> object:
    if name in _EXPORTS:
        value = getattr(importlib.import_module(f"{__name__}.{_EXPORTS[name]}"), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return __all__
