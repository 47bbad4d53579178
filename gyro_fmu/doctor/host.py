"""The C-host check of `gyro-fmu doctor`: compile chost/fmu_host.c, unpack an FMU, run it.

`compile_host` builds the minimal FMI 2.0 co-simulation importer with the system C
compiler, `unpack_fmu` reads what it needs from an FMU (`FmuInfo`), `run_host` runs it
from a clean environment (PATH=/usr/bin:/bin, no PYTHON* variable) plus the variables
given and parses its output (`HostRun`). What the host does: docs/fmi-notes.md.
"""

from __future__ import annotations

import subprocess
import sys
import zipfile
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from xml.etree import ElementTree

from ..cosim.archives import archive_problem
from ..errors import GyroFmuError
from ..fmu.interfaces import NATIVE_INTERFACES
from .environment import fmi2_header_dir

#: Source of the C host, shipped as package data.
HOST_SOURCE = Path(__file__).resolve().parent / "chost" / "fmu_host.c"

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

#: A check plan: the Real inputs held over every step, and the outputs read.
CheckPlan = tuple[dict[str, float], tuple[str, ...]]
CHECK_STEP = 5e-6  #: s, the default communication step of the scenarios
CHECK_STEPS = 20


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


class DoctorArchiveError(GyroFmuError):
    """An FMU archive the doctor will not unpack."""


def unpack_fmu(fmu: Path, dest: Path) -> FmuInfo:
    """Unzip an FMU and read the identifiers the C host needs."""
    with zipfile.ZipFile(fmu) as z:
        problem = archive_problem(z)
        if problem:
            raise DoctorArchiveError(f"{fmu} is not unpacked: {problem}; the FMU is damaged "
                                     "or not trustworthy")
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


def check_plan(info: FmuInfo) -> CheckPlan:
    """What the check holds and reads: the doctor_check its declaration gives
    (FmuInterface, by model identifier, whatever flavour the FMU was built in). Without
    one, no inputs and every Real output: an FMU that is none of ours, or a plan naming
    variables this FMU does not have."""
    interface = NATIVE_INTERFACES.get(info.model_identifier)
    plan = None if interface is None else interface.doctor_check
    if plan is None or not {*plan[0], *plan[1]} <= info.real_vrs.keys():
        return {}, info.outputs
    return dict(plan[0]), tuple(plan[1])


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
    """Run the C host on an unpacked FMU from a clean environment plus `env`; inputs and
    outputs default to the FMU's `check_plan`."""
    plan_inputs, plan_outputs = check_plan(info)
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
