"""Fast tests of gyro_fmu.estimation.observer: exactness, convergence, consistency, bad input."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from gyro_fmu.estimation.observer import GyroStateObserver, ObserverTuning
from gyro_fmu.model.drive import TwoToneDrive
from gyro_fmu.model.dynamics import HeldInputStepper, held_input_maps
from gyro_fmu.model.measurement import UNKNOWNS
from gyro_fmu.model.parameters import (
    PARAMETER_NAMES,
    PRESET_DRIVE_AMPLITUDE,
    GyroParameters,
    preset,
)
from gyro_fmu.model.rate import RateKind, RateProfile

H = 5e-6
SINE = RateProfile(RateKind.sine, offset=0.0, amplitude=1.0, frequency=100.0)
CONST = RateProfile(RateKind.constant, offset=1.0)


def guess(p: GyroParameters) -> GyroParameters:
    return GyroParameters(
        kxx=p.kxx * 1.05, kyy=p.kyy * 0.95, kxy=p.kxy * 1.05, dxx=p.dxx * 1.2,
        dyy=p.dyy * 1.2 if p.dyy else 2.0, dxy=p.dxy * 0.8, m=p.m * 1.05,
    )


def simulate(name: str, rate: RateProfile, n: int, pair: int = 1,
             hs: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Truth (ux, measured pair, h) over n held-input steps from rest."""
    p = preset(name)
    amp = PRESET_DRIVE_AMPLITUDE[name]
    drive = TwoToneDrive(A1=amp, A2=amp)
    hs = np.full(n, H) if hs is None else hs
    stepper = HeldInputStepper(p)
    s = np.zeros(4)
    t = 0.0
    ux = np.empty(n)
    z = np.empty((n, 2))
    for k in range(n):
        ux[k] = drive.ux(t)
        z[k] = s[[0, 2]] if pair == 1 else s[[1, 3]]
        s = stepper.step(s, ux[k], 0.0, rate.Omega_z(t), hs[k])
        t += hs[k]
    return ux, z, hs


def run(obs: GyroStateObserver, ux, z, hs, k0: int = 0, k1: int | None = None) -> None:
    for k in range(k0, len(ux) if k1 is None else k1):
        obs.step(float(ux[k]), 0.0, float(z[k, 0]), float(z[k, 1]), float(hs[k]))


def rel_errors(obs: GyroStateObserver, p: GyroParameters) -> dict[str, float]:
    e = obs.estimates()
    return {
        nm: abs(e[nm] - getattr(p, nm)) / (abs(getattr(p, nm)) if getattr(p, nm) else 10.0)
        for nm in PARAMETER_NAMES
    }


# ---------------------------------------------------------------- exact discretization
@pytest.mark.parametrize("name", ["park-horowitz", "patent-table1-corrected"])
@pytest.mark.parametrize("h", [5e-6, 2e-4])  # 2e-4 s exercises the sub-step split
def test_held_step_equals_plant_and_sensitivities_are_exact(name: str, h: float) -> None:
    p = preset(name)
    obs = GyroStateObserver(p)
    Om, ux, uy = 0.7, 0.3, -0.2
    s = np.array([1e-8, 2e-4, 3e-9, -1e-4])

    s1, Phi, S = obs.held_step(s, ux, uy, h, obs.theta0, Om)
    Phi_ref, Gam_ref = held_input_maps(p, Om, h)
    ref = Phi_ref @ s + Gam_ref @ np.array([ux, uy])
    np.testing.assert_allclose(s1, ref, rtol=1e-11, atol=1e-13 * np.abs(ref).max())
    np.testing.assert_allclose(Phi, Phi_ref, rtol=1e-9, atol=1e-12 * np.abs(Phi_ref).max())
    for i in range(8):  # central differences in each (scaled) parameter and Omega
        eps = 1e-4
        d = np.zeros(7)
        if i < 7:
            d[i] = eps
        th_p = obs.theta0 + obs.scale * d
        th_m = obs.theta0 - obs.scale * d
        om_p, om_m = (Om + eps, Om - eps) if i == 7 else (Om, Om)
        fd = (obs.held_step(s, ux, uy, h, th_p, om_p)[0]
              - obs.held_step(s, ux, uy, h, th_m, om_m)[0]) / (2 * eps)
        np.testing.assert_allclose(S[:, i], fd, rtol=0, atol=1e-5 * np.abs(S[:, i]).max())


def test_step_is_update_then_predict() -> None:
    """step() (one compiled call) equals update() then predict(), bit for bit."""
    name = "park-horowitz"
    ux, z, hs = simulate(name, CONST, 300)
    a = GyroStateObserver(guess(preset(name)))
    b = GyroStateObserver(guess(preset(name)))
    for k in range(len(ux)):
        a.step(float(ux[k]), 0.0, float(z[k, 0]), float(z[k, 1]), float(hs[k]))
        b.update(float(z[k, 0]), float(z[k, 1]), float(hs[k]))
        b.predict(float(ux[k]), 0.0, float(hs[k]))
    assert a.output_row() == b.output_row()
    np.testing.assert_array_equal(a.P, b.P)
    assert a.t == b.t


# ---------------------------------------------------------------- convergence
def test_converges_on_patent_case_with_sine_rate_positions() -> None:
    name = "patent-table1-corrected"
    p = preset(name)
    n = 1200  # 6 ms
    ux, z, _hs = simulate(name, SINE, n)
    obs = GyroStateObserver(guess(p))
    om_err = []
    for k in range(n):
        obs.step(float(ux[k]), 0.0, float(z[k, 0]), float(z[k, 1]), H)
        if k >= n - 200:  # last 1 ms; estimate is for t_{k+1}
            om_err.append(obs.estimates()["Omega_z"] - SINE.Omega_z((k + 1) * H))
    err = rel_errors(obs, p)
    assert max(err.values()) < 0.01, err
    assert math.sqrt(np.mean(np.square(om_err))) < 0.01


def test_converges_with_velocities_on_park_horowitz() -> None:
    name = "park-horowitz"
    p = preset(name)
    ux, z, hs = simulate(name, CONST, 2000, pair=2)
    obs = GyroStateObserver(guess(p), measured_pair=2)
    run(obs, ux, z, hs)
    err = rel_errors(obs, p)
    assert max(err.values()) < 0.01, err
    assert abs(obs.estimates()["Omega_z"] - 1.0) < 0.01


def test_converges_with_variable_step() -> None:
    name = "park-horowitz"
    p = preset(name)
    rng = np.random.default_rng(1)
    hs = rng.uniform(3e-6, 7e-6, 2000)
    ux, z, hs = simulate(name, CONST, 2000, hs=hs)
    obs = GyroStateObserver(guess(p))
    run(obs, ux, z, hs)
    assert max(rel_errors(obs, p).values()) < 0.01
    assert abs(obs.estimates()["Omega_z"] - 1.0) < 0.01


def test_no_update_without_information_does_not_move_parameters() -> None:
    """At rest with no drive there is nothing to learn: the guess must stay put."""
    p = preset("park-horowitz")
    obs = GyroStateObserver(p, Omega_z_0=0.3)
    for _ in range(200):
        obs.step(0.0, 0.0, 0.0, 0.0, H)
    e = obs.estimates()
    for nm in PARAMETER_NAMES:
        assert e[nm] == pytest.approx(getattr(p, nm), rel=1e-12)
    assert e["Omega_z"] == pytest.approx(0.3, abs=1e-9)


# ---------------------------------------------------------------- consistency
def test_sigmas_are_consistent_with_errors_under_noise() -> None:
    """Pooled RMS(err / sigma) over seeds within a factor 3 of 1 (noise 1e-4 of peak).

    A parameter error drifts slowly, so each seed gives about one independent sample:
    8 seeds (measured 0.76-1.31 for all unknowns; 4 seeds once gave m 0.31 by chance).
    """
    name = "park-horowitz"
    p = preset(name)
    n = 4000  # 20 ms
    ux, z0, _hs = simulate(name, CONST, n)
    peak = np.abs(z0).max(axis=0)
    truth = np.array([1.0] + [getattr(p, nm) for nm in PARAMETER_NAMES])
    ratios = []
    for seed in range(8):
        rng = np.random.default_rng(seed)
        z = z0 + rng.standard_normal(z0.shape) * 1e-4 * peak
        obs = GyroStateObserver(guess(p), tuning=ObserverTuning(noise_rel=1e-4, rate_model=3,
                                                              q_Omega=1e6))
        for k in range(n):
            obs.step(float(ux[k]), 0.0, float(z[k, 0]), float(z[k, 1]), H)
            if k >= n - 1000 and k % 50 == 0:
                e, s = obs.estimates(), obs.sigmas()
                est = np.array([e[nm] for nm in UNKNOWNS])
                sig = np.array([s[nm] for nm in UNKNOWNS])
                assert np.all(np.isfinite(est)) and np.all(sig > 0)
                ratios.append((est - truth) / sig)
    z_rms = np.sqrt(np.mean(np.square(ratios), axis=0))
    assert np.all(z_rms > 1 / 3) and np.all(z_rms < 3), dict(zip(UNKNOWNS, z_rms, strict=True))


def test_sigmas_shrink_and_interface_keys() -> None:
    name = "park-horowitz"
    p = preset(name)
    ux, z, hs = simulate(name, CONST, 400)
    obs = GyroStateObserver(guess(p))
    s0 = obs.sigmas()
    assert tuple(obs.estimates()) == UNKNOWNS
    assert tuple(s0) == UNKNOWNS
    run(obs, ux, z, hs)
    s1 = obs.sigmas()
    for nm in UNKNOWNS:
        assert 0.0 < s1[nm] < s0[nm], nm


# ---------------------------------------------------------------- state save / restore
@pytest.mark.parametrize("rate_model", [0, 4])
def test_get_set_state_roundtrip_is_exact_and_json_serializable(rate_model) -> None:
    """... with rate_model 4's moving bank: its scale travels with the state."""
    name = "patent-table1-corrected"
    p = preset(name)
    ux, z, hs = simulate(name, SINE, 600)
    a = GyroStateObserver(guess(p), tuning=ObserverTuning(noise_rel=1e-5, rate_model=rate_model))
    run(a, ux, z, hs, 0, 300)
    assert (a._c.rate_scale != 0.0) == (rate_model == 4)
    snap = json.loads(json.dumps(a.get_state()))
    run(a, ux, z, hs, 300, 600)
    b = GyroStateObserver(preset("park-horowitz"), measured_pair=2)  # different on purpose
    b.set_state(snap)
    run(b, ux, z, hs, 300, 600)
    assert b.estimates() == a.estimates()
    assert b.sigmas() == a.sigmas()
    np.testing.assert_array_equal(b.state_estimate(), a.state_estimate())


# ---------------------------------------------------------------- bad input
@pytest.mark.parametrize("pair", [0, 3, True, "1"])
def test_bad_measured_pair(pair) -> None:
    with pytest.raises(ValueError, match="measured_pair"):
        GyroStateObserver(preset(), measured_pair=pair)


def test_bad_initial_and_tuning() -> None:
    with pytest.raises(ValueError, match="m=0"):
        GyroStateObserver(preset().with_overrides(m=0.0))
    with pytest.raises(ValueError, match="positive definite"):
        GyroStateObserver(preset("patent-table1"))
    with pytest.raises(ValueError, match="Omega_z_0"):
        GyroStateObserver(preset(), Omega_z_0=math.nan)
    with pytest.raises(ValueError, match="omega_order"):
        ObserverTuning(omega_order=4)
    with pytest.raises(ValueError, match="noise_rel"):
        ObserverTuning(noise_rel=-1.0)
    with pytest.raises(ValueError, match="noise_rel"):
        ObserverTuning(noise_rel=0.0)
    with pytest.raises(ValueError, match="sigma0_d_rel"):
        ObserverTuning(sigma0_d_rel=0.0)
    with pytest.raises(ValueError, match="version"):
        GyroStateObserver(preset()).set_state({"xhat": []})


def test_bad_step_arguments() -> None:
    obs = GyroStateObserver(preset())
    with pytest.raises(ValueError, match="h=0"):
        obs.step(0.0, 0.0, 0.0, 0.0, 0.0)
    with pytest.raises(ValueError, match="h=nan"):
        obs.step(0.0, 0.0, 0.0, 0.0, math.nan)
    with pytest.raises(ValueError, match="non-finite"):
        obs.step(0.0, 0.0, math.inf, 0.0, H)
