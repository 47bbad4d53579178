"""The observer's adaptive rate model (observer_rate): it finds how fast the rate moves.

Default tuning throughout (rate_model 0, the noise not told: estimated from the
innovations), on a gyro that is no preset, data from the project's plant with white
noise of std = noise x each signal's peak. Tolerances are the issue's targets (2x the
Cramer-Rao bound for a constant rate, 3 % RMS for the patent's 100 Hz sine) measured
with margin on these seeds; docs/observer-rate-model.md has the full tables.
"""

from __future__ import annotations

import ctypes
import math

import numpy as np
import pytest

from gyro_fmu.estimation.observer import GyroStateObserver, ObserverTuning, rate_models
from gyro_fmu.model.parameters import GyroParameters, preset
from gyro_fmu.model.plant import GyroPlantModel
from gyro_fmu.model.rate import RateKind, RateProfile
from gyro_fmu.system.scenario import absolute_noise, scenario

FACTORS = {"kxx": 1.07, "kyy": 0.94, "kxy": 1.25, "dxx": 0.85, "dyy": 1.15, "dxy": 0.9,
           "m": 1.03}
_DP = ctypes.POINTER(ctypes.c_double)
H = 5e-6


def _run(profile: RateProfile, noise: float, n: int, seed: int = 0,
         with_constant: bool = False, **tuning):
    base = scenario("default").params
    sc = scenario("default", overrides={k: getattr(base, k) * f for k, f in FACTORS.items()},
                  noise=noise, seed=seed, rate=profile, stop_time=n * H)
    plant = GyroPlantModel(sc.params, absolute_noise(sc), seed)
    obs = GyroStateObserver(GyroParameters(**sc.initial_guess), 0.0, 1,
                            ObserverTuning(**tuning))
    om, truth, sig, p, pc = (np.empty(n) for _ in range(5))
    for k in range(n):
        ux, Om = sc.the_drive.ux(k * H), profile.Omega_z(k * H)
        z = plant.measured()
        plant.step(ux, 0.0, Om, H)
        obs.step(ux, 0.0, z[0], z[2], H)
        om[k], sig[k] = obs.estimates()["Omega_z"], obs.sigmas()["Omega_z"]
        truth[k] = profile.Omega_z((k + 1) * H)
        probabilities = obs.rate_probabilities()
        p[k], pc[k] = probabilities["agile"], probabilities["constant"]
    return (om, truth, sig, p, obs, pc) if with_constant else (om, truth, sig, p, obs)


def test_a_constant_rate_is_found_constant_and_estimated_as_well_as_by_the_constant_model():
    """Noise 1e-4, 80 ms (the issue's deadline), 3 seeds: P(constant) > 0.9, the error
    within 3 sigmas, and the RMS error within 1.25x that of the exactly-constant model on
    the same data (8 seeds: 7.15e-3 against 7.13e-3 rad/s, the bound 5.44e-3)."""
    const = RateProfile(RateKind.constant, offset=1.0)
    e_adapt, e_const = [], []
    for seed in range(3):
        om, _, sig, _, obs = _run(const, 1e-4, 16000, seed)
        assert obs.rate_probabilities()["constant"] > 0.9, obs.rate_probabilities()
        assert abs(om[-1] - 1.0) <= 3 * sig[-1]
        e_adapt.append(om[-1] - 1.0)
        om1, *_ = _run(const, 1e-4, 16000, seed, rate_model=1)
        e_const.append(om1[-1] - 1.0)
    ratio = math.sqrt(np.mean(np.square(e_adapt)) / np.mean(np.square(e_const)))
    assert ratio <= 1.25, (e_adapt, e_const)


def test_the_patents_100_hz_sine_is_tracked_at_default_settings():
    """sin(2 pi 100 t), noise 1e-5, 60 ms: RMS error over 40-60 ms below 3 % of the peak
    (the issue measured 4.2-5.3 % with the former default q_Omega 1e9), the agile model
    chosen, the error within 3 sigmas RMS."""
    om, truth, sig, p, _ = _run(RateProfile(RateKind.sine, offset=0.0, amplitude=1.0,
                                            frequency=100.0), 1e-5, 12000)
    w = slice(8000, 12000)
    rms = math.sqrt(np.mean((om[w] - truth[w]) ** 2))
    assert rms < 0.03, rms
    assert p[-1] > 0.9
    assert math.sqrt(np.mean(((om[w] - truth[w]) / sig[w]) ** 2)) < 3.0


def test_a_rate_that_starts_moving_is_followed_within_milliseconds():
    """Constant 1 rad/s, then a 100 Hz sine of 1 rad/s from 30 ms (noise 1e-5): the
    constant model is left within 2 ms (the rough one takes over first), the agile model
    holds the rate within 5 ms (measured 2-5 ms), and the error is back below 5 % RMS
    over 40-50 ms."""
    profile = RateProfile(RateKind.sine, offset=1.0, amplitude=1.0, frequency=100.0,
                          t_start=0.03)
    om, truth, _, p, _, pc = _run(profile, 1e-5, 10000, with_constant=True)
    assert p[5000] < 0.1  # 25 ms: constant
    assert pc[6400] < 0.1, pc[6000:6400:50]  # 32 ms
    assert p[7000] > 0.9, p[6000:7000:50]  # 35 ms
    w = slice(8000, 10000)
    assert math.sqrt(np.mean((om[w] - truth[w]) ** 2)) < 0.05


def _detector_delay(sc, profile: RateProfile, t_step: float, n: int) -> float:
    """The delay of an ideal change detector that knows the gyro, its state, the noise and
    the step: time after t_step until the expected log-likelihood ratio of the stepped
    against the unstepped noise-free trajectories, sum of ((dx/sx)^2 + (dy/sy)^2) / 2,
    reaches 5^2 / 2, the evidence of a 5-sigma shift."""
    noise = absolute_noise(sc)
    stepped, still = GyroPlantModel(sc.params), GyroPlantModel(sc.params)
    llr = 0.0
    for k in range(n):
        t = k * H
        if t >= t_step:
            d = stepped.s - still.s
            llr += 0.5 * ((d[0] / noise.x) ** 2 + (d[2] / noise.y) ** 2)
            if llr >= 12.5:
                return t + H - t_step
        ux = sc.the_drive.ux(t)
        stepped.step(ux, 0.0, profile.Omega_z(t), H)
        still.step(ux, 0.0, profile.offset, H)
    return math.inf


def test_after_a_step_the_estimate_is_blind_about_as_long_as_an_ideal_detector():
    """A rate step 1 -> 2 rad/s at 30 ms, noise 1e-5 and 1e-4, 2 seeds each: the time with
    the error beyond 5 sigma (status ignored: counted as 0) is on average at most 1.5x
    the delay of an ideal change detector that knows everything but the data. Measured:
    0.105, 0.125 ms against 0.080 ms at 1e-5; 0.29, 0.23 ms against 0.235 ms at 1e-4;
    1.19x pooled, 1.56x the worst run. Over the 16 random gyros of
    benchmarks/observer_families.py: 0.85-1.08x on average, 1.19x at worst."""
    t_step, n = 0.03, 8000
    profile = RateProfile(RateKind.step, offset=1.0, amplitude=1.0, t_start=t_step)
    t = (np.arange(n) + 1) * H
    base = scenario("default").params
    blind, delay = [], []
    for noise, seed in ((1e-5, 0), (1e-5, 2), (1e-4, 1), (1e-4, 3)):
        om, truth, sig, _, _ = _run(profile, noise, n, seed)
        blind.append(float(np.sum((t >= t_step) & (np.abs(om - truth) > 5 * sig))) * H)
        sc = scenario("default", overrides={k: getattr(base, k) * f for k, f in FACTORS.items()},
                      noise=noise, seed=seed, rate=profile, stop_time=n * H)
        delay.append(_detector_delay(sc, profile, t_step, n))
        assert abs(om[-1] - 2.0) <= 3 * sig[-1]
    assert max(delay) < 0.001
    assert sum(blind) <= 1.5 * sum(delay), (blind, delay)


class _GaussMarkov:
    """Omega_z = 1 + a first-order Gauss-Markov process (0.5 rad/s, 10 Hz), exact per step."""

    def __init__(self, seed: int, n: int) -> None:
        rng = np.random.default_rng(1000 + seed)
        rho = math.exp(-2 * math.pi * 10.0 * H)
        x = np.empty(n + 2)
        x[0] = 0.5 * rng.standard_normal()
        for k in range(n + 1):
            x[k + 1] = rho * x[k] + 0.5 * math.sqrt(1 - rho**2) * rng.standard_normal()
        self.values = 1.0 + x

    def Omega_z(self, t: float) -> float:
        return float(self.values[round(t / H)])


def test_a_wandering_rate_is_followed_and_its_sigma_stays_honest():
    """A Gauss-Markov rate (no smooth derivative), noise 1e-5, 60 ms: the rough model is
    chosen and error/sigma RMS over 40-60 ms stays below 2 (measured 1.28-1.39 over
    80-100 ms). Without the rough model the three smooth ones gave 6.8-7.7 with status 0."""
    n = 12000
    om, truth, sig, _, obs = _run(_GaussMarkov(0, n), 1e-5, n)
    w = slice(8000, n)
    assert obs.rate_probabilities()["rough"] > 0.9, obs.rate_probabilities()
    assert math.sqrt(np.mean(((om[w] - truth[w]) / sig[w]) ** 2)) < 2.0


def _core_filters(xs, Ps, mu, Pi):
    """An adaptive observer whose seven filters, probabilities and Pi are these."""
    obs = GyroStateObserver(preset("park-horowitz"), tuning=ObserverTuning())
    obs.xs[:], obs.Ps[:], obs.mu[:] = xs, Ps, mu
    M = len(mu)
    np.ctypeslib.as_array(obs._c.Pi)[:M, :M] = Pi
    return obs


@pytest.mark.parametrize("switching", ["general", "uniform", "uniform, one model likely"])
def test_mixture_and_mixing_equal_their_definitions(switching: str):
    """The core's combine: mean and covariance of a Gaussian mixture (with the spread of
    the means); mix: each filter restarted from the mixture weighted by mu_i Pi[i, j] /
    c_j, by the general sum for any Pi and by the one-mixture form for the uniform
    switching the observer builds (gyro_observer_imm.c); identical filters mix to
    themselves."""
    rng = np.random.default_rng(0)
    M, n = 7, 14
    xs = rng.standard_normal((M, n))
    A = rng.standard_normal((M, n, n))
    Ps = np.einsum("mij,mkj->mik", A, A)
    w = rng.dirichlet(np.ones(M))
    mu = rng.dirichlet(np.ones(M))
    if switching == "general":
        Pi = rng.dirichlet(np.ones(M), size=M)  # rows sum to 1
        Pi[0, 3] = 0.0  # a switch that cannot happen
        Pi[0] /= Pi[0].sum()
    else:  # as obs_set_rates builds it: 1 - sw on the diagonal, sw / (M - 1) off it
        sw = 0.3 if switching == "uniform" else 1e-4
        Pi = np.full((M, M), sw / (M - 1))
        np.fill_diagonal(Pi, 1.0 - sw)
        if switching != "uniform":
            mu = np.full(M, 1e-12)
            mu[2] = 1.0 - mu.sum() + 1e-12
    obs = _core_filters(xs, Ps, mu, Pi)
    x, P = np.empty(n), np.zeros((14, 14))
    obs._lib.gyro_observer_combine(obs._ref, w.ctypes.data_as(_DP), x.ctypes.data_as(_DP),
                                   P.ctypes.data_as(_DP))
    mean = w @ xs
    cov = sum(w[j] * (Ps[j] + np.outer(xs[j] - mean, xs[j] - mean)) for j in range(M))
    np.testing.assert_allclose(x, mean, rtol=1e-13)
    np.testing.assert_allclose(P, cov, rtol=1e-12, atol=1e-13)
    obs._lib.gyro_observer_mix(obs._ref)
    c = Pi.T @ mu
    np.testing.assert_allclose(obs.c, c, rtol=1e-15)
    for j in range(M):
        wj = Pi[:, j] * mu / c[j]
        m = wj @ xs
        np.testing.assert_allclose(obs.xs[j], m, rtol=1e-12, atol=1e-14)
        cj = sum(wj[i] * (Ps[i] + np.outer(xs[i] - m, xs[i] - m)) for i in range(M))
        np.testing.assert_allclose(obs.Ps[j], cj, rtol=1e-11, atol=1e-13)
    same = _core_filters(np.tile(xs[0], (M, 1)), np.tile(Ps[0], (M, 1, 1)), mu, Pi)
    same._lib.gyro_observer_mix(same._ref)
    np.testing.assert_allclose(same.xs, np.tile(xs[0], (M, 1)), rtol=1e-14)
    np.testing.assert_allclose(same.Ps, np.tile(Ps[0], (M, 1, 1)), rtol=1e-13)


#: The rough and slow models of the adaptive set follow rate_bandwidth divided by this.
SLOW_FRACTION = 10.0


def intensity(order: int, span: float, bandwidth: float) -> float:
    """The sizing rule of observer_rate's docstring, written independently of the core."""
    w = 2.0 * math.pi * bandwidth
    return span * span * w ** (2 * order - 1) / (2.0 * math.pi)


def test_the_rate_processes_and_their_switching():
    """Transitions and noise of the seven models over h (constant, rough, slow, agile,
    then rough at 3, 10 and 100 times its intensity); rows of Pi sum to 1; the mean time
    in a model is rate_dwell."""
    tun = ObserverTuning()
    Fr, Qr, Pi = rate_models(tun, H)
    assert Fr.shape == Qr.shape == (7, 3, 3)
    for j, grade in zip((4, 5, 6), (3.0, 10.0, 100.0), strict=True):
        np.testing.assert_array_equal(Fr[j], np.diag([1.0, 0.0, 0.0]))
        assert Qr[j][0, 0] == pytest.approx(grade * Qr[1][0, 0], rel=1e-14)
        assert not Qr[j][1:].any()
    np.testing.assert_array_equal(Fr[0], np.diag([1.0, 0.0, 0.0]))  # constant
    assert not Qr[0].any()
    slow = tun.rate_bandwidth / SLOW_FRACTION
    np.testing.assert_array_equal(Fr[1], np.diag([1.0, 0.0, 0.0]))  # rough: random walk
    assert Qr[1][0, 0] == pytest.approx(intensity(1, tun.rate_span, slow) * H, rel=1e-14)
    assert Qr[1][0, 0] == pytest.approx(tun.rate_span**2 * slow * H, rel=1e-14)
    np.testing.assert_allclose(Fr[2], [[1, H, 0], [0, 1, 0], [0, 0, 0]])  # slow: order 2
    q2 = intensity(2, tun.rate_span, slow)
    np.testing.assert_allclose(Qr[2][:2, :2], q2 * np.array([[H**3 / 3, H**2 / 2],
                                                            [H**2 / 2, H]]), rtol=1e-14)
    q3 = intensity(3, tun.rate_span, tun.rate_bandwidth)
    assert Qr[3][2, 2] == pytest.approx(q3 * H, rel=1e-14)
    np.testing.assert_allclose(Pi.sum(axis=1), 1.0, rtol=1e-15)
    assert 1.0 - Pi[0, 0] == pytest.approx(H / tun.rate_dwell, rel=1e-5)
    # 150 Hz at 1 rad/s on the 3rd derivative: 1 * (2 pi 150)^5 / (2 pi)
    assert q3 == pytest.approx((2 * math.pi * 150.0) ** 5 / (2 * math.pi), rel=1e-12)


@pytest.mark.parametrize("rate_model, n, names", [
    (0, 14, ("constant", "rough", "slow", "agile", "rough x3", "rough x10", "rough x100")),
    (1, 12, ("constant",)),
    (2, 14, ("tracking",)), (3, 13, ("expert",)),
    (4, 14, ("constant", "rough", "slow", "agile", "rough low", "rough high"))])
def test_each_rate_model_runs_and_reports_its_probabilities(rate_model, n, names):
    obs = GyroStateObserver(scenario("default").params, 0.0, 1,
                            ObserverTuning(rate_model=rate_model))
    assert obs.n == n and obs.rate_models == names
    p = obs.rate_probabilities()
    assert set(p) == {"constant", "rough", "slow", "agile"}
    assert sum(p.values()) == pytest.approx({0: 1.0, 1: 1.0, 2: 1.0, 3: 0.0, 4: 1.0}[rate_model])


@pytest.mark.parametrize("field, value, words", [
    ("rate_model", 5, "use 0 (adaptive)"), ("rate_bandwidth", 0.0, "unit: Hz"),
    ("rate_span", -1.0, "must be a finite number >= 0"), ("rate_dwell", 0.0, "unit: s")])
def test_bad_rate_tuning_is_refused_by_name(field, value, words):
    with pytest.raises(ValueError, match=field) as exc:
        ObserverTuning(**{field: value})
    assert words in str(exc.value)


def test_a_state_with_the_wrong_number_of_rate_probabilities_is_refused():
    """set_state checks mu and c against the observer's rate models (each on its own: a
    chained comparison once let mu and c of the same wrong length through)."""
    obs = GyroStateObserver(scenario("default").params, 0.0, 1, ObserverTuning())
    state = obs.get_state()
    state["rate_filters"]["mu"] = state["rate_filters"]["mu"][:3]
    state["rate_filters"]["c"] = state["rate_filters"]["c"][:3]
    with pytest.raises(ValueError, match="rate filters"):
        obs.set_state(state)


def test_a_restored_bank_scale_outside_its_range_is_refused_by_the_core():
    """rate_model 4's scale is checked where an FMU restores a state (the core's
    gyro_observer_restored_problem): within [ln 1e-3, ln 10] it goes on; beyond, it is
    refused by name (an exp of it would set the moving models' process noise)."""
    from gyro_fmu.estimation.observer import Params, c_tuning

    p = scenario("default").params
    tun = ObserverTuning(rate_model=4)
    obs = GyroStateObserver(p, 0.0, 1, tun)
    guess = Params(*(float(getattr(p, n)) for n, _ in Params._fields_))

    def problem(scale: float) -> str:
        obs._c.rate_scale = scale
        code = obs._lib.gyro_observer_restored_problem(
            obs._ref, ctypes.byref(guess), ctypes.c_double(0.0), ctypes.c_int(1),
            ctypes.byref(c_tuning(tun)), obs._msg, ctypes.c_size_t(len(obs._msg)))
        return obs._msg.value.decode() if code else ""

    assert problem(math.log(0.5)) == ""
    for bad in (math.log(20.0), math.log(1e-4), math.nan):
        assert "a moving bank's scale outside its range" in problem(bad), bad


def _stepped_observer(p, tuning: ObserverTuning) -> GyroStateObserver:
    """An observer of the gyro p after 50 steps of 5 us on a driven plant at 1 rad/s (its
    filters' covariances have off-diagonal entries that are not zero)."""
    from gyro_fmu.model.plant import GyroPlantModel, MeasurementNoise

    obs = GyroStateObserver(p, 0.0, 1, tuning)
    plant = GyroPlantModel(p, MeasurementNoise(x=1e-12, y=1e-12), 1)
    for k in range(50):
        ux = 1e-7 * math.sin(2 * math.pi * 4000 * k * 5e-6)
        z = plant.output_row()
        obs.step(ux, 0.0, float(z[0]), float(z[2]), 5e-6)
        plant.step(ux, 0.0, 1.0, 5e-6)
    return obs


def test_a_restored_covariance_not_symmetric_to_the_bit_is_refused_by_the_core():
    """Every step keeps each rate model's P symmetric to the bit, and the mixing and the
    combined P rely on it (each entry's expression is the same in (a, b) and (b, a), so no
    triangle is mirrored): a restored P whose two halves differ in one entry, by one ulp,
    is refused by name; the same P made symmetric goes on."""
    from gyro_fmu.estimation.observer import Params, c_tuning

    p = scenario("default").params
    tun = ObserverTuning(rate_model=0)
    obs = _stepped_observer(p, tun)
    guess = Params(*(float(getattr(p, n)) for n, _ in Params._fields_))

    def problem() -> str:
        code = obs._lib.gyro_observer_restored_problem(
            obs._ref, ctypes.byref(guess), ctypes.c_double(0.0), ctypes.c_int(1),
            ctypes.byref(c_tuning(tun)), obs._msg, ctypes.c_size_t(len(obs._msg)))
        return obs._msg.value.decode() if code else ""

    assert problem() == ""
    Ps = obs._c.Ps
    v = Ps[3][5][1]
    assert v != 0.0 and Ps[3][1][5] == v
    Ps[3][5][1] = math.nextafter(v, math.inf)
    assert "a rate model's covariance that is not symmetric" in problem()
    Ps[3][1][5] = Ps[3][5][1]
    assert problem() == ""


@pytest.mark.parametrize("change, words", [
    ("asymmetric", "a rate model's covariance that is not symmetric"),
    ("rate_scale", "a moving bank's scale outside its range"),
    ("probability", "model probabilities outside [0, 1]"),
    ("wander", "a constant model's wander test out of its range"),
    ("wander field", "expected the wander test's fields"),
])
def test_the_library_set_state_refuses_what_the_core_refuses(change: str, words: str):
    """The library's set_state runs the core's checks of a restored state (those an FMU's
    restore runs): a saved state edited out of what any run can hold is refused by name,
    and the observer it was to replace is left as it was."""
    p = scenario("default").params
    obs = _stepped_observer(p, ObserverTuning(rate_model=4))
    state = obs.get_state()
    GyroStateObserver(p, 0.0, 1, obs.tuning).set_state(state)  # as saved: restored
    rf = state["rate_filters"]
    if change == "asymmetric":
        rf["P"][2][5][1] = math.nextafter(rf["P"][2][5][1], math.inf)
    elif change == "rate_scale":
        rf["rate_scale"] = math.log(100.0)
    elif change == "wander":
        rf["wander"]["log_q"] = [math.log(1e-12), math.log(10.0)]  # q beyond the rough's
    elif change == "wander field":
        rf["wander"]["q"] = [0.0, 0.0]
    else:
        rf["mu"][1] = 1.5
    before = obs.get_state()
    with pytest.raises(ValueError, match=words.replace("[", r"\[").replace("]", r"\]")):
        obs.set_state(state)
    assert obs.get_state() == before
