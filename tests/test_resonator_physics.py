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
from scipy.linalg import solve_discrete_lyapunov

from gyro_fmu.model.loops import LoopSettings
from gyro_fmu.model.resonator import (
    K_B,
    ResonatorModel,
    ResonatorParameters,
    check_resonator,
    discretize,
    force_noise_covariance,
    system_matrices,
)
from gyro_fmu.selfcal.inprocess import CarrierSimulation
from gyro_fmu.selfcal.run import run_fmus

H = 25e-6
#: Every new term on (what the FMU test and the state test run).
ALL_ON = dict(beta_x=3e-3, beta_y=-1e-3, k3xy=2e16, k3yx=-3e16, m_modal=1e-11,
              drive_noise=1e-3, temperature_rate=20.0, tc_f=-30e-6, tc_Q=-2e-3,
              thermal_update_steps=300)
OFF = {f.name: f.default for f in dataclasses.fields(ResonatorParameters) if f.name in ALL_ON}
QUIET = LoopSettings(mode=0, excitation_amplitude=0.0)  # loops off, drives at 0 V


#: Relative difference allowed between the core's step and 0.3.0's (tests/oracle_selfcal):
#: the step matrices come from two matrix exponentials, each within 1e-14 of a 40-digit
#: one (the core measured in test_the_step_matrices_are_the_exact_exponential: 2e-15 at
#: 4 kHz, 4e-15 at 21 kHz; scipy 4e-16);
#: 120 open-loop steps keep that, 1e-12 leaves room for the lightly damped growth.
ORACLE_RTOL = 1e-12


def _drive(n):
    t = np.arange(n) * H
    return np.stack([0.6 * np.sin(2 * np.pi * 4000 * t), 0.1 * np.cos(2 * np.pi * 4000.3 * t)], 1)


@pytest.mark.parametrize("base", [
    ResonatorParameters(),
    ResonatorParameters(phi_x=0.0, ring_amplitude=0.5, k3x=4e17, k3y=-2e17, beta_x=3e-3,
                        k3xy=2e16, k3yx=-3e16),
], ids=["lags", "zero-lag-ring-cubic"])
def test_the_step_equals_the_numba_oracle_and_every_term_acts(base):
    """Noise-free, the core's resonator follows 0.3.0's numba one within ORACLE_RTOL over
    120 held steps at 0.2 rad/s; each added term, switched on, changes the output."""
    from oracle_selfcal import resonator as oracle

    V = _drive(120)

    def run(p, module):
        known = {f.name for f in dataclasses.fields(module.ResonatorParameters)}  # the oracle
        # predates the warm-up and the sensor (left at their defaults here)
        m = module.ResonatorModel(module.ResonatorParameters(
            **{k: v for k, v in dataclasses.asdict(p).items() if k in known}), seed=5)
        return np.array([m.step(v, 0.2, H).copy() for v in V])

    ref = run(base, oracle)
    got = run(base, __import__("gyro_fmu.model.resonator", fromlist=["x"]))
    np.testing.assert_allclose(got, ref, rtol=0, atol=ORACLE_RTOL * np.abs(ref).max())
    for name, value in ALL_ON.items():
        if name in ("tc_f", "tc_Q", "thermal_update_steps") or getattr(base, name) != 0.0:
            continue  # act only with a temperature_rate, or already on
        changed = dataclasses.replace(base, **{name: value},
                                      **({"tc_f": -30e-6} if name == "temperature_rate" else {}))
        m = ResonatorModel(changed, seed=5)
        assert not np.array_equal(np.array([m.step(v, 0.2, H).copy() for v in V]), got), name


def test_the_step_matrices_are_the_exact_exponential():
    """Phi and Gamma (Van Loan, Pade 13 in the core) against a 40-digit exponential."""
    mp = pytest.importorskip("mpmath")
    mp.mp.dps = 40
    for p, Omega_z in ((ResonatorParameters(), 0.0), (ResonatorParameters(), 0.3),
                       (ResonatorParameters(f_x=21e3, f_y=21.01e3, Q_x=3e3, Q_y=4e3), 1.0)):
        A, B = system_matrices(p, Omega_z)
        M = np.zeros((12, 12))
        M[:10, :10], M[:10, 10:] = A * H, B * H
        exact = np.array(mp.expm(mp.matrix(M.tolist())).tolist(), dtype=float)
        S = np.ones(12)
        S[2:4] = 1 / p.omega_x  # compared with velocities in units of omega_x (balanced)
        exact = exact * S[:, None] / S
        Phi, Gamma = (m * S[:10, None] / S[None, c] for m, c in zip(
            discretize(p, Omega_z, H), (slice(0, 10), slice(10, 12)), strict=True))
        assert np.abs(Phi - exact[:10, :10]).max() < 1e-14 * np.abs(exact[:10, :10]).max()
        assert np.abs(Gamma - exact[:10, 10:]).max() < 1e-14 * np.abs(exact[:10, 10:]).max()


def test_pickoff_noise_is_seeded_white_and_its_own_stream():
    """At rest with no drive the pick-offs read their noise alone: seeded (same seed, same
    samples), zero-mean with the given std (4096 samples: 5 sigma bounds), white (lag-1
    correlation), and the force/drive generator does not change it."""
    quiet = dict(Exx=0.0, Exy=0.0, Eyx=0.0, Eyy=0.0)
    p = ResonatorParameters(noise=2e-3, **quiet)

    def samples(p, seed):
        m = ResonatorModel(p, seed=seed)
        return np.array([m.step(np.zeros(2), 0.0, H).copy() for _ in range(4096)])

    a = samples(p, 11)
    assert np.array_equal(a, samples(p, 11)) and not np.array_equal(a, samples(p, 12))
    assert np.all(np.abs(a.mean(0)) < 5 * 2e-3 / 64) and np.all(np.abs(a.std(0) / 2e-3 - 1) < 0.06)
    assert abs(np.corrcoef(a[:-1, 0], a[1:, 0])[0, 1]) < 5 / 64
    # drive noise on a resonator that cannot move (no forcer reaches it: alpha = 0 and
    # the ring and pick-offs at rest) leaves the pick-off samples as they were
    still = dataclasses.replace(p, drive_noise=1e-3, Bx=1e-300, By=1e-300)
    assert np.allclose(samples(still, 11), a, rtol=0, atol=1e-12)


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


@pytest.mark.parametrize("name", ["noise", "drive_noise"])
def test_a_noise_of_no_electronics_is_refused_by_name(name):
    """A pick-off or drive noise beyond GYRO_RES_NOISE_MAX (1 kV per sample on carriers of
    about 1 V) is refused naming it: the CLI fuzzer's `selfcal --noise 1e300` ran the
    loops into NaNs and refused with words about the PLL (or, under load, escaped as
    numpy's LinAlgError)."""
    said = check_resonator(ResonatorParameters(**{name: 1e300}))
    assert any(s.startswith(f"{name}=1e+300 V per sample must lie in [0, 1000] V")
               for s in said), said
    assert check_resonator(ResonatorParameters(**{name: 1e3})) == []
