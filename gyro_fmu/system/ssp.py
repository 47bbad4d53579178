"""The standard system as an SSP package (SSP 1.0), and a run of it in libcosim.

`write_ssp` packs the four FMUs, the wiring of patent Fig. 2 (`scenario.CONNECTIONS`)
and the scenario's parameter values (exactly what `fmu_system` gives each
component, as inline ParameterBindings) into one `.ssp` zip, so any SSP tool can
run the same system our fmpy master runs.

`run_ssp_libcosim` runs such a package in libcosim (the Open Simulation Platform
engine, through libcosimpy). Why libcosim: of the SSP importers installable from
PyPI it is the one that applies ParameterBindings (fmpy.ssp ignores them,
docs/engines.md). Its fixed-step algorithm is the same Jacobi scheme as our master;
only its integer-nanosecond clock differs, which leaves about 1e-9 relative
differences in Omega_hat after 100 ms (see `run_ssp_libcosim`).

Two libcosim traits shape the file. It rejects connectors on the system itself
(docs/engines.md), so the package has component connectors only; every component
lists its inputs, outputs and bound parameters. And a fixed step is not part of
the SSP standard, so the step is written as the OSP annotation
`osp:FixedStepAlgorithm` in DefaultExperiment, where libcosim's parser looks
(other tools ignore it). The file validates against the SSP 1.0 schemas.

All bound values form one parameter set, `PARAMETER_SET` ("scenario"): every
component's ParameterBinding holds an ssv:ParameterSet of that same name. SSP
importers apply parameter sets by name: Ecos applies only the set named with
`--parameterSet` / `init(parameter_set=...)`, to every instance that has one of
that name, so with one name per component it applied a quarter of the scenario.
libcosim applies each component's (first) set. A single system-level set with
hierarchical names (drive.A1, ...) is what SSP also allows, but neither libcosim
nor Ecos reads system-level bindings (measured: both ran on the FMUs' defaults).
Every Real value carries the unit of its FMU variable (ssv:Real unit=), defined in
the set's ssv:Units (from the FMU's UnitDefinitions), as SSP 1.0 requires.
"""

from __future__ import annotations

import ctypes
import tempfile
import zipfile
from collections.abc import Iterable, Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np
from fmpy import read_model_description

from ..cosim.master import Component, Connection, CoSimulationError, whole_steps
from ..extras import require
from ..fmu.build import MODELS_DIR
from ..outputs import atomic_write
from ..upstream.libcosim_samples import get_real_samples
from .scenario import Scenario, fmu_system, scenario

#: Default package written by `write_ssp` for the default scenario.
DEFAULT_SSP = MODELS_DIR / "GyroSystem.ssp"
SYSTEM_NAME = "GyroSystem"

SSD = "http://ssp-standard.org/SSP1/SystemStructureDescription"
SSC = "http://ssp-standard.org/SSP1/SystemStructureCommon"
SSV = "http://ssp-standard.org/SSP1/SystemStructureParameterValues"
OSP = "http://opensimulationplatform.com/SSP/OSPAnnotations"
#: Annotation type libcosim looks for (its fixed-step master settings).
OSP_ANNOTATION = "com.opensimulationplatform"

for _prefix, _uri in (("ssd", SSD), ("ssc", SSC), ("ssv", SSV), ("osp", OSP)):
    ET.register_namespace(_prefix, _uri)

#: FMI type of a modelDescription variable -> SSP type element.
_SSP_TYPES = {"Real": "Real", "Integer": "Integer", "Enumeration": "Integer",
              "Boolean": "Boolean", "String": "String"}
#: libcosim time unit: durations and time points are integer nanoseconds.
_NS = 1_000_000_000
#: Name of the one parameter set of the package (what Ecos' --parameterSet names).
PARAMETER_SET = "scenario"
#: SI exponents of an FMI BaseUnit / ssc:BaseUnit (the same attributes in both).
_BASE_UNIT_ATTRIBUTES = ("kg", "m", "s", "A", "K", "mol", "cd", "rad", "factor", "offset")


class SSPError(CoSimulationError):
    """The package could not be written or run (a CoSimulationError, for the CLI)."""


def _q(ns: str, tag: str) -> str:
    return f"{{{ns}}}{tag}"


def _format(value: object, ssp_type: str) -> str:
    if ssp_type == "Real":
        return repr(float(value))  # shortest text that round-trips the double exactly
    if ssp_type == "Integer":
        return str(int(value))
    if ssp_type == "Boolean":
        return "true" if value else "false"
    return str(value)


def _connectors(parent: ET.Element, variables: Mapping[str, object],
                names: Iterable[str]) -> None:
    conns = ET.SubElement(parent, _q(SSD, "Connectors"))
    for name in names:
        v = variables[name]
        c = ET.SubElement(conns, _q(SSD, "Connector"), name=name, kind=v.causality)
        ET.SubElement(c, _q(SSC, _SSP_TYPES[v.type]))


def _unit_definitions(fmu: Path) -> dict[str, dict[str, str]]:
    """unit name -> its BaseUnit attributes (SI exponents, factor, offset), from the
    FMU's UnitDefinitions (a unit without BaseUnit: {}, i.e. dimensionless)."""
    with zipfile.ZipFile(fmu) as z:
        md = ET.fromstring(z.read("modelDescription.xml"))
    units = {}
    for unit in md.iterfind("UnitDefinitions/Unit"):
        base = unit.find("BaseUnit")
        units[unit.get("name")] = {} if base is None else {
            k: base.get(k) for k in _BASE_UNIT_ATTRIBUTES if base.get(k) is not None}
    return units


def _parameter_binding(parent: ET.Element, name: str, variables: Mapping[str, object],
                       values: Mapping[str, object],
                       units: Mapping[str, Mapping[str, str]]) -> None:
    """The component's ParameterBinding: an inline ssv:ParameterSet called `name`.

    A Real value carries its FMU variable's unit (ssv:Real unit=), and the set's
    ssv:Units defines each unit used (SSP 1.0: a unit attribute must reference a
    definition in the enclosing file). ssv:Integer has no unit in SSP 1.0.
    """
    bindings = ET.SubElement(parent, _q(SSD, "ParameterBindings"))
    binding = ET.SubElement(bindings, _q(SSD, "ParameterBinding"))
    pvalues = ET.SubElement(binding, _q(SSD, "ParameterValues"))
    pset = ET.SubElement(pvalues, _q(SSV, "ParameterSet"), version="1.0", name=name)
    params = ET.SubElement(pset, _q(SSV, "Parameters"))
    used: list[str] = []
    for pname, value in values.items():
        ssp_type = _SSP_TYPES[variables[pname].type]
        p = ET.SubElement(params, _q(SSV, "Parameter"), name=pname)
        attrs = {"value": _format(value, ssp_type)}
        unit = getattr(variables[pname], "unit", None) if ssp_type == "Real" else None
        if unit:
            if unit not in units:
                raise SSPError(f"{pname}: unit {unit!r} is not in the FMU's UnitDefinitions")
            attrs["unit"] = unit
            if unit not in used:
                used.append(unit)
        ET.SubElement(p, _q(SSV, ssp_type), attrs)
    if used:
        defs = ET.SubElement(pset, _q(SSV, "Units"))
        for unit in used:
            ET.SubElement(ET.SubElement(defs, _q(SSC, "Unit"), name=unit),
                          _q(SSC, "BaseUnit"), dict(units[unit]))


def system_structure(components: Iterable[Component], connections: Iterable[Connection],
                     stop_time: float, step: float, parameter_set: str = PARAMETER_SET
                     ) -> tuple[ET.Element, dict[str, Path]]:
    """The SystemStructure.ssd tree and the FMU files it refers to (resources/NAME.fmu).

    All bindings belong to the one parameter set `parameter_set` (each component's
    ParameterBinding holds a set of that name; see the module docstring).

    Each component lists its inputs, outputs and bound parameters as connectors,
    with the types from its modelDescription (an Integer parameter such as the
    rate profile's `kind` must be bound as ssv:Integer, or the importer refuses it).
    """
    root = ET.Element(_q(SSD, "SystemStructureDescription"), version="1.0", name=SYSTEM_NAME)
    system = ET.SubElement(root, _q(SSD, "System"), name=SYSTEM_NAME)
    elements = ET.SubElement(system, _q(SSD, "Elements"))
    resources: dict[str, Path] = {}
    for comp in components:
        fmu = Path(comp.fmu)
        if not fmu.exists():
            raise SSPError(f"FMU {fmu} of {comp.name!r} not found: run `gyro-fmu build`")
        variables = {v.name: v for v in read_model_description(str(fmu)).modelVariables}
        unknown = sorted(set(comp.parameters) - set(variables))
        if unknown:
            raise SSPError(f"{comp.name}: {fmu.name} has no variable(s) {unknown}")
        source = f"resources/{fmu.name}"
        if resources.setdefault(source, fmu) != fmu:
            raise SSPError(f"two different FMUs are both called {fmu.name}")
        element = ET.SubElement(elements, _q(SSD, "Component"), name=comp.name,
                                type="application/x-fmu-sharedlibrary", source=source)
        io = [n for n, v in variables.items() if v.causality in ("input", "output")]
        _connectors(element, variables, [*comp.parameters, *io])
        if comp.parameters:
            _parameter_binding(element, parameter_set, variables, comp.parameters,
                               _unit_definitions(fmu))
    conns = ET.SubElement(system, _q(SSD, "Connections"))
    for c in connections:
        src, _, src_var = c.src.partition(".")
        dst, _, dst_var = c.dst.partition(".")
        ET.SubElement(conns, _q(SSD, "Connection"), startElement=src, startConnector=src_var,
                      endElement=dst, endConnector=dst_var)
    experiment = ET.SubElement(root, _q(SSD, "DefaultExperiment"), startTime="0.0",
                               stopTime=repr(float(stop_time)))
    annotation = ET.SubElement(ET.SubElement(experiment, _q(SSD, "Annotations")),
                               _q(SSC, "Annotation"), type=OSP_ANNOTATION)
    algorithm = ET.SubElement(annotation, _q(OSP, "Algorithm"))
    ET.SubElement(algorithm, _q(OSP, "FixedStepAlgorithm"), baseStepSize=repr(float(step)))
    ET.indent(root)
    return root, resources


def write_ssp(sc: Scenario | None = None, models_dir: Path = MODELS_DIR,
              dest: Path | None = None, parameter_set: str = PARAMETER_SET) -> Path:
    """Write the scenario's system as an SSP package; returns its path.

    Contents: SystemStructure.ssd (components drive, rate, plant, observer; the
    connections of `scenario.CONNECTIONS`; every parameter value `fmu_system`
    sets, as inline ParameterBindings that form the one parameter set
    `parameter_set`, each Real value with its unit; DefaultExperiment 0..stop_time; the
    communication step as an OSP annotation) and resources/*.fmu.
    Default: models_dir/GyroSystem.ssp for the default scenario; a dest that is a folder
    gets GyroSystem.ssp inside it.
    """
    sc = scenario() if sc is None else sc
    models_dir = Path(models_dir)
    dest = models_dir / f"{SYSTEM_NAME}.ssp" if dest is None else Path(dest)
    if dest.is_dir():  # a folder given: the package goes into it
        dest = dest / f"{SYSTEM_NAME}.ssp"
    components, connections = fmu_system(sc, models_dir)
    return write_system_ssp(components, connections, sc.stop_time, sc.step, dest,
                            parameter_set)


def write_system_ssp(components: Iterable[Component], connections: Iterable[Connection],
                     stop_time: float, step: float, dest: Path,
                     parameter_set: str = PARAMETER_SET) -> Path:
    """Any system of our FMUs as an SSP package at dest (see `system_structure`); returns
    dest."""
    dest = Path(dest)
    root, resources = system_structure(components, connections, stop_time, step,
                                       parameter_set)
    dest.parent.mkdir(parents=True, exist_ok=True)
    xml = ET.tostring(root, encoding="UTF-8", xml_declaration=True)

    def write(tmp: Path) -> None:
        with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as z:
            z.writestr("SystemStructure.ssd", xml)
            for arcname, fmu in resources.items():
                z.write(fmu, arcname)

    return atomic_write(dest, write)  # whole under its name, or nothing left behind


def _package_for_libcosim(ssp_path: Path, step: float, work: Path) -> Path:
    """A copy of the package whose fixed-step annotation says `step` and one worker thread.

    One worker: libcosim's pool steps FMUs in parallel threads, but pythonfmu
    slaves hold the GIL, so parallel stepping gains nothing (measured 0.58 ms per
    macro step with 2 workers, 0.53 ms with 1) and a fixed order is deterministic.
    The step lives in the annotation because libcosimc's fixed-step constructor
    for SSP (`cosim_ssp_fixed_step_execution_create`) cannot set the thread count.
    """
    with zipfile.ZipFile(ssp_path) as src:
        root = ET.fromstring(src.read("SystemStructure.ssd"))
        experiment = root.find(_q(SSD, "DefaultExperiment"))
        if experiment is None:
            experiment = ET.SubElement(root, _q(SSD, "DefaultExperiment"), startTime="0.0")
        fixed = experiment.find(f".//{_q(OSP, 'FixedStepAlgorithm')}")
        if fixed is None:
            annotations = experiment.find(_q(SSD, "Annotations"))
            if annotations is None:
                annotations = ET.SubElement(experiment, _q(SSD, "Annotations"))
            annotation = ET.SubElement(annotations, _q(SSC, "Annotation"), type=OSP_ANNOTATION)
            fixed = ET.SubElement(ET.SubElement(annotation, _q(OSP, "Algorithm")),
                                  _q(OSP, "FixedStepAlgorithm"))
        fixed.set("baseStepSize", repr(float(step)))
        fixed.set("numWorkerThreads", "1")
        dest = work / ssp_path.name
        with zipfile.ZipFile(dest, "w", zipfile.ZIP_STORED) as out:
            for item in src.infolist():
                if item.filename == "SystemStructure.ssd":
                    out.writestr(item.filename,
                                 ET.tostring(root, encoding="UTF-8", xml_declaration=True))
                else:
                    out.writestr(item, src.read(item))
    return dest


def package_settings(ssp_path: Path, stop_time: float | None = None,
                     step: float | None = None) -> tuple[float, float]:
    """(stop time, step) of a run of the package: the ones given, else the package's
    DefaultExperiment stopTime and osp:FixedStepAlgorithm baseStepSize."""
    ssp_path = Path(ssp_path)
    if not ssp_path.exists():
        raise SSPError(f"SSP package {ssp_path} not found: write it with `write_ssp`")
    with zipfile.ZipFile(ssp_path) as z:
        root = ET.fromstring(z.read("SystemStructure.ssd"))
    experiment = root.find(_q(SSD, "DefaultExperiment"))
    fixed = root.find(f".//{_q(OSP, 'FixedStepAlgorithm')}")
    if stop_time is None and experiment is not None and experiment.get("stopTime"):
        stop_time = float(experiment.get("stopTime"))
    if step is None and fixed is not None and fixed.get("baseStepSize"):
        step = float(fixed.get("baseStepSize"))
    if stop_time is None or step is None or not step > 0:
        raise SSPError(f"{ssp_path.name} gives no stop time or step: pass stop_time and a "
                       "step > 0")
    return stop_time, step


def _last_error() -> str:
    from libcosimpy._internal import get_last_error_message

    return get_last_error_message() or "(libcosim gave no message)"


@contextmanager
def single_threaded_blas() -> Iterator[None]:
    """OpenBLAS on one thread while libcosim runs the FMUs.

    libcosim calls the FMUs from its worker thread, not Python's main thread; with
    OpenBLAS's own threads (2 on a 2-core machine) GyroPlant alone then took
    5.2 ms per step instead of 0.15 ms (measured), the whole run 76 s instead of
    ~10 s for 100 ms. numpy and scipy each carry an OpenBLAS: both are imported
    first so that threadpoolctl finds and limits both; the limits are restored
    afterwards.
    """
    import scipy.linalg  # noqa: F401 - load scipy's OpenBLAS so that it is limited too

    threadpool_limits = require("threadpoolctl", "ssp").threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        yield


def run_ssp_libcosim(
    ssp_path: Path,
    stop_time: float | None = None,
    step: float | None = None,
    record: Iterable[str] | None = None,
) -> dict[str, np.ndarray]:
    """Run an SSP package in libcosim's fixed-step algorithm; returns recorded signals.

    stop_time: s, default the package's DefaultExperiment stopTime; step: s, default
    the package's osp:FixedStepAlgorithm baseStepSize. record: "instance.variable"
    names, default every Real output of every component.
    Returns {"time": t_k, "instance.variable": values at t_k} at the n + 1
    communication points t_k = k * step, k = 0..n, like `run_cosimulation`.

    Semantics (libcosim's fixed_step_algorithm, checked against our master with an
    echo FMU): after initialization every connection is transferred once (outputs
    at t0 -> inputs); each step calls do_step(t, h) on every FMU, and only after
    all have finished transfers the outputs at t + h to the inputs. That is the
    Jacobi scheme of `master.run_cosimulation` (read all outputs at t, set all
    inputs, step all from t to t + h). The one difference is the clock: libcosim
    counts integer nanoseconds (the step must be a whole number of ns; 5 us is)
    and hands the FMUs t_k = (k * step_ns) / 1e9 and h_k = t_(k+1) - t_k in
    doubles, where our master passes k * step and step. So t_k differs by up to
    one ulp and h_k jitters by up to 2e-12 relative around 5e-6 (17 distinct
    values over 100 ms). With both aligned the two runs are bitwise identical
    (measured); as they are, the observer amplifies the jitter to about 2e-10
    (2 ms) and 1.2e-9 (100 ms) of Omega_hat, max |a - b| / max |b|.

    Runs in any Python process as is: the pythonfmu FMUs find libpython in the
    host process (no LD_PRELOAD). Side effect: sets libcosim's process-wide log
    level to warning (its default prints debug lines to stdout).
    """
    require("libcosimpy", "ssp", "running an SSP package in libcosim")
    from libcosimpy.CosimEnums import CosimVariableCausality, CosimVariableType
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver

    ssp_path = Path(ssp_path)
    stop_time, step = package_settings(ssp_path, stop_time, step)
    step_ns = round(step * _NS)
    if step_ns <= 0 or abs(step_ns - step * _NS) > 1e-6 * step_ns:
        raise SSPError(f"step {step} s is not a whole number of nanoseconds (libcosim's unit)")
    n_steps = whole_steps(stop_time, step)  # refuses a step that does not divide the run

    log_output_level(CosimLogLevel.WARNING)
    with tempfile.TemporaryDirectory(prefix="gyro_ssp_") as tmp, single_threaded_blas():
        package = _package_for_libcosim(ssp_path, step_ns / _NS, Path(tmp))
        try:
            execution = CosimExecution.from_ssp_file(str(package))
        except AssertionError:
            raise SSPError(f"libcosim could not load {ssp_path}: {_last_error()}") from None
        slaves = {info.name.decode(): info.index for info in execution.slave_infos()}
        outputs: dict[str, tuple[int, int]] = {}
        for name, index in slaves.items():
            for v in execution.slave_variables(index):
                if (v.causality == CosimVariableCausality.OUTPUT.value
                        and v.type == CosimVariableType.REAL.value):
                    outputs[f"{name}.{v.name.decode()}"] = (index, v.reference)
        wanted = list(outputs) if record is None else list(record)
        missing = [r for r in wanted if r not in outputs]
        if missing:
            raise SSPError(f"no Real output(s) {missing} in {ssp_path.name}; "
                           f"have {sorted(outputs)}")
        # Keep every sample in memory: the default time-series buffer holds fewer.
        observer = CosimObserver.create_time_series(n_steps + 1)
        execution.add_observer(observer)
        for ref in wanted:
            index, vr = outputs[ref]
            observer.start_time_series(index, vr, CosimVariableType.REAL)
        if not execution.simulate_until(n_steps * step_ns):
            raise SSPError(f"libcosim stopped before {stop_time} s: {_last_error()}")
        result: dict[str, np.ndarray] = {}
        get_samples = get_real_samples()
        count = n_steps + 1
        values = (ctypes.c_double * count)()
        steps = (ctypes.c_int64 * count)()
        times = (ctypes.c_int64 * count)()
        for ref in wanted:
            index, vr = outputs[ref]
            got = get_samples(observer.ptr(), index, vr, 0, count, values, steps, times)
            if got != count or steps[0] != 0 or steps[count - 1] != n_steps:
                raise SSPError(f"libcosim returned {got} of {count} samples of {ref}")
            result[ref] = np.array(values, dtype=float)
            if "time" not in result:  # libcosim's own time points, integer ns
                result = {"time": np.array(times, dtype=float) / _NS, **result}
        del observer, execution  # free the FMU instances before the folder goes
    return result


def relative_differences(
    a: Mapping[str, np.ndarray], b: Mapping[str, np.ndarray] | object
) -> dict[str, float]:
    """Per signal of a (except time): max_k |a_k - b_k| / max_k |b_k|.

    The measure used for "libcosim equals the fmpy master": the largest deviation
    over the run, relative to the signal's own peak (absolute where b is all zero).
    b: a dict or a `CoSimulationResult` (anything indexable by "instance.variable").
    """
    out = {}
    for name, values in a.items():
        if name == "time":
            continue
        ref = np.asarray(b[name])  # type: ignore[index]
        scale = float(np.max(np.abs(ref)))
        diff = float(np.max(np.abs(np.asarray(values) - ref)))
        out[name] = diff / scale if scale > 0.0 else diff
    return out
