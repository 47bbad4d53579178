"""The SSP package: its content, and libcosim running it like our fmpy master."""

from __future__ import annotations

import textwrap
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.ssp.ssd import read_ssd

from gyro_fmu.cosim.master import Component, Connection, run_cosimulation
from gyro_fmu.model.rate import RateKind, RateProfile
from gyro_fmu.system.run import run_fmus
from gyro_fmu.system.scenario import CONNECTIONS, fmu_system, scenario
from gyro_fmu.system.ssp import (
    PARAMETER_SET,
    SSD,
    SSV,
    SSPError,
    relative_differences,
    run_ssp_libcosim,
    system_structure,
    write_ssp,
)

#: A scenario whose every FMU has non-default parameters: if a ParameterBinding
#: were ignored, the FMU would run on its defaults and the comparison would fail.
SCENARIO = scenario(
    stop_time=0.002,
    overrides={"kxy": 5e7, "dxy": 3.0},
    rate=RateProfile(RateKind.sine, offset=0.5, amplitude=2.0, frequency=300.0),
    initial={"kxx": 3.6e8},
)


def test_the_package_holds_the_fmus_wiring_and_every_parameter(models_dir, tmp_path):
    path = write_ssp(SCENARIO, models_dir, tmp_path / "GyroSystem.ssp")
    ssd = read_ssd(str(path), validate=True)  # against the SSP 1.0 schemas fmpy ships
    with zipfile.ZipFile(path) as z:
        assert sorted(z.namelist()) == sorted(
            ["SystemStructure.ssd", "resources/TwoToneDrive.fmu", "resources/RateProfile.fmu",
             "resources/GyroPlant.fmu", "resources/GyroObserver.fmu"])
    connections = {(c.startElement, c.startConnector, c.endElement, c.endConnector)
                   for c in ssd.system.connections}
    assert connections == {(*c.src.split("."), *c.dst.split(".")) for c in CONNECTIONS}

    components, _ = fmu_system(SCENARIO, models_dir)
    bound = {}
    for element in ssd.system.elements:
        values = element.parameterBindings[0].parameterValues[0].parameters
        bound[element.name] = {p.name: (p.type, p.value) for p in values}
    for comp in components:
        for name, value in comp.parameters.items():
            kind, text = bound[comp.name][name]
            if kind == "Integer":
                assert int(text) == value
            else:
                assert kind == "Real" and float(text) == value  # repr: exact round trip


def test_all_bindings_form_one_parameter_set_with_units(models_dir, tmp_path):
    """One set name for the whole system (Ecos applies only the set it is told to),
    every Real value with its FMU variable's unit, defined in the set's ssv:Units."""
    path = write_ssp(SCENARIO, models_dir, tmp_path / "GyroSystem.ssp")
    with zipfile.ZipFile(path) as z:
        root = ET.fromstring(z.read("SystemStructure.ssd"))
    sets = list(root.iter(f"{{{SSV}}}ParameterSet"))
    assert len(sets) == 4 and {s.get("name") for s in sets} == {PARAMETER_SET}
    components = {c.name: c for c in fmu_system(SCENARIO, models_dir)[0]}
    for element in root.iter(f"{{{SSD}}}Component"):
        md = {v.name: v for v in read_model_description(
            str(components[element.get("name")].fmu)).modelVariables}
        pset = element.find(f".//{{{SSV}}}ParameterSet")
        defined = {u.get("name") for u in pset.iterfind(
            "{http://ssp-standard.org/SSP1/SystemStructureParameterValues}Units/"
            "{http://ssp-standard.org/SSP1/SystemStructureCommon}Unit")}
        for p in pset.iter(f"{{{SSV}}}Parameter"):
            value = p[0]
            if value.tag == f"{{{SSV}}}Real":
                assert value.get("unit") == md[p.get("name")].unit, p.get("name")
                assert value.get("unit") in defined
            else:
                assert value.get("unit") is None  # ssv:Integer has no unit in SSP 1.0


def test_libcosim_runs_the_package_like_the_fmpy_master(models_dir, tmp_path):
    path = write_ssp(SCENARIO, models_dir, tmp_path / "GyroSystem.ssp")
    ours = run_fmus(SCENARIO, models_dir)
    theirs = run_ssp_libcosim(path)  # stop time and 5 us step from the package
    assert len(theirs["time"]) == len(ours["time"]) == 401
    assert np.max(np.abs(theirs["time"] - ours["time"])) < 1e-18  # at most one ulp apart
    assert set(theirs) == set(ours.columns)
    rel = relative_differences(theirs, ours)
    # Plant, drive and rate agree to rounding; the observer amplifies libcosim's
    # clock (integer ns: t one ulp off, h jittering by 1e-12): on noise-free data its
    # innovations are differences of nearly equal numbers, and the adaptive rate model's
    # likelihoods and the noise estimated from them carry that on: measured 3e-7 on
    # Omega_hat and 1.2e-5 on the rate-model probabilities in 2 ms (2e-10 with a fixed
    # rate model and a fixed noise floor).
    rates = {k: v for k, v in rel.items() if k.startswith("observer.p_rate_")}
    assert len(rates) == 4 and max(rates.values()) < 1e-4, rates
    rest = {k: v for k, v in rel.items() if k not in rates}
    assert max(rest.values()) < 3e-6, sorted(rest.items(), key=lambda kv: -kv[1])[:3]
    for name in ("plant.x", "plant.y", "plant.vy", "drive.ux", "rate.Omega_z"):
        assert rel[name] < 1e-12, (name, rel[name])
    # The bindings mattered: on the FMUs' own defaults the plant moves differently.
    defaults = run_fmus(scenario(stop_time=0.002), models_dir)
    assert relative_differences({"plant.y": theirs["plant.y"]}, defaults)["plant.y"] > 1e-3


@pytest.fixture(scope="module")
def echo_fmu(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """y(t + h) = the u the master set for the step from t: shows when inputs are read."""
    FmuBuilder = pytest.importorskip("pythonfmu.builder", reason="the echo FMU is written "
                                     "with pythonfmu (the pythonfmu extra)").FmuBuilder
    folder = tmp_path_factory.mktemp("echo")
    src = folder / "Echo.py"
    src.write_text(textwrap.dedent('''
        from pythonfmu import Fmi2Causality, Fmi2Slave, Real

        class Echo(Fmi2Slave):
            def __init__(self, **kwargs):
                super().__init__(**kwargs)
                self.u = 0.0
                self.y = -1.0
                self.register_variable(Real("u", causality=Fmi2Causality.input))
                self.register_variable(Real("y", causality=Fmi2Causality.output))

            def do_step(self, t, h):
                self.y = self.u
                return True
    '''))
    return Path(FmuBuilder.build_FMU(src, dest=folder))


def test_libcosim_steps_like_the_jacobi_master(models_dir, echo_fmu, tmp_path):
    """Inputs of the step from t are the outputs at t, also for the first step.

    The rate runs at a constant 3 rad/s while its declared start value is 1: a host
    that only transferred values during initialization mode would feed 1 first.
    """
    components = [
        Component("drive", models_dir / "TwoToneDrive.fmu", {"A1": 1.0, "A2": 0.5}),
        Component("rate", models_dir / "RateProfile.fmu", {"kind": 1, "offset": 3.0}),
        Component("echo_u", echo_fmu),
        Component("echo_w", echo_fmu),
    ]
    connections = [Connection("drive.ux", "echo_u.u"), Connection("rate.Omega_z", "echo_w.u")]
    root, resources = system_structure(components, connections, 1e-4, 5e-6)
    path = tmp_path / "Echo.ssp"
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("SystemStructure.ssd", ET.tostring(root, encoding="UTF-8"))
        for arcname, fmu in resources.items():
            z.write(fmu, arcname)
    theirs = run_ssp_libcosim(path)
    ours = run_cosimulation(components, connections, 1e-4, 5e-6)
    for result in (theirs, ours):
        assert np.array_equal(result["echo_u.y"][1:], result["drive.ux"][:-1])  # Jacobi
        assert not np.allclose(result["echo_u.y"][1:], result["drive.ux"][1:])  # not G-S
        assert list(result["echo_w.y"][:3]) == [-1.0, 3.0, 3.0]
    assert np.max(np.abs(theirs["drive.ux"] - ours["drive.ux"])) < 1e-15


def test_errors_name_the_problem(models_dir, tmp_path):
    with pytest.raises(SSPError, match="not found"):
        run_ssp_libcosim(tmp_path / "missing.ssp")
    path = write_ssp(SCENARIO, models_dir, tmp_path / "G.ssp")
    with pytest.raises(SSPError, match="whole number of nanoseconds"):
        run_ssp_libcosim(path, step=1e-10 / 3)
    with pytest.raises(SSPError, match="no Real output"):
        run_ssp_libcosim(path, stop_time=1e-5, record=["plant.z"])
