"""`gyro-fmu doctor`: what a non-Python importer needs to load our FMUs, checked for real.

The FMU binaries come from pythonfmu. They embed a Python interpreter but do not
link libpython (FIELD-NOTES): inside a Python host (fmpy, libcosimpy) the
symbols are already in the process, but OMSimulator, Simulink, Dymola or a C
program must bring them, and the embedded interpreter must then find its
standard library and numpy/scipy. This module works out, for the interpreter
that runs it, the settings that make that happen:

- the libpython shared library to preload (``LD_PRELOAD``; ``python3.dll`` and
  ``python3X.dll`` on ``PATH`` on Windows);
- ``PYTHONHOME``: measured, not optional. pythonfmu initializes Python with the
  program name ``./PythonFMU``, so the embedded interpreter locates its prefix
  by searching ``PATH`` for a ``python3``; with ``/usr/bin`` first it picked the
  Debian 3.11.2 standard library for a pyenv 3.11.7 libpython here and failed
  with ``No module named 'math'``;
- ``PYTHONPATH``: the folders holding numpy and scipy (a venv's site-packages is
  invisible to an interpreter whose home is the base installation);
- the glibc the FMU binary needs (read from the binary's version references).

It then proves the settings by compiling ``chost/fmu_host.c``, a minimal FMI 2.0
co-simulation importer, with the system C compiler, and running it on an FMU
three times: with the prescribed environment (must pass), with no Python
settings at all (must fail at dlopen, which shows the check can fail) and with
only the preload (shows what ``PYTHONHOME``/``PYTHONPATH`` add). The host runs
from a clean environment (``PATH=/usr/bin:/bin``), so the user's shell cannot
make the check pass by accident.
"""

from __future__ import annotations

import os
import platform
import re
import shutil
import site
import subprocess
import sys
import sysconfig
import tempfile
import zipfile
from collections.abc import Sequence
from dataclasses import dataclass, field
from importlib.util import find_spec
from pathlib import Path
from xml.etree import ElementTree

from ..fmu.build import MODELS_DIR

#: Source of the C host, shipped as package data.
HOST_SOURCE = Path(__file__).resolve().parent / "chost" / "fmu_host.c"

#: Modules the shipped gyro_fmu package imports that are not in the FMU itself.
REQUIRED_MODULES: tuple[str, ...] = ("numpy", "scipy")

#: Oldest glibc the pythonfmu 0.7.0 binary runs on (FIELD-NOTES; re-read from the binary).
GLIBC_NEEDED = (2, 32)

#: The environment of the host runs: no user PATH, no PYTHON* variable.
CLEAN_PATH = "/usr/bin:/bin"

#: The line fmu_host.c prints just before `return` from main.
END_MARKER = "host: returning from main"

#: What fmu_host.c exit statuses mean (see its header).
HOST_EXIT_MEANING = {
    0: "ok",
    1: "usage error",
    2: "dlopen failed",
    3: "FMI symbol missing",
    4: "fmi2Instantiate returned NULL",
    5: "an FMI call failed",
}

#: Inputs held over every step and outputs read, per FMU we know; others get
#: no inputs and all their Real outputs. GyroPlant: 1e-7 N on x at 1 rad/s.
CHECK_PLANS: dict[str, tuple[dict[str, float], tuple[str, ...]]] = {
    "GyroPlant": ({"ux": 1e-7, "uy": 0.0, "Omega_z": 1.0}, ("x", "vx", "y", "vy")),
    "TwoToneDrive": ({}, ("ux", "uy")),
    "RateProfile": ({}, ("Omega_z",)),
}
CHECK_STEP = 5e-6  #: s, the default communication step of the scenarios
CHECK_STEPS = 20


# --------------------------------------------------------------------------- #
# What this machine needs
# --------------------------------------------------------------------------- #
@dataclass(frozen=True)
class LibPython:
    """Where the shared libpython of this interpreter is, or why there is none."""

    path: Path | None
    shared_build: bool  #: sysconfig Py_ENABLE_SHARED (always True on Windows)
    tried: tuple[Path, ...]
    note: str


def find_libpython() -> LibPython:
    """Locate the libpython this interpreter was built with.

    Preference goes to INSTSONAME (``libpython3.11.so.1.0``), the file the
    runtime loader actually maps; LDLIBRARY (``libpython3.11.so``) is only a
    development symlink that Debian ships in -dev packages. Candidates cover
    LIBDIR, the prefix's lib folder (pyenv, python.org, conda), LIBPL and the
    multiarch system folders, and finally whatever the executable is linked to.
    """
    version = f"{sys.version_info.major}.{sys.version_info.minor}"
    if sys.platform == "win32":
        return _find_python_dll(version)
    cfg = sysconfig.get_config_var
    shared = bool(cfg("Py_ENABLE_SHARED"))
    abiflags = getattr(sys, "abiflags", "")
    names = [str(n) for n in (cfg("INSTSONAME"), cfg("LDLIBRARY"))
             if n and (".so" in str(n) or str(n).endswith(".dylib"))]
    names += [f"libpython{version}{abiflags}.so.1.0", f"libpython{version}{abiflags}.so",
              f"libpython{version}{abiflags}.dylib"]
    dirs = [Path(d) for d in (cfg("LIBDIR"), Path(sys.base_prefix) / "lib",
                              Path(sys.base_exec_prefix) / "lib", cfg("LIBPL")) if d]
    if cfg("MULTIARCH"):
        dirs += [Path("/usr/lib") / cfg("MULTIARCH"), Path("/lib") / cfg("MULTIARCH")]
    dirs += [Path("/usr/lib64"), Path("/usr/lib"), Path("/usr/local/lib")]
    tried = [d / n for d in dict.fromkeys(dirs) for n in dict.fromkeys(names)]
    found = next((c.resolve() for c in tried if c.is_file()), None)
    if found is None:
        found = _linked_libpython(Path(sys.executable))
    if found is not None and shared:
        return LibPython(found, True, tuple(tried), "this Python was built with --enable-shared")
    static = ("this Python was built without a shared libpython (Py_ENABLE_SHARED=0), so a "
              "non-Python host cannot use it. ")
    fix = ("Use a Python with a shared library: pyenv: `env PYTHON_CONFIGURE_OPTS=--enable-shared "
           f"pyenv install {platform.python_version()}`; Debian/Ubuntu: `apt install "
           f"libpython{version}` with the system python{version}; conda and python.org builds "
           "ship one in their lib folder. Then install numpy and scipy for that Python and "
           "run `gyro-fmu doctor` with it")
    if found is not None:  # a same-version libpython of another installation (e.g. Debian's)
        return LibPython(None, False, tuple(tried), static + f"{found} belongs to another "
                         "installation: usable only with that installation's PYTHONHOME and "
                         "numpy/scipy. " + fix)
    return LibPython(None, shared, tuple(tried), ("" if shared else static) +
                     "no shared libpython found. " + fix)


def _linked_libpython(executable: Path) -> Path | None:
    """The libpython the executable is dynamically linked to, per ldd (Linux only)."""
    ldd = shutil.which("ldd")
    if not ldd:
        return None
    try:
        out = subprocess.run([ldd, str(executable)], capture_output=True, text=True,
                             timeout=20).stdout
    except (OSError, subprocess.SubprocessError):
        return None
    match = re.search(r"(libpython\S+)\s+=>\s+(\S+)", out)
    return Path(match.group(2)).resolve() if match and Path(match.group(2)).is_file() else None


def _find_python_dll(version: str) -> LibPython:
    """On Windows the host needs python3X.dll (and python3.dll) on PATH."""
    dll = f"python{version.replace('.', '')}.dll"
    tried = [Path(sys.base_prefix) / dll, Path(sys._base_executable).parent / dll]  # type: ignore[attr-defined]
    for candidate in tried:
        if candidate.is_file():
            return LibPython(candidate, True, tuple(tried), "put its folder on PATH")
    return LibPython(None, True, tuple(tried), f"{dll} not found next to the base interpreter")


def python_home() -> str:
    """PYTHONHOME for the embedded interpreter: the base installation of this Python.

    ``prefix:exec_prefix`` when they differ (POSIX syntax). A venv has no
    standard library of its own, so the base prefix is right there too.
    """
    prefix, exec_prefix = sys.base_prefix, sys.base_exec_prefix
    return prefix if prefix == exec_prefix else f"{prefix}{os.pathsep}{exec_prefix}"


def required_paths(modules: Sequence[str] = REQUIRED_MODULES) -> tuple[list[str], list[str]]:
    """The sys.path folders that hold `modules`, and the modules not importable at all.

    Only these folders go on PYTHONPATH: a whole sys.path would also carry the
    current directory and this interpreter's stdlib, which PYTHONHOME provides.
    Note that .pth files (editable installs) are honoured only in site folders,
    not in PYTHONPATH entries; numpy and scipy need none.
    """
    folders: list[str] = []
    missing: list[str] = []
    for name in modules:
        spec = find_spec(name)
        if spec is None or not spec.origin:
            missing.append(name)
            continue
        origin = Path(spec.origin).resolve()
        top = origin.parent.parent if origin.name == "__init__.py" else origin.parent
        folders.append(str(top))
    return list(dict.fromkeys(folders)), missing


def site_packages() -> list[str]:
    """Every site-packages folder of this interpreter (venv and user site included)."""
    dirs = list(site.getsitepackages())
    if site.ENABLE_USER_SITE and Path(site.getusersitepackages()).is_dir():
        dirs.append(site.getusersitepackages())
    return dirs


def glibc_version() -> tuple[int, int] | None:
    """The glibc of this machine, or None (musl, macOS, Windows)."""
    try:
        text = os.confstr("CS_GNU_LIBC_VERSION") or ""
    except (AttributeError, ValueError, OSError):
        text = ""
    match = re.search(r"glibc (\d+)\.(\d+)", text)
    return (int(match.group(1)), int(match.group(2))) if match else None


def glibc_required(binary: bytes) -> tuple[int, int] | None:
    """The newest GLIBC_x.y symbol version an ELF binary references (its real need)."""
    versions = {(int(a), int(b)) for a, b in re.findall(rb"GLIBC_(\d+)\.(\d+)", binary)}
    return max(versions) if versions else None


def find_compiler() -> str | None:
    """The system C compiler: $CC, then cc, gcc, clang."""
    for name in (os.environ.get("CC"), "cc", "gcc", "clang"):
        if name:
            path = shutil.which(name)
            if path:
                return path
    return None


def fmi2_header_dir() -> Path | None:
    """The folder of fmi2FunctionTypes.h that fmpy ships (fmpy/c-code), if any."""
    spec = find_spec("fmpy")
    if spec is None or not spec.origin:
        return None
    folder = Path(spec.origin).parent / "c-code"
    return folder if (folder / "fmi2FunctionTypes.h").is_file() else None


# --------------------------------------------------------------------------- #
# The check: a C host loading an FMU
# --------------------------------------------------------------------------- #
@dataclass
class HostRun:
    """One run of the compiled C host on an FMU, with the environment it got."""

    label: str
    env: dict[str, str]  #: variables set besides PATH=/usr/bin:/bin
    command: list[str]
    returncode: int
    stdout: str
    stderr: str
    outputs: dict[str, list[float]] = field(default_factory=dict)  #: name -> value per step
    times: list[float] = field(default_factory=list)

    @property
    def reached_end(self) -> bool:
        """True when the host printed its last line: the simulation itself succeeded."""
        return END_MARKER in self.stdout

    @property
    def crashed_at_exit(self) -> bool:
        """Everything ran, then the process died in exit-time teardown."""
        return self.reached_end and self.returncode != 0

    @property
    def passed(self) -> bool:
        return self.reached_end and self.returncode == 0

    def verdict(self) -> str:
        code = self.returncode
        signal_note = f" (signal {-code})" if code < 0 else (" (SIGABRT)" if code == 134 else "")
        if self.passed:
            return f"PASS: exit status 0, {len(self.times)} steps"
        if self.crashed_at_exit:
            return (f"simulation OK ({len(self.times)} steps), then CRASHED AT PROCESS EXIT: "
                    f"exit status {code}{signal_note}")
        meaning = HOST_EXIT_MEANING.get(code, "crashed" if code < 0 else "failed")
        return f"FAIL: exit status {code}{signal_note}: {meaning}"

    def key_lines(self, limit: int = 6) -> list[str]:
        """The host and FMU log lines that explain the outcome."""
        lines = [ln for ln in (self.stdout + self.stderr).splitlines()
                 if ln.startswith(("log:", "host: dlopen", "host: symbol", "host: fmi2Inst"))
                 or "Error" in ln or "corrupted" in ln or "free()" in ln or "Abort" in ln]
        return lines[:limit]


@dataclass(frozen=True)
class FmuInfo:
    """What the host needs from modelDescription.xml and the unzipped FMU."""

    model_identifier: str
    guid: str
    binary: Path
    resources: Path
    real_vrs: dict[str, int]
    outputs: tuple[str, ...]


def unpack_fmu(fmu: Path, dest: Path) -> FmuInfo:
    """Unzip an FMU and read the identifiers the C host needs."""
    with zipfile.ZipFile(fmu) as z:
        z.extractall(dest)
    root = ElementTree.parse(dest / "modelDescription.xml").getroot()
    cs = root.find("CoSimulation")
    if cs is None:
        raise ValueError(f"{fmu} is not an FMI 2.0 co-simulation FMU")
    ident = cs.get("modelIdentifier", "")
    reals: dict[str, int] = {}
    outputs: list[str] = []
    for var in root.iter("ScalarVariable"):
        if var.find("Real") is not None:
            reals[var.get("name", "")] = int(var.get("valueReference", "0"))
            if var.get("causality") == "output":
                outputs.append(var.get("name", ""))
    platform_dir, suffix = {"win32": ("win64", ".dll"), "darwin": ("darwin64", ".dylib")}.get(
        sys.platform, ("linux64", ".so"))
    return FmuInfo(ident, root.get("guid", ""), dest / "binaries" / platform_dir / (ident + suffix),
                   dest / "resources", reals, tuple(outputs))


def compile_host(workdir: Path, compiler: str) -> tuple[Path | None, str]:
    """Compile fmu_host.c; returns (executable or None, compiler command and messages)."""
    exe = workdir / "fmu_host"
    cmd = [compiler, "-std=c99", "-O1", "-o", str(exe), str(HOST_SOURCE)]
    headers = fmi2_header_dir()
    if headers is not None:
        cmd[1:1] = ["-DHAVE_FMI2_HEADERS", f"-I{headers}"]
    if sys.platform.startswith("linux"):
        cmd.append("-ldl")
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    text = " ".join(cmd) + ("\n" + proc.stderr.strip() if proc.stderr.strip() else "")
    return (exe if proc.returncode == 0 and exe.exists() else None), text


def run_host(
    exe: Path,
    info: FmuInfo,
    env: dict[str, str],
    label: str,
    inputs: dict[str, float] | None = None,
    outputs: Sequence[str] | None = None,
    step: float = CHECK_STEP,
    steps: int = CHECK_STEPS,
    extra_args: Sequence[str] = (),
) -> HostRun:
    """Run the C host on an unpacked FMU from a clean environment plus `env`."""
    plan_inputs, plan_outputs = CHECK_PLANS.get(info.model_identifier, ({}, info.outputs))
    inputs = plan_inputs if inputs is None else inputs
    names = list(plan_outputs if outputs is None else outputs)[:64]
    cmd = [str(exe), str(info.binary), info.guid, info.resources.as_uri(), repr(step), str(steps)]
    for name, value in inputs.items():
        cmd += ["-s", f"{info.real_vrs[name]}={value!r}"]
    for name in names:
        cmd += ["-o", str(info.real_vrs[name])]
    cmd += list(extra_args)
    full_env = {"PATH": CLEAN_PATH, "LC_ALL": "C.UTF-8", **env}
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, env=full_env, timeout=300,
                              cwd=exe.parent)
        code, out, err = proc.returncode, proc.stdout, proc.stderr
    except subprocess.TimeoutExpired as exc:
        code, out, err = -9, str(exc.stdout or ""), "timed out after 300 s"
    run = HostRun(label, env, cmd, code, out, err)
    by_vr = {str(info.real_vrs[n]): n for n in names}
    for line in out.splitlines():
        if line.startswith("step "):
            fields_ = line.split()
            run.times.append(float(fields_[2].removeprefix("t=")))
            for item in fields_[3:]:
                vr, _, value = item.partition("=")
                run.outputs.setdefault(by_vr.get(vr, vr), []).append(float(value))
    return run


# --------------------------------------------------------------------------- #
# The report
# --------------------------------------------------------------------------- #
@dataclass
class DoctorReport:
    """Everything `gyro-fmu doctor` found; `format()` is what it prints."""

    python: str
    libpython: LibPython
    python_home: str
    pythonpath: list[str]
    missing_modules: list[str]
    site_packages: list[str]
    glibc: tuple[int, int] | None
    glibc_needed: tuple[int, int] | None
    fmu: Path | None = None
    compiler: str | None = None
    compile_log: str = ""
    runs: list[HostRun] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def environment(self) -> dict[str, str]:
        """The variables a non-Python importer's process needs (POSIX form)."""
        env = {"PYTHONHOME": self.python_home, "PYTHONPATH": os.pathsep.join(self.pythonpath)}
        if self.libpython.path is not None and sys.platform != "win32":
            key = "DYLD_INSERT_LIBRARIES" if sys.platform == "darwin" else "LD_PRELOAD"
            env = {key: str(self.libpython.path), **env}
        return env

    @property
    def glibc_ok(self) -> bool | None:
        if self.glibc is None or self.glibc_needed is None:
            return None
        return self.glibc >= self.glibc_needed

    @property
    def check(self) -> HostRun | None:
        """The run with the prescribed environment, if the check ran."""
        return next((r for r in self.runs if r.label == "prescribed"), None)

    @property
    def ok(self) -> bool:
        """Settings found, glibc new enough and, if the check ran, the C host simulated."""
        check = self.check
        return (self.libpython.path is not None and not self.missing_modules
                and self.glibc_ok is not False
                and (check is None or check.reached_end))

    def format(self) -> str:
        """Human-readable report: settings first, then the evidence."""
        out: list[str] = [f"gyro-fmu doctor: {self.python}", ""]
        lib = self.libpython
        out.append("1. libpython to preload")
        out.append(f"   {lib.path if lib.path else 'NOT FOUND'}  ({lib.note})")
        out.append("2. PYTHONHOME (measured necessary: pythonfmu's embedded interpreter otherwise")
        out.append("   searches PATH for python3 and may take another installation's stdlib)")
        out.append(f"   {self.python_home}")
        out.append("3. PYTHONPATH (the folders holding " + ", ".join(REQUIRED_MODULES) + ")")
        out.append(f"   {os.pathsep.join(self.pythonpath) or '(none found)'}")
        if self.missing_modules:
            out.append(f"   MISSING here: {', '.join(self.missing_modules)}: pip install them")
        out.append("   (all site-packages of this interpreter: "
                   f"{os.pathsep.join(self.site_packages)})")
        out.append("4. Windows")
        out.extend("   " + line for line in self._windows_lines())
        out.append("5. glibc")
        have = "not glibc" if self.glibc is None else "{}.{}".format(*self.glibc)
        need = "?" if self.glibc_needed is None else "{}.{}".format(*self.glibc_needed)
        verdict = {True: "OK", False: "TOO OLD: the FMU binary will not load", None: "n/a"}[
            self.glibc_ok]
        out.append(f"   this machine {have}, FMU binary needs >= {need}: {verdict}")
        out.append("")
        out.append("In a shell (OMSimulator, a C program, or the shell that starts")
        out.append("MATLAB/Simulink or Dymola):")
        for key, value in self.environment().items():
            out.append(f"   export {key}={_shell_quote(value)}")
        out.append("")
        out.append("Check with a compiled C FMI 2.0 co-simulation host")
        if self.fmu is not None:
            out.append(f"   FMU: {self.fmu}")
        if self.compile_log:
            out.append(f"   compiled: {self.compile_log.splitlines()[0]}")
        for run in self.runs:
            given = " ".join(f"{k}=..." for k in run.env) or "nothing but PATH=" + CLEAN_PATH
            out.append(f"   [{run.label}] env: {given}")
            out.append(f"      {run.verdict()}")
            if run.outputs:
                last = ", ".join(f"{n}={v[-1]:.9g}" for n, v in run.outputs.items())
                out.append(f"      at t={run.times[-1]:.6g} s: {last}")
            out.extend(f"      | {line}" for line in run.key_lines())
        out.extend("   note: " + n for n in self.notes)
        out.append("")
        result = "OK" if self.ok else "PROBLEMS (see above)"
        check = self.check
        if self.ok and check is not None and check.crashed_at_exit:
            result += " for loading and stepping; WARNING: the host process crashed at exit"
        out.append("RESULT: " + result)
        return "\n".join(out)

    def _windows_lines(self) -> list[str]:
        if sys.platform == "win32":
            folder = self.libpython.path.parent if self.libpython.path else Path(sys.base_prefix)
            return [f"put {folder} on PATH (it holds python3.dll and "
                    f"python{sys.version_info.major}{sys.version_info.minor}.dll), and set",
                    f"PYTHONHOME={self.python_home} and PYTHONPATH as above (';'-separated)"]
        return ["(not this machine) put the folder of the base Python installation, the one",
                "holding python3.dll and python3XY.dll (e.g. C:\\Program Files\\Python311 or",
                "%LOCALAPPDATA%\\Programs\\Python\\Python311; a venv's base, not its Scripts),",
                "on PATH of the importer; set PYTHONHOME to that folder and PYTHONPATH to the",
                "Lib\\site-packages holding numpy and scipy (';'-separated). Same Python",
                "minor version as the one the FMUs were built with."]


def _shell_quote(value: str) -> str:
    return value if re.fullmatch(r"[\w./:=+-]*", value) else "'" + value.replace("'", "'\\''") + "'"


def default_fmu(workdir: Path) -> Path:
    """models/GyroPlant.fmu, built into workdir if the models folder has none."""
    fmu = MODELS_DIR / "GyroPlant.fmu"
    if fmu.exists():
        return fmu
    from ..fmu.build import build_fmu

    return build_fmu("GyroPlant", workdir)


def doctor(fmu: Path | None = None, compile_host: bool = True) -> DoctorReport:
    """Work out the settings a non-Python importer needs and, unless told not to,
    prove them by loading `fmu` (default models/GyroPlant.fmu) in a compiled C host."""
    lib = find_libpython()
    paths, missing = required_paths()
    report = DoctorReport(
        python=f"Python {platform.python_version()} at {sys.executable} "
               f"({platform.system()} {platform.machine()})",
        libpython=lib, python_home=python_home(), pythonpath=paths,
        missing_modules=missing, site_packages=site_packages(),
        glibc=glibc_version(), glibc_needed=None,
    )
    with tempfile.TemporaryDirectory(prefix="gyro-fmu-doctor-") as tmp:
        work = Path(tmp)
        fmu_path = Path(fmu) if fmu is not None else default_fmu(work)
        report.fmu = fmu_path
        info = unpack_fmu(fmu_path, work / "fmu")
        if info.binary.exists():
            needed = glibc_required(info.binary.read_bytes())
            report.glibc_needed = needed if needed is not None else (
                GLIBC_NEEDED if sys.platform.startswith("linux") else None)
        else:
            report.notes.append(f"the FMU has no binary for this platform ({info.binary.name})")
        if not compile_host:
            report.notes.append("C-host check skipped (compile_host=False)")
            return report
        _check(report, info, work)
    return report


def _check(report: DoctorReport, info: FmuInfo, work: Path) -> None:
    """Compile the C host and run it with, without and with half the environment."""
    if sys.platform == "win32":
        report.notes.append("the C-host check runs on Linux only (it uses dlopen and LD_PRELOAD)")
        return
    report.compiler = find_compiler()
    if report.compiler is None:
        report.notes.append("no C compiler (cc, gcc, clang or $CC) found: C-host check skipped")
        return
    if not info.binary.exists():
        return
    exe, log = compile_host(work, report.compiler)
    report.compile_log = log
    if exe is None:
        report.notes.append(f"compiling the C host failed:\n{log}")
        return
    env = report.environment()
    report.runs.append(run_host(exe, info, env, "prescribed"))
    report.runs.append(run_host(exe, info, {}, "without"))
    preload_only = {k: v for k, v in env.items() if not k.startswith("PYTHON")}
    report.runs.append(run_host(exe, info, preload_only, "preload only"))
    check = report.check
    if check is not None and check.crashed_at_exit:
        report.notes.append(
            "the crash at exit is pythonfmu 0.7.0's: its static shared_ptr<PyState> is destroyed "
            "by an exit handler, then its __attribute__((destructor)) onLibraryUnload assigns to "
            "it again (use after free, valgrind: invalid read in finalizePythonInterpreter). "
            "Whether it aborts depends on the heap at exit (numpy/scipy imports change it). "
            "Results before exit are complete and correct.")


def main(fmu: Path | None = None, compile_host: bool = True) -> int:
    """Print the doctor's report; exit status 0 when the setup works, 1 otherwise."""
    report = doctor(fmu, compile_host)
    print(report.format())
    return 0 if report.ok else 1
