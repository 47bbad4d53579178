"""The native FMUs in hosts we did not write, as a user meets them: copied into an empty
folder and run by a C host with an empty environment (`env -i`), by the same host built
for Windows running the win64 DLL under wine, each reproducing the reference results the
FMU carries. (fmpy from a venv without gyro_fmu: .ci/wheel-check; libcosim and Ecos run
the native FMUs in test_ssp.py and test_ecos.py.)

Tolerance against the reference: 1e-12 of each output's range. The reference was made by
fmpy.simulate_fmu, whose input table lookup gives inputs a few ulps off the table's
values (5e-15 of the range measured); the hosts here set the table's values exactly.
The observer amplifies such differences (an adaptive filter: mixing weights are
exponentials of likelihoods): inputs scaled by 1 + 2 ulp move its outputs by 1.8e-10 of
their range (measured in process on the reference inputs), so its tolerance is 1e-9.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description

from gyro_fmu.doctor.report import find_compiler
from gyro_fmu.fmu.build import NATIVE_NAMES, prebuilt_fmu
from gyro_fmu.fmu.reference import LS_REF_DIR, parse_csv

HOST_C = Path(__file__).resolve().parents[1] / "gyro_fmu" / "doctor" / "chost" / "fmu_host.c"
TOLERANCE = 1e-12
#: GyroObserver's and GyroSensor's filters amplify libm's last-bit differences between
#: platforms (measured: GyroSensor's win64 DLL 1.2e-11 of range: its output filter at
#: f_c / f_s = 2e-3 scales rounding by about (f_s / f_c)^2)
TOLERANCES = {"GyroObserver": 1e-9, "GyroSensor": 1e-9}


def _reference(fmu: Path, name: str) -> tuple[np.ndarray, np.ndarray | None]:
    with zipfile.ZipFile(fmu) as z:
        out = parse_csv(z.read(f"{LS_REF_DIR}/{name}_out.csv"), "out")
        members = z.namelist()
        inp = (parse_csv(z.read(f"{LS_REF_DIR}/{name}_in.csv"), "in")
               if f"{LS_REF_DIR}/{name}_in.csv" in members else None)
    return out, inp


def _host_args(folder: Path, name: str, library: str, uri: str) -> tuple[list[str], np.ndarray]:
    """Arguments of fmu_host for the FMU's reference run, and the reference outputs."""
    fmu = folder / f"{name}.fmu"
    md = read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    out, inp = _reference(fmu, name)
    step = float(md.defaultExperiment.stepSize)
    args = [library, md.guid, uri, repr(step), str(len(out) - 1)]
    if inp is not None:
        names = list(inp.dtype.names[1:])
        table = folder / "inputs.txt"
        np.savetxt(table, np.column_stack([inp[n] for n in names]), fmt="%.17g")
        args += [a for n in names for a in ("-s", f"{vr[n]}=0")] + ["-f", table.name]
    args += [a for n in out.dtype.names[1:] for a in ("-o", str(vr[n]))]
    return args, out


def _parse(stdout: str, out: np.ndarray, vr: dict[str, int]) -> np.ndarray:
    rows = []
    for line in stdout.splitlines():
        if line.startswith("step "):
            cells = dict(c.split("=") for c in line.split()[2:])
            rows.append([float(cells[str(vr[n])]) for n in out.dtype.names[1:]])
    return np.array(rows)


def _worst(got: np.ndarray, out: np.ndarray) -> float:
    """Largest |host - reference| over each output's range (rows after the first)."""
    worst = 0.0
    for j, n in enumerate(out.dtype.names[1:]):
        ref = out[n][1:]
        scale = max(np.ptp(ref), np.max(np.abs(ref)), 1e-300)
        worst = max(worst, float(np.max(np.abs(got[:, j] - ref)) / scale))
    return worst


@pytest.fixture(scope="module")
def linux_host(tmp_path_factory: pytest.TempPathFactory) -> Path:
    compiler = find_compiler()
    if compiler is None:
        pytest.skip("needs a C compiler for the C host")
    exe = tmp_path_factory.mktemp("chost") / "fmu_host"
    subprocess.run([compiler, "-O1", "-o", str(exe), str(HOST_C), "-ldl"], check=True)
    return exe


@pytest.mark.parametrize("name", NATIVE_NAMES)
def test_a_c_host_with_an_empty_environment_reproduces_the_reference(
        linux_host: Path, name: str, tmp_path: Path) -> None:
    folder = tmp_path / "empty"
    folder.mkdir()
    shutil.copy(prebuilt_fmu(name), folder)
    with zipfile.ZipFile(folder / f"{name}.fmu") as z:
        z.extractall(folder / "fmu")
    library = folder / "fmu" / "binaries" / "linux64" / f"{name}.so"
    args, out = _host_args(folder, name, str(library), (folder / "fmu" / "resources").as_uri())
    proc = subprocess.run([str(linux_host), *args], cwd=folder, env={}, capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr
    assert "host: returning from main" in proc.stdout
    md = read_model_description(str(folder / f"{name}.fmu"))
    got = _parse(proc.stdout, out, {v.name: v.valueReference for v in md.modelVariables})
    assert got.shape == (len(out) - 1, len(out.dtype.names) - 1)
    assert _worst(got, out) <= TOLERANCES.get(name, TOLERANCE)


def _windows_tools() -> tuple[str, str] | None:
    gcc, wine = shutil.which("x86_64-w64-mingw32-gcc"), shutil.which("wine")
    return (gcc, wine) if gcc and wine else None


@pytest.fixture(scope="module")
def windows_host(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    tools = _windows_tools()
    if tools is None:
        pytest.skip("needs Debian's gcc-mingw-w64-x86-64 and wine64 (.ci/run installs them)")
    exe = tmp_path_factory.mktemp("winhost") / "fmu_host.exe"
    subprocess.run([tools[0], "-O1", "-o", str(exe), str(HOST_C)], check=True)
    env = {**os.environ, "WINEDEBUG": "-all",
           "WINEPREFIX": str(tmp_path_factory.mktemp("wineprefix"))}
    return exe, env


@pytest.mark.parametrize("name", NATIVE_NAMES)
def test_the_win64_dll_under_wine_reproduces_the_reference(
        windows_host: tuple[Path, dict], name: str, tmp_path: Path) -> None:
    """The FMU's Windows x86_64 binary, loaded by a Windows C host (mingw) under wine."""
    exe, env = windows_host
    folder = tmp_path / "empty"
    folder.mkdir()
    shutil.copy(prebuilt_fmu(name), folder)
    with zipfile.ZipFile(folder / f"{name}.fmu") as z:
        z.extractall(folder / "fmu")
    dll = "Z:" + str(folder / "fmu" / "binaries" / "win64" / f"{name}.dll").replace("/", "\\")
    args, out = _host_args(folder, name, dll, "file:///Z:" + str(folder / "fmu" / "resources"))
    proc = subprocess.run(["wine", str(exe), *args], cwd=folder, env=env, capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    md = read_model_description(str(folder / f"{name}.fmu"))
    got = _parse(proc.stdout, out, {v.name: v.valueReference for v in md.modelVariables})
    assert got.shape == (len(out) - 1, len(out.dtype.names) - 1)
    worst = _worst(got, out)
    print(f"{name}: win64 under wine, max |difference| / range = {worst:.3g}")
    assert worst <= TOLERANCES.get(name, TOLERANCE)
