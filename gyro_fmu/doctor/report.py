"""`gyro-fmu doctor`: the settings a non-Python importer needs to load our FMUs, proved.

`doctor()` collects the settings of this interpreter (`environment`: libpython to
preload, PYTHONHOME, PYTHONPATH, glibc) and, unless told not to, runs the compiled C
host on an FMU (`host`) three times: with those settings (must pass), with none (must
fail at dlopen: the check can fail) and with the preload only. `DoctorReport.format()`
is what the command prints; `main()` exits 0 when the setup works. Why each setting is
needed: docs/fmi-notes.md.
"""

from __future__ import annotations

import os
import platform
import re
import sys
import tempfile
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import GyroFmuError
from ..fmu.build import MODELS_DIR
from ..pythonfmu.loader import recorded_python
from .environment import (
    GLIBC_NEEDED,
    REQUIRED_MODULES,
    LibPython,
    find_compiler,
    find_libpython,
    glibc_required,
    glibc_version,
    python_home,
    required_paths,
    site_packages,
)
from .environment import fmi2_header_dir as fmi2_header_dir  # re-exported: older imports
from .host import CLEAN_PATH, FmuInfo, HostRun, compile_host, run_host, unpack_fmu

#: The doctor's negative check: the recorded Python made unreachable, the FMU must refuse
#: at fmi2Instantiate, naming it (its report says so, not "FAIL").
MUST_FAIL = "Python moved"


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
    #: What the FMU's own loader will use (resources/python_env.txt), None without one.
    loader: dict[str, list[str]] | None = None
    #: A native C FMU (no Python inside): it needs no settings, and the check proves it.
    native: bool = False

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
        """The run that must work, if the check ran: with no settings at all for an FMU
        with our loader, with the prescribed environment for one without."""
        label = "without" if (self.loader is not None or self.native) else "prescribed"
        return next((r for r in self.runs if r.label == label), None)

    @property
    def ok(self) -> bool:
        """Settings found, glibc new enough and, if the check ran, the C host simulated."""
        check = self.check
        if self.native:
            return self.glibc_ok is not False and (check is None or check.reached_end)
        return (self.libpython.path is not None and not self.missing_modules
                and self.glibc_ok is not False
                and (check is None or check.reached_end))

    def format(self) -> str:
        """Human-readable report: settings first, then the evidence."""
        if self.native:
            return self._format_native()
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
        if self.loader is not None:
            out.append("This FMU loads the Python it was built with by itself (its loader; no "
                       "settings needed on this machine):")
            for key in ("libpython", "pythonhome", "pythonpath"):
                out.extend(f"   {key}: {v}" for v in self.loader.get(key, []))
            out.append("On another machine, or after moving this Python, set these instead")
            out.append("(the loader keeps PYTHONHOME/PYTHONPATH you set; PYTHONFMU_LIBPYTHON")
            out.append("names another libpython):")
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
            verdict = run.verdict()
            if run.label == MUST_FAIL and not run.passed:  # the intended negative check
                verdict = "refused as it must: " + verdict.removeprefix("FAIL: ")
            out.append(f"      {verdict}")
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

    def _format_native(self) -> str:
        """A native FMU: no settings to give; the evidence is the C host with nothing."""
        out = [f"gyro-fmu doctor: {self.fmu}", "",
               "This is a native C FMU (no Python inside): any host loads it as it is, on",
               "Linux x86_64/aarch64 (glibc 2.17 or newer), Windows x86_64 and macOS. It needs",
               "no LD_PRELOAD, PYTHONHOME, PYTHONPATH or PATH setting.", ""]
        have = "not glibc" if self.glibc is None else "{}.{}".format(*self.glibc)
        need = "?" if self.glibc_needed is None else "{}.{}".format(*self.glibc_needed)
        out.append(f"glibc: this machine {have}, FMU binary needs >= {need}")
        out.append("Check with a compiled C FMI 2.0 co-simulation host, empty environment")
        for run in self.runs:
            out.append(f"   [{run.label}] {run.verdict()}")
            if run.outputs:
                last = ", ".join(f"{n}={v[-1]:.9g}" for n, v in run.outputs.items())
                out.append(f"      at t={run.times[-1]:.6g} s: {last}")
        out.extend("   note: " + n for n in self.notes)
        out += ["", "OK" if self.ok else "PROBLEMS (see above)"]
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


class DoctorError(GyroFmuError):
    """The FMU given to the doctor cannot be opened."""


def default_fmu(workdir: Path) -> Path:
    """A pythonfmu FMU to check: models/GyroObserver.fmu if there, else the pythonfmu
    flavour of GyroPlant built into workdir. (The native FMUs need no settings: any host
    loads them as they are.)"""
    fmu = MODELS_DIR / "GyroObserver.fmu"
    if fmu.exists():
        return fmu
    from ..fmu.build import build_fmu

    return build_fmu("GyroPlant", workdir, flavour="pythonfmu")


def doctor(fmu: Path | None = None, compile_host: bool = True) -> DoctorReport:
    """Work out the settings a non-Python importer needs and, unless told not to,
    prove them by loading `fmu` (default: see default_fmu) in a compiled C host."""
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
        report.loader = recorded_python(fmu_path)
        info = unpack_fmu(fmu_path, work / "fmu")
        report.native = not (work / "fmu" / "resources" / "gyro_fmu").is_dir()
        real = info.binary.with_name(f"{info.binary.stem}_pythonfmu.so")  # behind our loader
        if info.binary.exists():
            needed = glibc_required((real if real.exists() else info.binary).read_bytes())
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
    if report.native:  # nothing to prescribe: the run with nothing must work
        report.runs.append(run_host(exe, info, {}, "without"))
        return
    env = report.environment()
    report.runs.append(run_host(exe, info, env, "prescribed"))
    report.runs.append(run_host(exe, info, {}, "without"))
    if report.loader is not None:  # the check can fail: the recorded Python made unreachable
        report.runs.append(run_host(exe, info, {"PYTHONFMU_LIBPYTHON": "/nonexistent/libpython.so"},
                                    MUST_FAIL))
    else:
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
    if fmu is not None:
        try:
            with zipfile.ZipFile(fmu) as z:
                z.getinfo("modelDescription.xml")
        except (zipfile.BadZipFile, KeyError, OSError) as exc:
            raise DoctorError(f"{fmu} is not an FMU the doctor can open ({exc}): name an .fmu "
                              "file (a zip archive with a modelDescription.xml)") from None
    report = doctor(fmu, compile_host)
    print(report.format())
    return 0 if report.ok else 1
