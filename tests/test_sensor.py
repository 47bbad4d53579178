"""GyroSensor.fmu: the gyroscope as a sensor, run as a system model's host runs it (fmpy,
FMI 2.0 and 3.0, a host step of milliseconds), against the chain computed in-process
(gyro_fmu.sensor.inprocess: the library's plant and observer stepped from Python, scipy's
Butterworth), with bad input refused by name."""

from __future__ import annotations

import math

import fmpy
import numpy as np
import pytest
from fmu_harness import Instance

from gyro_fmu.fmu.build import prebuilt_fmu
from gyro_fmu.sensor.inprocess import run_chain

STEP_AT = 0.021  # s: a multiple of 1, 0.7 and 0.1 ms


def rate(t: float) -> float:
    return 1.0 if t >= STEP_AT else 0.0


def simulate(version: int, stop: float, h: float, **start) -> np.ndarray:
    path = prebuilt_fmu("GyroSensor", fmi_version=version)
    t = np.arange(round(stop / h) + 1) * h
    inputs = np.zeros(t.size, dtype=[("time", float), ("Omega_z", float)])
    inputs["time"], inputs["Omega_z"] = t, [rate(x) for x in t]
    return fmpy.simulate_fmu(str(path), stop_time=stop, output_interval=h, input=inputs,
                             start_values=start, fmi_type="CoSimulation")


@pytest.mark.parametrize("version", [2, 3])
def test_the_fmu_is_the_chain_then_the_readout(version):
    """The FMU's outputs at a 1 ms host step against the in-process chain: the rate
    estimate bit for bit (the same core in the same order); the output filter to 1e-9
    rad/s. scipy's coefficients differ from the FMU's in the last bit, and a biquad at
    f_c / f_s = 5e-4 amplifies that by about (f_s / f_c)^2 = 4e6 (measured: 1.1e-11 rad/s
    at a 1 rad/s step, 1e-10 of the rate), seven orders below the output's noise."""
    r = simulate(version, 0.03, 1e-3, resolution=0.0)
    chain = run_chain({"resolution": 0.0}, rate, r["time"])
    assert np.array_equal(r["Omega_hat"], chain.Omega_hat)
    np.testing.assert_allclose(r["Omega_meas"], chain.filtered, rtol=0, atol=1e-9)
    np.testing.assert_allclose(r["sigma_Omega_meas"], chain.sigma_Omega_z, rtol=1e-15)
    assert np.all(r["status"] == chain.status)


def test_host_steps_of_1_07_and_01_ms_give_the_same_outputs_at_common_times():
    """The internal clock is fixed: the same internal steps happen whatever the host's
    step, so the outputs at a common time are the same numbers."""
    runs = {h: simulate(2, 0.042, h) for h in (1e-3, 7e-4, 1e-4)}
    common = np.arange(0, 0.042 + 1e-12, 7e-3)
    picked = {}
    for h, r in runs.items():
        idx = [int(np.argmin(np.abs(r["time"] - t))) for t in common]
        assert np.allclose(r["time"][idx], common, atol=1e-12)
        picked[h] = r["Omega_meas"][idx]
    assert np.array_equal(picked[1e-3], picked[7e-4])
    assert np.array_equal(picked[1e-3], picked[1e-4])


def test_the_output_follows_the_true_rate_within_its_noise():
    """After the step (and the filter's settling, 5 time constants of 100 Hz) the output is
    the true rate within 5 of its sigmas."""
    r = simulate(2, 0.06, 1e-3)
    late = r["time"] >= STEP_AT + 0.02
    err = np.abs(r["Omega_meas"][late] - 1.0)
    assert np.all(r["status"] == 0)
    assert np.all(err <= 5 * r["sigma_Omega_meas"][late]), err / r["sigma_Omega_meas"][late]


def test_quantization_and_full_scale():
    r = simulate(2, 0.03, 1e-3, full_scale=0.5, resolution=1e-3)
    q = r["Omega_meas"] / 1e-3
    assert np.allclose(q, np.round(q), atol=1e-9)
    after = r["time"] >= STEP_AT + 0.005
    assert np.all(r["Omega_meas"][after] == 0.5) and np.all(r["saturated"][after] == 1)
    assert np.all(r["saturated"][r["time"] < STEP_AT] == 0)


def test_saturation_is_logged_once():
    inst = Instance(prebuilt_fmu("GyroSensor"), parameters={"full_scale": 0.5})
    try:
        inst.set({"Omega_z": 2.0})
        for _ in range(5):
            assert inst.step(1e-3) == 0
        said = inst.messages()
        assert said.count("beyond full scale") == 1 and "full_scale=0.5 rad/s" in said
    finally:
        inst.close()


def test_a_step_shorter_than_the_internal_step_is_refused_and_nothing_changes():
    inst = Instance(prebuilt_fmu("GyroSensor"))
    try:
        assert inst.step(1e-6) == 2  # fmi2Discard (the default gyro runs at 20 us inside)
        assert "communication step 1e-06 s is shorter than the internal step 2e-05 s" in \
            inst.messages()
        assert inst.step(1e-3) == 0
    finally:
        inst.close()


@pytest.mark.parametrize("params, said", [
    ({"bandwidth": 1e5}, "bandwidth=100000.0 Hz must be > 0 and below a quarter"),
    ({"internal_step": 1e-4}, "internal_step=0.0001 s is too coarse"),
    ({"kxy": 5e8}, "the gyro as fabricated is unusable"),
    ({"resolution": 1e-14}, "resolution=1e-14 rad/s must be 0 (not quantized) or a"),
])
def test_parameters_no_gyro_can_have_are_refused_with_the_remedy(params, said):
    inst = Instance(prebuilt_fmu("GyroSensor"), parameters=params, initialize=False)
    try:
        with pytest.raises(Exception):  # noqa: B017 - fmpy's FMICallException
            inst.initialize()
        assert said in inst.messages(), inst.messages()
    finally:
        inst.slave.freeInstance()


def test_a_value_outside_a_declared_range_is_refused_when_set():
    inst = Instance(prebuilt_fmu("GyroSensor"), initialize=False)
    try:
        with pytest.raises(Exception):  # noqa: B017 - fmpy's FMICallException
            inst.set({"kxx_0": -1.0})
        assert "kxx_0=-1.0 is below its minimum" in inst.messages()
    finally:
        inst.slave.freeInstance()


def test_a_rate_no_gyro_can_sense_is_refused():
    inst = Instance(prebuilt_fmu("GyroSensor"))
    try:
        inst.set({"Omega_z": 1e5})
        assert inst.step(1e-3) == 3  # fmi2Error
        assert "Omega_z=100000.0" in inst.messages()
    finally:
        inst.slave.freeInstance()


@pytest.mark.parametrize("rate_model", [0, 4])
def test_state_round_trip_reproduces_the_outputs(rate_model):
    inst = Instance(prebuilt_fmu("GyroSensor"), parameters={"rate_model": rate_model})
    try:
        inst.set({"Omega_z": 0.3})
        for _ in range(3):
            inst.step(1e-3)
        saved = inst.slave.serializeFMUstate(inst.slave.getFMUstate())
        first = [inst.get(["Omega_meas", "Omega_hat"]) for _ in range(1) if inst.step(1e-3) == 0]
        inst.slave.setFMUstate(inst.slave.deSerializeFMUstate(saved))
        inst.t -= 1e-3
        again = [inst.get(["Omega_meas", "Omega_hat"]) for _ in range(1) if inst.step(1e-3) == 0]
        assert first == again and math.isfinite(first[0][0])
    finally:
        inst.close()


def test_twenty_gyros_that_are_not_presets_read_their_rate_within_their_sigma():
    """Random gyros (gyro_fmu.sensor.gyros: modes 2-8 kHz, splits 1-25 %, Q 300-1e4,
    couplings up to 15 %, masses 1e-9 to 1e-6 kg), each from design values 5-20 % off, at
    a constant 1 rad/s: over the last 0.1 s of 0.3 s, the output's mean error is within
    4 of its stated sigmas, and the status is 0 from 10 ms on (measured: RMS bias/sigma
    0.96, worst 2.58; before the covariance's noise of 0.4.0, 1.09 / 3.01 with status 0
    throughout). The observer may flag its first milliseconds while it converges from
    design values 20 % off: gyro 7 is status 1 at 3 and 4 ms (its innovations not yet
    white), which is what the status is for."""
    from gyro_fmu.sensor.gyros import random_gyro, sensor_settings

    path = prebuilt_fmu("GyroSensor")
    md = fmpy.read_model_description(str(path))
    unzipped = fmpy.extract(str(path))
    stop, h = 0.3, 1e-3
    t = np.arange(round(stop / h) + 1) * h
    inputs = np.zeros(t.size, dtype=[("time", float), ("Omega_z", float)])
    inputs["time"], inputs["Omega_z"] = t, 1.0
    rng = np.random.default_rng(1)
    ratios = []
    for i in range(20):
        settings = sensor_settings(random_gyro(rng), seed=i)
        r = fmpy.simulate_fmu(unzipped, stop_time=stop, output_interval=h, input=inputs,
                              start_values=settings, model_description=md)
        late = r["time"] >= 0.2
        bias = float(np.mean(r["Omega_meas"][late] - 1.0))
        sigma = float(np.sqrt(np.mean(r["sigma_Omega_meas"][late] ** 2)))
        assert np.all(r["status"][r["time"] >= 0.01] == 0), (i, settings)
        ratios.append(bias / sigma)
    assert np.max(np.abs(ratios)) <= 4.0, ratios
    assert 0.3 < np.sqrt(np.mean(np.square(ratios))) < 1.5, ratios  # honest, not inflated


def test_a_communication_step_beyond_the_bounded_work_is_refused_by_name():
    inst = Instance(prebuilt_fmu("GyroSensor"))
    try:
        assert inst.step(5.0) == 3  # fmi2Error: nothing done, no minutes of CPU
        said = inst.messages()
        assert "needs 2.5e+05 internal steps of 2e-05 s, above the 200000 one call may do: " \
               "use communication steps of at most 4 s" in said, said
    finally:
        inst.slave.freeInstance()


def test_host_steps_follow_the_true_rate_delayed_by_the_declared_latency():
    """Host steps of 1, 0.7 and 0.1 ms on a 2 Hz sine of 1 rad/s (from 0.3 s, after the
    warm-up): Omega_meas is the true rate delayed by the datasheet's latency within 4 of
    the FMU's own sigmas at every point from 0.4 s (measured: 2.5 at most; the error is
    the observer's while it tracks the sine, RMS 0.020 rad/s against a sigma of 0.034), and
    closer to it than to the undelayed rate (the 2.6 ms latency is 0.033 rad/s here)."""
    from gyro_fmu.sensor.datasheet_fmu import read_fmu_datasheet

    latency = read_fmu_datasheet(prebuilt_fmu("GyroSensor"))["figures"]["latency"]["value"]

    def sine(t):
        return np.where(t >= 0.3, np.sin(2 * np.pi * 2.0 * (t - 0.3)), 0.0)

    for h in (1e-3, 7e-4, 1e-4):
        t = np.arange(round(0.7 / h) + 1) * h
        inputs = np.zeros(t.size, dtype=[("time", float), ("Omega_z", float)])
        inputs["time"], inputs["Omega_z"] = t, sine(t)
        r = fmpy.simulate_fmu(str(prebuilt_fmu("GyroSensor")), stop_time=0.7,
                              output_interval=h, input=inputs)
        late = r["time"] >= 0.4
        delayed = r["Omega_meas"][late] - sine(r["time"][late] - latency)
        assert np.all(r["status"] == 0)
        assert np.all(np.abs(delayed) <= 4 * r["sigma_Omega_meas"][late]), h
        undelayed = r["Omega_meas"][late] - sine(r["time"][late])
        assert np.sqrt(np.mean(delayed**2)) < np.sqrt(np.mean(undelayed**2)), h


def _sway_run(rate_model: int, seed: int) -> tuple[float, float]:
    """GyroSensor.fmu at a 1 ms host step: 0.5 s at rest, then a sway of 0.05 rad/s at
    2 Hz to 1.5 s. Over 1.0-1.5 s: the gain of Omega_hat at 2 Hz (a least-squares sine
    fit) and the RMS of its error over the FMU's own sigma_Omega_meas (resolution 0)."""
    from gyro_fmu.studies.response import sine_gain

    rest, stop, amplitude, f, h = 0.5, 1.5, 0.05, 2.0, 1e-3

    def sway(t):
        return np.where(t >= rest, amplitude * np.sin(2 * np.pi * f * (t - rest)), 0.0)

    t = np.arange(round(stop / h) + 1) * h
    inputs = np.zeros(t.size, dtype=[("time", float), ("Omega_z", float)])
    inputs["time"], inputs["Omega_z"] = t, sway(t)
    r = fmpy.simulate_fmu(str(prebuilt_fmu("GyroSensor")), stop_time=stop, output_interval=h,
                          input=inputs, start_values={"rate_model": rate_model,
                                                      "resolution": 0.0, "seed": seed})
    judged = r["time"] >= 1.0 - 1e-9
    held = r["time"][judged] - h  # the output at t follows the input held over the step
    gain = sine_gain(held - rest, r["Omega_hat"][judged], f, amplitude)["gain"]
    ratio = (r["Omega_hat"][judged] - sway(held)) / r["sigma_Omega_meas"][judged]
    return gain, float(np.sqrt(np.mean(ratio**2)))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_small_slow_sway_is_found_by_the_moving_bank_and_by_the_wander_test(seed):
    """rate_model 4 (the moving bank) on a sway far below the adaptive set's fixed
    intensities: gain 1 within 15 % and error/sigma under 1.4 (measured over seeds 0-5:
    gain 1.02-1.07, error/sigma 0.76-1.14). The default, rate_model 0, finds the same
    sway through its constant model's wander test, half a second into it not yet fully:
    gain within 0.9-1.2 and error/sigma under 3.2 (measured over seeds 0-5: gain
    0.98-1.15, error/sigma 1.45-2.79; before the test gain 0.75-1.32 and 3.4-5.6, seed 4
    at status 0). docs/gyro-sensor.md, "What falls short", quotes these."""
    gain, honesty = _sway_run(4, seed)
    assert 0.85 <= gain <= 1.15 and honesty < 1.4, (gain, honesty)
    gain, honesty = _sway_run(0, seed)
    assert 0.9 <= gain <= 1.2 and honesty < 3.2, (gain, honesty)
