"""rate_model 0's constant model tested along Omega_z at two time scales (the core's
GyroWander, gyro_observer_rates.c): a rate that wanders more slowly than the rough models
gives the constant model a random walk of its own intensity; at rest it stays constant.
GyroSensor's chain in process (gyro_fmu.sensor.inprocess) at its defaults; the figures
quoted are docs/observer-rate-model.md's ("The constant model's wander test")."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from gyro_fmu.sensor.inprocess import chain_parts

REST = 0.5  #: s at rest before the sway


def _run(seed: int, rate, seconds: float, judged_from: float, hold_off: bool = False,
         observer_out: list | None = None) -> dict:
    """The chain for `seconds` with Omega_z = rate(t): over t >= judged_from, the RMS of
    error / sigma and the output's standard deviation; the largest log10 of each scale's
    q (over the rough model's intensity) seen at the samples. hold_off: the wander test's
    blocks never end (its q stays 0: the constant model as before the test)."""
    plant, obs, drive, h = chain_parts({"seed": seed})
    if hold_off:
        obs._c.wander.time[0] = obs._c.wander.time[1] = -1e9
    ratio, out, top = [], [], [-99.0, -99.0]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the re-fit test's warnings
        for k in range(round(seconds / h)):
            t = k * h
            ux = drive.ux(t)
            z = plant.output_row()
            obs.step(ux, 0.0, z[0], z[2], h)
            plant.step(ux, 0.0, rate(t), h)
            if t + h >= judged_from and k % 10 == 0:
                hat = obs.estimates()["Omega_z"]
                ratio.append((hat - rate(t + h)) / obs.sigmas()["Omega_z"])
                out.append(hat)
                top = [max(top[i], obs._c.wander.log_q[i] / math.log(10)) for i in (0, 1)]
    if observer_out is not None:
        observer_out.extend((obs, plant, drive, h))
    honesty = float(np.sqrt(np.mean(np.square(ratio)))) if ratio else math.nan
    return {"honesty": honesty, "std": float(np.std(out)) if out else math.nan,
            "log10_q": top}


def _sway(amplitude: float, f: float):
    return lambda t: amplitude * math.sin(2 * math.pi * f * (t - REST)) if t >= REST else 0.0


@pytest.mark.parametrize("f, scale", [(0.5, 1), (2.0, 0)])
def test_the_constant_model_takes_a_slow_sway_at_its_own_intensity(f: float, scale: int):
    """A sway of 0.05 rad/s, far below the rough models' intensity, judged 1.5-3 s into it
    (seed 0): the scale that finds it leaves its floor, and error/sigma is under 2.5
    (measured 1.94 at 0.5 Hz, 1.62 at 2 Hz), where the same run with the test held off
    (the constant model as before) reads over 3.5 (5.66 and 4.38). The 0.5 Hz sway is
    found by the 200 ms scale (it moves too little within 20 ms), the 2 Hz one by the 20 ms
    scale. Over seeds 0-5: 0.77-2.09 (RMS 1.45) and 1.34-1.67 (RMS 1.58), against
    2.64-8.95 (RMS 6.47) and 2.01-4.38 (RMS 3.04) held off."""
    on = _run(0, _sway(0.05, f), REST + 3.0, REST + 1.5)
    off = _run(0, _sway(0.05, f), REST + 3.0, REST + 1.5, hold_off=True)
    assert on["log10_q"][scale] > -8.0, on
    assert on["honesty"] < 2.5 and off["honesty"] > 3.5, (on, off)


@pytest.mark.parametrize("seed", [3, 5])
def test_at_rest_the_constant_model_stays_constant(seed: int):
    """At rest the bias of the test's law holds q near its floor: the largest q seen over
    3 s stays below 1e-7 of the rough model's intensity (where the output's noise is
    unchanged), and the output's spread equals that of the same run with the test held off
    within 2 % (measured over 10 s: within 1 %). Without the bias, seeds 3 and 5 let q
    wander up to 1e-3 and 1e-5 and the noise rose 1.5-2.3x."""
    rest = lambda t: 0.0  # noqa: E731
    on = _run(seed, rest, 3.0, 1.0)
    off = _run(seed, rest, 3.0, 1.0, hold_off=True)
    assert max(on["log10_q"]) < -7.0, on
    assert max(off["log10_q"]) < -11.99, off
    assert on["std"] == pytest.approx(off["std"], rel=0.02), (on, off)


def test_the_wander_test_travels_with_the_state():
    """get_state / set_state carry both scales' sums, q and averages: an observer restored
    mid-sway (q off its floor, blocks half full) goes on bit for bit with the original."""
    kept: list = []
    start = REST + 0.61
    _run(2, _sway(0.05, 2.0), start, 10.0, observer_out=kept)
    obs, plant, drive, h = kept
    state = obs.get_state()
    assert set(state["rate_filters"]["wander"]) == {"log_q", "C", "V", "time", "mu_min", "r"}
    assert max(obs._c.wander.log_q) > math.log(1e-8) and 0 < obs._c.wander.time[1] < 0.2
    twin = chain_parts({"seed": 2})[1]
    twin.set_state(state)
    rows: tuple[list, list] = ([], [])
    sway = _sway(0.05, 2.0)
    for k in range(round(0.2 / h)):  # blocks of both scales end
        t = start + k * h
        ux = drive.ux(t)
        z = plant.output_row()
        for o, row in zip((obs, twin), rows, strict=True):
            o.step(ux, 0.0, z[0], z[2], h)
            row.append(o.output_row())
        plant.step(ux, 0.0, sway(t), h)
    assert np.array_equal(np.array(rows[0]), np.array(rows[1]))
    assert obs.get_state()["rate_filters"]["wander"] == twin.get_state()["rate_filters"][
        "wander"]
