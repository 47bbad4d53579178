"""Issue 15, parts 1-2: the observer converges or refuses by name, at any step, start, scale.

The issue's silent failures (steps of 2.5 and 3 us, Omega_z_0 = 1.4, a 0.5 kg proof mass
with 2e-15 m displacements) now converge; a filter that is lost raises
ObserverDivergedError, and GyroObserver.fmu then publishes status 2 and refuses the step
with fmi2Discard and the cause in its log; `gyro-fmu run` ends with exit code 2.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from fmu_harness import Instance

from gyro_fmu.core.observer import cholesky_ok
from gyro_fmu.errors import GyroFmuError
from gyro_fmu.estimation.observer import (
    CoarseStepWarning,
    GyroStateObserver,
    ObserverDivergedError,
    ObserverStepError,
    ObserverTuning,
)
from gyro_fmu.model.drive import TwoToneDrive
from gyro_fmu.model.parameters import GyroParameters, preset
from gyro_fmu.model.plant import GyroPlantModel, MeasurementNoise
from gyro_fmu.system.scenario import absolute_noise, observer_tuning, scenario


def run(h: float, n: int, Omega_z_0: float = 0.0, overrides: dict | None = None,
        drive: TwoToneDrive | None = None, tuning: dict | None = None,
        check_spd_every: int = 0) -> GyroStateObserver:
    """The default scenario in-process (as gyro-fmu run), noise-free, n steps of h."""
    sc = scenario("default", Omega_z_0=Omega_z_0, overrides=overrides or {})
    sc = sc.with_(drive=drive) if drive is not None else sc
    plant = GyroPlantModel(sc.params)
    tun = {**observer_tuning(sc, MeasurementNoise()), **(tuning or {})}
    obs = GyroStateObserver(GyroParameters(**sc.initial_guess), Omega_z_0, 1,
                            ObserverTuning(**tun))
    d = sc.the_drive
    for k in range(n):
        ux = d.ux(k * h)
        z = plant.measured()
        obs.step(ux, 0.0, z[0], z[2], h)
        plant.step(ux, 0.0, 1.0, h)
        if check_spd_every and k % check_spd_every == 0:
            assert cholesky_ok(obs.P), k
    return obs


@pytest.mark.parametrize(("h", "n", "Omega_z_0", "overrides"), [
    (3e-6, 999, 0.0, {}),  # was Omega_hat -7.66, every sigma 0 at 1 ms
    (2.5e-6, 2000, 0.0, {}),  # was -3.9e4 at 1 ms, NaN from 2.9-4.2 ms
    (5e-6, 1200, 1.4, {}),  # was Omega_hat 527, kyy 1.3e11, sigma 0, exit 0
    (5e-6, 1000, 0.0, {"m": 0.5}),  # displacements ~1e-15 m: was -15.0 with sigma 0
], ids=["3us", "2.5us", "Omega_z_0=1.4", "m=0.5"])
def test_the_issues_silent_failures_now_converge(h, n, Omega_z_0, overrides):
    obs = run(h, n, Omega_z_0, overrides, check_spd_every=50)
    e, s = obs.estimates(), obs.sigmas()
    assert obs.status == 0
    assert abs(e["Omega_z"] - 1.0) < 0.01 and 0.0 < s["Omega_z"] < 0.01, (e, s)
    truth = preset(**overrides)
    for name in ("kxx", "kyy", "kxy", "dxx", "dyy", "dxy", "m"):
        assert abs(e[name] / getattr(truth, name) - 1.0) < 0.01, name
        assert s[name] > 0.0, name


def test_a_gyro_driven_1e7_times_softer_gives_the_same_relative_errors():
    """Every prior and floor scales with the signal: 3e-9 m and 3e-16 m displacements."""
    loud = run(5e-6, 1000)
    soft = run(5e-6, 1000, drive=TwoToneDrive(A1=1e-14, A2=1e-14))
    assert abs(soft.state_estimate()[0]) < 1e-15
    for name in GyroStateObserver.ESTIMATED:
        a, b = loud.estimates()[name], soft.estimates()[name]
        assert b == pytest.approx(a, rel=1e-6, abs=1e-9), name
        assert soft.sigmas()[name] == pytest.approx(loud.sigmas()[name], rel=1e-3), name


def junk_steps(obs: GyroStateObserver, n: int) -> None:
    """Measurements that no gyro makes: white 1e-9 m junk told as 1e-12 m noise."""
    rng = np.random.default_rng(0)
    d = TwoToneDrive()
    for k in range(n):
        obs.step(d.ux(k * 5e-6), 0.0, 1e-9 * rng.standard_normal(),
                 1e-9 * rng.standard_normal(), 5e-6)


def test_a_lost_filter_raises_a_named_error_and_refuses_every_later_step():
    obs = GyroStateObserver(preset(), 0.0, 1, ObserverTuning(sigma_z1=1e-12, sigma_z2=1e-12))
    with pytest.raises(ObserverDivergedError, match="observer lost at t=") as info:
        junk_steps(obs, 100)
    assert isinstance(info.value, GyroFmuError)
    assert "physical range" in str(info.value) and "initial" in str(info.value)
    assert obs.status == 2
    state = obs.get_state()
    with pytest.raises(ObserverDivergedError, match="observer lost"):
        obs.step(0.0, 0.0, 0.0, 0.0, 5e-6)
    other = GyroStateObserver(preset())
    other.set_state(state)
    assert other.status == 2 and other.lost == obs.lost


def _break_covariance(obs: GyroStateObserver, diagonal: bool) -> None:
    """Every rate model's P made indefinite: a negative variance of vx, or (diagonal False)
    a correlation of x and y beyond 1 with every variance positive."""
    for P in obs.Ps:
        if diagonal:
            P[1, 1] = -abs(P[1, 1])
        else:
            c = 3.0 * math.sqrt(P[0, 0] * P[2, 2])
            P[0, 2] = P[2, 0] = c


@pytest.mark.parametrize("rate_model", [0, 1])
def test_a_broken_covariance_is_lost_within_one_block(rate_model):
    """The whole Cholesky check runs when a block of corrections is judged (every 200
    steps), the diagonal at every step (fmu_src/core/gyro_observer_monitor.c): a negative
    variance is lost at the next step, an indefinite P with a positive diagonal within one
    block."""
    for diagonal, within in ((True, 1), (False, 200)):
        obs = run(5e-6, 1000, tuning={"rate_model": rate_model})
        assert obs.status == 0
        _break_covariance(obs, diagonal)
        steps = 0
        with pytest.raises(ObserverDivergedError, match="lost positive definiteness"):
            while steps < within:
                steps += 1
                obs.step(0.0, 0.0, 0.0, 0.0, 5e-6)
        assert obs.status == 2 and steps <= within, (diagonal, steps)


def test_noise_larger_than_told_is_a_warning_not_silence():
    """Absolute noise stds 10x too small: the block NIS (~200) leaves its chi-square band."""
    p = preset()
    sc = scenario("default", noise=1e-4)
    drive = sc.the_drive
    plant = GyroPlantModel(p, MeasurementNoise(x=3e-13, vx=0.0, y=3e-13, vy=0.0), 1)
    obs = GyroStateObserver(GyroParameters(**sc.initial_guess), 0.0, 1,
                            ObserverTuning(sigma_z1=3e-14, sigma_z2=3e-14, rate_model=1))
    for k in range(1000):
        ux = drive.ux(k * 5e-6)
        z = plant.measured()
        obs.step(ux, 0.0, z[0], z[2], 5e-6)
        plant.step(ux, 0.0, 1.0, 5e-6)
    assert obs.status == 1
    assert "chi-square" in obs.warning and "noise larger than told" in obs.warning


def test_the_fmu_publishes_status_and_refuses_a_lost_filter_with_its_cause(models_dir):
    params = {"sigma_z1": 1e-12, "sigma_z2": 1e-12}
    obs = Instance(models_dir / "GyroObserver.fmu", "lost-observer", params)
    assert obs.vars["status"].causality == "output"
    assert obs.get(["status"]) == [0.0]
    rng = np.random.default_rng(0)
    codes = []
    for k in range(20):
        obs.set({"ux": 1e-7 * math.sin(2 * math.pi * 4000 * k * 5e-6),
                 "x_meas": 1e-9 * rng.standard_normal(), "y_meas": 1e-9 * rng.standard_normal()})
        codes.append(obs.step(5e-6))
        if codes[-1]:
            break
    assert codes[-1] == 2  # fmi2Discard
    assert obs.get(["status"]) == [2.0]
    assert all(math.isnan(v) for v in obs.get(["Omega_hat", "kxx_hat", "sigma_Omega_z"]))
    log = obs.messages()
    assert "refused: observer lost at t=" in log and "physical range" in log, log
    assert obs.step(5e-6) in (2, 3)  # and it does not go on
    obs.close()


def test_gyro_fmu_run_stops_with_exit_2_naming_the_lost_observer(models_dir, tmp_path, capsys):
    """Noise 1e-3 of the peak told as 1e-15 m: lost at the first steps."""
    from gyro_fmu.cli import main

    argv = ["run", "--stop-time", "0.001", "--noise", "1e-3", "--tuning", "sigma_z1=1e-15",
            "--tuning", "sigma_z2=1e-15", "--out", str(tmp_path), "--no-figures",
            "--models", str(models_dir)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "observer" in err and "refused the step" in err and "observer lost at t=" in err, err


def test_the_fmu_publishes_a_warning_status_and_logs_it(models_dir):
    """Noise 10x larger than told: status 1 and the chi-square warning in the log."""
    sc = scenario("default")
    obs = Instance(models_dir / "GyroObserver.fmu", "warned-observer",
                   {**{f"{k}_0": v for k, v in sc.initial_guess.items()},
                    "sigma_z1": 3e-14, "sigma_z2": 3e-14, "rate_model": 1})
    plant = GyroPlantModel(sc.params, MeasurementNoise(x=3e-13, y=3e-13), 1)
    for k in range(600):
        ux = sc.the_drive.ux(k * 5e-6)
        z = plant.measured()
        obs.set({"ux": ux, "x_meas": z[0], "y_meas": z[2]})
        assert obs.step(5e-6) == 0
        plant.step(ux, 0.0, 1.0, 5e-6)
    assert obs.get(["status"]) == [1.0]
    assert "chi-square" in obs.messages() and "noise larger than told" in obs.messages()
    assert obs.get(["sigma_Omega_z"])[0] > 0.0
    obs.close()


def test_a_step_too_coarse_for_the_resonance_is_refused_by_name_and_changes_nothing():
    """200 us samples the 3.7 kHz resonance at omega h = 4.6: aliased, refused; the
    observer goes on with a smaller step (the FMU: fmi2Discard, recoverable)."""
    obs = GyroStateObserver(preset())
    before = obs.get_state()
    with pytest.raises(ObserverStepError, match=r"too coarse.*use a step <= 0\.000108 s"):
        obs.step(1e-8, 0.0, 0.0, 0.0, 200e-6)
    assert isinstance(ObserverStepError("x"), GyroFmuError)
    assert obs.get_state() == before
    with pytest.warns(CoarseStepWarning, match="omega h = 2.31"):
        obs.step(1e-8, 0.0, 0.0, 0.0, 100e-6)
    assert obs.status == 0


def test_a_coarse_step_below_the_refusal_is_a_warning_once_per_step_size(models_dir):
    """omega h above 1.2 (and up to the refusal at 2.5) is taken, with a warning naming the
    step, omega h and the remedy: CoarseStepWarning once per step size in the library,
    the same words in GyroObserver.fmu's log; 1.0 is no warning."""
    import warnings

    obs = GyroStateObserver(preset())
    omega = max(math.sqrt(preset().kxx), math.sqrt(preset().kyy))
    with pytest.warns(CoarseStepWarning, match=r"omega h = 1\.5, above 1\.2.*use a step <= "):
        obs.step(1e-8, 0.0, 0.0, 0.0, 1.5 / omega)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        obs.step(1e-8, 0.0, 0.0, 0.0, 1.5 / omega)  # the same step size: said once
        obs.step(1e-8, 0.0, 0.0, 0.0, 1.0 / omega)
    assert obs.status == 0
    inst = Instance(models_dir / "GyroObserver.fmu", "coarse")
    omega = math.sqrt(max(inst.get(["kxx_0", "kyy_0"])))  # the FMU's own default guess
    assert inst.step(1.5 / omega) == 0
    assert inst.step(1.5 / omega) == 0
    text = inst.messages()
    assert text.count("is coarse for the observer") == 1 and "omega h = 1.5" in text, text
    inst.close()


def _far_noise_free_run(tuning: ObserverTuning) -> GyroStateObserver:
    """10 us steps, parameters 30 % off, noise-free, 20 ms: the EKF still converging."""
    sc = scenario("default")
    truth = sc.params
    signs = {"kxx": 1, "kyy": -1, "kxy": 1, "dxx": 1, "dyy": 1, "dxy": -1, "m": 1}
    guess = GyroParameters(**{n: getattr(truth, n) * (1 + 0.3 * s) for n, s in signs.items()})
    obs = GyroStateObserver(guess, 0.0, 1, tuning)
    plant = GyroPlantModel(truth)
    for k in range(2000):
        ux = sc.the_drive.ux(k * 10e-6)
        z = plant.measured()
        obs.step(ux, 0.0, z[0], z[2], 10e-6)
        plant.step(ux, 0.0, 1.0, 10e-6)
    return obs


@pytest.mark.parametrize("rate_model", [0, 1])
def test_a_slow_noise_free_convergence_is_honest(rate_model):
    """The far start at 20 ms: Omega within 3 of its sigmas, or flagged. The noise
    estimated from the innovations (innov_floor 1, the default) counts the misfit that is
    left; with the former innov_floor 0.5 the constant-rate model was 0.7 % off at ~35
    sigmas with status 0. Since the covariance takes in the plain mean of the first
    squared innovations (0.4.0; here they are misfit, not noise, and the first is 0: the
    plant starts at rest), the constant-rate model converges later: at 20 ms 5.6 sigmas
    off with status 1, at 40 ms 1.4 (status 1), where it was 0.7 and 0.2 (measured)."""
    obs = _far_noise_free_run(ObserverTuning(rate_model=rate_model))
    err = obs.estimates()["Omega_z"] - 1.0
    assert abs(err) <= 3 * obs.sigmas()["Omega_z"] or obs.status != 0, \
        (err, obs.sigmas()["Omega_z"], obs.status)


def test_a_slow_overconfident_noise_free_convergence_is_flagged():
    """The same with the noise floor at half the innovations (innov_floor 0.5): 0.7 % off
    at ~35 sigmas; the innovations are a slow misfit, not noise: status 1, not 0."""
    obs = _far_noise_free_run(ObserverTuning(rate_model=1, innov_floor=0.5, innov_tau=1e-4))
    err = obs.estimates()["Omega_z"] - 1.0
    assert abs(err) > 5 * obs.sigmas()["Omega_z"]
    assert obs.status == 1  # the innovations are not white
    assert obs.warning.startswith("observer at t=0.02 s: ")
    assert "not white" in obs.warning


def test_a_constant_rate_filter_keeps_its_footing_over_seconds():
    """Constant-rate model, noise 1e-4 told, 3.3 s (660,000 steps): without the plant-state
    noise floor (observer_rate.STATE_NOISE) the state-parameter correlations reached
    1 - 1e-16 and the covariance lost positive definiteness at 3.09 s (found by gyro-fmu
    spec). Now it runs on and its sigma keeps falling."""
    sc = scenario("default", noise=1e-4)
    std = absolute_noise(sc)
    plant = GyroPlantModel(sc.params, std, 0)
    obs = GyroStateObserver(GyroParameters(**sc.initial_guess), 0.0, 1,
                            ObserverTuning(rate_model=1, sigma_z1=std.x, sigma_z2=std.y))
    h, drive = 5e-6, sc.the_drive
    sigma_at_1s = None
    for k in range(660_000):
        ux = drive.ux(k * h)
        z = plant.measured()
        plant.step(ux, 0.0, 1.0, h)
        obs.step(ux, 0.0, z[0], z[2], h)
        if k == 200_000:
            sigma_at_1s = obs.sigmas()["Omega_z"]
    assert obs.status in (0, 1) and obs.lost is None
    assert obs.sigmas()["Omega_z"] < 0.7 * sigma_at_1s  # ~1/sqrt(t): 0.55
    assert abs(obs.estimates()["Omega_z"] - 1.0) < 4 * obs.sigmas()["Omega_z"]
