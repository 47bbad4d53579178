"""The posterior Cramér-Rao bound for tracking (gyro_fmu.estimation.tracking_bound),
checked against independent computations: the batch CRB of identify.crb_at, Kalman
filters written here, and its monotone behaviour."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gyro_fmu.estimation import tracking_bound as tb
from gyro_fmu.estimation.identify import crb_at, make_record
from gyro_fmu.estimation.observer import GyroStateObserver
from gyro_fmu.model.parameters import PARAMETER_NAMES
from gyro_fmu.model.rate import RateKind, RateProfile
from gyro_fmu.system.scenario import absolute_noise, noise_free_run, scenario
from gyro_fmu.system.tracking import rate_model_for, tracking_bound_for_scenario


@pytest.fixture(scope="module")
def sc40():
    return scenario("default", stop_time=0.04, noise=1e-4)


@pytest.fixture(scope="module")
def std40(sc40):
    n = absolute_noise(sc40)
    return (n.x, n.y)


def test_constant_rate_without_prior_is_the_batch_crb(sc40, std40):
    """Constant rate, no prior on Omega and p, plant known at rest: identify.crb_at (its
    own sensitivity system, m instead of 1/m) at 20 and 40 ms."""
    h = sc40.step
    rate = tb.constant_rate(1.0, h, sc40.n_steps, sigma0=None)
    b = tb.tracking_bound(sc40.params, sc40.the_drive, rate, std40, h, sc40.n_steps,
                          param_prior=False, state_prior=False, t_eval=[0.02, 0.04])
    states = noise_free_run(sc40)
    for e, T in enumerate((0.02, 0.04)):
        n = round(T / h)  # the bound at t_n has used z_0 .. z_{n-1}
        t = np.arange(n) * h
        ux = np.array([sc40.the_drive.ux(v) for v in t])
        rec = make_record(t, ux, 0.0 * ux, states[:n][:, [0, 2]], 1)
        crb = crb_at(sc40.params, 1.0, rec, std40)
        assert b.sigma_Omega[e] == pytest.approx(crb["Omega_z"], rel=0.02)
        for name in PARAMETER_NAMES:
            assert b.sigma_params[name][e] == pytest.approx(crb[name], rel=0.02), name


def _kalman_predicted(F_of, Hm, R, Q, P0, n_steps):
    """P_{k|k-1}, k = 0 .. n_steps, of x_{k+1} = F_k x_k + w, z_k = Hm x_k + v."""
    P = P0.copy()
    out = [P.copy()]
    for k in range(n_steps):
        S = Hm @ P @ Hm.T + R
        K = P @ Hm.T @ np.linalg.inv(S)
        P = (np.eye(P.shape[0]) - K @ Hm) @ P
        F = F_of(k)
        P = F @ P @ F.T + Q
        out.append(P.copy())
    return out


def _toy():
    A = np.array([[0.98, 0.1], [-0.1, 0.97]])
    Bp = np.array([[0.05], [0.02]])
    bom = np.array([0.0, 0.3])
    Hm = np.array([[1.0, 0.0]])

    def step(k, s, om):
        s1 = A @ s + bom * om + np.array([math.sin(0.3 * k), 0.0])
        return s1, A, Bp, bom

    return A, Bp, bom, Hm, step


def test_linear_toy_gauss_markov_equals_the_kalman_filter():
    """Linear system, Gauss-Markov rate sampled every step: the bound is the Kalman
    filter's predicted covariance of Omega (and of the parameter)."""
    A, Bp, bom, Hm, step = _toy()
    n_steps, h, std, bw, sr, sp, ss = 60, 1e-3, 0.5, 20.0, 0.2, 0.7, 0.3
    rate = tb.gauss_markov_rate(h, n_steps, std, bw, knot_step=1)
    ev = [5, 20, 40, 60]
    M = tb.bayesian_information(step, np.zeros(2), 1, rate, Hm, [sr], ev, n_draws=1)
    J0 = np.zeros(M.shape[1:])
    J0[:2, :2] = np.eye(2) / ss**2
    J0[2, 2] = 1.0 / sp**2
    J0[3:, 3:] = rate.info
    rho = math.exp(-2 * math.pi * bw * h)
    F = np.zeros((4, 4))
    F[:2, :2], F[:2, 2], F[:2, 3], F[2, 2], F[3, 3] = A, Bp[:, 0], bom, 1.0, rho
    Q = np.diag([0.0, 0.0, 0.0, std**2 * (1 - rho**2)])
    Ps = _kalman_predicted(lambda k: F, np.hstack([Hm, np.zeros((1, 2))]), np.array([[sr**2]]),
                           Q, np.diag([ss**2, ss**2, sp**2, std**2]), n_steps)
    for e, k in enumerate(ev):
        C = np.linalg.inv(J0 + M[e])
        r = np.zeros(C.shape[0])
        r[3:] = rate.row(k)
        assert r @ C @ r == pytest.approx(Ps[k][3, 3], rel=1e-8)
        assert C[2, 2] == pytest.approx(Ps[k][2, 2], rel=1e-8)


def test_linear_toy_sine_equals_the_kalman_filter_of_its_coefficients():
    """Sine of known frequency: the harmonic oscillator with zero process noise, i.e. a
    Kalman filter of the constant coefficients (c, a, b) with Omega = c + a cos + b sin."""
    A, Bp, bom, Hm, step = _toy()
    n_steps, h, f, sr = 80, 1e-3, 25.0, 0.5
    rate = tb.sine_rate(h, n_steps, f, amplitude=1.0, offset=0.3, phase=0.4, sigma0=2.0)
    ev = [10, 50, 80]
    M = tb.bayesian_information(step, np.zeros(2), 1, rate, Hm, [sr], ev,
                                s0_free=np.zeros(2, bool))
    J0 = np.zeros(M.shape[1:])
    J0[0, 0] = 1.0 / 0.7**2
    J0[1:, 1:] = rate.info
    w = 2 * math.pi * f

    def F_of(k):
        F = np.eye(6)
        F[:2, :2], F[:2, 2] = A, Bp[:, 0]
        F[:2, 3:] = np.outer(bom, [1.0, math.cos(w * k * h), math.sin(w * k * h)])
        return F

    Ps = _kalman_predicted(F_of, np.hstack([Hm, np.zeros((1, 4))]), np.array([[sr**2]]),
                           np.zeros((6, 6)), np.diag([0, 0, 0.49, 4.0, 4.0, 4.0]), n_steps)
    for e, k in enumerate(ev):
        C = np.linalg.inv(J0 + M[e])
        basis = np.array([1.0, math.cos(w * k * h), math.sin(w * k * h)])
        assert rate.row(k) == pytest.approx(basis)
        r = np.concatenate([[0.0], basis])
        assert r @ C @ r == pytest.approx(basis @ Ps[k][3:, 3:] @ basis, rel=1e-8)


def test_gyro_sine_bound_is_the_riccati_along_the_truth():
    """The gyro with a 100 Hz sine: tracking_bound equals a covariance-form Riccati on
    [s, p, c, a, b] written here from held_step along the true trajectory, with the
    observer's priors (rebuilt here from ObserverTuning's documented meaning)."""
    sc = scenario("default", stop_time=0.004, noise=1e-4,
                  rate=RateProfile(RateKind.sine, offset=0.0, amplitude=1.0, frequency=100.0))
    n = absolute_noise(sc)
    std = (n.x, n.y)
    b = tracking_bound_for_scenario(sc, state_prior=False, t_eval=[0.001, 0.004])
    p, g = sc.params, sc.initial_guess
    obs = GyroStateObserver(p)
    th = obs.theta0.copy()
    dmax = max(abs(g["dxx"]), abs(g["dyy"]), abs(g["dxy"]))
    phys = np.array([0.1 * g["kxx"], 0.1 * g["kyy"], 0.1 * abs(g["kxy"]), 0.5 * dmax,
                     0.5 * dmax, 0.5 * dmax, 0.1 / g["m"]])
    P = np.diag([0, 0, 0, 0, *((phys / obs.scale) ** 2), 4.0, 4.0, 4.0])
    Hm = np.zeros((2, 14))
    Hm[0, 0] = Hm[1, 2] = 1.0
    R = np.diag(np.square(std))
    h, w = sc.step, 2 * math.pi * 100.0
    s = np.zeros(4)
    got = {}
    for k in range(sc.n_steps + 1):
        if k in (200, 800):
            basis = np.array([1.0, math.cos(w * k * h), math.sin(w * k * h)])
            got[k] = math.sqrt(basis @ P[11:, 11:] @ basis)
        if k == sc.n_steps:
            break
        K = P @ Hm.T @ np.linalg.inv(Hm @ P @ Hm.T + R)
        P = (np.eye(14) - K @ Hm) @ P
        om = math.sin(w * k * h)
        s, Phi, S = obs.held_step(s, sc.the_drive.ux(k * h), 0.0, h, theta=th, Omega_z=om)
        F = np.eye(14)
        F[:4, :4], F[:4, 4:11] = Phi, S[:, :7]
        F[:4, 11:] = np.outer(S[:, 7], [1.0, math.cos(w * k * h), math.sin(w * k * h)])
        P = F @ P @ F.T
    assert b.sigma_Omega[0] == pytest.approx(got[200], rel=1e-5)
    assert b.sigma_Omega[1] == pytest.approx(got[800], rel=1e-5)


def test_slow_gauss_markov_tends_to_the_constant_rate(sc40, std40):
    """A Gauss-Markov rate of vanishing bandwidth is a constant with the same prior
    (Monte Carlo D-terms included: two draws)."""
    sc = sc40.with_(stop_time=0.005)
    h = sc.step
    gm = tb.gauss_markov_rate(h, sc.n_steps, 0.5, 1e-3, mean=1.0, knot_step=50)
    c = tb.constant_rate(1.0, h, sc.n_steps, sigma0=0.5)
    kw = dict(t_eval=[0.005])
    b_gm = tb.tracking_bound(sc.params, sc.the_drive, gm, std40, h, sc.n_steps, n_draws=2, **kw)
    b_c = tb.tracking_bound(sc.params, sc.the_drive, c, std40, h, sc.n_steps, **kw)
    assert b_gm.n_draws == 2 and b_c.n_draws == 1
    assert b_gm.sigma_Omega[0] == pytest.approx(b_c.sigma_Omega[0], rel=0.02)


def test_more_noise_gives_a_larger_bound(sc40, std40):
    sc = sc40.with_(stop_time=0.005)
    h = sc.step
    rate = tb.sine_rate(h, sc.n_steps, 10.0, 0.5, offset=1.0)
    sig = [tb.tracking_bound(sc.params, sc.the_drive, rate, np.multiply(std40, f), h,
                             sc.n_steps, t_eval=[0.0025, 0.005]).sigma_Omega
           for f in (0.3, 1.0, 3.0)]
    assert np.all(sig[0] < sig[1]) and np.all(sig[1] < sig[2])
    assert sig[2][-1] / sig[0][-1] > 3.0  # ~ the noise ratio 10 where data dominates


def test_faster_rate_process_gives_a_larger_bound(sc40, std40):
    sc = sc40.with_(stop_time=0.004)
    h, n = sc.step, sc.n_steps
    kw = dict(t_eval=[0.004], n_draws=2)
    gm = [tb.tracking_bound(sc.params, sc.the_drive,
                            tb.gauss_markov_rate(h, n, 0.5, bw, mean=1.0, knot_step=40),
                            std40, h, n, **kw).sigma_Omega[0] for bw in (3.0, 30.0, 300.0)]
    assert gm[0] < gm[1] < gm[2] < 0.5
    irw = [tb.tracking_bound(sc.params, sc.the_drive,
                             tb.integrated_random_walk_rate(h, n, q, 2.0, 10.0, mean=1.0,
                                                            knot_step=40),
                             std40, h, n, **kw).sigma_Omega[0] for q in (1e2, 1e4, 1e6)]
    assert irw[0] < irw[1] < irw[2]


def test_rate_model_checks():
    with pytest.raises(ValueError, match="knot_step"):
        tb.gauss_markov_rate(1e-5, 10, 1.0, 1.0, knot_step=0)
    sc = scenario("default", stop_time=0.001, noise=1e-4,
                  rate=RateProfile(RateKind.step, amplitude=1.0, t_start=0.0005))
    with pytest.raises(ValueError, match="no rate model"):
        rate_model_for(sc)
    with pytest.raises(ValueError, match="noise"):
        tracking_bound_for_scenario(sc.with_(noise=0.0, rate=RateProfile()))
    r = tb.constant_rate(1.0, 1e-5, 100)
    with pytest.raises(ValueError, match="samples"):
        tb.tracking_bound(sc.params, sc.the_drive, r, (1e-9, 1e-9), 1e-5, 50)
