"""GyroSensor's datasheet (documentation/datasheet.json, measured by the build from the
FMU's own output): other seeds reproduce it within its stated uncertainty, through the
command a user runs in their CI; the check fails on a sensor that is not the one described;
the step and sine analyses against responses of known latency and gain."""

from __future__ import annotations

import copy
import json
import math
import zipfile

import numpy as np
import pytest
from scipy.stats import t as student

from gyro_fmu.cli import main
from gyro_fmu.fmu.build import prebuilt_fmu
from gyro_fmu.sensor.datasheet import (
    CHECK_PROBABILITY,
    CHECK_SEEDS,
    DATASHEET,
    DATASHEET_TEXT,
    SEEDS,
    TERMS,
    _step_response,
    check_datasheet,
)
from gyro_fmu.sensor.datasheet_fmu import read_fmu_datasheet
from gyro_fmu.sensor.presets import SENSOR_PRESETS
from gyro_fmu.studies.response import bandwidth_3db, sine_gain


@pytest.fixture(scope="module", params=list(SENSOR_PRESETS))
def checked(request, tmp_path_factory):
    """`gyro-fmu datasheet --check --preset P`: the FMU's datasheet of each preset against
    seeds 101 and 102."""
    out = tmp_path_factory.mktemp("datasheet")
    code = main(["datasheet", "--check", "--preset", request.param, "--out", str(out)])
    return request.param, code, json.loads((out / "datasheet.json").read_text()), out


def test_other_seeds_reproduce_the_shipped_datasheet(checked):
    preset, code, measured, out = checked
    assert code == 0
    assert measured["protocol"]["seeds"] == list(CHECK_SEEDS)
    assert (out / "datasheet.png").stat().st_size > 10_000
    shipped = read_fmu_datasheet(prebuilt_fmu("GyroSensor"), preset)
    assert shipped["preset"] == preset and shipped["settings"] == SENSOR_PRESETS[preset]
    assert shipped["protocol"]["seeds"] == list(SEEDS)
    assert set(TERMS) <= set(shipped["figures"])
    for name in TERMS:  # a spread, not a constant: six seeds that differ
        assert shipped["figures"][name]["uncertainty"] > 0, name


def test_the_check_fails_on_a_sensor_that_is_not_the_one_described(checked):
    """The same measurement against a datasheet whose bandwidth is higher, and whose latency
    shorter, by twice what the check allows each: both named (the measurement passed, so it
    lies within one allowance of the true datasheet and beyond one of the shifted one)."""
    preset, _, measured, _ = checked
    shipped = read_fmu_datasheet(prebuilt_fmu("GyroSensor"), preset)
    assert check_datasheet(shipped, measured) == []
    k, m = len(shipped["protocol"]["seeds"]), len(measured["protocol"]["seeds"])
    q = student.ppf(0.5 + CHECK_PROBABILITY / 2, k - 1) * math.sqrt(1 / k + 1 / m)
    other = copy.deepcopy(shipped)
    for name, sign in (("bandwidth", 1), ("latency", -1)):
        other["figures"][name]["value"] += sign * 2 * q * shipped["figures"][name]["uncertainty"]
    problems = check_datasheet(other, measured)
    assert [p.split(":")[0] for p in problems] == ["latency", "bandwidth"]


def test_the_presets_are_different_gyros():
    """The presets' datasheets differ where their gyros do: the low-cost one (noise x 3,
    Q 300) is at least twice as noisy as the consumer one (angle random walk bound) and
    rings more after a step (overshoot)."""
    sheets = {p: read_fmu_datasheet(prebuilt_fmu("GyroSensor"), p)["figures"]
              for p in SENSOR_PRESETS}
    assert sheets["low-cost"]["arw"]["value"] > 2 * sheets["consumer"]["arw"]["value"]
    assert sheets["low-cost"]["overshoot"]["value"] > 2 * sheets["consumer"]["overshoot"]["value"]


def test_fmi2_and_fmi3_carry_the_same_datasheet():
    sheets = [zipfile.ZipFile(prebuilt_fmu("GyroSensor", v)).read(DATASHEET) for v in (2, 3)]
    assert sheets[0] == sheets[1]
    figures = json.loads(sheets[0])["figures"]
    assert figures["full_scale"]["value"] == 35.0
    text = zipfile.ZipFile(prebuilt_fmu("GyroSensor", 3)).read(DATASHEET_TEXT).decode()
    assert f"| bandwidth | {figures['bandwidth']['value']:.4g} |" in text


def test_step_response_of_a_known_delay_and_time_constant():
    """A first-order lag of time constant T behind a pure delay D, sampled at 0.2 ms:
    50 % at D + T ln 2, 10-90 % in T ln 9, no overshoot."""
    h, D, T, t_step = 2e-4, 1e-3, 2e-3, 0.01
    t = h * np.arange(1, 301)
    y = np.where(t > t_step + D, 1.0 - np.exp(-(t - t_step - D) / T), 0.0)
    r = _step_response(t, y, t_step)
    assert r["latency"] == pytest.approx(D + T * math.log(2), abs=2e-6)
    assert r["rise_time"] == pytest.approx(T * math.log(9), abs=4e-6)
    assert r["overshoot"] == pytest.approx(0.0, abs=1e-6)  # final: the last 10 ms' mean


def test_sine_gain_and_bandwidth_of_a_known_filter():
    """A first-order low-pass of corner 100 Hz, evaluated exactly: the fitted gains and
    phases are its own, and the -3 dB point is found within the interpolation's error."""
    fc = 100.0
    tau = np.arange(0, 0.2, 2e-4)
    points = []
    for f in (5.0, 10.0, 20.0, 50.0, 80.0, 100.0, 150.0):
        g = 1.0 / complex(1.0, f / fc)
        y = abs(g) * np.sin(2 * math.pi * f * tau + np.angle(g)) + 0.01
        points.append(sine_gain(tau, y, f, 1.0))
        assert points[-1]["gain"] == pytest.approx(abs(g), rel=1e-9)
        assert points[-1]["phase_deg"] == pytest.approx(math.degrees(np.angle(g)), abs=1e-6)
    assert bandwidth_3db(points)["f_3db_hz"] == pytest.approx(fc, rel=0.02)


def test_seeds_that_cannot_give_an_uncertainty_and_foreign_fmus_are_refused():
    """A repeated seed repeats its run (a spread of 0 claimed as the uncertainty), a check
    with the datasheet's own seeds would pass by construction, an FMU that is not GyroSensor
    has nothing to measure: each refused by name, before any run."""
    from gyro_fmu.sensor.datasheet import DatasheetError, measure_datasheet

    fmu = prebuilt_fmu("GyroSensor")
    with pytest.raises(DatasheetError, match=r"seeds \[3, 3\]: give at least 2 different"):
        measure_datasheet(fmu, seeds=(3, 3))
    with pytest.raises(DatasheetError, match=r"has no .*Omega_meas.*GyroSensor"):
        measure_datasheet(prebuilt_fmu("GyroPlant"))
    shipped = read_fmu_datasheet(fmu)
    again = copy.deepcopy(shipped)
    again["protocol"]["seeds"] = [1, 101]
    assert check_datasheet(shipped, again) == [
        "seeds [1] made the datasheet too: check with other seeds"]
