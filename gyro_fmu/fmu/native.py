"""Build the native FMUs and the Python core from fmu_src/ with zig cc, for every platform.

One C model per FMU (fmu_src/models/<Model>/model.c) over the shared FMI layer
(fmu_src/fmi/) and the core (fmu_src/core/). From each `FmuInterface`
(gyro_fmu.model.interfaces) this module generates the model's `variables.h` and its FMI
2.0 and 3.0 model descriptions, so every name, unit and bound is written once. One binary
per model and platform serves both FMI versions (fmi2* and fmi3* functions side by side).

Platforms: linux x86_64 and aarch64 (glibc 2.17 and newer), windows x86_64, macOS x86_64
and arm64 (FMI 2.0: one universal darwin64 binary). The compiler is `ziglang` from PyPI,
so no system compiler is needed; every object is compiled with -ffp-contract=off, so no
platform fuses a multiply-add and the arithmetic is the same everywhere.
"""

from __future__ import annotations

import hashlib
import os
import re
import subprocess
import sys
import tempfile
import uuid
import zipfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from xml.etree.ElementTree import Element, SubElement, indent, tostring

from ..core import structs
from ..estimation.interface import OBSERVER, OBSERVER_SOURCES
from ..model.interfaces import PHYSICS_INTERFACES, FmuInterface
from ..model.selfcal_interfaces import SELFCAL_INTERFACES
from ..model.units import UNITS
from ..sensor.interface import SENSOR
from ..sensor.platform import PLATFORM
from .macho import universal_macho
from .sources import DECLARATION_FILES, sources_root  # noqa: F401 - part of this API


@dataclass(frozen=True)
class Target:
    """One platform: zig's target, FMI folders and the library file name."""

    zig: str
    fmi3: str  #: FMI 3.0 platform tuple (also the core library's folder)
    fmi2: str | None  #: FMI 2.0 folder; None where a universal binary serves (macOS)
    suffix: str

    def library(self, stem: str, lib_prefix: bool = False) -> str:
        """File name of a library: FMU binaries are <Model><suffix>; the core is
        libgyro_core.so / .dylib and gyro_core.dll."""
        prefix = "lib" if lib_prefix and self.suffix != ".dll" else ""
        return f"{prefix}{stem}{self.suffix}"


TARGETS = (
    Target("x86_64-linux-gnu.2.17", "x86_64-linux", "linux64", ".so"),
    Target("aarch64-linux-gnu.2.17", "aarch64-linux", "aarch64-linux", ".so"),
    Target("x86_64-windows-gnu", "x86_64-windows", "win64", ".dll"),
    Target("x86_64-macos", "x86_64-darwin", None, ".dylib"),
    Target("aarch64-macos", "aarch64-darwin", None, ".dylib"),
)
FLAGS = ["-std=c99", "-O2", "-g0", "-s", "-ffp-contract=off", "-fno-fast-math", "-Wall", "-Wextra"]
FMI_LAYER = ("instance.c", "fmi2.c", "fmi3.c")
FMI_HEADERS = ("model.h", "instance.h")
#: The FMI standard's own headers (FMI 2.0.4, 3.0), taken at build time from fmpy, which
#: ships them (fmpy/c-code): the repository keeps only code written here, and each FMU's
#: sources/ carries them, as the Reference-FMUs' do.
STANDARD_HEADERS = ("fmi2Functions.h", "fmi2FunctionTypes.h", "fmi2TypesPlatform.h",
                    "fmi3Functions.h", "fmi3FunctionTypes.h", "fmi3PlatformTypes.h")
CORE_SOURCES = ("gyro_text.c", "gyro_rng.c", "gyro_plant.c", "gyro_signals.c",
                *OBSERVER_SOURCES, "gyro_master.c", "gyro_resonator.c", "gyro_loops.c",
                "gyro_carrier.c", "gyro_demod.c", "gyro_chain.c")
#: Core sources every model's binary needs (the FMI layer's messages).
COMMON_CORE = ("gyro_text.c",)
GENERATION_TOOL = "gyro_fmu (native C, zig cc)"
DEFAULT_EXPERIMENT = {"startTime": "0", "stopTime": "0.01", "stepSize": "5e-06"}


#: The native FMUs, by model identifier: the physics' and the observer's declarations.
NATIVE_INTERFACES: dict[str, FmuInterface] = {**PHYSICS_INTERFACES,
                                              OBSERVER.identifier: OBSERVER,
                                              **SELFCAL_INTERFACES,
                                              SENSOR.identifier: SENSOR,
                                              PLATFORM.identifier: PLATFORM}

class NativeBuildError(RuntimeError):
    """The C compiler failed or is missing."""


# ---- generated from the declarations -------------------------------------------------
def token(interface: FmuInterface) -> str:
    """FMI 2.0 guid and FMI 3.0 instantiationToken: a hash of the declarations and of every
    source the binary is made of, so a changed model never loads a stale description."""
    h = hashlib.sha256(repr(interface.variables).encode())
    h.update(structs.header().encode())
    for path in model_sources(interface):
        h.update(path.name.encode() + path.read_bytes())
    return "{" + str(uuid.UUID(bytes=h.digest()[:16], version=5)) + "}"


def _c_double(value: float | None, default: str) -> str:
    if value is None:
        return default
    return repr(float(value)) if value == value else "NAN"


def variables_header(interface: FmuInterface) -> str:
    """The variables.h a model's C file includes: the struct of the variables and their
    table (generated into the build folder and into the FMU's sources/, never committed)."""
    lines = [f"/* {interface.identifier}'s variables, generated by gyro_fmu.fmu.native from",
             " * its declaration (gyro_fmu.fmu.native.NATIVE_INTERFACES): do not edit. */",
             "#ifndef GYRO_VARIABLES_H", "#define GYRO_VARIABLES_H", "",
             "#include <math.h>", "#include <stddef.h>", "#include <stdint.h>", "",
             '#include "model.h"', "",
             f'#define MODEL_IDENTIFIER "{interface.identifier}"',
             f'#define MODEL_TOKEN "{token(interface)}"', "", "typedef struct {"]
    for v in interface.variables:
        ctype = "int32_t" if v.integer else "double"
        lines.append(f"    {ctype} {v.name}; /* {v.causality}, {v.unit or '1'}: "
                     f"{v.description} */")
    lines += ["} Variables;", "", "static const GyroVariable VARIABLES[] = {"]
    for vr, v in enumerate(interface.variables, start=1):
        kind = "GYRO_INT32" if v.integer else "GYRO_FLOAT64"
        causality = f"GYRO_{v.causality.upper()}"
        lines.append(
            f'    {{{vr}, "{v.name}", {kind}, {causality}, offsetof(Variables, {v.name}), '
            f"{_c_double(v.start, '0.0')}, {_c_double(v.min, '-INFINITY')}, "
            f"{_c_double(v.max, 'INFINITY')}, {int(v.min_exclusive)}, "
            f'"{"" if v.integer else (v.unit or "1")}"}},')
    lines += ["};", "#define N_VARIABLES (sizeof VARIABLES / sizeof VARIABLES[0])"]
    names = {v.name for v in interface.variables}
    if interface.struct_copies:
        lines += ["", '#include "gyro_structs.h"', "",
                  "/* The core structs filled from the variables (declared: gyro_fmu.core.structs;",
                  " * FmuInterface.struct_copies). */"]
    for copy in interface.struct_copies:
        lines += [*structs.copy_function(copy.function, copy.struct, names, dict(copy.rename),
                                         copy.zero), ""]
    lines += ["#endif", ""] if interface.struct_copies else ["", "#endif", ""]
    return "\n".join(lines)


def _number(value: float | int, integer: bool) -> str:
    return str(int(value)) if integer else repr(float(value))


def model_description(interface: FmuInterface, fmi_version: int) -> bytes:
    """modelDescription.xml of the FMI 2.0 or 3.0 FMU."""
    two = fmi_version == 2
    root = Element("fmiModelDescription", {
        "fmiVersion": "2.0" if two else "3.0", "modelName": interface.identifier,
        ("guid" if two else "instantiationToken"): token(interface),
        "description": interface.description, "author": "gyro_fmu", "license": "MIT",
        "generationTool": GENERATION_TOOL, "variableNamingConvention": "flat",
        **({"numberOfEventIndicators": "0"} if two else {})})
    cs = SubElement(root, "CoSimulation", {
        "modelIdentifier": interface.identifier,
        "canHandleVariableCommunicationStepSize": "true",
        ("canGetAndSetFMUstate" if two else "canGetAndSetFMUState"): "true",
        ("canSerializeFMUstate" if two else "canSerializeFMUState"): "true",
        "canBeInstantiatedOnlyOncePerProcess": "false", "needsExecutionTool": "false",
        **({"canNotUseMemoryManagementFunctions": "true"} if two else
           {"hasEventMode": "false", "providesIntermediateUpdate": "false"})})
    if two:
        files = SubElement(cs, "SourceFiles")
        for path in model_sources(interface):
            if path.suffix == ".c":
                SubElement(files, "File", name=path.name)
    units = SubElement(root, "UnitDefinitions")
    used = [v.unit or "1" for v in interface.variables if not v.integer]
    for unit in dict.fromkeys(used if two else ["s", *used]):  # FMI 3.0: time is in s
        SubElement(SubElement(units, "Unit", name=unit), "BaseUnit",
                   {k: str(e) for k, e in UNITS[unit].items()})
    categories = SubElement(root, "LogCategories")
    for name, text in (("logEvents", "life-cycle messages (with debug logging on)"),
                       ("logStatusWarning", "warnings: a growing mode, a refused value kept"),
                       ("logStatusDiscard", "a refused step: nothing advanced (a smaller "
                        "step or a restored state goes on)"),
                       ("logStatusError", "errors: a refused call or value, a failed step")):
        SubElement(categories, "Category", name=name, description=text)
    experiment = dict(DEFAULT_EXPERIMENT)
    if interface.default_experiment is not None:
        stop, step = interface.default_experiment
        experiment.update(stopTime=f"{stop:g}", stepSize=f"{step:g}")
    SubElement(root, "DefaultExperiment", experiment)
    variables = SubElement(root, "ModelVariables")
    if not two:
        SubElement(variables, "Float64", name="time", valueReference="0",
                   causality="independent", variability="continuous",
                   description="simulation time", unit="s")
    for vr, v in enumerate(interface.variables, start=1):
        attrs = {"name": v.name, "valueReference": str(vr), "causality": v.causality,
                 "description": v.description}
        attrs["variability"] = ("fixed" if v.is_parameter else
                                "discrete" if v.integer else "continuous")
        if v.causality == "output":
            attrs["initial"] = "calculated"
        elif v.is_parameter:
            attrs["initial"] = "exact"
        typed = {}
        if not v.integer:
            typed["unit"] = v.unit or "1"
        for key in ("min", "max", "nominal"):
            value = getattr(v, key)
            if value is not None:
                typed[key] = _number(value, v.integer)
        if v.causality != "output":
            typed["start"] = _number(v.start, v.integer)
        if two:
            sv = SubElement(variables, "ScalarVariable", attrs)
            SubElement(sv, "Integer" if v.integer else "Real", typed)
        else:
            SubElement(variables, "Int32" if v.integer else "Float64", {**attrs, **typed})
    structure = SubElement(root, "ModelStructure")
    outputs = [vr for vr, v in enumerate(interface.variables, start=1)
               if v.causality == "output"]
    if two:  # FMI 2.0 indices count ScalarVariables from 1 = value references here
        out = SubElement(structure, "Outputs")
        for vr in outputs:
            SubElement(out, "Unknown", index=str(vr), dependencies="")
        init = SubElement(structure, "InitialUnknowns")
        for vr in outputs:
            SubElement(init, "Unknown", index=str(vr), dependencies="")
    else:
        for vr in outputs:
            SubElement(structure, "Output", valueReference=str(vr), dependencies="")
        for vr in outputs:
            SubElement(structure, "InitialUnknown", valueReference=str(vr), dependencies="")
    indent(root)
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + tostring(root, encoding="utf-8")


def build_description(interface: FmuInterface) -> bytes:
    """sources/buildDescription.xml of the FMI 3.0 FMU (FMI 3.0.1 section 2.5.1)."""
    root = Element("fmiBuildDescription", fmiVersion="3.0")
    config = SubElement(root, "BuildConfiguration", modelIdentifier=interface.identifier)
    files = SubElement(config, "SourceFileSet", language="C99")
    for path in model_sources(interface):
        if path.suffix == ".c":
            SubElement(files, "SourceFile", name=path.name)
    SubElement(config, "Library", name="m")
    indent(root)
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + tostring(root, encoding="utf-8")


def fmi_header_dir() -> Path:
    """The folder of the FMI standard's headers: fmpy's c-code (fmpy is a dependency of
    the build and of the package)."""
    from importlib.util import find_spec

    spec = find_spec("fmpy")
    folder = Path(spec.origin).parent / "c-code" if spec and spec.origin else None
    if folder is None or not all((folder / h).is_file() for h in STANDARD_HEADERS):
        raise NativeBuildError("the FMI standard's headers (fmpy/c-code: "
                               f"{', '.join(STANDARD_HEADERS)}) are missing: pip install "
                               "fmpy (0.3.20 or later)")
    return folder


def model_sources(interface: FmuInterface) -> list[Path]:
    """Every C file and header one model's binary is compiled from (variables.h aside)."""
    root = sources_root()
    core = root / "core"
    sources = [core / n for n in (*COMMON_CORE, *interface.core_sources)]
    return [root / "models" / interface.identifier / "model.c",
            *(root / "fmi" / n for n in (*FMI_LAYER, *FMI_HEADERS)),
            *(fmi_header_dir() / n for n in STANDARD_HEADERS), *sources,
            *(core / h for h in _core_headers(sources))]


def _core_headers(sources: list[Path]) -> list[str]:
    """The core headers the sources include, directly or through another core header."""
    found: list[str] = []
    todo = list(sources)
    while todo:
        text = todo.pop().read_text(encoding="utf-8")
        for name in re.findall(r'^#include "(\w+\.h)"', text, re.M):
            path = sources[0].parent / name
            if name not in found and path.is_file():
                found.append(name)
                todo.append(path)
    return sorted(found)


# ---- compiling --------------------------------------------------------------------------
def zig_command() -> list[str]:
    """The zig compiler driver from the ziglang package of this Python."""
    try:
        import ziglang  # noqa: F401
    except ImportError:
        raise NativeBuildError("the native build needs the ziglang package (pip install "
                               "ziglang): it cross-compiles the C sources for every "
                               "platform") from None
    return [sys.executable, "-m", "ziglang", "cc"]


def compile_library(target: Target, sources: list[Path], include: list[Path], out: Path,
                    exported_core: bool = False) -> Path:
    """One shared library for `target`. FMU binaries export only the FMI functions;
    exported_core keeps every core function visible (the Python library's core)."""
    out.parent.mkdir(parents=True, exist_ok=True)
    cmd = [*zig_command(), "-target", target.zig, *FLAGS, "-shared", "-o", str(out),
           *(f"-I{d}" for d in include), *map(str, sources)]
    if not target.zig.startswith("x86_64-windows"):
        cmd.insert(len(zig_command()) + 2, "-fPIC")
        if not exported_core:
            cmd.insert(len(zig_command()) + 2, "-fvisibility=hidden")
    if "linux" in target.zig:
        cmd += ["-lm", "-lpthread"]
    env = {**os.environ, "ZIG_GLOBAL_CACHE_DIR": os.environ.get(
        "ZIG_GLOBAL_CACHE_DIR", str(Path(tempfile.gettempdir()) / "gyro_fmu-zig-cache"))}
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
    if proc.returncode != 0 or not out.is_file():
        raise NativeBuildError(f"zig cc for {target.zig} failed ({proc.returncode}):\n"
                               f"{' '.join(cmd)}\n{proc.stderr}")
    if proc.stderr.strip():
        raise NativeBuildError(f"zig cc for {target.zig} warned (warnings are errors "
                               f"here):\n{proc.stderr}")
    for extra in out.parent.iterdir():  # import libraries and debug files zig leaves
        if extra.suffix in (".lib", ".pdb", ".a"):
            extra.unlink()
    return out


def generated_headers(gen: Path, interface: FmuInterface | None = None) -> Path:
    """Write the generated headers into gen: gyro_structs.h (the core's structs, from
    gyro_fmu.core.structs) and, for a model, its variables.h. Returns gen."""
    gen.mkdir(parents=True, exist_ok=True)
    (gen / "gyro_structs.h").write_text(structs.header())
    if interface is not None:
        (gen / "variables.h").write_text(variables_header(interface))
    return gen


def build_core(dest: Path, targets: tuple[Target, ...] = TARGETS) -> list[Path]:
    """The core as the Python library loads it: dest/<platform tuple>/<lib>."""
    core = sources_root() / "core"
    out = []
    with tempfile.TemporaryDirectory(prefix="gyro_fmu-core-") as tmp:
        gen = generated_headers(Path(tmp))
        for t in targets:
            lib = dest / t.fmi3 / t.library("gyro_core", lib_prefix=True)
            out.append(compile_library(t, [core / n for n in CORE_SOURCES], [gen, core], lib,
                                       exported_core=True))
    return out


def build_binaries(interface: FmuInterface, work: Path,
                   targets: tuple[Target, ...] = TARGETS) -> dict[str, Path]:
    """The model's binary per FMI 3.0 platform tuple, plus 'darwin64' (universal)."""
    root = sources_root()
    gen = generated_headers(work / "generated" / interface.identifier, interface)
    sources = [p for p in model_sources(interface) if p.suffix == ".c"]
    include = [gen, root / "fmi", root / "core", fmi_header_dir()]
    binaries = {t.fmi3: compile_library(t, sources, include,
                                        work / t.fmi3 / t.library(interface.identifier))
                for t in targets}
    macs = [binaries[t.fmi3] for t in targets if t.fmi2 is None]
    if macs:
        binaries["darwin64"] = universal_macho(
            macs, work / "darwin64" / f"{interface.identifier}.dylib")
    return binaries


# ---- packaging --------------------------------------------------------------------------
def fmu_members(interface: FmuInterface, fmi_version: int,
                binaries: dict[str, Path]) -> dict[str, bytes]:
    """Every file of the FMU but its documentation and reference results."""
    members = {"modelDescription.xml": model_description(interface, fmi_version)}
    for t in TARGETS:
        folder = t.fmi3 if fmi_version == 3 else (t.fmi2 or "darwin64")
        if fmi_version == 2 and t.fmi2 is None:
            source = binaries.get("darwin64")
        else:
            source = binaries.get(t.fmi3)
        if source is not None:
            members[f"binaries/{folder}/{interface.identifier}{t.suffix}"] = source.read_bytes()
    for path in model_sources(interface):
        members[f"sources/{path.name}"] = path.read_bytes()
    members["sources/variables.h"] = variables_header(interface).encode()
    members["sources/gyro_structs.h"] = structs.header().encode()
    if fmi_version == 3:
        members["sources/buildDescription.xml"] = build_description(interface)
    return members


def write_fmu(interface: FmuInterface, fmi_version: int, binaries: dict[str, Path],
              dest: Path, reference: bool = True) -> Path:
    """dest/<Model>.fmu, written to a temporary name and moved into place whole."""
    from .docs import add_documentation
    from .reference import write_reference

    dest.mkdir(parents=True, exist_ok=True)
    final = dest / f"{interface.identifier}.fmu"
    fd, temp = tempfile.mkstemp(suffix=".fmu", prefix=f".{interface.identifier}-", dir=dest)
    os.close(fd)
    try:
        with zipfile.ZipFile(temp, "w", zipfile.ZIP_DEFLATED) as z:
            for name, data in fmu_members(interface, fmi_version, binaries).items():
                info = zipfile.ZipInfo(name, date_time=(2026, 1, 1, 0, 0, 0))
                info.external_attr = 0o644 << 16  # readable by every user that unpacks it
                z.writestr(info, data, zipfile.ZIP_DEFLATED)
        if reference:
            write_reference(Path(temp), interface.reference_inputs)
        add_documentation(Path(temp), sources_root() / "models" / interface.identifier /
                          "readme.md")
        os.chmod(temp, 0o644)
        os.replace(temp, final)
    except BaseException:
        Path(temp).unlink(missing_ok=True)
        raise
    return final


def build_native(dest: Path, names: tuple[str, ...] = tuple(NATIVE_INTERFACES),
                 fmi_versions: tuple[int, ...] = (2, 3), reference: bool = True,
                 targets: tuple[Target, ...] = TARGETS,
                 say: Callable[[str], None] | None = None) -> list[Path]:
    """The native FMUs into dest/fmi2/ and dest/fmi3/; returns their paths. say: told
    each FMU as its build starts (the install's progress)."""
    out = []
    with tempfile.TemporaryDirectory(prefix="gyro_fmu-native-") as tmp:
        for i, name in enumerate(names, 1):
            if say is not None:
                say(f"building {name}.fmu ({i} of {len(names)}): {len(targets)} platforms, "
                    f"FMI {' and '.join(map(str, fmi_versions))}")
            interface = NATIVE_INTERFACES[name]
            binaries = build_binaries(interface, Path(tmp) / name, targets)
            built = [write_fmu(interface, version, binaries, Path(dest) / f"fmi{version}",
                               reference) for version in fmi_versions]
            if interface.datasheet and reference and 2 in fmi_versions:
                if say is not None:
                    say(f"{name}'s datasheets, one per preset: measured from its own "
                        "output (about 3 minutes), or kept from the last build of the same "
                        "binary")
                from ..sensor.datasheet import add_datasheet

                add_datasheet(built, Path(dest) / f".{name}.datasheet.json")
            out += built
    return out
