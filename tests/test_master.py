"""The fmpy master: clear errors for bad systems, and a user's FMU in place of ours."""

from __future__ import annotations

import importlib.util
import os
import shutil
import signal
import sys
import textwrap
import threading
import zipfile
from pathlib import Path

import numpy as np
import pytest

from gyro_fmu.cosim.instances import unpacked
from gyro_fmu.cosim.master import (
    Component,
    Connection,
    CoSimulationError,
    run_cosimulation,
)
from gyro_fmu.fmu.build import ensure_current, is_pythonfmu, prebuilt_fmu
from gyro_fmu.pythonfmu.build import stale_sources
from gyro_fmu.system.run import run_fmus
from gyro_fmu.system.scenario import scenario


def test_bad_systems_get_errors_that_name_the_problem(models_dir, tmp_path):
    drive = Component("drive", models_dir / "TwoToneDrive.fmu")
    plant = Component("plant", models_dir / "GyroPlant.fmu")
    cases = [
        ([Component("d", tmp_path / "missing.fmu")], [], "missing.fmu .* not found"),
        ([drive, plant], [Connection("drive.uz", "plant.ux")], "has no variable 'uz'"),
        ([drive, plant], [Connection("plant.ux", "drive.ux")], "'ux' is a input, expected output"),
        ([drive, plant], [Connection("drive.ux", "plant.ux"), Connection("drive.uy", "plant.ux")],
         "connected twice"),
        ([drive, plant], [Connection("drive.ux", "nobody.ux")], "no instance 'nobody'"),
        ([Component("plant", models_dir / "GyroPlant.fmu", {"kzz": 1.0})], [],
         "has no parameter 'kzz'"),
        ([drive, drive], [], "instance names must be unique"),
        ([Component("plant", models_dir / "GyroPlant.fmu", inputs={"kxx": 1.0})], [],
         "has no input 'kxx'; its inputs are \\['Omega_z', 'ux', 'uy'\\]"),
        ([drive, Component("plant", models_dir / "GyroPlant.fmu", inputs={"ux": 1e-7})],
         [Connection("drive.ux", "plant.ux")],
         "plant.ux is driven by a connection and also given the value 1e-07"),
    ]
    for components, connections, message in cases:
        with pytest.raises(CoSimulationError, match=message):
            run_cosimulation(components, connections, 1e-4, 5e-6)
    with pytest.raises(CoSimulationError, match="must read"):
        Connection.parse("drive.ux plant.ux")


def test_refused_parameters_surface_with_the_fmus_own_message(models_dir):
    bad = Component("plant", models_dir / "GyroPlant.fmu", {"kxy": 1e9})
    with pytest.raises(CoSimulationError, match="not positive definite") as info:
        run_cosimulation([bad], [], 1e-4, 5e-6)
    assert "plant: initialization failed" in str(info.value)  # the native FMU's error
    assert "it said:\nGyroPlant: initialization failed: stiffness matrix" in str(info.value)


def test_a_users_fmu_replaces_ours(models_dir, tmp_path):
    """A user's square-wave drive FMU (different name, same interface) runs in our system."""
    FmuBuilder = pytest.importorskip("pythonfmu.builder", reason="the user's FMU is written "
                                     "with pythonfmu (the pythonfmu extra)").FmuBuilder
    src = tmp_path / "UserSquareDrive.py"
    src.write_text(textwrap.dedent('''
        import math
        from pythonfmu import Fmi2Causality, Fmi2Slave, Real

        class UserSquareDrive(Fmi2Slave):
            def __init__(self, **kwargs):
                super().__init__(**kwargs)
                self.ux = 0.0
                self.uy = 0.0
                self.register_variable(Real("ux", causality=Fmi2Causality.output))
                self.register_variable(Real("uy", causality=Fmi2Causality.output))

            def do_step(self, t, h):
                self.ux = 1e-7 * math.copysign(1.0, math.sin(2 * math.pi * 1700 * (t + h)))
                return True
    '''))
    user_fmu = FmuBuilder.build_FMU(src, dest=tmp_path)
    sc = scenario("default", stop_time=0.001)
    ours, theirs = run_fmus(sc, models_dir), run_fmus(sc, models_dir, {"drive": user_fmu})
    assert set(np.unique(np.abs(theirs["drive.ux"][1:]))) == {1e-7}
    assert np.max(np.abs(ours["plant.x"] - theirs["plant.x"])) > 0.1 * np.max(
        np.abs(ours["plant.x"]))
    assert np.all(np.isfinite(theirs["observer.Omega_hat"]))


def test_the_master_leaves_the_hosts_sys_path_as_it_found_it(models_dir):
    """pythonfmu prepends each FMU's resources to sys.path; left there, subprocesses
    (Dask workers) would import gyro_fmu from inside an unpacked FMU."""
    before = list(sys.path)
    run_cosimulation([Component("drive", models_dir / "TwoToneDrive.fmu")], [], 1e-4, 5e-6)
    assert sys.path == before


def test_an_archive_is_unpacked_once_until_it_changes(models_dir, tmp_path):
    fmu = tmp_path / "TwoToneDrive.fmu"
    shutil.copy(models_dir / "TwoToneDrive.fmu", fmu)
    first = unpacked(fmu)
    assert unpacked(fmu) == first and Path(first, "modelDescription.xml").is_file()
    stat = fmu.stat()
    os.utime(fmu, ns=(stat.st_atime_ns, stat.st_mtime_ns + 10**9))  # "rebuilt"
    second = unpacked(fmu)
    assert second != first and not Path(first).exists()
    result = run_cosimulation([Component("drive", fmu)], [], 1e-4, 5e-6)
    assert result["drive.ux"][-1] != 0.0


def test_a_stale_fmu_is_found_and_rebuilt(pythonfmu_all, tmp_path):
    """A pythonfmu FMU built from older sources would run its old adapter on this
    gyro_fmu: rebuilt in its flavour; a native FMU that is not the package's is replaced
    by the package's."""
    fmu = tmp_path / "GyroLoops.fmu"
    shutil.copy(pythonfmu_all / "GyroLoops.fmu", fmu)
    assert stale_sources(fmu, "GyroLoops") == []
    with zipfile.ZipFile(pythonfmu_all / "GyroLoops.fmu") as old, \
            zipfile.ZipFile(fmu, "w", zipfile.ZIP_DEFLATED) as new:
        for item in old.infolist():
            data = old.read(item.filename)
            if item.filename == "resources/gyro_fmu/model/loops.py":
                data += b"# an older version\n"
            new.writestr(item, data)
        new.writestr("resources/gyro_fmu/removed_since.py", b"")
    assert stale_sources(fmu, "GyroLoops") == [
        "resources/gyro_fmu/model/loops.py", "resources/gyro_fmu/removed_since.py"]
    assert ensure_current(("GyroLoops",), tmp_path) == [fmu]
    assert stale_sources(fmu, "GyroLoops") == [] and is_pythonfmu(fmu)
    assert ensure_current(("GyroLoops",), tmp_path) == []
    native = tmp_path / "TwoToneDrive.fmu"
    native.write_bytes(prebuilt_fmu("TwoToneDrive", 3).read_bytes())  # not the FMI 2.0 one
    assert ensure_current(("TwoToneDrive",), tmp_path) == [native]
    assert native.read_bytes() == prebuilt_fmu("TwoToneDrive").read_bytes()
    assert ensure_current(("TwoToneDrive",), tmp_path) == []


def _compiled_null_builder():
    """benchmarks/compiled_null.py: do-nothing FMUs compiled from C, optionally refusing."""
    from gyro_fmu.doctor.report import find_compiler, fmi2_header_dir

    if find_compiler() is None or fmi2_header_dir() is None:
        pytest.skip("needs a C compiler and fmpy's FMI headers")
    path = Path(__file__).resolve().parents[1] / "benchmarks" / "compiled_null.py"
    spec = importlib.util.spec_from_file_location("compiled_null", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.build_compiled_null_fmus


@pytest.mark.parametrize("refuse, message", [
    (None, None),
    ("get", r"plant refused fmi2GetReal at t=1\.5e-05 s \(fmi2Error\)"),
    ("set", r"plant refused fmi2SetReal at t=1\.5e-05 s \(fmi2Error\)"),
    ("step", r"plant \(CompiledGyroPlant\.fmu\) refused the step at t=1\.5e-05 s "
             r"\(fmi2DoStep returned fmi2Error\)"),
])
def test_a_refused_call_stops_the_compiled_loop_at_its_step_and_is_named(
        models_dir, tmp_path, refuse, message):
    """A C FMU with GyroPlant's interface refuses its 4th getReal, setReal or doStep."""
    build = _compiled_null_builder()
    plant = build({"plant": models_dir / "GyroPlant.fmu"}, tmp_path, refuse, after=3)["plant"]
    components = [Component("drive", models_dir / "TwoToneDrive.fmu"), Component("plant", plant)]
    connections = [Connection("drive.ux", "plant.ux"), Connection("drive.uy", "plant.uy")]
    if message is None:
        result = run_cosimulation(components, connections, 1e-4, 5e-6)
        assert result.data.shape == (21, 1 + 2 + 6)
        assert np.array_equal(result["plant.x"], np.arange(21.0))  # steps taken before row k
        assert np.any(result["drive.ux"] != 0.0)
        assert np.array_equal(result["time"], np.arange(21) * 5e-6)
        return
    with pytest.raises(CoSimulationError, match=message):
        run_cosimulation(components, connections, 1e-4, 5e-6)


def test_ctrl_c_stops_the_run_between_chunks_with_a_keyboard_interrupt(pythonfmu_all,
                                                                       terminal_sigint):
    """Raised inside an FMU's Python callback, Ctrl-C became fmi2Fatal (pythonfmu);
    the master holds it until the end of a chunk of steps and raises it there."""
    drive = Component("drive", pythonfmu_all / "TwoToneDrive.fmu")
    timer = threading.Timer(0.3, os.kill, (os.getpid(), signal.SIGINT))
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt, match=r"co-simulation interrupted at t = "):
            run_cosimulation([drive], [], 5.0, 5e-6)  # 1e6 steps, several seconds
    finally:
        timer.cancel()
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    assert run_cosimulation([drive], [], 1e-4, 5e-6)["drive.ux"][-1] != 0.0


def test_chunks_of_the_compiled_loop_join_without_a_seam(models_dir, tmp_path, monkeypatch):
    """Row k holds outputs after exactly k steps and t_k = k h, whatever the chunk size."""
    import gyro_fmu.cosim.master as master

    plant = _compiled_null_builder()({"plant": models_dir / "GyroPlant.fmu"}, tmp_path)["plant"]
    components = [Component("drive", models_dir / "TwoToneDrive.fmu"), Component("plant", plant)]
    connections = [Connection("drive.ux", "plant.ux")]
    runs = {}
    for chunk in (2000, 7, 50, 51):
        monkeypatch.setattr(master, "_CHUNK", chunk)
        runs[chunk] = run_cosimulation(components, connections, 50 * 5e-6, 5e-6)
    for chunk, result in runs.items():
        assert np.array_equal(result.data, runs[2000].data), chunk
    assert np.array_equal(runs[7]["plant.vy"], np.arange(51.0))
    assert np.array_equal(runs[7]["time"], np.arange(51) * 5e-6)


def test_values_of_unconnected_inputs_hold_for_the_whole_run(models_dir):
    """GyroPlant with ux and Omega_z given as values (no connections) equals the library
    stepped with the same held inputs, bit for bit."""
    from gyro_fmu.model.parameters import DEFAULT_PRESET, PRESETS
    from gyro_fmu.model.plant import GyroPlantModel

    plant = Component("plant", models_dir / "GyroPlant.fmu",
                      inputs={"ux": 2e-7, "Omega_z": 10.0})
    result = run_cosimulation([plant], [], 100 * 5e-6, 5e-6)
    model = GyroPlantModel(PRESETS[DEFAULT_PRESET])
    expected = [model.measured().copy()]
    for _ in range(100):
        model.step(2e-7, 0.0, 10.0, 5e-6)
        expected.append(model.measured().copy())
    got = np.stack([result[f"plant.{s}"] for s in ("x", "vx", "y", "vy")], axis=1)
    assert np.array_equal(got, np.array(expected))
    assert np.max(np.abs(got[:, 2])) > 0.0  # Omega_z = 10 rad/s couples x into y


def _reference_master(components, connections, stop_time: float, step: float) -> dict:
    """The simplest co-simulation master: a Python loop through fmpy's FMU2Slave, Jacobi
    order (read every output at t_k, set every connected input, step every FMU), inputs
    set exactly. The C loop of cosim.stepping is held against it."""
    from native_host import NativeRun

    runs = {c.name: NativeRun(c.fmu) for c in components}
    try:
        for c in components:
            runs[c.name].set(**c.inputs)
            runs[c.name].initialize(**c.parameters)
        outputs = {name: [v.name for v in run.md.modelVariables if v.causality == "output"
                          and v.type in ("Real", "Float64")] for name, run in runs.items()}
        rows = {f"{n}.{o}": [] for n, outs in outputs.items() for o in outs}
        n = round(stop_time / step)
        for k in range(n + 1):
            values = {}
            for name, run in runs.items():
                for o, v in zip(outputs[name], run.get(outputs[name]), strict=True):
                    values[f"{name}.{o}"] = v
            for key, v in values.items():
                rows[key].append(v)
            if k == n:
                break
            for c in connections:
                dst, var = c.dst.split(".", 1)
                runs[dst].set(**{var: values[c.src]})
            for run in runs.values():
                run.fmu.doStep(k * step, step)
        return {key: np.array(v) for key, v in rows.items()}
    finally:
        for run in runs.values():
            run.close()


def test_the_c_stepping_loop_equals_a_plain_python_master() -> None:
    """The default four-FMU system (native FMUs), 2 ms with noise: every recorded output of
    run_cosimulation equals the reference master's bit for bit (same calls, same order)."""
    from gyro_fmu.fmu.build import prebuilt_fmu
    from gyro_fmu.system.scenario import INSTANCE_FMUS, fmu_system, scenario

    sc = scenario("default", stop_time=0.002, noise=1e-5)
    folder = prebuilt_fmu("GyroPlant").parent
    components, connections = fmu_system(sc, folder)
    assert {c.fmu.name for c in components} == set(INSTANCE_FMUS.values())
    got = run_cosimulation(components, connections, sc.stop_time, sc.step)
    want = _reference_master(components, connections, sc.stop_time, sc.step)
    assert len(want) >= 30
    for key, column in want.items():
        assert np.array_equal(got[key], column), key


def test_a_sink_gets_every_row_of_the_run_in_order(models_dir):
    """sink: the rows handed on chunk by chunk are the rows a whole run keeps, with a
    buffer of one chunk (5,001 points: three chunks, the last one short)."""
    drive = Component("drive", models_dir / "TwoToneDrive.fmu")
    plant = Component("plant", models_dir / "GyroPlant.fmu")
    wiring = [Connection("drive.ux", "plant.ux"), Connection("drive.uy", "plant.uy")]
    whole = run_cosimulation([drive, plant], wiring, 0.025, 5e-6, record=["plant.x", "drive.ux"])
    chunks, firsts = [], []

    def sink(rows: np.ndarray, k: int) -> None:
        chunks.append(rows.copy())
        firsts.append(k)

    last = run_cosimulation([drive, plant], wiring, 0.025, 5e-6, record=["plant.x", "drive.ux"],
                            sink=sink)
    rows = np.concatenate(chunks)
    assert np.array_equal(rows, whole.data) and len(rows) == 5001
    assert firsts == list(np.cumsum([0] + [len(c) for c in chunks[:-1]]))
    assert len(chunks) > 1 and np.array_equal(last.data, whole.data[-1:])
