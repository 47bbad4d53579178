"""The one place where gyro_fmu adapts pythonfmu: variable tables, units, safe callbacks.

Every FMU slave in fmu_src/ is a subclass of `GyroSlave` that declares a table
of `Var` and implements `setup()` and `advance()`. This base class

- registers the variables with pythonfmu and writes what pythonfmu leaves out
  of modelDescription.xml (units with base-unit exponents, min/max/nominal),
- builds the library objects from the parameters when initialization ends,
- never lets a Python exception escape a callback: pythonfmu turns one into
  fmi2Fatal, after which fmi2Terminate crashes the importer (FIELD-NOTES).
  A failed step returns False, which pythonfmu reports as fmi2Discard.

Library imports happen inside the slaves' methods, not at module top: a C host
that imported numpy at module load aborted at process exit (FIELD-NOTES).
"""

from __future__ import annotations

import math
import traceback
import warnings
from dataclasses import dataclass
from typing import Any, ClassVar
from xml.etree.ElementTree import Element, SubElement

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability
from pythonfmu.enums import Fmi2Initial, Fmi2Status
from pythonfmu.variables import Integer, Real

#: SI base-unit exponents of every unit the FMUs use (FMI 2.0 <BaseUnit>).
UNITS: dict[str, dict[str, int]] = {
    "m": {"m": 1},
    "m/s": {"m": 1, "s": -1},
    "m/s2": {"m": 1, "s": -2},
    "N": {"kg": 1, "m": 1, "s": -2},
    "kg": {"kg": 1},
    "s": {"s": 1},
    "Hz": {"s": -1},
    "1/s": {"s": -1},
    "1/s2": {"s": -2},
    "rad/s": {"rad": 1, "s": -1},
    "rad/s2": {"rad": 1, "s": -2},
}


@dataclass(frozen=True)
class Var:
    """One FMU variable: what pythonfmu registers plus what it cannot write."""

    name: str
    causality: str  #: "parameter", "input" or "output"
    start: float | int
    unit: str | None  #: key of UNITS, or None for dimensionless
    description: str
    integer: bool = False
    min: float | None = None
    max: float | None = None
    nominal: float | None = None

    @property
    def is_parameter(self) -> bool:
        return self.causality == "parameter"


class GyroSlave(Fmi2Slave):
    """Base of all gyro_fmu slaves: declares VARIABLES, guards every callback."""

    VARIABLES: ClassVar[tuple[Var, ...]] = ()
    author = "gyro_fmu"
    license = "MIT"

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.failed: str | None = None
        self.start_time = 0.0
        for var in self.VARIABLES:
            setattr(self, var.name, var.start)
            self.register_variable(self._pythonfmu_variable(var))

    @staticmethod
    def _pythonfmu_variable(var: Var) -> Real | Integer:
        causality = Fmi2Causality[var.causality]
        if var.is_parameter:
            variability, initial = Fmi2Variability.fixed, None
        elif var.integer:
            variability, initial = Fmi2Variability.discrete, None
        else:
            variability, initial = Fmi2Variability.continuous, None
        if causality == Fmi2Causality.output:
            initial = Fmi2Initial.exact
        cls = Integer if var.integer else Real
        return cls(
            var.name,
            causality=causality,
            description=var.description,
            variability=variability,
            initial=initial,
        )

    # --- hooks for subclasses ------------------------------------------------
    def setup(self) -> None:
        """Build the library objects from the parameters (end of initialization)."""

    def advance(self, t: float, h: float) -> None:
        """Advance from t to t+h and update the outputs."""
        raise NotImplementedError

    # --- FMI callbacks -------------------------------------------------------
    def setup_experiment(
        self, start_time: float, stop_time: float | None, tolerance: float | None
    ) -> None:
        self.start_time = start_time

    def exit_initialization_mode(self) -> None:
        try:
            self._check_finite_parameters()
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                self.setup()
            for w in caught:  # e.g. a growing mode: the importer's log must show it
                self.log(f"{self.modelName}: {w.message}", Fmi2Status.warning)
        except Exception as exc:
            self._fail("initialization", exc)

    def do_step(self, current_time: float, step_size: float) -> bool:
        if self.failed is not None:
            self.log(f"{self.modelName}: cannot step: {self.failed}", Fmi2Status.error)
            return False
        try:
            if not (math.isfinite(step_size) and step_size > 0.0):
                raise ValueError(
                    f"communication step size {step_size!r} s must be > 0 and finite"
                )
            self.advance(current_time, step_size)
        except Exception as exc:
            self.log(
                f"{self.modelName}: step at t={current_time:.9g} s failed: {exc}",
                Fmi2Status.discard,
            )
            self.log(traceback.format_exc(), Fmi2Status.ok, category="logAll")
            return False
        return True

    def _check_finite_parameters(self) -> None:
        for var in self.VARIABLES:
            if var.is_parameter:
                value = getattr(self, var.name)
                if not math.isfinite(value):
                    raise ValueError(f"parameter {var.name}={value!r} must be finite")

    def _fail(self, where: str, exc: Exception) -> None:
        self.failed = f"{where} failed: {exc}"
        self.log(f"{self.modelName}: {self.failed}", Fmi2Status.error)
        self.log(traceback.format_exc(), Fmi2Status.ok, category="logAll")

    # --- model description: what pythonfmu leaves out ------------------------
    def to_xml(self, model_options: dict[str, str] | None = None) -> Element:
        root = super().to_xml(model_options or {})
        by_name = {v.name: v for v in self.VARIABLES}
        used_units: list[str] = []
        for node in root.iter("ScalarVariable"):
            var = by_name[node.get("name")]
            type_node = node[0]
            if var.unit is not None and not var.integer:
                type_node.set("unit", var.unit)
                if var.unit not in used_units:
                    used_units.append(var.unit)
            for attr in ("min", "max", "nominal"):
                value = getattr(var, attr)
                if value is not None:
                    type_node.set(attr, f"{value:.16g}" if not var.integer else str(int(value)))
        if used_units:
            unit_defs = Element("UnitDefinitions")
            for unit in used_units:
                u = SubElement(unit_defs, "Unit", name=unit)
                SubElement(u, "BaseUnit", {k: str(v) for k, v in UNITS[unit].items()})
            position = list(root).index(root.find("CoSimulation")) + 1
            root.insert(position, unit_defs)
        return root


def dataclass_parameters(cls: type) -> tuple[Var, ...]:
    """FMU parameters for the fields of a tuning dataclass (float, int or bool fields).

    Each field may carry metadata {"unit": ..., "description": ...}; booleans become
    Integer 0/1 parameters so every importer can set them.
    """
    import dataclasses

    out = []
    for f in dataclasses.fields(cls):
        integer = f.type in (int, bool, "int", "bool")
        boolean = f.type in (bool, "bool")
        start = int(f.default) if integer else float(f.default)
        out.append(Var(f.name, "parameter", start, f.metadata.get("unit"),
                       f.metadata.get("description", f"tuning: {f.name}"), integer=integer,
                       min=0 if boolean else None,
                       max=1 if boolean else None))
    return tuple(out)


def dataclass_from_parameters(cls: type, slave: object) -> object:
    """Instance of a tuning dataclass from the slave's parameters of the same names."""
    import dataclasses

    casts = {"int": int, "bool": bool, "float": float, int: int, bool: bool, float: float}
    return cls(**{f.name: casts.get(f.type, float)(getattr(slave, f.name))
                  for f in dataclasses.fields(cls)})
