"""FMU instances for the master: unpack, instantiate, initialize, log, release (fmpy)."""

from __future__ import annotations

import logging
import os
import shutil
import sys
import tempfile
import zipfile
from collections.abc import Iterable
from ctypes import c_char_p, c_void_p
from dataclasses import dataclass, field
from pathlib import Path

from fmpy import platform as fmpy_platform
from fmpy import platform_tuple, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (  # type: ignore[attr-defined]
    FMU2Slave,
    calloc,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
    free,
)

from .archives import archive_problem
from .system import Component, CoSimulationError

_log = logging.getLogger(__name__)


class LogCollector:
    """Keeps every FMU log message, so an error can quote what the FMU said. FMI 2.0's
    message is a format string (an FMU writes '%' as '%%' and '#' as '##'): kept as the
    text it stands for."""

    def __init__(self) -> None:
        #: (instance, status, category, message) of every message, in order
        self.messages: list[tuple[str, int, str, str]] = []

    def __call__(self, env: c_void_p, instance: c_char_p, status: int, category: c_char_p,
                 message: c_char_p) -> None:
        def text(b: bytes | None) -> str:
            return (b or b"").decode("utf-8", "replace")

        said = text(message).replace("%%", "%").replace("##", "#")
        self.messages.append((text(instance), int(status), text(category), said))
        _log.debug("%s [%s]: %s", text(instance), text(category), said)

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
class Instance:
    component: Component
    description: object
    unzip_dir: str
    slave: FMU2Slave
    variables: dict  # name -> ScalarVariable
    out_vrs: list[int] = field(default_factory=list)
    in_vrs: list[int] = field(default_factory=list)


def split_reference(ref: str) -> tuple[str, str]:
    name, _, var = ref.partition(".")
    if not var:
        raise CoSimulationError(f"{ref!r} must read 'instance.variable'")
    return name, var


def variable(inst: Instance, var: str, causality: Iterable[str], ref: str):
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


#: FMU archives unpacked in this process: (path, mtime, size) -> directory. Unpacking
#: (about 60 files per FMU) cost more than a 20,000-step run's stepping of drive and rate
#: together (measured in 0.2.0); FMI resources are read-only, so every instance of
#: an unchanged archive shares one directory, removed when the process ends.
_UNPACKED: dict[tuple[str, int, int], tempfile.TemporaryDirectory] = {}


def unpacked(path: Path) -> str:
    """The directory FMU `path` is unpacked in, unpacking it once per process and version.
    The archive is checked first (archives.archive_problem). Folders are named after this
    process, so the ones a killed process left are removed by the next one."""
    if not _UNPACKED:
        sweep_dead_folders()
    stat = path.stat()
    key = (str(path.resolve()), stat.st_mtime_ns, stat.st_size)
    folder = _UNPACKED.get(key)
    if folder is None:
        for old in [k for k in _UNPACKED  # a rebuilt archive, or one gone (a build's)
                    if k[0] == key[0] or not Path(k[0]).exists()]:
            _UNPACKED.pop(old).cleanup()
        folder = tempfile.TemporaryDirectory(prefix=f"{FOLDER_PREFIX}{os.getpid()}_{path.stem}_")
        try:
            with zipfile.ZipFile(path) as z:
                problem = archive_problem(z)
                if not problem:
                    z.extractall(folder.name, members=_members_to_run(z.namelist()))
        except (zipfile.BadZipFile, OSError) as exc:
            problem = f"not a readable archive ({exc})"
        if problem:
            folder.cleanup()
            raise CoSimulationError(f"{path} is not unpacked: {problem}; the FMU is damaged "
                                    "or not trustworthy")
        _UNPACKED[key] = folder
    return folder.name


#: The binaries' folders of this host (FMI 2.0's name, FMI 3.0's platform tuple).
_HOST_BINARIES = (f"binaries/{fmpy_platform}/", f"binaries/{platform_tuple}/")


def _members_to_run(names: list[str]) -> list[str]:
    """What an instance reads: the model description, the resources and this host's
    binaries (not the other platforms' binaries, the sources, the documentation: a
    quarter of the files and of the unpacking time)."""
    return [n for n in names if n == "modelDescription.xml" or n.startswith("resources/")
            or n.startswith(_HOST_BINARIES)]


#: Unpacked folders are <tmp>/gyro_fmu_<pid>_<model>_<random>.
FOLDER_PREFIX = "gyro_fmu_"


def sweep_dead_folders() -> list[Path]:
    """Remove the unpacked folders of processes that are gone (killed: no clean-up ran)."""
    removed = []
    for folder in Path(tempfile.gettempdir()).glob(f"{FOLDER_PREFIX}*_*"):
        pid = folder.name[len(FOLDER_PREFIX):].split("_", 1)[0]
        if not pid.isdigit() or not folder.is_dir():
            continue
        try:
            os.kill(int(pid), 0)
            continue  # alive (or not ours to signal)
        except ProcessLookupError:
            shutil.rmtree(folder, ignore_errors=True)
            removed.append(folder)
        except (PermissionError, OverflowError):
            continue
    return removed


def instantiate(comp: Component, callbacks: fmi2CallbackFunctions) -> Instance:
    path = Path(comp.fmu)
    if not path.exists():
        raise CoSimulationError(
            f"FMU {path} of instance {comp.name!r} not found: check the path (gyro_fmu's own "
            "FMUs are put into models/ by `gyro-fmu build`)"
        )
    if path.is_dir():
        raise CoSimulationError(f"FMU {path} of instance {comp.name!r} is a folder: give "
                                "the .fmu file")
    try:
        md = read_model_description(str(path))
    except Exception as exc:  # not a zip, truncated, no or bad modelDescription.xml
        raise CoSimulationError(
            f"{path} (instance {comp.name!r}) is not a readable FMU: {exc}; give an FMI 2.0 "
            "co-simulation .fmu (ours: `gyro-fmu build`)") from None
    if md.fmiVersion != "2.0" or md.coSimulation is None:
        raise CoSimulationError(f"{path} is not an FMI 2.0 co-simulation FMU")
    unzip_dir = unpacked(path)
    slave = FMU2Slave(
        guid=md.guid,
        unzipDirectory=unzip_dir,
        modelIdentifier=md.coSimulation.modelIdentifier,
        instanceName=comp.name,
    )
    try:
        slave.instantiate(callbacks=callbacks, loggingOn=True)
    finally:
        # pythonfmu puts the FMU's resources first on the host's sys.path for good: later
        # imports, and subprocesses that inherit sys.path (Dask, multiprocessing), would
        # take modules from inside the FMU. What it imported stays in sys.modules.
        sys.path[:] = [p for p in sys.path
                       if not (isinstance(p, str) and p.startswith(unzip_dir))]
    variables = {v.name: v for v in md.modelVariables}
    return Instance(comp, md, unzip_dir, slave, variables)


def units_of(instances: dict[str, Instance]) -> dict[str, str]:
    return {f"{n}.{v.name}": v.unit or "" for n, inst in instances.items()
            for v in inst.variables.values()}


def initialize(inst: Instance, start_time: float, stop_time: float, logger: LogCollector,
                connected: set[str]) -> None:
    """Set up the experiment, set parameters, initialize, and give unconnected inputs
    their values. connected: names of the inputs that connections drive.

    Parameters are set before fmi2EnterInitializationMode (initial="exact" allows it);
    inputs only from then on, where FMI 2.0 allows setting them."""
    slave, name = inst.slave, inst.component.name
    parameters = [(var, value, "parameter") for var, value in inst.component.parameters.items()]
    inputs = [(var, value, "input") for var, value in inst.component.inputs.items()]
    try:
        for var, value, causality in parameters + inputs:  # check all before any FMI call
            _start_variable(inst, var, value, causality, connected)
        slave.setupExperiment(startTime=start_time, stopTime=stop_time)
        for var, value, _ in parameters:
            _set_value(slave, inst.variables[var], value)
        slave.enterInitializationMode()
        for var, value, _ in inputs:
            _set_value(slave, inst.variables[var], value)
        slave.exitInitializationMode()
    except FMICallException as exc:
        raise CoSimulationError(
            f"{name}: initialization failed ({exc}); it said:\n{logger.recent(name)}"
        ) from None


def _start_variable(inst: Instance, var: str, value: object, causality: str,
                    connected: set[str]):
    """The variable a start value is given for, or a CoSimulationError saying why not."""
    name = inst.component.name
    v = inst.variables.get(var)
    if v is None or v.causality != causality:
        have = sorted(k for k, x in inst.variables.items() if x.causality == causality)
        raise CoSimulationError(
            f"{name}: {inst.component.fmu.name} has no {causality} {var!r}; "
            f"its {causality}s are {have}"
        )
    if var in connected:
        raise CoSimulationError(
            f"{name}.{var} is driven by a connection and also given the value "
            f"{value!r}: drop one of the two"
        )
    return v


def _set_value(slave: FMU2Slave, v, value: float | int | bool | str) -> None:
    """Set one start value; an Integer given a non-integral number or a Boolean given
    anything but 0/1 is refused by name (int(1.5) would silently run 1)."""
    if v.type == "Real":
        slave.setReal([v.valueReference], [float(value)])
    elif v.type in ("Integer", "Enumeration"):
        number = float(value)
        if not (number.is_integer() and -2**31 <= number < 2**31):
            raise CoSimulationError(
                f"{v.name}={value!r} is not an integer the FMI 2.0 Integer {v.name} can "
                "hold: give a whole number")
        slave.setInteger([v.valueReference], [int(number)])
    elif v.type == "Boolean":
        if value not in (0, 1):  # True and False included
            raise CoSimulationError(f"{v.name}={value!r} is not a Boolean: give 0 or 1")
        slave.setBoolean([v.valueReference], [bool(value)])
    else:
        slave.setString([v.valueReference], [str(value)])


def release(inst: Instance) -> None:
    try:
        inst.slave.terminate()
        inst.slave.freeInstance()
    except Exception:
        pass
