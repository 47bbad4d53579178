"""A fixed-step co-simulation master on fmpy: any FMI 2.0 CS FMUs, any connections.

Each communication step is a Jacobi step: read every output at t, set every
connected input, then step every FMU from t to t+h. All inputs are therefore
the values at t, held over the step, which is what GyroPlant and GyroObserver
assume. Per step and FMU there is one getReal (all needed outputs) and one
setReal (all its connected inputs): the fewest calls FMI 2.0 allows.
"""

from __future__ import annotations

import shutil
from collections.abc import Iterable, Mapping, Sequence
from ctypes import CFUNCTYPE, c_char_p, c_double, c_int, c_size_t, c_void_p, cast
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (  # type: ignore[attr-defined]
    FMU2Slave,
    calloc,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
    fmi2ValueReference,
    free,
)


class CoSimulationError(RuntimeError):
    """A co-simulation could not be set up or an FMU refused a step."""


@dataclass(frozen=True)
class Component:
    """One FMU instance: a name used in connections, its file, and parameter values."""

    name: str
    fmu: Path
    parameters: Mapping[str, float | int] = field(default_factory=dict)


@dataclass(frozen=True)
class Connection:
    """Output `src` ("instance.variable") feeds input `dst` ("instance.variable")."""

    src: str
    dst: str

    @classmethod
    def parse(cls, text: str) -> Connection:
        """From 'drive.ux->plant.ux'."""
        try:
            src, dst = (s.strip() for s in text.split("->"))
        except ValueError:
            raise CoSimulationError(
                f"connection {text!r} must read 'instance.output->instance.input'"
            ) from None
        return cls(src, dst)


class LogCollector:
    """Keeps every FMU log message, so an error can quote what the FMU said."""

    def __init__(self) -> None:
        #: (instance, status, category, message) of every message, in order
        self.messages: list[tuple[str, int, str, str]] = []

    def __call__(self, env: c_void_p, instance: c_char_p, status: int, category: c_char_p,
                 message: c_char_p) -> None:
        def text(b: bytes | None) -> str:
            return (b or b"").decode("utf-8", "replace")

        self.messages.append((text(instance), int(status), text(category), text(message)))

    def recent(self, instance: str, count: int = 5) -> str:
        lines = [m for name, status, _, m in self.messages if name == instance and status > 0]
        return "\n".join(lines[-count:]) or "(the FMU logged nothing)"


def fmi2_callbacks(logger: LogCollector) -> fmi2CallbackFunctions:
    callbacks = fmi2CallbackFunctions()
    callbacks.logger = fmi2CallbackLoggerTYPE(logger)
    callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
    callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
    return callbacks


@dataclass
class _Instance:
    component: Component
    description: object
    unzip_dir: str
    slave: FMU2Slave
    variables: dict  # name -> ScalarVariable
    out_vrs: list[int] = field(default_factory=list)
    in_vrs: list[int] = field(default_factory=list)


@dataclass(frozen=True)
class CoSimulationResult:
    """Recorded signals: `data[:, j]` is column `columns[j]` ("time" first)."""

    columns: tuple[str, ...]
    data: np.ndarray
    units: dict[str, str]

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.data[:, self.columns.index(name)]
        except ValueError:
            raise KeyError(f"no recorded signal {name!r}; recorded: {list(self.columns)}") from None

    def write_csv(self, path: Path) -> None:
        header = ",".join(self.columns)
        np.savetxt(path, self.data, delimiter=",", header=header, comments="", fmt="%.17g")


def _split(ref: str) -> tuple[str, str]:
    name, _, var = ref.partition(".")
    if not var:
        raise CoSimulationError(f"{ref!r} must read 'instance.variable'")
    return name, var


def _variable(inst: _Instance, var: str, causality: Iterable[str], ref: str):
    v = inst.variables.get(var)
    if v is None:
        raise CoSimulationError(
            f"{ref!r}: {inst.component.fmu.name} has no variable {var!r}; "
            f"it has {sorted(inst.variables)}"
        )
    if v.causality not in causality:
        raise CoSimulationError(
            f"{ref!r}: variable {var!r} is a {v.causality}, expected {'/'.join(causality)}"
        )
    if v.type != "Real":
        raise CoSimulationError(f"{ref!r}: only Real connections are supported, not {v.type}")
    return v


def run_cosimulation(
    components: Sequence[Component],
    connections: Sequence[Connection],
    stop_time: float,
    step: float,
    start_time: float = 0.0,
    record: Sequence[str] | None = None,
) -> CoSimulationResult:
    """Run the coupled FMUs with a fixed communication step and record signals.

    record: "instance.variable" names to keep; by default every output of every FMU.
    Returns values at the n + 1 communication points start_time + k * step.
    """
    if not step > 0.0:
        raise CoSimulationError(f"communication step {step!r} s must be > 0")
    if not stop_time > start_time:
        raise CoSimulationError(f"stop time {stop_time!r} s must be after start time {start_time}")
    names = [c.name for c in components]
    if len(set(names)) != len(names):
        raise CoSimulationError(f"instance names must be unique, got {names}")
    n_steps = round((stop_time - start_time) / step)
    logger = LogCollector()
    callbacks = fmi2_callbacks(logger)
    instances: dict[str, _Instance] = {}
    try:
        for comp in components:
            instances[comp.name] = _instantiate(comp, callbacks)
        outputs = _OutputTable(instances)
        wiring = _wire(outputs, connections)
        columns, getters = _recording(outputs, record)
        plan = _Plan(instances, outputs, wiring, getters, n_steps)
        for inst in instances.values():
            _initialize(inst, start_time, stop_time, logger)
        data = plan.data
        base, row_bytes = data.ctypes.data, data.strides[0]
        gets, sets, steps = plan.gets, plan.sets, plan.steps
        for k in range(n_steps + 1):
            t = start_time + k * step
            addr = base + k * row_bytes
            for get, comp, vrs, n, offset, name in gets:
                if get(comp, vrs, n, addr + offset) > _WARNING:
                    raise CoSimulationError(
                        f"{name} refused fmi2GetReal at t={t:.9g} s; it said:\n"
                        f"{logger.recent(name)}"
                    )
            if k == n_steps:
                break
            row = data[k]
            for set_, comp, vrs, n, offset, idx, buf, buf_addr, name in sets:
                if idx is None:
                    status = set_(comp, vrs, n, addr + offset)
                else:
                    np.take(row, idx, out=buf)
                    status = set_(comp, vrs, n, buf_addr)
                if status > _WARNING:
                    raise CoSimulationError(
                        f"{name} refused fmi2SetReal at t={t:.9g} s; it said:\n"
                        f"{logger.recent(name)}"
                    )
            for do_step, comp, name, fmu_name in steps:
                if do_step(comp, t, step, 1) > _WARNING:
                    raise CoSimulationError(
                        f"{name} ({fmu_name}) refused the step at t={t:.9g} s "
                        f"(fmi2DoStep returned an error status); it said:\n"
                        f"{logger.recent(name)}"
                    )
        data[:, 0] = start_time + np.arange(n_steps + 1) * step
        return CoSimulationResult(tuple(columns), plan.result(), _units(instances))
    finally:
        for inst in instances.values():
            _release(inst)


#: fmi2Status values above this are errors (fmi2Warning = 1).
_WARNING = 1
#: Raw prototypes of the FMI functions the loop calls: addresses as plain integers, so
#: getReal can write straight into a row of the result array (no ctypes array per call).
_GET_SET_REAL = CFUNCTYPE(c_int, c_void_p, c_void_p, c_size_t, c_void_p)
_DO_STEP = CFUNCTYPE(c_int, c_void_p, c_double, c_double, c_int)


class _Plan:
    """Memory layout and raw FMI entry points of the stepping loop.

    Row layout: time, then each instance's outputs as one contiguous block (the recorded
    ones first, in recording order, then those read only for connections), so each
    instance fills its block with a single fmi2GetReal straight into the result array.
    A destination whose sources sit in consecutive columns is set from the row itself;
    otherwise its values are gathered into a small buffer first. The loop makes the FMI
    calls the master always made (one getReal per FMU with outputs, one setReal per
    connected FMU, one doStep per FMU), without fmpy's per-call ctypes conversions.
    """

    def __init__(self, instances: dict[str, _Instance], outputs: _OutputTable, wiring: dict,
                 getters: list[tuple[str, int]], n_steps: int) -> None:
        # outputs.add registered (instance, variable) -> position in inst.out_vrs
        recorded = [(name, instances[name].out_vrs[i]) for name, i in getters]
        column: dict[tuple[str, int], int] = {}
        self.gets = []
        ncol = 1
        for name, inst in instances.items():
            start = ncol
            order = [vr for n, vr in recorded if n == name]
            order += [vr for vr in inst.out_vrs if vr not in order]
            for vr in order:
                if (name, vr) not in column:
                    column[(name, vr)] = ncol
                    ncol += 1
            vrs = [vr for vr in order if column[(name, vr)] >= start]
            if vrs:
                self.gets.append((_raw(inst.slave, "fmi2GetReal", _GET_SET_REAL),
                                  inst.slave.component, _vr_array(vrs), len(vrs), start * 8,
                                  name))
        self.sets = []
        for dst, (in_vrs, sources) in wiring.items():
            cols = [column[(s, instances[s].out_vrs[i])] for s, i in sources]
            slave = instances[dst].slave
            contiguous = cols == list(range(cols[0], cols[0] + len(cols)))
            idx = None if contiguous else np.array(cols, dtype=np.intp)
            buf = np.empty(len(cols))
            self.sets.append((_raw(slave, "fmi2SetReal", _GET_SET_REAL), slave.component,
                              _vr_array(in_vrs), len(in_vrs), cols[0] * 8, idx, buf,
                              buf.ctypes.data, dst))
        self.steps = [(_raw(inst.slave, "fmi2DoStep", _DO_STEP), inst.slave.component, name,
                       inst.component.fmu.name) for name, inst in instances.items()]
        self._keep = [s[2] for s in self.gets] + [s[2] for s in self.sets]
        self.data = np.empty((n_steps + 1, ncol))
        wanted = [0] + [column[r] for r in recorded]
        self._wanted = None if wanted == list(range(ncol)) else np.array(wanted, dtype=np.intp)

    def result(self) -> np.ndarray:
        """The recorded columns in the order asked for (no copy in the default layout)."""
        return self.data if self._wanted is None else self.data[:, self._wanted]


def _raw(slave: FMU2Slave, function: str, prototype):
    return prototype(cast(getattr(slave.dll, function), c_void_p).value)


def _vr_array(vrs: list[int]):
    return (fmi2ValueReference * len(vrs))(*vrs)


def _instantiate(comp: Component, callbacks: fmi2CallbackFunctions) -> _Instance:
    path = Path(comp.fmu)
    if not path.exists():
        raise CoSimulationError(
            f"FMU {path} of instance {comp.name!r} not found: build it with `gyro-fmu build`"
        )
    md = read_model_description(str(path))
    if md.fmiVersion != "2.0" or md.coSimulation is None:
        raise CoSimulationError(f"{path} is not an FMI 2.0 co-simulation FMU")
    unzip_dir = extract(str(path))
    slave = FMU2Slave(
        guid=md.guid,
        unzipDirectory=unzip_dir,
        modelIdentifier=md.coSimulation.modelIdentifier,
        instanceName=comp.name,
    )
    slave.instantiate(callbacks=callbacks, loggingOn=True)
    variables = {v.name: v for v in md.modelVariables}
    return _Instance(comp, md, unzip_dir, slave, variables)


class _OutputTable:
    """Which outputs each instance must deliver per step (one getReal each)."""

    def __init__(self, instances: dict[str, _Instance]) -> None:
        self.instances = instances
        self._index: dict[tuple[str, str], int] = {}

    def instance(self, ref: str) -> tuple[str, str]:
        name, var = _split(ref)
        if name not in self.instances:
            raise CoSimulationError(f"{ref!r}: no instance {name!r}; have {sorted(self.instances)}")
        return name, var

    def add(self, ref: str) -> tuple[str, int]:
        """Register output `ref`; returns (instance, position in its getReal result)."""
        name, var = self.instance(ref)
        inst = self.instances[name]
        if (name, var) not in self._index:
            v = _variable(inst, var, ("output",), ref)
            self._index[(name, var)] = len(inst.out_vrs)
            inst.out_vrs.append(v.valueReference)
        return name, self._index[(name, var)]


def _wire(outputs: _OutputTable, connections: Sequence[Connection]) -> dict:
    """Per destination: its input value references and (source, output index) pairs."""
    wiring: dict[str, tuple[list[int], list[tuple[str, int]]]] = {}
    seen: set[str] = set()
    for conn in connections:
        source = outputs.add(conn.src)
        dst_name, dst_var = outputs.instance(conn.dst)
        if conn.dst in seen:
            raise CoSimulationError(f"input {conn.dst!r} is connected twice")
        seen.add(conn.dst)
        v = _variable(outputs.instances[dst_name], dst_var, ("input",), conn.dst)
        in_vrs, sources = wiring.setdefault(dst_name, ([], []))
        in_vrs.append(v.valueReference)
        sources.append(source)
    return wiring


def _recording(outputs: _OutputTable, record: Sequence[str] | None):
    if record is None:
        record = [f"{n}.{v.name}" for n, inst in outputs.instances.items()
                  for v in inst.variables.values() if v.causality == "output" and v.type == "Real"]
    return ["time", *record], [outputs.add(ref) for ref in record]


def _units(instances: dict[str, _Instance]) -> dict[str, str]:
    return {f"{n}.{v.name}": v.unit or "" for n, inst in instances.items()
            for v in inst.variables.values()}


def _initialize(inst: _Instance, start_time: float, stop_time: float, logger: LogCollector):
    slave, name = inst.slave, inst.component.name
    try:
        slave.setupExperiment(startTime=start_time, stopTime=stop_time)
        for pname, value in inst.component.parameters.items():
            v = inst.variables.get(pname)
            if v is None or v.causality != "parameter":
                params = sorted(k for k, x in inst.variables.items() if x.causality == "parameter")
                raise CoSimulationError(
                    f"{name}: {inst.component.fmu.name} has no parameter {pname!r}; "
                    f"its parameters are {params}"
                )
            if v.type == "Real":
                slave.setReal([v.valueReference], [float(value)])
            elif v.type in ("Integer", "Enumeration"):
                slave.setInteger([v.valueReference], [int(value)])
            elif v.type == "Boolean":
                slave.setBoolean([v.valueReference], [bool(value)])
            else:
                slave.setString([v.valueReference], [str(value)])
        slave.enterInitializationMode()
        slave.exitInitializationMode()
    except FMICallException as exc:
        raise CoSimulationError(
            f"{name}: initialization failed ({exc}); it said:\n{logger.recent(name)}"
        ) from None


def _release(inst: _Instance) -> None:
    try:
        inst.slave.terminate()
        inst.slave.freeInstance()
    except Exception:
        pass
    shutil.rmtree(inst.unzip_dir, ignore_errors=True)

