"""The self-calibration FMUs: their parameter tables, and their co-simulation.

- `parameter_variables`: the FMU parameters of a settings dataclass (ResonatorParameters,
  LoopSettings): one per field, same name and default, the SI unit given by the FMU,
  the description taken from the field's `#:` comment. GyroResonator.fmu and
  GyroLoops.fmu declare their parameters with it, so a new field cannot be forgotten
  (the build fails until the FMU names its unit).
- `run_fmus`: GyroResonator.fmu and GyroLoops.fmu through the fmpy master
  (gyro_fmu.cosim.master), recorded as a CarrierRecord. It is bit-identical to
  CarrierSimulation.run, which the tests hold; CarrierSimulation is the fast path for
  long calibration records, this is the same system as importers see it.

The FMUs import this module, so it imports the master and the builder only when
`run_fmus` is called.
"""

from __future__ import annotations

import dataclasses
import inspect
import re
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ..fmu.slave import Var, dataclass_parameters
from .inprocess import COLUMNS, DEFAULT_STEP, CarrierRecord
from .loops import OUTPUTS as LOOP_OUTPUTS
from .loops import LoopSettings
from .resonator import ResonatorParameters

#: The FMUs of the self-calibration system (model identifiers).
SELFCAL_FMUS = ("GyroResonator", "GyroLoops")
#: LoopSettings fields whose FMU parameter has another name: the setpoint `amplitude`
#: would clash with the loops' output `amplitude` (the measured one).
LOOPS_RENAMED = {"amplitude": "amplitude_setpoint"}

_FIELD_COMMENT = re.compile(r"^\s+(\w+)\s*:[^=\n]+=[^#\n]*#:\s*(.+?)\s*$", re.MULTILINE)


def field_comments(cls: type) -> dict[str, str]:
    """The `#:` comment of each field of a dataclass, without a leading unit ("Hz, ...").

    A comment's first comma-separated part is taken for a unit when it has no space
    ("m/s^2/V, x forcer gain" -> "x forcer gain"; "0 loops off, 1 ..." stays whole).
    Empty when the source cannot be read.
    """
    try:
        source = inspect.getsource(cls)
    except (OSError, TypeError):
        return {}
    out = {}
    for name, comment in _FIELD_COMMENT.findall(source):
        head, _, rest = comment.partition(", ")
        if " " not in head:  # a unit: "Hz, NCO centre frequency" or a bare "Hz"
            comment = rest
        if comment:
            out[name] = comment
    return out


def parameter_variables(
    cls: type,
    units: Mapping[str, str],
    descriptions: Mapping[str, str] | None = None,
    bounds: Mapping[str, Mapping[str, float]] | None = None,
    renamed: Mapping[str, str] | None = None,
) -> tuple[Var, ...]:
    """FMU parameters for every field of the dataclass cls (keyed by field name below).

    units: the FMI unit (a key of gyro_fmu.fmu.slave.UNITS) of every float field; integer
    fields are Integer parameters without unit. descriptions: replacements of field
    comments that do not read well alone. bounds: {"min": ..., "max": ..., "nominal": ...}
    per field, refused at set time by the FMU. renamed: FMU names of fields whose own
    name is taken by another variable of the FMU.
    """
    comments = field_comments(cls)
    descriptions, bounds, renamed = descriptions or {}, bounds or {}, renamed or {}
    out = []
    for v in dataclass_parameters(cls):
        if not v.integer and v.name not in units:
            raise KeyError(f"{cls.__name__}.{v.name}: give its FMI unit in the FMU's table")
        text = descriptions.get(v.name) or comments.get(v.name) or v.name
        out.append(dataclasses.replace(
            v, name=renamed.get(v.name, v.name), unit=None if v.integer else units[v.name],
            description=text, **bounds.get(v.name, {}),
        ))
    return tuple(out)


def settings_from_parameters(cls: type, slave: object,
                             renamed: Mapping[str, str] | None = None) -> object:
    """The dataclass cls from the parameters of a slave declared by parameter_variables."""
    renamed = renamed or {}
    casts = {"int": int, "bool": bool, "float": float, int: int, bool: bool, float: float}
    return cls(**{f.name: casts.get(f.type, float)(getattr(slave, renamed.get(f.name, f.name)))
                  for f in dataclasses.fields(cls)})


def fmu_parameters(settings: object, renamed: Mapping[str, str] | None = None) -> dict:
    """Parameter values of an FMU declared by parameter_variables, from a dataclass."""
    renamed = renamed or {}
    return {renamed.get(k, k): v for k, v in dataclasses.asdict(settings).items()}


def run_fmus(
    resonator: ResonatorParameters,
    settings: LoopSettings,
    duration: float,
    step: float = DEFAULT_STEP,
    Omega_z: float = 0.0,
    seed: int = 0,
    record_from: float = 0.0,
    models_dir: Path | None = None,
) -> CarrierRecord:
    """Co-simulate GyroResonator.fmu and GyroLoops.fmu from rest for duration (s).

    Same arguments and record as CarrierSimulation(resonator, settings, seed, step,
    Omega_z).run(duration, record_from): columns carrier.COLUMNS, the communication
    points from record_from (s) to the end, both included. Missing FMUs are built
    into models_dir (default gyro_fmu.fmu.build.MODELS_DIR).

    The constant rate Omega_z is the value of the resonator's unconnected input
    Omega_z, set once before initialization (an FMI 2.0 input holds its last value).
    """
    from ..cosim.master import Component, Connection, run_cosimulation
    from ..fmu.build import MODELS_DIR, ensure_current

    models_dir = Path(MODELS_DIR if models_dir is None else models_dir)
    ensure_current(SELFCAL_FMUS, models_dir)
    problems = settings.problems()
    if problems:  # the FMU would say the same at initialization, less directly
        from .loops import LoopsError

        raise LoopsError("; ".join(problems))
    components = [
        Component("resonator", models_dir / "GyroResonator.fmu",
                  {**fmu_parameters(resonator), "seed": int(seed)},
                  inputs={"Omega_z": float(Omega_z)}),
        Component("loops", models_dir / "GyroLoops.fmu", fmu_parameters(settings, LOOPS_RENAMED)),
    ]
    connections = [Connection(f"loops.{v}", f"resonator.{v}") for v in ("Vx", "Vy")]
    connections += [Connection(f"resonator.{v}", f"loops.{v}") for v in ("Vpx", "Vpy")]
    record = [f"loops.{v}" for v in LOOP_OUTPUTS] + ["resonator.Vpx", "resonator.Vpy"]
    n = round(duration / step)
    result = run_cosimulation(components, connections, n * step, step, record=record)
    if result.data.shape != (n + 1, len(COLUMNS)):
        raise RuntimeError(f"the master returned {result.data.shape} samples, "
                           f"expected {(n + 1, len(COLUMNS))}")
    r0 = min(max(0, round(record_from / step)), n)
    return CarrierRecord(np.ascontiguousarray(result.data[r0:]), step)
