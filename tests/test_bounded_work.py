"""Nothing silently wrong, round 4: bounded work in every step, restored states checked in
every field, and a validate that a wide time band cannot talk into a pass. Each test is
one of the issue's trials, run on the native FMUs through fmpy."""

from __future__ import annotations

import math
import struct
import time
import zipfile

import numpy as np
import pytest
from fmpy.fmi1 import FMICallException
from fmu_harness import Instance
from test_reference import _tamper

from gyro_fmu.cli import main

H = 5e-6


def _first_step(models_dir, params: dict, ux: float) -> tuple[int, list[float], float]:
    inst = Instance(models_dir / "GyroObserver.fmu", parameters=params)
    try:
        inst.set({"ux": ux})
        t0 = time.perf_counter()
        status = inst.step(H)
        elapsed = time.perf_counter() - t0
        return status, inst.get(["x_hat", "vx_hat", "y_hat", "vy_hat"]), elapsed
    finally:
        inst.close()


@pytest.mark.parametrize("ux", [1e9, 1e13, 1e300])
def test_a_large_force_is_predicted_in_bounded_time_and_linearly(models_dir, ux):
    """Trials 1-2: ux = 1e13 N returned x_hat = 0 with status OK (the sub-step count
    overflowed int), ux = 1e9 N took 7-40 s a step. The first prediction from rest is
    linear in the force: it must equal ux times the prediction for 1 N, in milliseconds."""
    _, unit, _ = _first_step(models_dir, {}, 1.0)
    status, big, elapsed = _first_step(models_dir, {}, ux)
    assert elapsed < 0.5, f"one observer step took {elapsed:.2f} s at ux={ux:g} N"
    if ux == 1e300:  # beyond the double range on the way: refused, never a silent number
        assert status != 0 or not np.all(np.isfinite(big))
        return
    assert status == 0
    np.testing.assert_allclose(big, ux * np.asarray(unit), rtol=1e-12)
    assert big[0] > 0.0  # pushed along +x: not the zeros the overflow gave


def test_a_tiny_mass_guess_predicts_what_its_force_per_mass_says(models_dir):
    """Trial 1: m_0 = 1e-22 kg (legal: > 0) gave zeros with status OK. The first prediction
    depends on ux / m only: the same acceleration from the default mass must match."""
    m_default = 1.89e-7
    _, tiny, elapsed = _first_step(models_dir, {"m_0": 1e-22}, 1e-6)
    _, same, _ = _first_step(models_dir, {}, 1e-6 * m_default / 1e-22)
    assert elapsed < 0.5
    assert tiny[0] > 0.0
    np.testing.assert_allclose(tiny, same, rtol=1e-9)


def test_sideband_count_has_a_maximum_that_is_declared_and_refused(models_dir):
    """Trial 3: sideband_count = 2e9 (legal before: min 0, no max) hung the first step."""
    from fmpy import read_model_description

    md = read_model_description(str(models_dir / "GyroLoops.fmu"))
    declared = {v.name: v.max for v in md.modelVariables if v.type == "Integer"}
    assert declared["sideband_count"] == "1000"
    for fmu in ("GyroLoops", "GyroResonator", "GyroPlant", "RateProfile", "GyroObserver"):
        md = read_model_description(str(models_dir / f"{fmu}.fmu"))
        unbounded = [v.name for v in md.modelVariables if v.type == "Integer" and v.max is None]
        assert not unbounded, f"{fmu}: Integer variables without a max: {unbounded}"
    inst = Instance(models_dir / "GyroLoops.fmu", parameters={"sideband_count": 1000},
                    initialize=False)
    try:
        with pytest.raises(FMICallException):
            inst.set({"sideband_count": 2_000_000_000})
        assert "sideband_count=2000000000.0 is above its maximum 1000" in inst.messages()
        inst.initialize()  # the value kept, 1000, initializes
    finally:
        inst.close()


def test_the_core_refuses_what_the_description_bounds():
    """The same maxima in the C core (the in-process path does not pass the FMI layer)."""
    from gyro_fmu.model.loops import LoopSettings
    from gyro_fmu.model.resonator import ResonatorParameters, check_resonator

    assert any("sideband_count=1001 is above its maximum 1000" in p
               for p in LoopSettings(sideband_count=1001).problems())
    assert LoopSettings(sideband_count=1000).problems() == []
    assert any("cubic_substeps=1001 must be in 1..1000" in p
               for p in check_resonator(ResonatorParameters(cubic_substeps=1001)))


def _observer_offset(blob: bytes) -> int:
    """Where the core's GyroObserver starts in a serialized GyroObserver.fmu state: its
    tuning's first five numbers at the FMU's defaults, after the FMU's own variables (the
    same five numbers, first)."""
    marker = struct.pack("<5d", 1e-6, 0.0, 0.0, 1.0, 1e-3)
    first = blob.find(marker)
    at = blob.find(marker, first + 1)
    assert 0 < first < at and blob.find(marker, at + 1) < 0
    return at


@pytest.mark.parametrize("field, index, value, cause", [
    ("Ps", 3 * 14 * 14 + 5, math.inf, "a rate model's covariance that is not finite"),
    ("xs", 2 * 14 + 11, math.nan, "a rate model's estimate that is not finite"),
    ("mu", 1, 2.0, "model probabilities outside [0, 1]"),
    ("mon", 4, 1e30, "a monitor count, verdict or index out of its range"),
    ("refit", 4 * 8 + 8 + 64 + 2 + 16 + 0, 1e300, "a re-fit count out of its range"),
    ("peak", 0, -1.0, "signal peaks that are not finite and >= 0"),
])
def test_a_patched_observer_state_is_refused_in_every_field(models_dir, field, index, value,
                                                            cause):
    """Trial 5: xs, Ps, mu, the monitor, h_cached, Fr and Qr were taken unchecked from a
    deserialized state (inf or NaN then reached a float-to-int conversion)."""
    from gyro_fmu.core.observer import Observer

    inst = Instance(models_dir / "GyroObserver.fmu")
    try:
        for _ in range(3):
            inst.set({"ux": 1e-6, "x_meas": 1e-9})
            assert inst.step(H) == 0
        s = inst.slave.getFMUstate()
        raw = bytearray(inst.slave.serializeFMUstate(s))
        inst.slave.freeFMUstate(s)
        at = _observer_offset(bytes(raw)) + getattr(Observer, field).offset + 8 * index
        raw[at:at + 8] = struct.pack("<d", value)
        with pytest.raises(FMICallException):
            inst.slave.deSerializeFMUstate(bytes(raw))
        assert f"the saved observer holds {cause}" in inst.messages()
        assert inst.step(H) == 0  # nothing changed: the instance goes on
    finally:
        inst.close()


def test_validate_refuses_a_time_band_that_spans_the_signal(models_dir, tmp_path, capsys):
    """Trial 6: --dx 300 (and 100000) passed a GyroPlant whose reference x was doubled."""
    bad = tmp_path / "GyroPlant.fmu"
    _tamper(models_dir / "GyroPlant.fmu", bad, "GyroPlant", "x", 2.0)
    for dx in ("3", "30", "300", "100000"):
        assert main(["validate", "--dx", dx, str(bad)]) == 1, dx
        out = capsys.readouterr().out
        assert "all outputs match" not in out
    assert main(["validate", "--dx", "300", str(models_dir / "GyroPlant.fmu")]) == 1
    out = capsys.readouterr().out
    assert "band dx=300 samples spans the time scale of" in out and "use --dx <=" in out


@pytest.mark.parametrize("factor", [0.999, 1.001, 0.5])
def test_a_scaled_reference_fails_at_the_widest_band_allowed(models_dir, tmp_path, capsys,
                                                             factor):
    """Both ways: a reference scaled up or down fails at a dx the band check accepts."""
    bad = tmp_path / "GyroPlant.fmu"
    _tamper(models_dir / "GyroPlant.fmu", bad, "GyroPlant", "x", factor)
    assert main(["validate", "--dx", "3", str(bad)]) == 1
    assert "FAIL  x" in capsys.readouterr().out


def test_a_negative_step_size_is_named(models_dir, tmp_path, capsys):
    """Trial 7: a negative default stepSize spoke of '-1999 communication points'."""
    src, bad = models_dir / "GyroPlant.fmu", tmp_path / "GyroPlant.fmu"
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(bad, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item)
            if item.filename == "modelDescription.xml":
                data = data.replace(b'stepSize="5e-06"', b'stepSize="-5e-06"')
                assert b'stepSize="-5e-06"' in data
            zout.writestr(item, data)
    assert main(["validate", str(bad)]) == 1
    out = capsys.readouterr().out
    assert "stepSize=-5e-06 s must be finite and > 0" in out
    assert "communication points" not in out
