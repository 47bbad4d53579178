"""What a tool integrator relies on: valid descriptions, exact state, safe failure, instances."""

from __future__ import annotations

import math
import zipfile
from xml.etree import ElementTree

import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.validation import validate_fmu
from fmu_harness import Instance, assert_bad_input_refused, assert_state_round_trip

from gyro_fmu.fmu.build import FMU_NAMES
from gyro_fmu.model.parameters import preset
from gyro_fmu.model.plant import GyroPlantModel

H = 5e-6
#: Default communication steps other than H: the self-calibration FMUs run at carrier rate
#: (10 samples per cycle of 4 kHz).
DEFAULT_STEPS = {"GyroResonator": 25e-6, "GyroLoops": 25e-6, "GyroSensor": 1e-3,
                 "StabilizedPlatform": 1e-3}


@pytest.mark.parametrize("name", FMU_NAMES)
def test_model_description_is_complete_and_valid(models_dir, name):
    path = models_dir / f"{name}.fmu"
    assert validate_fmu(str(path)) == []
    md = read_model_description(str(path))
    cs = md.coSimulation
    assert cs.canGetAndSetFMUstate and cs.canSerializeFMUstate
    assert cs.canHandleVariableCommunicationStepSize and not cs.needsExecutionTool
    units = {u.name for u in md.unitDefinitions}
    for v in md.modelVariables:
        assert v.description, v.name
        if v.type == "Real":
            assert v.unit in units, v.name
    outputs = [v for v in md.modelVariables if v.causality == "output"]
    assert len(md.outputs) == len(outputs) == len(md.initialUnknowns)
    assert float(md.defaultExperiment.stepSize) == DEFAULT_STEPS.get(name, H)
    xml = zipfile.ZipFile(path).read("modelDescription.xml").decode()
    assert '<BaseUnit' in xml and 'dependencies=""' in xml


@pytest.mark.parametrize("name", FMU_NAMES)
def test_each_fmu_documents_its_interface(models_dir, name):
    """documentation/index.html (what Dymola or OMEdit shows) lists every variable of the
    model description with its causality and unit, and parses as XHTML."""
    fmu = models_dir / f"{name}.fmu"
    with zipfile.ZipFile(fmu) as z:
        page = ElementTree.fromstring(z.read("documentation/index.html"))
    ns = {"h": "http://www.w3.org/1999/xhtml"}
    rows = {r[0].text: [c.text or "" for c in r]
            for r in page.iterfind(".//h:table/h:tr", ns) if r[0].tag.endswith("td")}
    md = read_model_description(str(fmu))
    assert set(rows) == {v.name for v in md.modelVariables}
    for v in md.modelVariables:
        assert rows[v.name][1] == v.causality and rows[v.name][3] == (v.unit or ""), v.name
    assert md.description in "".join(page.itertext())


def test_physical_bounds_and_nominals_are_declared(models_dir):
    md = read_model_description(str(models_dir / "GyroPlant.fmu"))
    v = {x.name: x for x in md.modelVariables}
    assert float(v["m"].min) == 0.0 and float(v["noise_x"].min) == 0.0
    assert float(v["kxx"].nominal) == 1e8 and float(v["x"].nominal) == 1e-9
    assert v["kxy"].min is None  # a cross stiffness may be negative


def _drive(t):
    return {"ux": 1e-7 * (math.sin(2 * math.pi * 2500 * t) + math.sin(2 * math.pi * 1200 * t)),
            "Omega_z": 1.0}


CASES = {
    "GyroPlant": ({"noise_x": 1e-12, "noise_vy": 1e-8, "seed": 5}, ["x", "vx", "y", "vy", "ax"],
                  _drive),
    # measurements no gyro makes: told as 1e-9 m noise, so that the divergence monitor
    # (docs/observer-soundness.md) does not refuse the filter as lost within the run
    "GyroObserver": ({"sigma_z1": 1e-9, "sigma_z2": 1e-9},
                     ["x_hat", "Omega_hat", "dxy_hat", "sigma_Omega_z", "m_hat"],
                     lambda t: {"ux": _drive(t)["ux"], "x_meas": 1e-9 * math.sin(9e3 * t),
                                "y_meas": 2e-10 * math.cos(7e3 * t)}),
    "TwoToneDrive": ({}, ["ux"], None),
    "RateProfile": ({"kind": 4, "offset": 0.0, "amplitude": 1.0, "frequency": 100.0},
                    ["Omega_z"], None),
}


@pytest.mark.parametrize("name", list(CASES))
def test_state_restore_and_serialization_are_exact(models_dir, name):
    """Run to t1, save; run to t2; restore, run to t2 again: identical outputs bit for bit.
    The same after serialize -> deserialize into a fresh instance."""
    params, outputs, inputs = CASES[name]
    assert_state_round_trip(models_dir / f"{name}.fmu", params, outputs, inputs, H, 40, 60)


# The bad-input table of the README: (FMU, parameters before init, action, what it answers)
BAD_INPUTS = [
    ("GyroPlant", {}, ("input", "ux", float("nan")), "input ux=nan is not finite"),
    ("GyroPlant", {}, ("input", "Omega_z", float("inf")), "input Omega_z=inf is not finite"),
    ("GyroObserver", {}, ("input", "x_meas", float("-inf")), "input x_meas=-inf is not finite"),
    ("GyroPlant", {}, ("step", -H, None), "must be > 0"),
    ("GyroPlant", {}, ("step", 0.0, None), "must be > 0"),
    ("GyroPlant", {}, ("after_init", "kxx", 1e8), "kxx is a fixed parameter"),
    ("GyroPlant", {"m": -1.0}, ("init", None, None), "m=-1.0 is below its minimum 0"),
    ("GyroPlant", {"noise_x": float("nan")}, ("init", None, None),
     "parameter noise_x=nan is not finite"),
    ("GyroPlant", {"kxy": 1e9}, ("init", None, None), "not positive definite"),
    ("GyroObserver", {"measured_pair": 3}, ("init", None, None),
     "measured_pair=3 is above its maximum 2"),
    ("GyroObserver", {"kxx_0": float("inf")}, ("init", None, None), "kxx_0=inf is not finite"),
    ("TwoToneDrive", {"f1": -5.0}, ("init", None, None), "f1=-5.0 is below its minimum 0"),
    ("RateProfile", {"kind": 9}, ("init", None, None), "kind=9 is above its maximum 4"),
]


@pytest.mark.parametrize(("name", "params", "action", "message"), BAD_INPUTS,
                         ids=[f"{r[0]}-{r[2][0]}-{r[2][1]}-{r[3][:20]}" for r in BAD_INPUTS])
def test_bad_input_is_refused_with_a_message_and_never_crashes(pythonfmu_all, name, params, action,
                                                              message):
    assert_bad_input_refused(pythonfmu_all / f"{name}.fmu", params, action, message, H)


@pytest.mark.parametrize(("name", "params"), [(r[0], r[1]) for r in BAD_INPUTS
                                              if r[2][0] == "init"],
                         ids=[f"{r[0]}-{r[3][:20]}" for r in BAD_INPUTS if r[2][0] == "init"])
def test_a_host_that_ignores_discard_reads_no_plausible_number(pythonfmu_all, name, params):
    """After a refused initialization or parameter every Real output is NaN, at once and
    after any number of (refused) steps: never the zeros of before initialization."""
    inst = Instance(pythonfmu_all / f"{name}.fmu", "failed", params)
    outputs = [v for v, x in inst.vars.items() if x.causality == "output" and x.type == "Real"]
    assert all(math.isnan(v) for v in inst.get(outputs)), inst.get(outputs)
    for _ in range(3):
        assert inst.step(H) == 3  # the loader: "refused: the instance failed (why)"
        inst.t += H  # a careless host goes on in time
    assert all(math.isnan(v) for v in inst.get(outputs))
    inst.close()


def test_many_instances_in_one_process_are_independent(models_dir):
    """Two plants and two observers with different parameters, interleaved step by step."""
    p1, p2 = preset(), preset(kxy=3e7, dxy=5.0)
    plants = [Instance(models_dir / "GyroPlant.fmu", f"plant{i}", p.as_dict())
              for i, p in enumerate((p1, p2))]
    observers = [Instance(models_dir / "GyroObserver.fmu", f"obs{i}",
                          {f"{k}_0": v for k, v in p.as_dict().items()})
                 for i, p in enumerate((p1, p2))]
    refs = [GyroPlantModel(p) for p in (p1, p2)]
    for _ in range(200):
        inputs = _drive(plants[0].t)
        for plant, obs, ref in zip(plants, observers, refs, strict=True):
            x, y = plant.get(["x", "y"])
            obs.set({"ux": inputs["ux"], "x_meas": x, "y_meas": y})
            plant.set(inputs)
            assert plant.step(H) == 0 and obs.step(H) == 0
            ref.step(inputs["ux"], 0.0, inputs["Omega_z"], H)
    for plant, ref in zip(plants, refs, strict=True):
        assert np.array_equal(np.array(plant.get(["x", "vx", "y", "vy"])), ref.s)
    y1, y2 = (p.get(["y"])[0] for p in plants)
    assert abs(y1 - y2) > 0.1 * abs(y1)  # really different parameters
    kxy = [o.get(["kxy_hat"])[0] for o in observers]
    assert abs(kxy[0] - p1.kxy) < 0.01 * p1.kxy and abs(kxy[1] - p2.kxy) < 0.01 * p2.kxy
    for inst in plants + observers:
        inst.close()


def test_a_different_gyro_fmu_in_the_host_is_reported(pythonfmu_all, monkeypatch):
    """The host's gyro_fmu runs inside our FMUs (one module cache per process): when its
    version differs from the one the FMU ships, the FMU says so in its log."""
    import gyro_fmu

    shipped = gyro_fmu.__version__
    same = Instance(pythonfmu_all / "TwoToneDrive.fmu", "same")
    assert "ships gyro_fmu" not in same.messages()
    same.close()
    monkeypatch.setattr(gyro_fmu, "__version__", "0.0.0-host")
    other = Instance(pythonfmu_all / "TwoToneDrive.fmu", "other")
    text = other.messages()
    assert f"ships gyro_fmu {shipped}, but the host process had already imported gyro_fmu " \
           "0.0.0-host" in text
    assert "rebuild the FMUs" in text
    assert other.step(H) == 0  # a warning, not a failure
    other.close()


_ONE_AFTER_ANOTHER = """
import sys
import fmpy
for name, var in (("RateProfile", "Omega_z"), ("GyroPlant", "x"), ("GyroObserver", "Omega_hat"),
                  ("TwoToneDrive", "ux")):
    r = fmpy.simulate_fmu(sys.argv[1] + "/" + name + ".fmu", stop_time=1e-4,
                          output_interval=5e-6)
    print(name, r[var][-1])
"""


@pytest.mark.parametrize("flavour", ["native", "pythonfmu"])
def test_a_python_host_simulates_our_fmus_one_after_another(models_dir, pythonfmu_models,
                                                            tmp_path, flavour):
    """fmpy.simulate_fmu of RateProfile, then GyroPlant, GyroObserver, TwoToneDrive in one
    fresh process: each pythonfmu FMU ships gyro_fmu, the first one's folder is deleted
    after its run, and the second failed with "Failed to instantiate model" until
    gyro_fmu/pythonfmu/shipped_copies.py found the submodules in the living copy (the hook a
    copy inside an FMU installs; an installed gyro_fmu installs none)."""
    import os
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    folder = models_dir if flavour == "native" else pythonfmu_models
    proc = subprocess.run([sys.executable, "-c", _ONE_AFTER_ANOTHER, str(folder)],
                          cwd=tmp_path, capture_output=True, text=True, timeout=300, env=env)
    assert proc.returncode == 0, proc.stderr[-2000:]
    lines = proc.stdout.split("\n")
    assert [ln.split()[0] for ln in lines if ln] == ["RateProfile", "GyroPlant",
                                                    "GyroObserver", "TwoToneDrive"]
