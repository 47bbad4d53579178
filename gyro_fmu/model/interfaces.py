"""The FMU interfaces of the physics, declared once: names, units, bounds, descriptions.

Each `FmuInterface` generates the native FMU's `variables.h` (the C struct and table the
FMI layer checks against), its FMI 2.0 and 3.0 model descriptions and its documentation
page (`gyro_fmu.fmu.native`), and the pythonfmu flavour's variables (`fmu_src/*.py`).
Value references are the position in `variables` plus 1 (0 is FMI 3.0's `time`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

from ..core.structs import Struct
from ..core.structs import plant as structs
from ..options import SEED_MAX  # the FMUs' seed range (FMI 2.0 Integer)
from .drive import TwoToneDrive
from .parameters import (
    DEFAULT_PRESET,
    PARAMETER_BOUNDS,
    PARAMETER_DESCRIPTIONS,
    PARAMETER_UNITS,
    PRESETS,
)
from .rate import RateKind, RateProfile


@dataclass(frozen=True)
class Var:
    """One FMU variable."""

    name: str
    causality: str  #: "parameter", "input" or "output"
    start: float | int
    unit: str | None  #: key of gyro_fmu.model.units.UNITS; None only for Integers
    description: str
    integer: bool = False
    min: float | None = None
    max: float | None = None
    nominal: float | None = None
    min_exclusive: bool = False  #: min itself is refused too (FMI's min is inclusive)

    @property
    def is_parameter(self) -> bool:
        return self.causality == "parameter"

    def range_problem(self, value: float) -> str | None:
        """Why `value` is not acceptable for this variable, with the remedy; None if fine.
        The native FMI layer (fmu_src/fmi/instance_values.c, inst_range_problem) words
        it the same."""
        if not math.isfinite(value):
            what = "parameter" if self.is_parameter else self.causality
            return (f"{what} {self.name}={value!r} is not finite: give a finite value "
                    f"in {self.unit or '1'}")
        if self.min is not None and (value < self.min or
                                     (self.min_exclusive and value == self.min)):
            op = ">" if self.min_exclusive else ">="
            where = "is below its" if value < self.min else "is its exclusive"
            return f"{self.name}={value!r} {where} minimum {self.min:g}: use {op} {self.min:g}"
        if self.max is not None and value > self.max:
            return f"{self.name}={value!r} is above its maximum {self.max:g}: use <= {self.max:g}"
        return None


def dataclass_parameters(cls: type) -> tuple[Var, ...]:
    """FMU parameters for the fields of a tuning dataclass (float, int or bool fields).

    Each field may carry metadata {"unit", "description", "min", "max", "nominal",
    "min_exclusive"} (gyro_fmu.core.structs.Field.metadata); booleans
    become Integer 0/1 parameters so every importer can set them.
    """
    import dataclasses

    out = []
    for f in dataclasses.fields(cls):
        integer = f.type in (int, bool, "int", "bool")
        boolean = f.type in (bool, "bool")
        meta = f.metadata
        out.append(Var(
            f.name, "parameter", int(f.default) if integer else float(f.default),
            None if integer else meta.get("unit", "1"),
            meta.get("description", f"tuning: {f.name}"), integer=integer,
            min=0 if boolean else meta.get("min"), max=1 if boolean else meta.get("max"),
            nominal=meta.get("nominal"), min_exclusive=meta.get("min_exclusive", False),
        ))
    return tuple(out)


@dataclass(frozen=True)
class StructCopy:
    """A core struct filled from an FMU's variables (generated into variables.h): field f
    from the variable rename.get(f, rename.get("*", "{}").format(f)); fields in `zero` 0."""

    function: str
    struct: Struct
    rename: Mapping[str, str] = field(default_factory=dict)
    zero: tuple[str, ...] = ()


@dataclass(frozen=True)
class FmuInterface:
    """What an FMU shows its importer: its variables and what its checks need."""

    identifier: str  #: modelIdentifier, and the folder fmu_src/models/<identifier>/
    description: str
    variables: tuple[Var, ...]
    #: `gyro-fmu doctor`'s C-host check: (inputs held over every step, outputs read).
    doctor_check: tuple[dict[str, float], tuple[str, ...]]
    #: Inputs of the reference run stored in the FMU: (stop_time, step) -> structured array
    #: with 'time' first (`input_table`), or None for none.
    reference_inputs: Callable[[float, float], np.ndarray | None] = field(
        default=lambda stop_time, step: None)
    #: Core sources (fmu_src/core/) the model's C file needs.
    core_sources: tuple[str, ...] = ()
    #: (stopTime, stepSize) of the DefaultExperiment (and of the stored reference run);
    #: None for gyro_fmu.fmu.native.DEFAULT_EXPERIMENT.
    default_experiment: tuple[float, float] | None = None
    #: The build measures a datasheet from the built FMU's own output and ships it as
    #: documentation/datasheet.json (gyro_fmu.sensor.datasheet: GyroSensor).
    datasheet: bool = False
    #: Core structs the model's C file fills from its variables: variables.h defines each
    #: copy as `static inline <Struct> <function>(const Variables *v)` (StructCopy).
    struct_copies: tuple[StructCopy, ...] = ()

    def value_reference(self, name: str) -> int:
        return 1 + [v.name for v in self.variables].index(name)


def input_table(time: np.ndarray, columns: dict[str, np.ndarray]) -> np.ndarray:
    """Reference inputs as fmpy takes them: a structured array, 'time' first, then
    `columns` in their order."""
    out = np.zeros(time.size, dtype=[("time", float)] + [(n, float) for n in columns])
    out["time"] = time
    for name, column in columns.items():
        out[name] = column
    return out


_P = PRESETS[DEFAULT_PRESET]


def _plant_reference_inputs(stop_time: float, step: float) -> np.ndarray:
    """The default scenario's two-tone drive and a constant 1 rad/s."""
    t = np.arange(round(stop_time / step) + 1) * step
    return input_table(t, {"ux": TwoToneDrive().ux_many(t), "uy": 0 * t,
                           "Omega_z": np.ones_like(t)})


PLANT = FmuInterface(
    identifier="GyroPlant",
    description=("MEMS vibratory gyroscope (US 2011/0314910 A1, eqs. 3-5, consistent form). "
                 "Inputs ux, uy, Omega_z are held over each communication step and the step "
                 "is integrated exactly (matrix exponential); outputs x, vx, y, vy are the "
                 "measured signals (seeded white noise when noise_* > 0)."),
    variables=(
        *(Var(n, "parameter", getattr(_P, n), PARAMETER_UNITS[n], d, **PARAMETER_BOUNDS[n])
          for n, d in PARAMETER_DESCRIPTIONS.items()),
        Var("noise_x", "parameter", 0.0, "m", "std of white noise on measured x", min=0.0,
            nominal=1e-12),
        Var("noise_vx", "parameter", 0.0, "m/s", "std of white noise on measured vx", min=0.0,
            nominal=1e-8),
        Var("noise_y", "parameter", 0.0, "m", "std of white noise on measured y", min=0.0,
            nominal=1e-12),
        Var("noise_vy", "parameter", 0.0, "m/s", "std of white noise on measured vy", min=0.0,
            nominal=1e-8),
        Var("seed", "parameter", 0, None, "seed of the noise generator", integer=True, min=0,
            max=SEED_MAX),
        Var("ux", "input", 0.0, "N", "x-axis drive force, held over the step", nominal=1e-7),
        Var("uy", "input", 0.0, "N", "y-axis drive force, held over the step", nominal=1e-7),
        Var("Omega_z", "input", 0.0, "rad/s", "angular rate about z, held over the step"),
        Var("x", "output", 0.0, "m", "measured x-axis position", nominal=1e-9),
        Var("vx", "output", 0.0, "m/s", "measured x-axis velocity", nominal=1e-5),
        Var("y", "output", 0.0, "m", "measured y-axis position", nominal=1e-9),
        Var("vy", "output", 0.0, "m/s", "measured y-axis velocity", nominal=1e-5),
        Var("ax", "output", 0.0, "m/s2", "x-axis acceleration (inputs of the last step)"),
        Var("ay", "output", 0.0, "m/s2", "y-axis acceleration (inputs of the last step)"),
    ),
    # 1e-7 N on x at 1 rad/s moves the default plant by a few nm.
    doctor_check=({"ux": 1e-7, "uy": 0.0, "Omega_z": 1.0}, ("x", "vx", "y", "vy")),
    reference_inputs=_plant_reference_inputs,
    core_sources=("gyro_rng.c", "gyro_plant.c"),
    struct_copies=(StructCopy("params_of", structs.PARAMS),
                   StructCopy("noise_of", structs.PICKOFF_NOISE, {"*": "noise_{}"})),
)

_D = TwoToneDrive()
DRIVE = FmuInterface(
    identifier="TwoToneDrive",
    description=("ux = A1 sin(2 pi f1 t) + A2 sin(2 pi f2 t) (US 2011/0314910 A1, eq. 10); "
                 "uy = 0 for a single-axis-control-input gyroscope."),
    variables=(
        Var("A1", "parameter", _D.A1, "N", "amplitude of tone 1"),
        Var("f1", "parameter", _D.f1, "Hz", "frequency of tone 1", min=0.0),
        Var("A2", "parameter", _D.A2, "N", "amplitude of tone 2"),
        Var("f2", "parameter", _D.f2, "Hz", "frequency of tone 2", min=0.0),
        Var("ux", "output", 0.0, "N", "x-axis drive force"),
        Var("uy", "output", 0.0, "N", "y-axis drive force (0: single-axis control input)"),
    ),
    doctor_check=({}, ("ux", "uy")),
    core_sources=("gyro_signals.c",),
    struct_copies=(StructCopy("drive_of", structs.TWO_TONE_DRIVE),),
)

_R = RateProfile()
RATE = FmuInterface(
    identifier="RateProfile",
    description=("Omega_z(t): kind 1 constant (offset), 2 step (offset + amplitude from "
                 "t_start), 3 ramp (offset + slope (t - t_start) from t_start), 4 sine (offset "
                 "+ amplitude sin(2 pi frequency (t - t_start)) from t_start; the patent's case "
                 "is 1 rad/s at 100 Hz)."),
    variables=(
        Var("kind", "parameter", int(_R.kind), None,
            "profile: 1 constant, 2 step, 3 ramp, 4 sine", integer=True,
            min=min(RateKind), max=max(RateKind)),
        Var("offset", "parameter", _R.offset, "rad/s", "constant part of the rate"),
        Var("amplitude", "parameter", _R.amplitude, "rad/s", "step height or sine amplitude"),
        Var("frequency", "parameter", _R.frequency, "Hz", "sine frequency", min=0.0),
        Var("slope", "parameter", _R.slope, "rad/s2", "ramp slope"),
        Var("t_start", "parameter", _R.t_start, "s", "time the step, ramp or sine starts"),
        Var("Omega_z", "output", _R.offset, "rad/s", "angular rate about z"),
    ),
    doctor_check=({}, ("Omega_z",)),
    core_sources=("gyro_signals.c",),
    struct_copies=(StructCopy("rate_of", structs.RATE_PROFILE),),
)

#: The physics' native FMUs, by model identifier (gyro_fmu.fmu.native adds the observer).
PHYSICS_INTERFACES: dict[str, FmuInterface] = {i.identifier: i for i in (PLANT, DRIVE, RATE)}
