"""Canaries: one per upstream defect that gyro_fmu.upstream works around. Each shows the
defect in the pinned version; when one fails, upstream has fixed it (or changed), and
the workaround it names may go (gyro_fmu/upstream/__init__.py lists them)."""

from __future__ import annotations

import ctypes
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from gyro_fmu.fmu.build import prebuilt_fmu


def test_libcosimpy_still_drops_a_sample(tmp_path: Path) -> None:
    """libcosimpy 0.0.6's wrapper returns one sample fewer than asked for from step 0;
    gyro_fmu.upstream.libcosim_samples reads them all."""
    from libcosimpy.CosimEnums import CosimVariableType
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    from gyro_fmu.upstream.libcosim_samples import get_real_samples

    execution = CosimExecution.from_step_size(step_size=10_000)  # 10 us
    index = execution.add_local_slave(CosimLocalSlave(
        fmu_path=str(prebuilt_fmu("RateProfile")), instance_name="rate"))
    vr = next(v.reference for v in execution.slave_variables(index)
              if v.name.decode() == "Omega_z")
    observer = CosimObserver.create_time_series(11)
    execution.add_observer(observer)
    observer.start_time_series(index, vr, CosimVariableType.REAL)
    assert execution.simulate_until(10 * 10_000)
    _, _, wrapped = observer.time_series_real_samples(index, vr, 0, 11)  # times, steps, values
    values, steps, times = (ctypes.c_double * 11)(), (ctypes.c_int64 * 11)(), (
        ctypes.c_int64 * 11)()
    got = get_real_samples()(observer.ptr(), index, vr, 0, 11, values, steps, times)
    assert got == 11 and list(steps) == list(range(11))
    assert len(wrapped) == 10, f"libcosimpy returned {len(wrapped)} of 11: fixed upstream? " \
        "then gyro_fmu.upstream.libcosim_samples may go"
    del observer, execution


def test_fmpy_still_has_one_global_logger_proxy() -> None:
    """fmpy 0.3.32 keeps the logger of the last run that passed one in a single global of
    its C proxy (fmpy/logging): gyro_fmu.upstream.fmpy_logger re-arms it. The canary: the
    proxy library still exports addLoggerProxy and fmpy is the pinned version."""
    import fmpy
    from fmpy.logging import addLoggerProxy  # noqa: F401  (the proxy still exists)

    assert fmpy.__version__ == "0.3.32", (
        f"fmpy {fmpy.__version__}: check whether its logger proxy still keeps one global "
        "pointer (tests/test_hostile_fmu.py shows the crash) and retire "
        "gyro_fmu.upstream.fmpy_logger if not")


def _raw_pythonfmu(pythonfmu_models: Path, name: str, dest: Path) -> Path:
    """The FMU unpacked with pythonfmu's own binary in place of our loader."""
    folder = dest / name
    with zipfile.ZipFile(pythonfmu_models / f"{name}.fmu") as z:
        z.extractall(folder)
    binaries = folder / "binaries" / "linux64"
    (binaries / f"{name}_pythonfmu.so").replace(binaries / f"{name}.so")
    return folder


_HOST = r"""
import ctypes, sys
from fmpy.fmi2 import FMU2Slave
from fmpy import read_model_description
folder, uri = sys.argv[1], sys.argv[2]
md = read_model_description(folder)
slave = FMU2Slave(guid=md.guid, unzipDirectory=folder,
                  modelIdentifier=md.coSimulation.modelIdentifier, instanceName="raw")
slave.instantiate()
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="pythonfmu's linux64 binary")
def test_pythonfmu_still_takes_the_uri_undecoded(pythonfmu_models: Path, tmp_path: Path) -> None:
    """pythonfmu 0.7.0 in a folder whose URI is percent-encoded (a non-ASCII letter; fmpy
    leaves a space as it is): its own binary fails to instantiate (or crashes); through
    our loader (decoded_uri) it instantiates."""
    base = tmp_path / "dossier-\u00e9t\u00e9"
    base.mkdir()
    raw = _raw_pythonfmu(pythonfmu_models, "TwoToneDrive", base)
    proc = subprocess.run([sys.executable, "-c", _HOST, str(raw), ""], capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode != 0, ("pythonfmu instantiated from a non-ASCII folder: "
                                  "fixed upstream? then decoded_uri in "
                                  "gyro_fmu/pythonfmu/python_loader.c may go")
    ours = base / "ours"
    with zipfile.ZipFile(pythonfmu_models / "TwoToneDrive.fmu") as z:
        z.extractall(ours)
    proc = subprocess.run([sys.executable, "-c", _HOST, str(ours), ""], capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]


_DISCARD = r"""
import ctypes, sys
from fmpy.fmi2 import FMU2Slave, fmi2Terminated
from fmpy import read_model_description
folder = sys.argv[1]
md = read_model_description(folder)
vr = {v.name: v.valueReference for v in md.modelVariables}
slave = FMU2Slave(guid=md.guid, unzipDirectory=folder,
                  modelIdentifier=md.coSimulation.modelIdentifier, instanceName="raw")
slave.instantiate()
slave.setupExperiment(startTime=0.0)
slave.enterInitializationMode()
slave.exitInitializationMode()
dll, c = slave.dll, slave.component  # the binary's own functions: every status as it is
dll.fmi2SetReal(c, (ctypes.c_uint * 1)(vr["ux"]), ctypes.c_size_t(1),
                (ctypes.c_double * 1)(float("nan")))
dll.fmi2DoStep.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.c_double, ctypes.c_int]
status = dll.fmi2DoStep(c, 0.0, 5e-6, 1)
terminated = ctypes.c_int(0)
dll.fmi2GetBooleanStatus(c, ctypes.c_int(fmi2Terminated), ctypes.byref(terminated))
print(status, terminated.value)
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="pythonfmu's linux64 binary")
def test_pythonfmu_still_answers_terminated_after_a_discard(pythonfmu_models: Path,
                                                             tmp_path: Path) -> None:
    """After a refused input the step is discarded (2) and pythonfmu 0.7.0 answers
    fmi2Terminated = true (fmpy.simulate_fmu then ends the run silently); our loader
    answers false, since the instance can go on."""
    raw = _raw_pythonfmu(pythonfmu_models, "GyroPlant", tmp_path)
    out = subprocess.run([sys.executable, "-c", _DISCARD, str(raw)], capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == ["2", "1"], (
        f"pythonfmu answered {out.stdout!r}: fixed upstream? then the fmi2Terminated answer "
        "of gyro_fmu/pythonfmu/python_loader.c may go")
    ours = tmp_path / "ours"
    with zipfile.ZipFile(pythonfmu_models / "GyroPlant.fmu") as z:
        z.extractall(ours)
    out = subprocess.run([sys.executable, "-c", _DISCARD, str(ours)], capture_output=True,
                         text=True, timeout=120)
    assert out.stdout.split() == ["2", "0"], out.stdout + out.stderr[-2000:]


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="pythonfmu's linux64 binary")
def test_pythonfmu_still_aborts_a_c_host_at_exit(pythonfmu_models: Path, tmp_path: Path) -> None:
    """pythonfmu 0.7.0 frees its interpreter guard twice at process exit. With scipy
    loaded in the FMU's Python and gyro_fmu.pythonfmu.upstream_exit switched off in the
    FMU's own copy, the C host of `gyro-fmu doctor` crashes after its run (measured 3 of
    3). Our FMUs as shipped exit 0 (their adapters load numpy only; measured: they exit 0
    even with the workaround off, and with scipy loaded they crash with it on too, so the
    workaround alone does not cover a scipy user: CHANGELOG, known issues)."""
    from gyro_fmu.doctor import environment as env
    from gyro_fmu.doctor import host
    from gyro_fmu.doctor import report as doc

    compiler = env.find_compiler()
    if compiler is None:
        pytest.skip("needs a C compiler for the doctor's host")
    exe, log = host.compile_host(tmp_path, compiler)
    assert exe is not None, log
    fmu = pythonfmu_models / "GyroPlant.fmu"
    environment = doc.doctor(compile_host=False, fmu=fmu).environment()
    info = host.unpack_fmu(fmu, tmp_path / "off")
    package = info.resources / "gyro_fmu"
    shipped = package / "pythonfmu" / "upstream_exit.py"
    shipped.write_text(shipped.read_text().replace(
        "def install(binary: Path) -> bool:",
        "def install(binary: Path) -> bool:\n    return False\n\n\n"
        "def _switched_off(binary: Path) -> bool:"))
    init = package / "__init__.py"
    init.write_text(init.read_text() + "\nimport scipy.optimize  # noqa: E402,F401\n")
    runs = [host.run_host(exe, info, environment, "off", steps=3) for _ in range(3)]
    assert all(r.reached_end for r in runs), runs[0].stdout + runs[0].stderr
    assert any(r.crashed_at_exit for r in runs), (
        "no crash at exit without the workaround: fixed upstream? then "
        "gyro_fmu.pythonfmu.upstream_exit may go")
    on = host.run_host(exe, host.unpack_fmu(fmu, tmp_path / "on"), environment, "on", steps=3)
    assert on.returncode == 0 and not on.crashed_at_exit, on.stdout + on.stderr


def test_fmpy_still_rescales_the_time_it_plots() -> None:
    """fmpy 0.3.32's create_plotly_figure multiplies the given array's time column by
    1e3 (ms) in place; examples/read_results.py plots a copy."""
    import numpy as np

    pytest.importorskip("plotly")
    from fmpy.util import create_plotly_figure

    table = np.zeros(3, dtype=[("time", "f8"), ("a", "f8")])
    table["time"] = [0.0, 0.005, 0.01]
    create_plotly_figure(table)
    assert table["time"][-1] == pytest.approx(10.0), "fixed upstream: the copy can go"


def test_fmu_container_still_fails_on_an_init_warning(models_dir: Path, tmp_path: Path) -> None:
    """fmu-manipulation-toolbox 2.0: GyroPlant's warning at fmi2ExitInitializationMode
    (an indefinite damping matrix) fails the container (gyro_fmu.upstream.fmu_container).
    When this fails, the container runs the patent scenario and the refusal can go."""
    import fmpy
    from fmpy.fmi1 import FMICallException

    from gyro_fmu.model.parameters import PRESETS
    from gyro_fmu.system.container import build_container

    container = build_container(models_dir, tmp_path / "GyroSystem.fmu")
    told = []
    patent = vars(PRESETS["patent-table1-corrected"])  # its plant warns: D indefinite
    with pytest.raises(FMICallException, match="fmi2ExitInitializationMode failed"):
        fmpy.simulate_fmu(str(container), stop_time=1e-4, output_interval=5e-6,
                          start_values=dict(patent), logger=lambda *a: told.append(a[-1]))
    assert any(b"indefinite" in m for m in told)


def _interrupted_png_save(monkeypatch: pytest.MonkeyPatch, save) -> list[str]:
    """save() with Pillow's PNG encoder interrupted (a Ctrl-C inside it): the warnings it
    left once collected."""
    import gc
    import warnings

    from PIL import PngImagePlugin

    def interrupted(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt("inside Pillow's PNG writer")

    monkeypatch.setattr(PngImagePlugin, "_save", interrupted)
    monkeypatch.setitem(PngImagePlugin.Image.SAVE, "PNG", interrupted)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with pytest.raises(KeyboardInterrupt):
            save()
        gc.collect()
    return [f"{w.category.__name__}: {w.message}" for w in caught]


def test_pillow_still_leaks_its_file_on_an_interrupt(tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    """Pillow 13.0's Image.save closes the file it opened only on an Exception: a Ctrl-C
    inside the encoder leaves it open (gyro_fmu.outputs.save_figure opens the file
    itself). The stop-53 CI flake of the CLI fuzzer (a trial cut by its alarm there)."""
    from PIL import Image

    image = Image.new("RGB", (4, 4))
    said = _interrupted_png_save(monkeypatch, lambda: image.save(tmp_path / "a.png"))
    assert any(w.startswith("ResourceWarning") for w in said), said


def test_an_interrupted_figure_leaves_no_open_file(tmp_path: Path,
                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    pytest.importorskip("matplotlib")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from gyro_fmu.outputs import save_figure

    fig, _ = plt.subplots()
    try:
        said = _interrupted_png_save(monkeypatch,
                                     lambda: save_figure(fig, tmp_path / "f.png"))
    finally:
        plt.close(fig)
    assert said == [], said
    assert list(tmp_path.iterdir()) == []  # nothing half-written either
