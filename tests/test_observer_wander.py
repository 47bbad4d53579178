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


#: The law's constants, as gyro_observer_internal.h states them (WANDER_*): the replay below
#: is an independent reading of obs_wander_step, so a change there must be made here too.
BLOCK, GAIN, BIAS = (0.02, 0.2), (0.5, 0.75), (0.75, 0.5)
R_MAX, Q_MIN, Q_MAX, MU_JUMP = 20.0, 1e-12, 1.0, 1e-6


def test_the_law_replayed_from_the_filters_own_corrections():
    """Step by step, from the constant model's Omega_z and variance before and after each
    correction and its probability, a Python replay of the law (blocks of 20 and 200 ms;
    log q += G (min(r, 20) - 1 - b), within [1e-12, 1]; no rise in a block where the
    probability fell below 1e-6) ends every block on the core's log q to 1e-12. The run
    (seed 0) sways 0.05 rad/s at 2 Hz from 0.3 s and jumps by 2 rad/s at 1.2 s, so that
    rises, the floor and the jump's gate all occur; the replay starts from the core's
    accumulators after 10 steps (the first ones set the state's prior inside the update)."""
    from gyro_fmu.estimation.observer import I_OM

    plant, obs, drive, h = chain_parts({"seed": 0})
    sway = _sway(0.05, 2.0)

    def rate(t: float) -> float:
        return (sway(t) if t >= 0.3 else 0.0) + (2.0 if t >= 1.2 else 0.0)

    w = obs._c.wander
    mine = None
    seen = {"rise": 0, "floor": 0, "gate": 0, "blocks": 0}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for k in range(round(1.5 / h)):
            t = k * h
            ux = drive.ux(t)
            z = plant.output_row()
            if k == 10:
                mine = {f: [float(v) for v in getattr(w, f)]
                        for f in ("log_q", "C", "V", "time", "mu_min")}
            x0, p0, restarts = obs.xs[0, I_OM], obs.Ps[0, I_OM, I_OM], obs.restarts
            obs.update(z[0], z[2], h)
            if mine is not None:
                assert obs.restarts == restarts, "a restart moves P inside the update"
                c, v = obs.xs[0, I_OM] - x0, p0 - obs.Ps[0, I_OM, I_OM]
                for s in (0, 1):
                    mine["C"][s] += c
                    mine["V"][s] += v
                    mine["time"][s] += h
                    mine["mu_min"][s] = min(mine["mu_min"][s], obs.mu[0])
                    if mine["time"][s] < BLOCK[s] * (1.0 - 1e-9):
                        continue
                    r = mine["C"][s] ** 2 / mine["V"][s]
                    d = GAIN[s] * (min(r, R_MAX) - 1.0 - BIAS[s])
                    if mine["mu_min"][s] < MU_JUMP and d > 0.0:
                        d, seen["gate"] = 0.0, seen["gate"] + 1
                    seen["rise"] += d > 0.0
                    q = mine["log_q"][s] + d
                    seen["floor"] += q < math.log(Q_MIN)
                    mine["log_q"][s] = min(max(q, math.log(Q_MIN)), math.log(Q_MAX))
                    mine["C"][s] = mine["V"][s] = mine["time"][s] = 0.0
                    mine["mu_min"][s] = 1.0
                    seen["blocks"] += 1
                    assert mine["log_q"][s] == pytest.approx(w.log_q[s], abs=1e-12), (t, s)
            obs.predict(ux, 0.0, h)
            plant.step(ux, 0.0, rate(t), h)
    assert seen["blocks"] == 75 + 7 and min(seen.values()) > 0, seen
