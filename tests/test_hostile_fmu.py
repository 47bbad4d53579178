"""Hostile hosts and inputs, through real FMUs and fmpy: crafted states, restore of an
un-initialized state, fmi2Terminated after a refusal (fmpy.simulate_fmu itself), outputs
that are not finite, parameter messages, and a short fuzz run of mutated states."""

from __future__ import annotations

import base64
import json
import math
import os
import struct
import subprocess
import sys
import textwrap
from pathlib import Path

import fmpy
import numpy as np
import pytest
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import fmi2Terminated
from fmu_harness import Instance

from gyro_fmu.model.parameters import ParameterError, preset, validate_for_plant

H = 5e-6


def _saved(inst: Instance) -> dict:
    state = inst.slave.getFMUstate()
    blob = json.loads(bytes(inst.slave.serializeFMUstate(state)))
    inst.slave.freeFMUstate(state)
    return blob


def _restore_refused(inst: Instance, blob: dict) -> None:
    """Restore blob; fmi2SetFMUstate must answer fmi2Error (the C loader raises pythonfmu's
    fmi2OK to what the slave reported)."""
    state = inst.slave.deSerializeFMUstate(json.dumps(blob).encode())
    with pytest.raises(FMICallException, match="fmi2SetFMUstate failed with status 3"):
        inst.slave.setFMUstate(state)
    inst.slave.freeFMUstate(state)


def _crafted(kind: str, s: dict) -> dict:
    v = s["variables"]
    if kind == "methods":
        v["get_real"], v["do_step"] = 1.0, 2
    elif kind == "method-instead":
        del v["ux"]
        v["get_real"] = 0.0
    elif kind == "integer-float":
        v["seed"] = 1.5
    elif kind == "parameter-range":
        v["m"] = -1.0
    elif kind == "input-nan":
        v["Omega_z"] = float("nan")
    elif kind == "flags":
        s["flags"] = [None, None, "yes"]
    elif kind == "times":
        s["times"] = [0.0, float("inf")]
    elif kind == "extra-key":
        s["extra"] = 1
    elif kind == "model-length":
        s["model"]["core"] = base64.b64encode(base64.b64decode(s["model"]["core"])[:-8]).decode()
    elif kind == "model-key":
        s["model"] = {"kore": s["model"]["core"]}
    elif kind == "model-type":
        s["model"]["core"] = 5
    elif kind == "model-nan":  # the plant's x, after its 7 parameters and 4 noise levels
        raw = bytearray(base64.b64decode(s["model"]["core"]))
        raw[88:96] = struct.pack("<d", float("nan"))
        s["model"]["core"] = base64.b64encode(bytes(raw)).decode()
    elif kind == "model-other-plant":  # kxx of another plant
        raw = bytearray(base64.b64decode(s["model"]["core"]))
        raw[0:8] = struct.pack("<d", 4e8)
        s["model"]["core"] = base64.b64encode(bytes(raw)).decode()
    return s


CRAFTED = {
    "methods": "unknown ['do_step', 'get_real']",
    "method-instead": "unknown ['get_real'], missing ['ux']",
    "integer-float": "Integer variable seed must be an integer",
    "parameter-range": "m=-1.0 is below its minimum 0: use > 0",
    "input-nan": "input Omega_z=nan is not finite",
    "flags": "flags must be [str|null, str|null, bool]",
    "times": "times must be two finite numbers",
    "extra-key": "unexpected ['extra']",
    "model-length": "plant state of 432 bytes, 440 expected",
    "model-key": "model must have the keys ['core']",
    "model-type": "model.core must be str, got int",
    "model-nan": "the saved plant's x=nan is not finite",
    "model-other-plant": "the saved plant has other parameters or noise than the variables",
}


@pytest.mark.parametrize("kind", list(CRAFTED))
def test_a_crafted_plant_state_is_refused_by_name_and_never_crashes(pythonfmu_all, kind):
    """Only the variables, flags, times and model structure the slave saves are accepted;
    anything else: fmi2SetFMUstate returns fmi2Error with a log naming it, outputs NaN,
    steps discarded, and
    terminate/free work (a state naming get_real/do_step used to give fmi2Fatal)."""
    inst = Instance(pythonfmu_all / "GyroPlant.fmu", "crafted")
    inst.set({"ux": 1e-7, "Omega_z": 1.0})
    assert inst.step(H) == 0
    _restore_refused(inst, _crafted(kind, _saved(inst)))
    errors = inst.messages(min_status=3)
    assert "restoring the FMU state failed" in errors and CRAFTED[kind] in errors, errors
    outputs = [n for n, v in inst.vars.items() if v.causality == "output"]
    assert all(math.isnan(x) for x in inst.get(outputs))
    assert inst.step(H) == 3  # the instance failed: refused by the loader
    assert "refused: the instance failed (" in inst.messages(min_status=3)
    with pytest.raises(FMICallException):  # cannot go on: not a normal end either
        inst.slave.getBooleanStatus(fmi2Terminated)
    inst.close()


def test_a_crafted_observer_state_of_another_shape_is_refused(pythonfmu_all):
    """A covariance of the wrong size never reaches the core (pythonfmu's JSON state)."""
    inst = Instance(pythonfmu_all / "GyroObserver.fmu", "crafted-obs")
    assert inst.step(H) == 0
    s = _saved(inst)
    s["model"]["P"] = [row[:-1] for row in s["model"]["P"][:-1]]
    _restore_refused(inst, s)
    assert "model.P must be a list of length" in inst.messages(min_status=3)
    assert inst.step(H) == 3
    inst.close()


def test_a_never_initialized_state_un_initializes_the_instance(pythonfmu_all):
    """Restoring a state saved before initialization drops the library model: doStep is
    refused by name (fmi2Error), and initialization makes the instance step again."""
    inst = Instance(pythonfmu_all / "GyroPlant.fmu", "uninit", initialize=False)
    early = inst.slave.getFMUstate()
    assert inst.step(H) == 3
    assert "fmi2DoStep is not allowed in instantiated mode" in inst.messages()
    inst.initialize()
    inst.set({"ux": 1e-7, "Omega_z": 1.0})
    for _ in range(5):
        assert inst.step(H) == 0
    inst.slave.setFMUstate(early)
    inst.log.messages.clear()
    assert inst.step(H) == 3  # it used to return fmi2OK and go on from the old state
    assert "fmi2DoStep is not allowed in instantiated mode" in inst.messages()
    assert "no attribute" not in inst.messages()
    inst.initialize()
    inst.t = 0.0
    assert inst.step(H) == 0
    inst.close()


def _input_table(rows: dict) -> np.ndarray:
    t = np.linspace(0.0, 1000 * H, 1001)
    columns = {"ux": 1e-7 * np.sin(2e4 * t), "uy": 0 * t, "Omega_z": 0 * t + 1.0}
    for (name, k), value in rows.items():
        columns[name][k] = value
    return np.array(list(zip(t, *columns.values(), strict=True)),
                    dtype=[("time", float)] + [(n, float) for n in columns])


def test_simulate_fmu_goes_on_after_a_recoverable_bad_input(pythonfmu_all):
    """One NaN input row: the step is discarded once (fmi2Terminated false), fmpy retries it
    with the same NaN, and the FMU does it with the kept value (fmi2Warning). The run
    reaches the stop time (it used to end silently at 502 of 1001 rows)."""
    messages = []
    result = fmpy.simulate_fmu(str(pythonfmu_all / "GyroPlant.fmu"), stop_time=1000 * H,
                               step_size=H, output_interval=H, timeout=60,
                               input=_input_table({("ux", 500): float("nan")}),
                               debug_logging=True,
                               logger=lambda *a: messages.append(a[4].decode()))
    assert math.isclose(result["time"][-1], 1000 * H)
    assert len(np.unique(result["time"])) == 1001
    assert np.isfinite(result["x"]).all()
    text = "\n".join(messages)
    assert "input ux=nan is not finite" in text and "done with the kept value" in text


@pytest.mark.parametrize(("start", "rows", "cause"), [
    ({"m": -1.0}, {}, "m=-1.0 is below its minimum 0: use > 0"),
    ({}, {("Omega_z", 300): 1e300}, "Omega_z=1e+300 held over the step"),
])
def test_simulate_fmu_raises_when_the_fmu_cannot_go_on(pythonfmu_all, start, rows, cause):
    """A refused parameter or a step that overflowed: fmi2Terminated is answered with
    fmi2Error, and any further call refused, with the cause logged, so fmpy raises (m=-1
    used to return 2 rows, no error)."""
    messages = []
    with pytest.raises(FMICallException, match="failed with status 3"):
        fmpy.simulate_fmu(str(pythonfmu_all / "GyroPlant.fmu"), stop_time=1000 * H,
                          step_size=H, output_interval=H, timeout=60, start_values=start,
                          input=_input_table(rows),
                          logger=lambda *a: messages.append(a[4].decode()))
    assert any(("cannot go on" in m or "the instance failed" in m) and cause in m
               for m in messages), messages


def test_the_loader_message_reaches_a_host_that_does_not_format(pythonfmu_all):
    """gyro_fmu's own master (and the harness) log through a plain ctypes callback that
    gets the message only: the loader formats it itself (it used to arrive as
    "%s cannot go on (...): %s")."""
    inst = Instance(pythonfmu_all / "GyroPlant.fmu", "plain")
    inst.set({"ux": 1e-7, "Omega_z": 1e300})
    assert inst.step(H) == 2
    with pytest.raises(FMICallException):
        inst.slave.getBooleanStatus(fmi2Terminated)
    errors = inst.messages(min_status=3)
    assert "plain cannot go on" in errors and "Omega_z=1e+300 held" in errors, errors
    assert "%s" not in errors
    inst.close()


def test_a_recoverable_refusal_is_not_termination(pythonfmu_all):
    inst = Instance(pythonfmu_all / "GyroPlant.fmu", "recoverable")
    inst.set({"ux": float("nan")})
    assert inst.step(H) == 2
    assert inst.slave.getBooleanStatus(fmi2Terminated) is False  # pythonfmu said True
    assert inst.step(H) == 0
    inst.close()


def test_non_finite_outputs_are_the_error_of_the_fmu_that_made_them(pythonfmu_all):
    """Omega_z = 1e300 is finite, so the input is accepted; the step makes NaN outputs:
    refused by the plant, naming the inputs it held (it used to return fmi2OK with NaN
    and the observer downstream was blamed for x_meas=nan)."""
    inst = Instance(pythonfmu_all / "GyroPlant.fmu", "overflow")
    inst.set({"ux": 1e-7, "Omega_z": 1e300})
    assert inst.step(H) == 2
    text = inst.messages(min_status=3)
    assert "GyroPlant: the step from t=0 s over 5e-06 s gave non-finite outputs (x=nan" in text
    assert "ux=1e-07, uy=0.0, Omega_z=1e+300 held over the step" in text
    assert inst.step(H) == 3  # failed: refused until a reset or a restore
    inst.close()


PARAMETER_MESSAGES = [  # (override, library ParameterError text, FMU log text)
    ({"m": -1.0}, "mass m=-1.0 kg must be > 0", "m=-1.0 is below its minimum 0: use > 0"),
    ({"m": 0.0}, "mass m=0.0 kg must be > 0", "m=0.0 is its exclusive minimum 0: use > 0"),
    ({"dxx": 1e300}, "dxx=1e+300 1/s is beyond |dxx| <= 1e+10 1/s",
     "dxx=1e+300 is above its maximum 1e+10: use <= 1e+10"),
    ({"kxx": -1.0}, "x-axis stiffness kxx=-1 1/s2 must be > 0",
     "kxx=-1.0 is below its minimum 0: use > 0"),
    ({"kyy": -1.0}, "y-axis stiffness kyy=-1 1/s2 must be > 0",
     "kyy=-1.0 is below its minimum 0: use > 0"),
]


@pytest.mark.parametrize(("override", "library", "fmu"), PARAMETER_MESSAGES,
                         ids=[str(r[0]) for r in PARAMETER_MESSAGES])
def test_parameter_messages_name_the_real_cause(pythonfmu_all, override, library, fmu):
    with pytest.raises(ParameterError) as err:
        validate_for_plant(preset(**override))
    assert library in str(err.value)
    assert "math range error" not in str(err.value) and "kxy" not in str(err.value)
    inst = Instance(pythonfmu_all / "GyroPlant.fmu", "params", override)
    assert inst.step(H) == 3
    assert fmu in inst.messages(min_status=3)
    inst.close()


def test_fuzzed_states_never_crash_the_host(pythonfmu_all):
    """50 mutated states per FMU (bit flips, truncation, JSON-aware mutations), each
    deserialize -> set -> doStep -> terminate -> free in worker subprocesses."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from fuzz_states import run

    rows = run(["GyroPlant", "GyroObserver"], 50, seed=1, batch=50, models=pythonfmu_all)
    for row in rows:
        assert row["trials"] == 50 and row["crashes"] == row["fatal"] == 0, row
        assert row["refused"] >= 40, row


_ONE_PROCESS = textwrap.dedent("""
    import gc, sys
    from pathlib import Path
    import fmpy
    import numpy as np
    from fmpy.fmi1 import FMICallException
    from fmpy.fmi2 import fmi2Terminated
    from fmu_harness import Instance
    from test_hostile_fmu import H, _input_table
    from gyro_fmu.upstream.fmpy_logger import rearm_default_logger
    from gyro_fmu.fmu.validate import validate_files

    models, refused_copy = Path(sys.argv[1]), sys.argv[2]
    plant = str(models / "GyroPlant.fmu")
    others = ["RateProfile", "TwoToneDrive", "GyroObserver", "GyroResonator", "GyroLoops",
              "GyroPlant"]
    kw = dict(stop_time=200 * H, step_size=H, output_interval=H, timeout=60)
    refusing = dict(kw, stop_time=400 * H, input=_input_table({("Omega_z", 300): 1e300}))
    cause = "Omega_z=1e+300 held over the step"

    def refused(fmu, log=True):
        messages = []
        extra = {"logger": lambda *a: messages.append(a[4].decode())} if log else {}
        try:
            fmpy.simulate_fmu(fmu, **refusing, **extra)
        except FMICallException as e:
            assert "fmi2GetBooleanStatus failed with status 3" in str(e), e
        else:
            raise AssertionError("the refused run did not raise")
        assert not log or any("cannot go on" in m and cause in m for m in messages), messages

    count = 0
    for round_ in range(3):
        for name in others:  # each with its own logger: the one fmpy's proxy keeps
            fmpy.simulate_fmu(str(models / f"{name}.fmu"), **kw,
                              logger=lambda *a: None)
            gc.collect()
        refused(plant)  # its own logger
        gc.collect()
        lines = []  # the CLI's path: reference.py's simulate_fmu on the default callbacks
        assert validate_files([refused_copy], write=lines.append) == 1
        assert "FAIL: the simulation of the default experiment failed" in lines[0], lines
        refused(plant)
        gc.collect()
        rearm_default_logger()  # fmpy's default callbacks: through a live printer
        refused(plant, log=False)
        # The same FMU file extracted twice and loaded at once (two copies of the loader
        # and of pythonfmu's binary with one model identifier): the refusal of one copy
        # is reported to that copy only.
        alive = Instance(models / "GyroPlant.fmu", f"alive{round_}")
        alive.set({"ux": 1e-7, "Omega_z": 1.0})
        assert alive.step(H) == 0
        unzipped = [fmpy.extract(plant) for _ in range(2)]
        for folder in unzipped:
            refused(folder)
        assert alive.step(H) == 0
        assert alive.slave.getBooleanStatus(fmi2Terminated) is False
        alive.set({"Omega_z": 1e300})
        assert alive.step(H) == 2
        try:
            alive.slave.getBooleanStatus(fmi2Terminated)
        except FMICallException:
            pass
        else:
            raise AssertionError("the alive copy's refusal was not reported to it")
        alive.close()
        refused(unzipped[0])  # the first folder again, after the other copy was freed
        count += 7
    print("refused runs", count)
""")


def test_many_fmus_then_refusals_in_one_process_never_crash(pythonfmu_all, tmp_path):
    """In one process: every FMU run by simulate_fmu with a logger, then the refused
    GyroPlant run (own logger; fmpy's default callbacks; validate_files on a copy whose
    reference inputs hold Omega_z=1e300; the same FMU extracted twice beside a live
    instance of a third copy), three rounds. Each refusal is an FMICallException at
    fmi2GetBooleanStatus. It used to segfault there: fmpy's logger proxy keeps one
    process-global target, left pointing at a freed ctypes thunk by an earlier
    simulate_fmu(logger=...), and the default callbacks call it at the FMU's first log
    message (see gyro_fmu/upstream/fmpy_logger.py). A child process, so a crash is an exit
    code."""
    from test_hostile_validate import _copy

    refused_copy = _copy(pythonfmu_all / "GyroPlant.fmu", tmp_path / "refused.fmu",
                         lambda n, d: d.replace(b",1.0\n", b",1e300\n")
                         if n.endswith("_in.csv") else d)
    here = Path(__file__).resolve().parent
    proc = subprocess.run([sys.executable, "-c", _ONE_PROCESS, str(pythonfmu_all),
                           str(refused_copy)], cwd=tmp_path, capture_output=True, text=True,
                          timeout=600, env={**os.environ, "PYTHONPATH": str(here)})
    assert proc.returncode == 0, (proc.returncode, proc.stdout[-3000:], proc.stderr[-3000:])
    assert "refused runs 21" in proc.stdout, proc.stdout[-3000:]
    # a freed thunk that did not crash says so through Python's unraisable hook
    assert "PyObject is NULL" not in proc.stderr and "Exception ignored" not in proc.stderr, \
        proc.stderr[-3000:]


@pytest.mark.parametrize("folder", ["tmp-ü", "a b$+,#%?*[]'", "日本語 100%"])
def test_a_pythonfmu_fmu_instantiates_under_any_folder_name(models_dir, tmp_path, folder):
    """pythonfmu 0.7.0 cut "file://" off the resource URI and decoded nothing: under a
    folder with a character a URI escapes, every FMU segfaulted (0.2.0). The loader hands
    it the decoded path."""
    import zipfile

    from fmpy import read_model_description
    from fmpy.fmi2 import FMU2Slave

    unzipdir = tmp_path / folder / "GyroLoops"
    with zipfile.ZipFile(models_dir / "GyroLoops.fmu") as z:
        z.extractall(unzipdir)
    md = read_model_description(str(unzipdir / "modelDescription.xml"))
    slave = FMU2Slave(guid=md.guid, unzipDirectory=str(unzipdir), modelIdentifier="GyroLoops",
                      instanceName="named")
    slave.instantiate()
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    slave.exitInitializationMode()
    slave.doStep(0.0, 2.5e-5)
    slave.terminate()
    slave.freeInstance()
