"""GyroResonator.fmu and GyroLoops.fmu, native and pythonfmu: the same C core as the
self-calibration library.

The co-simulation of the two FMUs through the project's master equals the in-process
CarrierSimulation bit for bit, in both flavours; their state is exact; bad values are
refused (the native FMUs' call-by-call semantics: test_native_fmi_layer.py).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from fmpy import read_model_description
from fmu_harness import Instance, assert_bad_input_refused, assert_state_round_trip

from gyro_fmu.model.loops import OUTPUTS, LoopSettings, LoopsModel
from gyro_fmu.model.resonator import ResonatorModel, ResonatorParameters
from gyro_fmu.model.selfcal_interfaces import LOOPS_RENAMED
from gyro_fmu.model.units import UNITS
from gyro_fmu.selfcal.inprocess import COLUMNS, CarrierSimulation
from gyro_fmu.selfcal.run import run_fmus

H = 25e-6


def _assert_bit_identical(fmu, ref):
    assert fmu.data.shape == ref.data.shape
    for j, name in enumerate(COLUMNS):
        assert np.array_equal(fmu.data[:, j], ref.data[:, j]), name


@pytest.mark.parametrize(("resonator", "settings", "Omega_z", "seed"), [
    (ResonatorParameters(noise=1e-3), LoopSettings(mode=1), 0.3, 7),
    (ResonatorParameters(ring_amplitude=1.0), LoopSettings(mode=0), 0.0, 0),
    (ResonatorParameters(noise=1e-3), LoopSettings(mode=2, sideband_index=0.05,
                                                   amplitude=0.8), 0.0, 3),
], ids=["mode1-noise-rate", "mode0-ring", "mode2-sidebands"])
@pytest.mark.parametrize("flavour", ["native", "pythonfmu"])
def test_fmu_cosimulation_equals_carrier_simulation_bit_for_bit(request, flavour, resonator,
                                                                settings, Omega_z, seed):
    models = request.getfixturevalue("models_dir" if flavour == "native" else "pythonfmu_all")
    duration, record_from = 0.05, 0.01
    ref = CarrierSimulation(resonator, settings, seed=seed, step=H, Omega_z=Omega_z).run(
        duration, record_from=record_from)
    fmu = run_fmus(resonator, settings, duration, step=H, Omega_z=Omega_z, seed=seed,
                   record_from=record_from, models_dir=models)
    assert fmu.step == H
    assert fmu.time[0] == pytest.approx(record_from) and fmu.time[-1] == pytest.approx(duration)
    _assert_bit_identical(fmu, ref)
    if settings.mode:
        assert fmu["amplitude"][-1] > 0.1  # the oscillator really runs
    else:
        assert np.ptp(fmu["Vpy"]) > 0.0  # tones and ring excitation reach the pick-offs


def test_parameters_mirror_the_dataclasses(models_dir):
    for fmu, cls, extra, renamed in (("GyroResonator", ResonatorParameters, {"seed"}, {}),
                                     ("GyroLoops", LoopSettings, set(), LOOPS_RENAMED)):
        md = read_model_description(str(models_dir / f"{fmu}.fmu"))
        params = {v.name: v for v in md.modelVariables if v.causality == "parameter"}
        fields = {renamed.get(f.name, f.name): f for f in dataclasses.fields(cls)}
        assert set(params) == set(fields) | extra
        for name, f in fields.items():
            v = params[name]
            assert float(v.start) == float(f.default), name
            assert (v.type == "Integer") == (f.type in (int, "int")), name
            if v.type == "Real":
                assert v.unit in UNITS, name
                assert v.unit == f.metadata["unit"], name  # the struct's declaration
            assert v.description == f.metadata["description"], name
    md = read_model_description(str(models_dir / "GyroLoops.fmu"))
    assert [v.name for v in md.modelVariables if v.causality == "output"] == list(OUTPUTS)
    units = {v.name: v.unit for v in md.modelVariables}
    assert (units["theta"], units["omega"], units["Vx"]) == ("rad", "rad/s", "V")
    md = read_model_description(str(models_dir / "GyroResonator.fmu"))
    units = {v.name: v.unit for v in md.modelVariables}
    assert (units["Bx"], units["Px"], units["c_ring"], units["kxy"]) == (
        "m/s2/V", "V/m", "m/V", "1/s2")


def test_initial_outputs_are_the_models(models_dir):
    p = ResonatorParameters(noise=1e-3, ring_amplitude=0.5, phi_x=0.0, phi_y=0.0)
    res = Instance(models_dir / "GyroResonator.fmu", "r", {**p.as_dict(), "seed": 4})
    assert res.get(["Vpx", "Vpy"]) == ResonatorModel(p, seed=4).out.tolist()
    res.close()
    s = LoopSettings(f_nominal=3999.0)
    loops = Instance(models_dir / "GyroLoops.fmu", "l", {"f_nominal": s.f_nominal})
    assert loops.get(list(OUTPUTS)) == LoopsModel(s).out.tolist()
    loops.close()


def test_the_temperature_sensor_follows_the_history(models_dir):
    """A ramp plus an exponential warm-up, sensed with noise: GyroResonator.fmu's
    T_sensor equals the library's sample for sample (the same core), its mean follows
    temperature + rate t + span (1 - exp(-t / tau)) and its scatter is the sensor's."""
    p = ResonatorParameters(temperature_rate=20.0, warmup_span=3.0, warmup_tau=0.01,
                            temperature_noise=0.05, tc_f=-30e-6, thermal_update_steps=40)
    h, n = 25e-6, 2000
    res = Instance(models_dir / "GyroResonator.fmu", "r", {**p.as_dict(), "seed": 7})
    model = ResonatorModel(p, seed=7)
    fmu, lib = [res.get(["T_sensor"])[0]], [model.T_sensor]
    for _ in range(n):
        res.set({"Vx": 0.1, "Vy": 0.0, "Omega_z": 0.0})
        assert res.step(h) == 0
        model.step(np.array([0.1, 0.0]), 0.0, h)
        fmu.append(res.get(["T_sensor"])[0])
        lib.append(model.T_sensor)
    res.close()
    assert fmu == lib
    t = np.arange(n + 1) * h
    truth = 300.0 + 20.0 * t + 3.0 * -np.expm1(-t / 0.01)
    assert np.array(fmu)[-1] == pytest.approx(300.0 + 1.0 + 3.0 * (1 - math.exp(-5)), abs=0.3)
    assert np.std(np.array(fmu) - truth) == pytest.approx(0.05, rel=0.1)
    assert p.temperature_offset(0.05) == pytest.approx(truth[-1] - 300.0, rel=1e-12)
    # the history composes: later(a).later(b) is later(a + b)
    assert p.later(0.02).later(0.03).temperature == pytest.approx(p.later(0.05).temperature,
                                                                  abs=1e-12)


CASES = {
    "GyroResonator": ({"noise": 1e-3, "ring_amplitude": 1.0, "seed": 5}, ["Vpx", "Vpy"],
                      lambda t: {"Vx": math.sin(2 * math.pi * 4000 * t),
                                 "Vy": 0.3 * math.cos(2 * math.pi * 3000 * t),
                                 "Omega_z": 0.2}),
    "GyroLoops": ({"sideband_index": 0.05, "ff_xx": 1e-3}, list(OUTPUTS),
                  lambda t: {"Vpx": 0.5 * math.sin(2 * math.pi * 4000.5 * t),
                             "Vpy": 0.01 * math.cos(2 * math.pi * 4000.5 * t)}),
}


@pytest.mark.parametrize("name", list(CASES))
def test_state_restore_and_serialization_are_exact(models_dir, name):
    """Run, save; run on; restore and run again: the same bits. The same through
    serialize -> deserialize into a fresh instance (noise generator and block included:
    6000 steps cross a 4096-sample noise block)."""
    params, outputs, inputs = CASES[name]
    assert_state_round_trip(models_dir / f"{name}.fmu", params, outputs, inputs, H, 4000, 300)


BAD_INPUTS = [
    ("GyroResonator", {}, ("input", "Vx", float("nan")), "input Vx=nan is not finite"),
    ("GyroResonator", {}, ("input", "Omega_z", float("inf")), "input Omega_z=inf is not finite"),
    ("GyroResonator", {}, ("step", 0.0, None), "must be > 0"),
    ("GyroResonator", {}, ("after_init", "f_x", 4100.0), "f_x is a fixed parameter"),
    ("GyroResonator", {"noise": -1.0}, ("init", None, None), "noise=-1.0 is below its minimum 0"),
    ("GyroResonator", {"Q_x": 0.0}, ("init", None, None), "Q_x=0.0 must be > 0"),
    ("GyroResonator", {"kxy": 1e9}, ("init", None, None), "makes the stiffness indefinite"),
    ("GyroLoops", {}, ("input", "Vpy", float("-inf")), "input Vpy=-inf is not finite"),
    ("GyroLoops", {"mode": 3}, ("init", None, None), "mode=3 is above its maximum 2"),
    ("GyroLoops", {"amplitude_setpoint": 0.0}, ("init", None, None),
     "amplitude=0.0 must be > 0"),
]


@pytest.mark.parametrize(("name", "params", "action", "message"), BAD_INPUTS,
                         ids=[f"{r[0]}-{r[2][0]}-{r[2][1]}" for r in BAD_INPUTS])
def test_bad_input_is_refused_with_a_message_and_never_crashes(pythonfmu_all, name, params,
                                                              action, message):
    """The pythonfmu flavour's refusals; the native FMUs': the next test and
    test_native_fmi_layer.py."""
    assert_bad_input_refused(pythonfmu_all / f"{name}.fmu", params, action, message, H)


@pytest.mark.parametrize(("name", "params", "message"), [
    ("GyroResonator", {"Q_x": 0.0}, "Q_x=0.0 must be > 0"),
    ("GyroResonator", {"kxy": 1e9}, "kxy=1000000000.0 1/s^2 makes the stiffness indefinite"),
    ("GyroResonator", {"phi_y": 1.4, "beta_x": 0.2, "m_modal": 1e-9, "dxy": 10.0},
     "dxy=10.0 1/s makes the damping indefinite"),
    ("GyroLoops", {"amplitude_setpoint": 0.0, "drive_limit": 0.0},
     "amplitude=0.0 must be > 0; drive_limit=0.0 must be > 0"),
], ids=["Q", "kxy", "dxy", "loops-gains"])
@pytest.mark.parametrize("version", [2, 3])
def test_the_native_fmus_refuse_the_librarys_values_in_its_words(name, params, message,
                                                                 version):
    """The native FMUs check with the core, which the library calls too: the same values
    refused at initialization, in the library's words; every output NaN after."""
    from fmpy.fmi1 import FMICallException
    from native_host import NativeRun

    from gyro_fmu.fmu.build import prebuilt_fmu

    run = NativeRun(prebuilt_fmu(name, version))
    run.set(**params)
    with pytest.raises(FMICallException):
        run.initialize()
    assert message in [m for s, m in run.messages if s == 3][-1]
    outputs = ["Vpx", "Vpy"] if name == "GyroResonator" else list(OUTPUTS)
    assert all(math.isnan(v) for v in run.get(outputs))
    run.close()
    library = (ResonatorParameters, LoopSettings)[name == "GyroLoops"]
    field_of = {fmu: f for f, fmu in LOOPS_RENAMED.items()}
    fields = {field_of.get(k, k): v for k, v in params.items()}
    if library is ResonatorParameters:
        from gyro_fmu.model.resonator import check_resonator

        problems = check_resonator(ResonatorParameters(**fields))
    else:
        problems = LoopSettings(**fields).problems()
    assert message in "; ".join(problems)


def test_selfcal_through_the_fmus_equals_the_in_process_calibration(models_dir):
    """The whole sequence on the FMU engine gives the same calibration, bit for bit."""
    from gyro_fmu.selfcal.alarms import CalibrationRefusedError
    from gyro_fmu.selfcal.sequence import SelfCalConfig, self_calibrate

    cfg = SelfCalConfig(settle=1.0, record=2.5, sideband_spacing=0.4, sideband_count=2,
                        ff_duration=0.2, models_dir=str(models_dir))
    res = ResonatorParameters(noise=2.5e-4)

    def calibrate(cfg: SelfCalConfig):
        try:
            return self_calibrate(res, cfg)
        except CalibrationRefusedError as exc:  # 1 s of settling: the misfit alarm may
            return exc.result  # trip; the untrusted results must still be identical

    fmu = calibrate(dataclasses.replace(cfg, engine="fmu"))
    lib = calibrate(cfg)
    assert np.array_equal(fmu.fit.x, lib.fit.x)
    assert fmu.bias == lib.bias and fmu.scale_factor == lib.scale_factor
