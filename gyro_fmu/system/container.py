"""The whole system as one FMI 2.0 co-simulation FMU (an FMU container).

`build_container` packs the drive, rate, plant and observer FMUs, wired as in
patent Fig. 2 (`scenario.CONNECTIONS`), into models/GyroSystem.fmu: a tool that
can run one FMU runs the whole gyroscope-plus-observer system.

Built with fmu-manipulation-toolbox (FMUCT 2.0), not fmpy.container_fmu:
FMUCT builds a working container from a few declarative rules (links, exposed
inputs/parameters/outputs) and exposes embedded parameters as container
parameters, while fmpy 0.3.32's container needs a hand-made modelDescription
and two work-arounds (connection type "Real" where its binary wants "Float64";
value reference 0 taken as time; docs/engines.md).

Top-level interface (`exposed_names`): every parameter and every Real output of
the four FMUs under its own name (kxx ... m, noise_*, seed of the plant; kind,
offset, amplitude, frequency, slope, t_start of the rate profile; A1, f1, A2, f2
of the drive; the observer's initial guesses and tuning; outputs ux, uy,
Omega_z, x, vx, y, vy, ax, ay, x_hat ... m_hat, Omega_hat, sigma_*). The names do
not collide today; if a future FMU adds a colliding name, the later one is
exposed as "instance.name". The container's defaults are the FMUs' defaults,
which are the default scenario; `container_start_values(sc)` gives the start
values of any other scenario (e.g. for fmpy.simulate_fmu(start_values=...)).

Stepping: FMUCT's default ("parallel") mode is the Jacobi scheme of our master:
all embedded FMUs step from t to t + h on the inputs read at t, outputs are
transferred after the step. The internal step is fixed at build time (default
the scenario step, 5 us); a host's communication step must be a multiple of it.
"""

from __future__ import annotations

import math
import shutil
import tempfile
import zipfile
from collections.abc import Mapping
from pathlib import Path
from xml.etree import ElementTree as ET

from fmpy import read_model_description

from ..cosim.master import CoSimulationError
from ..extras import require
from ..fmu.build import MODELS_DIR
from ..model.drive import TwoToneDrive
from .scenario import CONNECTIONS, INSTANCE_FMUS, Scenario, fmu_system

CONTAINER_NAME = "GyroSystem"
SYSTEM_DESCRIPTION = (
    "MEMS gyroscope system of US 2011/0314910 A1: two-tone drive, angular-rate profile, "
    "2-DOF plant and the observer of its imperfections (kxx ... m) and of Omega_z, "
    "co-simulated inside one FMU (fmu-manipulation-toolbox container, Jacobi steps)"
)
#: Internal fixed step of the container, s (the scenarios' communication step).
DEFAULT_STEP = 5e-6


class ContainerError(CoSimulationError):
    """The container could not be built (a CoSimulationError, for the CLI)."""


def _variables(models_dir: Path) -> dict[str, list]:
    """instance -> the modelDescription variables of its FMU."""
    out = {}
    for instance, fmu in INSTANCE_FMUS.items():
        path = Path(models_dir) / fmu
        if not path.exists():
            raise ContainerError(f"FMU {path} not found: run `gyro-fmu build`")
        out[instance] = list(read_model_description(str(path)).modelVariables)
    return out


def exposed_names(models_dir: Path = MODELS_DIR) -> dict[tuple[str, str], str]:
    """(instance, variable) -> name on the container, for every parameter and Real output.

    Plain names where they are unique across the four FMUs (they are today:
    `kxy` is the plant's, `kxy_0` the observer's guess, `kxy_hat` its estimate);
    "instance.variable" for a name already taken. Connected inputs stay internal.
    """
    names: dict[tuple[str, str], str] = {}
    taken: set[str] = {"time"}
    for instance, variables in _variables(models_dir).items():
        for v in variables:
            exposed = v.causality == "parameter" or (v.causality == "output" and v.type == "Real")
            if not exposed:
                continue
            name = v.name if v.name not in taken else f"{instance}.{v.name}"
            taken.add(name)
            names[(instance, v.name)] = name
    return names


def container_start_values(sc: Scenario, models_dir: Path = MODELS_DIR) -> dict[str, float | int]:
    """The container parameter values of scenario sc (what `fmu_system` sets per FMU).
    Raises ContainerError for a scenario the container runtime cannot initialize (a plant
    that warns at initialization: gyro_fmu.upstream.fmu_container)."""
    from ..core.library import core_text
    from ..model.parameters import _c_params
    from ..upstream.fmu_container import container_init_problem

    problem = container_init_problem(core_text("gyro_params_warning", _c_params(sc.params)))
    if problem:
        raise ContainerError(problem)
    names = exposed_names(models_dir)
    components, _ = fmu_system(sc, models_dir)
    return {names[(c.name, p)]: value for c in components for p, value in c.parameters.items()}


def build_container(
    models_dir: Path = MODELS_DIR, dest: Path | None = None, step: float = DEFAULT_STEP
) -> Path:
    """Build the system container FMU (FMI 2.0 CS) from the FMUs in models_dir.

    dest: default models_dir/GyroSystem.fmu. step: the container's internal fixed
    communication step, s. Built in a temporary folder (FMUCT writes beside its
    input FMUs), so models_dir gets nothing but dest. Returns dest.
    """
    models_dir = Path(models_dir)
    dest = models_dir / f"{CONTAINER_NAME}.fmu" if dest is None else Path(dest)
    if not (math.isfinite(step) and step > 0.0):
        raise ContainerError(f"step={step!r} s must be a finite number > 0")
    problem = TwoToneDrive().sampling_problem(step)  # the drive the container starts with
    if problem:
        raise ContainerError(f"step={step:g} s: {problem}")
    names = exposed_names(models_dir)
    variables = _variables(models_dir)
    require("fmu_manipulation_toolbox", "container")
    from fmu_manipulation_toolbox.assembly import AssemblyNode

    with tempfile.TemporaryDirectory(prefix="gyro_container_") as tmp:
        work = Path(tmp)
        for fmu in INSTANCE_FMUS.values():
            shutil.copy2(models_dir / fmu, work / fmu)
        # Explicit rules only: no auto-link by equal names (the observer's ux must be
        # wired like the plant's, x must go to x_meas), no auto-exposed inputs.
        node = AssemblyNode(f"{CONTAINER_NAME}.fmu", step_size=step, auto_link=False,
                            auto_input=False, auto_output=False, auto_parameter=False)
        for fmu in INSTANCE_FMUS.values():
            node.add_fmu(fmu)
        for c in CONNECTIONS:
            src, _, src_var = c.src.partition(".")
            dst, _, dst_var = c.dst.partition(".")
            node.add_link(INSTANCE_FMUS[src], src_var, INSTANCE_FMUS[dst], dst_var)
        for instance, vs in variables.items():
            fmu = INSTANCE_FMUS[instance]
            for v in vs:
                name = names.get((instance, v.name))
                if name is None:
                    continue
                if v.causality == "parameter":
                    node.add_input(name, fmu, v.name)
                else:
                    node.add_output(fmu, v.name, name)
        try:
            node.make_fmu(work)
        except Exception as exc:  # FMUCT raises its own error types; keep its message
            raise ContainerError(f"fmu-manipulation-toolbox failed: {exc}") from exc
        built = work / f"{CONTAINER_NAME}.fmu"
        _finish_model_description(built, models_dir, names)
        # its reference results, as every FMU of ours carries (gyro-fmu validate
        # models/*.fmu checks it with the rest); it has no inputs
        from ..fmu.reference import write_reference

        write_reference(built, lambda stop_time, step: None)
        dest.parent.mkdir(parents=True, exist_ok=True)
        shutil.move(str(built), dest)
    return dest


def _finish_model_description(fmu: Path, models_dir: Path,
                              names: Mapping[tuple[str, str], str]) -> None:
    """Put back what FMUCT 2.0 leaves out of the container's modelDescription.xml.

    - units: FMUCT copies names, descriptions and start values but drops every
      `unit` and the UnitDefinitions (its EmbeddedFMUPort never reads `unit`); they
      are copied from the embedded FMUs, also onto FMUCT's local link variables
      ("twotonedrive.ux", ...), and time gets "s".
    - InitialUnknowns: FMUCT lists every output there, also outputs declared
      initial="exact", which `fmpy validate` rejects; only outputs whose initial
      is calculated or approx are kept (FMI 2.0, section 2.2.8).
    - description: says what the system is.
    The container binary reads resources/container.txt, not this file, so the
    edit cannot change what it computes.
    """
    embedded = {}
    unit_definitions: dict[str, ET.Element] = {}
    for instance, fmu_name in INSTANCE_FMUS.items():
        with zipfile.ZipFile(Path(models_dir) / fmu_name) as z:
            md = ET.fromstring(z.read("modelDescription.xml"))
        for unit in md.iterfind("UnitDefinitions/Unit"):
            unit_definitions.setdefault(unit.get("name"), unit)
        for sv in md.iterfind("ModelVariables/ScalarVariable"):
            embedded[(instance, sv.get("name"))] = sv
    by_exposed = {exposed: embedded[key] for key, exposed in names.items()}
    # FMUCT's local variables of the links are called "<fmu id>.<variable>", the id being
    # the FMU file's lower-case stem (twotonedrive.ux); time is the independent variable.
    stems = {Path(fmu_name).stem.lower(): instance for instance, fmu_name in INSTANCE_FMUS.items()}
    for (instance, variable), sv in embedded.items():
        stem = Path(INSTANCE_FMUS[instance]).stem.lower()
        by_exposed.setdefault(f"{stem}.{variable}", sv)
    assert len(stems) == len(INSTANCE_FMUS)
    time_unit = ET.Element("ScalarVariable")
    ET.SubElement(time_unit, "Real", unit="s")
    by_exposed.setdefault("time", time_unit)

    with zipfile.ZipFile(fmu) as z:
        entries = [(info, z.read(info)) for info in z.infolist()]
    md_bytes = next(data for info, data in entries if info.filename == "modelDescription.xml")
    root = ET.fromstring(md_bytes)
    root.set("description", SYSTEM_DESCRIPTION)
    variables = root.findall("ModelVariables/ScalarVariable")
    used_units = set()
    for sv in variables:
        source = by_exposed.get(sv.get("name"))
        if source is None:
            continue
        unit = next(iter(source), None)
        mine = next(iter(sv), None)
        if unit is not None and mine is not None and unit.get("unit"):
            mine.set("unit", unit.get("unit"))
            used_units.add(unit.get("unit"))
    if used_units:
        definitions = ET.Element("UnitDefinitions")
        definitions.extend(unit_definitions[u] for u in sorted(used_units) if u in unit_definitions)
        anchor = list(root).index(root.find("CoSimulation")) + 1
        root.insert(anchor, definitions)
    initial_unknowns = root.find("ModelStructure/InitialUnknowns")
    if initial_unknowns is not None:
        for unknown in list(initial_unknowns):
            sv = variables[int(unknown.get("index")) - 1]
            if sv.get("initial", "calculated") not in ("calculated", "approx"):
                initial_unknowns.remove(unknown)
        if len(initial_unknowns) == 0:
            root.find("ModelStructure").remove(initial_unknowns)
    new_md = ET.tostring(root, encoding="UTF-8", xml_declaration=True)
    with zipfile.ZipFile(fmu, "w", zipfile.ZIP_DEFLATED) as z:
        for info, data in entries:
            z.writestr(info, new_md if info.filename == "modelDescription.xml" else data)
