"""`gyro-fmu doctor`: its C host loads GyroPlant.fmu and reproduces the Python plant."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from gyro_fmu.doctor import environment as env
from gyro_fmu.doctor import host
from gyro_fmu.doctor import report as doc
from gyro_fmu.estimation.interface import OBSERVER
from gyro_fmu.fmu import build
from gyro_fmu.model.interfaces import PLANT
from gyro_fmu.model.parameters import DEFAULT_PRESET, PRESETS
from gyro_fmu.model.plant import GyroPlantModel

needs_c_host = pytest.mark.skipif(
    not sys.platform.startswith("linux") or env.find_compiler() is None,
    reason="the C-host check needs Linux and a C compiler (cc, gcc, clang or $CC)",
)


@pytest.fixture(scope="module")
def report(pythonfmu_models: Path) -> doc.DoctorReport:
    if not sys.platform.startswith("linux") or env.find_compiler() is None:
        pytest.skip("the C-host check needs Linux and a C compiler (cc, gcc, clang or $CC)")
    return doc.doctor(pythonfmu_models / "GyroPlant.fmu")


@needs_c_host
def test_c_host_reproduces_python_plant(report: doc.DoctorReport) -> None:
    check = report.check
    assert check is not None, report.format()
    assert check.reached_end, report.format()
    inputs, names = PLANT.doctor_check
    model = GyroPlantModel(PRESETS[DEFAULT_PRESET])
    expected = []
    for _ in range(host.CHECK_STEPS):
        model.step(inputs["ux"], inputs["uy"], inputs["Omega_z"], host.CHECK_STEP)
        expected.append(model.measured().copy())
    expected_arr = np.array(expected)
    assert len(check.times) == host.CHECK_STEPS
    np.testing.assert_allclose(check.times, host.CHECK_STEP * np.arange(1, host.CHECK_STEPS + 1),
                               rtol=1e-15)
    for i, name in enumerate(names):
        got = np.array(check.outputs[name])
        want = expected_arr[:, i]
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12 * np.abs(want).max(),
                                   err_msg=name)
    assert np.abs(expected_arr[:, 0]).max() > 1e-10  # a few nm: the drive really moved it


@needs_c_host
def test_the_fmu_needs_no_settings_and_the_check_can_fail(report: doc.DoctorReport) -> None:
    """Our loader finds the Python that built the FMU: with nothing but PATH the C host
    simulates; with that Python made unreachable, fmi2Instantiate fails (exit 4) with a
    logged message that names what it looked for and the remedy."""
    assert report.loader is not None and report.loader["libpython"]
    without = next(r for r in report.runs if r.label == "without")
    assert without.returncode == 0 and without.reached_end, without.stdout + without.stderr
    assert report.check is without
    moved = next(r for r in report.runs if r.label == "Python moved")
    assert moved.returncode == 4, moved.stdout + moved.stderr  # fmi2Instantiate returned NULL
    said = moved.stdout + moved.stderr
    assert "/nonexistent/libpython.so" in said and "PYTHONFMU_LIBPYTHON" in said
    assert not moved.reached_end
    text = report.format()  # the intended refusal is not reported as a failure
    assert "refused as it must: exit status 4" in text and "FAIL" not in text


@needs_c_host
def test_c_host_exits_cleanly(report: doc.DoctorReport) -> None:
    """pythonfmu 0.7.0 frees its interpreter guard twice at exit (SIGABRT in a C host,
    3 runs of 3 before gyro_fmu.pythonfmu.upstream_exit); with the workaround the host exits 0."""
    check = report.check
    assert check is not None
    assert check.returncode == 0, check.stdout + check.stderr
    assert not check.crashed_at_exit
    text = report.format()
    assert "export LD_PRELOAD=" in text and "export PYTHONHOME=" in text
    assert ("CRASHED AT PROCESS EXIT" in text) == check.crashed_at_exit


def test_the_check_plan_is_the_declarations_and_without_one_every_output(
        models_dir: Path, pythonfmu_models: Path, tmp_path: Path,
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The doctor reads what to hold and read from the FMU's declaration (whatever its
    flavour); for an FMU that is none of ours it holds no inputs and reads every Real
    output."""
    info = host.unpack_fmu(pythonfmu_models / "GyroPlant.fmu", tmp_path / "fmu")
    assert host.check_plan(info) == PLANT.doctor_check
    observer = host.unpack_fmu(models_dir / "GyroObserver.fmu", tmp_path / "observer")
    inputs, read = host.check_plan(observer)
    assert (inputs, read) == ({}, tuple(OBSERVER.doctor_check[1]))  # its 20 estimates
    assert set(read) < set(observer.outputs) and len(read) == 20
    monkeypatch.setattr(host, "NATIVE_INTERFACES", {})
    assert host.check_plan(info) == ({}, ("x", "vx", "y", "vy", "ax", "ay"))
    compiler = env.find_compiler()
    if not sys.platform.startswith("linux") or compiler is None:
        return
    exe, log = host.compile_host(tmp_path, compiler)
    assert exe is not None, log
    run = host.run_host(exe, info, doc.doctor(compile_host=False,
                                              fmu=pythonfmu_models / "GyroPlant.fmu").environment(),
                        "no source", steps=3)
    assert run.passed, run.stdout + run.stderr
    assert sorted(run.outputs) == sorted(info.outputs)
    assert all(v == [0.0, 0.0, 0.0] for v in run.outputs.values())  # at rest without inputs


@needs_c_host
@pytest.mark.parametrize("name", build.PYTHONFMU_NAMES)
def test_each_pythonfmu_fmu_runs_on_what_it_ships_alone(pythonfmu_models: Path,
                                                        tmp_path: Path, name: str) -> None:
    """A C host has no gyro_fmu but the FMU's own copy: the modules the adapter can reach
    (gyro_fmu.pythonfmu.shipping) suffice, nothing above the step travels, and the outputs are
    the native FMU's in the same host (both step the same core)."""
    import zipfile

    from gyro_fmu.pythonfmu.shipping import NEVER_IN_AN_FMU

    fmu = pythonfmu_models / f"{name}.fmu"
    with zipfile.ZipFile(fmu) as z:
        shipped = [n for n in z.namelist() if n.startswith("resources/gyro_fmu/")]
    forbidden = [m.replace(".", "/") for m in NEVER_IN_AN_FMU]
    assert not [n for n in shipped if any(n.startswith(f"resources/{f}") for f in forbidden)]
    assert len(shipped) < 40, shipped
    exe, log = host.compile_host(tmp_path, env.find_compiler())
    assert exe is not None, log
    runs = {}
    for flavour, path in (("pythonfmu", fmu), ("native", build.prebuilt_fmu(name))):
        info = host.unpack_fmu(path, tmp_path / flavour)
        environment = doc.doctor(compile_host=False, fmu=path).environment()
        runs[flavour] = host.run_host(exe, info, environment, flavour, steps=20)
        assert runs[flavour].passed, runs[flavour].stdout + runs[flavour].stderr
    assert runs["pythonfmu"].outputs == runs["native"].outputs


def test_settings_of_this_interpreter() -> None:
    lib = env.find_libpython()
    if lib.path is None:
        pytest.skip(f"this Python has no shared libpython: {lib.note}")
    assert lib.path.is_file() and "python" in lib.path.name
    paths, missing = env.required_paths()
    assert not missing
    assert all((Path(p) / "numpy").is_dir() or (Path(p) / "scipy").is_dir() for p in paths)
    assert env.python_home().startswith(sys.base_prefix)


def test_no_compiler_skips_cleanly(models_dir: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(doc, "find_compiler", lambda: None)  # as the report looks it up
    report = doc.doctor(models_dir / "TwoToneDrive.fmu")
    assert report.runs == []
    assert report.check is None
    if sys.platform.startswith("linux"):
        assert any("no C compiler" in n for n in report.notes)
        assert report.glibc_needed is not None and report.glibc_needed >= (2, 2)
    assert "C-host check" in report.format() or "no C compiler" in report.format()


@needs_c_host
def test_a_native_fmu_needs_nothing_and_the_doctor_proves_it() -> None:
    """The doctor gives no Python settings for a native FMU and shows the C host
    simulating it with an empty environment."""
    from gyro_fmu.fmu.build import prebuilt_fmu

    report = doc.doctor(prebuilt_fmu("GyroPlant"))
    text = report.format()
    assert report.native and report.ok, text
    assert "This is a native C FMU" in text and "export" not in text
    assert [r.label for r in report.runs] == ["without"] and report.check.reached_end
