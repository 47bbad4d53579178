"""The resonator's added physics (issue 14, points 4-6): pick-off non-orthogonality,
cross-cubic stiffness, thermomechanical force noise, drive-voltage noise and a
temperature ramp. Each is off by default and then changes nothing; each does what its
equation says; the FMU equals the in-process engine with all of them on.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from fmu_harness import assert_state_round_trip
from scipy.linalg import expm, solve_discrete_lyapunov

from gyro_fmu.selfcal.inprocess import CarrierSimulation
from gyro_fmu.selfcal.loops import LoopSettings
from gyro_fmu.selfcal.noise import NoiseStream
from gyro_fmu.selfcal.resonator import (
    K_B,
    ResonatorModel,
    ResonatorParameters,
    check_resonator,
    discretize,
    force_noise_covariance,
    system_matrices,
)
from gyro_fmu.selfcal.run import run_fmus

H = 25e-6
#: Every new term on (what the FMU test and the state test run).
ALL_ON = dict(beta_x=3e-3, beta_y=-1e-3, k3xy=2e16, k3yx=-3e16, m_modal=1e-11,
              drive_noise=1e-3, temperature_rate=20.0, tc_f=-30e-6, tc_Q=-2e-3,
              thermal_update_steps=300)
OFF = {f.name: f.default for f in dataclasses.fields(ResonatorParameters) if f.name in ALL_ON}
QUIET = LoopSettings(mode=0, excitation_amplitude=0.0)  # loops off, drives at 0 V


def _old_discretize(p, Omega_z, h):
    """discretize() as it was before the new terms (commit 14d2510)."""
    A, B = system_matrices(p, Omega_z)
    n = A.shape[0]
    M = np.zeros((n + 2, n + 2))
    M[:n, :n], M[:n, n:] = A * h, B * h
    E = expm(M)
    Phi, Gamma = E[:n, :n].copy(), E[:n, n:].copy()
    for i, tau in ((0, p.tau_x), (1, p.tau_y)):
        if tau <= 0.0:
            Phi[4 + i] = Phi[i]
            Phi[4 + i] += p.c_ring * p.ring_amplitude * (Phi[6] + Phi[8])
            Gamma[4 + i] = Gamma[i]
    return Phi, Gamma


def _old_run(p, seed, V, Omega_z=0.2):
    """The step as it was (same loop order as the numba kernel), pure Python."""
    Phi, Gamma = _old_discretize(p, Omega_z, H if p.k3x == p.k3y == 0 else H / 8)
    s = np.zeros(10)
    s[6] = s[8] = 1.0
    noise = NoiseStream(p.noise, seed).take(len(V) + 1)[1:]
    out = []
    for k, v in enumerate(V):
        for _ in range(1 if p.k3x == p.k3y == 0 else 4):
            for _half in range(2):
                new = [Gamma[i, 0] * v[0] + Gamma[i, 1] * v[1] for i in range(10)]
                for i in range(10):
                    for j in range(10):
                        new[i] += Phi[i, j] * s[j]
                s = np.array(new)
                if _half == 0 and not p.k3x == p.k3y == 0:
                    s[2] -= p.k3x * s[0] ** 3 * (H / 4)
                    s[3] -= p.k3y * s[1] ** 3 * (H / 4)
                if p.k3x == p.k3y == 0:
                    break
        out.append([p.Px * s[4] + p.Exx * v[0] + p.Exy * v[1] + noise[k, 0],
                    p.Py * s[5] + p.Eyx * v[0] + p.Eyy * v[1] + noise[k, 1]])
    return np.array(out)


@pytest.mark.parametrize("base", [
    ResonatorParameters(noise=1e-3),
    ResonatorParameters(noise=1e-3, phi_x=0.0, ring_amplitude=0.5, k3x=4e17, k3y=-2e17),
], ids=["lags-noise", "zero-lag-ring-cubic"])
def test_every_new_term_off_is_bit_identical_to_the_old_step(base):
    """Off, the new terms leave the step matrices and every output bit for bit as the
    code before them (re-implemented above); each one on changes the output."""
    t = np.arange(120) * H
    V = np.stack([0.6 * np.sin(2 * np.pi * 4000 * t), 0.1 * np.cos(2 * np.pi * 4000.3 * t)], 1)
    for got, want in zip(discretize(base, 0.2, H), _old_discretize(base, 0.2, H), strict=True):
        assert np.array_equal(got, want)
    ref = _old_run(base, 5, V)

    def run(p):
        m = ResonatorModel(p, seed=5)
        return np.array([m.step(v, 0.2, H).copy() for v in V])

    assert np.array_equal(run(base), ref)
    for name, value in ALL_ON.items():
        if name in ("tc_f", "tc_Q", "thermal_update_steps"):
            continue  # act only with a temperature_rate
        changed = dataclasses.replace(base, **{name: value},
                                      **({"tc_f": -30e-6} if name == "temperature_rate" else {}))
        assert not np.array_equal(run(changed), ref), name


def test_pickoff_noise_sequence_is_unchanged_and_independent_of_the_new_stream():
    old = np.random.Generator(np.random.PCG64(11)).standard_normal((4096, 2)) * 2e-3
    assert np.array_equal(NoiseStream(2e-3, 11).take(4096), old)
    p = ResonatorParameters(noise=2e-3, m_modal=1e-10, drive_noise=1e-3)
    m = ResonatorModel(p, seed=11)
    assert np.array_equal(m.noise.take(4095), old[1:])  # the first went to the initial output
    extra = m.extra.take(4096)
    assert abs(np.corrcoef(extra[:, 0], old[:, 0])[0, 1]) < 0.06  # 4 sigma for 4096 pairs


def test_nonorthogonal_pickoffs_sense_cos_beta_own_plus_sin_beta_other():
    """Static deflection by held DC voltages: x = Bx Vx / kxx, y = By Vy / kyy; each
    pick-off reads its sensing axis (through its lag, which passes DC)."""
    p = ResonatorParameters(Q_x=5.0, Q_y=5.0, kxy=0.0, dxy=0.0, alpha_x=0.0, alpha_y=0.0,
                            Exx=0.0, Exy=0.0, Eyx=0.0, Eyy=0.0, beta_x=0.05, beta_y=-0.02)
    m = ResonatorModel(p)
    for _ in range(2000):  # 50 ms, 100 decay times
        out = m.step(np.array([2.0, -3.0]), 0.0, H)
    x, y = p.Bx * 2.0 / p.kxx, p.By * -3.0 / p.kyy
    np.testing.assert_allclose(m.s[:2], [x, y], rtol=1e-9)
    np.testing.assert_allclose(out, [p.Px * (math.cos(0.05) * x + math.sin(0.05) * y),
                                     p.Py * (math.cos(-0.02) * y + math.sin(-0.02) * x)],
                               rtol=1e-9)
    # a zero-lag pick-off reads the same axis at once
    s0 = np.zeros(10)
    s0[:2] = 1e-6, 2e-6
    z = ResonatorModel(dataclasses.replace(p, phi_x=0.0, phi_y=0.0), initial_state=s0).out
    np.testing.assert_allclose(z, [p.Px * (math.cos(0.05) + 2 * math.sin(0.05)) * 1e-6,
                                   p.Py * (2 * math.cos(-0.02) + math.sin(-0.02)) * 1e-6])


def _frequency(x, h, f0=4000.0):
    """Mean frequency of a near-f0 oscillation: the slope of its phase against f0,
    demodulated and averaged over whole f0 periods (10 samples: 2 f0 is nulled).
    Zero crossings would not do: their linear interpolation at 10 samples per cycle
    errs by up to 5e-3 rad, and the error drifts with the sampling phase (mHz)."""
    t = np.arange(len(x)) * h
    z = np.convolve(x * np.exp(-2j * np.pi * f0 * t), np.ones(10) / 10, "valid")
    return f0 + np.polyfit(t[:len(z)], np.unwrap(np.angle(z)), 1)[0] / (2 * np.pi)


@pytest.mark.parametrize("sign", [1, -1], ids=["in-phase", "anti-phase"])
def test_cross_cubic_shifts_the_frequency_as_the_duffing_formula(sign):
    """Equal modes with k3xy = k3yx = k: on the diagonal x = +-y the system is the
    Duffing oscillator x'' + w^2 x +- k x^3 = 0, frequency w +- 3 k a^2 / (8 w) (first
    order in the 1 Hz shift of 4 kHz; the second order is 2.5e-4 Hz)."""
    k, a = 4.2e17, 1e-6
    p = ResonatorParameters(f_y=4000.0, Q_x=1e9, Q_y=1e9, dxy=0.0, kxy=0.0, phi_x=0.0,
                            phi_y=0.0, k3xy=k, k3yx=k)
    sim = CarrierSimulation(p, QUIET, step=H)
    sim.plant.s[:2] = a, sign * a
    rec = sim.run(0.2)
    x = rec["Vpx"] / p.Px
    np.testing.assert_allclose(rec["Vpy"] / p.Py, sign * x, atol=1e-12 * a / 1e-6)
    shift = 3 * k * a**2 / (8 * p.omega_x) / (2 * math.pi)
    assert shift == pytest.approx(1.0, rel=0.01)
    assert _frequency(x, H) - p.f_x == pytest.approx(sign * shift, abs=2e-3)


def test_force_noise_discretization_is_exact_equipartition():
    """The held-step noise covariance makes the discrete stationary covariance the
    continuous one, k_B T / m per velocity and k_B T / m K^-1 in position, to rounding,
    with cross damping, cross stiffness, rotation and pick-off lags on."""
    p = ResonatorParameters(m_modal=1e-9, temperature=350.0, Q_x=300.0, Q_y=250.0,
                            dxy=5.0)
    S = np.array([1, 1, 1 / p.omega_x, 1 / p.omega_x, 1, 1])  # velocities / omega
    Phi = discretize(p, 0.5, H)[0][:6, :6] * S[:, None] / S
    P = solve_discrete_lyapunov(Phi, force_noise_covariance(p, 0.5, H) * np.outer(S, S))
    P /= np.outer(S, S)
    kT_m = K_B * 350.0 / 1e-9
    np.testing.assert_allclose(np.diag(P)[2:4], kT_m, rtol=1e-7)
    K = np.array([[p.kxx, p.kxy], [p.kxy, p.kyy]])
    np.testing.assert_allclose(P[:2, :2], kT_m * np.linalg.inv(K), rtol=1e-7)
    assert abs(P[2, 3]) < 1e-7 * kT_m  # velocities uncorrelated
    assert any("damping indefinite" in s for s in check_resonator(
        dataclasses.replace(p, dxy=p.dyy)))


def test_force_noise_of_a_free_resonator_meets_equipartition_statistically():
    """Drawn noise, 40 s of a free Q = 50 resonator: m w^2 <x^2> = k_B T per mode. The
    estimate of a narrow-band variance over T has relative std sqrt(2 / (T dxx)) = 1.0 %
    per mode (dxx = 503 1/s), 0.7 % for the mean of x and y: 3.5 % is 5 sigma."""
    p = ResonatorParameters(f_y=4100.0, Q_x=50.0, Q_y=50.0 * 4100 / 4000, dxy=0.0, kxy=0.0,
                            phi_x=0.0, phi_y=0.0, m_modal=1e-10)
    sim = CarrierSimulation(p, QUIET, seed=2, step=H)
    sim.run(0.05)  # 12 decay times of the energy
    energy = []
    for _ in range(4):
        rec = sim.run(10.0, record_from=sim.k * H)
        energy.append([np.mean((rec["Vpx"][:-1] / p.Px) ** 2) * p.kxx,
                       np.mean((rec["Vpy"][:-1] / p.Py) ** 2) * p.kyy])
    ratio = np.mean(energy, axis=0) / (K_B * 300.0 / 1e-10)
    assert abs(ratio.mean() - 1) < 0.035, ratio
    assert np.all(np.abs(ratio - 1) < 0.05), ratio


def test_temperature_ramp_moves_the_frequency_by_tc_f_and_the_damping_by_tc_Q():
    """Free oscillation through a ramp of 10 K/s with tc_f = -30e-6: f falls 1.2 Hz/s,
    measured in 50 ms windows of five 10 ms updates (the staircase's mean is the line);
    tc_Q = -0.05 halves Q over the second: the decay is exp(-int dxx(t) / 2 dt)."""
    p = ResonatorParameters(f_y=4100.0, Q_x=1e4, Q_y=1e4, dxy=0.0, kxy=0.0,
                            temperature_rate=10.0, tc_f=-30e-6, tc_Q=-0.05,
                            thermal_update_steps=400)
    sim = CarrierSimulation(p, QUIET, step=H)
    sim.plant.s[0] = 1e-6
    x = sim.run(1.0)["Vpx"][:-1]
    w = round(0.05 / H)
    for t0 in (0.0, 0.5, 0.95):
        i = round(t0 / H)
        f = p.f_x * (1 + p.tc_f * p.temperature_rate * (t0 + 0.025))
        assert _frequency(x[i:i + w], H) == pytest.approx(f, abs=1e-3), t0
    n = round(0.02 / H)  # rms over 80 cycles at the start and at the end
    ratio = math.sqrt(np.mean(x[-n:] ** 2) / np.mean(x[:n] ** 2))
    t = np.linspace(0.01, 0.99, 20001)
    dxx = p.omega_x * (1 - 3e-4 * t) / (p.Q_x * (1 - 0.5 * t))
    assert ratio == pytest.approx(math.exp(-np.trapezoid(dxx, t) / 2), rel=2e-3)
    assert ratio < 0.2  # the ramp matters: without it exp(-0.98 dxx / 2) = 0.54


def test_ramp_chunks_and_restarts_do_not_change_the_run():
    p = ResonatorParameters(noise=1e-4, **ALL_ON)
    a = CarrierSimulation(p, LoopSettings(), seed=3, step=H, Omega_z=0.1).run(0.03)
    sim = CarrierSimulation(p, LoopSettings(), seed=3, step=H, Omega_z=0.1)
    b = np.vstack([sim.run(0.0111, chunk=77).data[:-1], sim.run(0.0189, chunk=1000).data])
    assert np.array_equal(a.data, b)


def test_fmu_equals_in_process_with_every_new_term_on(models_dir):
    res = ResonatorParameters(noise=1e-3, **ALL_ON)
    lo = LoopSettings(mode=1, sideband_index=0.05)
    ref = CarrierSimulation(res, lo, seed=7, step=H, Omega_z=0.3).run(0.05, record_from=0.01)
    fmu = run_fmus(res, lo, 0.05, step=H, Omega_z=0.3, seed=7, record_from=0.01,
                   models_dir=models_dir)
    assert fmu.data.shape == ref.data.shape
    assert np.array_equal(fmu.data, ref.data)
    assert fmu["amplitude"][-1] > 0.1
    off = CarrierSimulation(dataclasses.replace(res, **OFF), lo, seed=7, step=H,
                            Omega_z=0.3).run(0.05, record_from=0.01)
    assert not np.array_equal(off.data, ref.data)


def test_fmu_state_with_the_new_noise_and_ramp_restores_exactly(models_dir):
    """Save, run on, restore: the same bits, the force/drive noise stream and the ramp
    clock included (6000 steps cross a noise block and 20 re-discretizations)."""
    assert_state_round_trip(
        models_dir / "GyroResonator.fmu", {**ALL_ON, "noise": 1e-3, "seed": 5},
        ["Vpx", "Vpy"], lambda t: {"Vx": math.sin(2 * math.pi * 4000 * t), "Vy": 0.0,
                                   "Omega_z": 0.2}, H, 4000, 300)
