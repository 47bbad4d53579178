"""The observer at its defaults on hard gyros of the wide set (issue 44,
benchmarks/observer_families.py --set wide): a high-Q gyro under tones not designed for
it, a low-Q one under tones at its modes, and the 3 kHz gyro of the issue's drive
(2500 + 1200 Hz). 100 ms of a constant 1 rad/s from guesses 5 % off, noise 1e-4 of each
signal's peak, two noise seeds each. The guard is the issue's worst outcome: a run that
ends more than 4 sigma off with status 0. On 2 x 416 runs of the wide set none did
(docs/observer-rate-model.md); a regression to the issue's 8 sigma fails here.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from gyro_fmu.estimation.observer import GyroStateObserver, ObserverTuning
from gyro_fmu.model.drive import TwoToneDrive
from gyro_fmu.model.parameters import PARAMETER_NAMES, GyroParameters
from gyro_fmu.model.plant import GyroPlantModel

H, N = 5e-6, 20_000


def gyro(fx: float, fy: float, qx: float, qy: float, kxy: float, dxy: float,
         m: float) -> GyroParameters:
    wx, wy = 2 * math.pi * fx, 2 * math.pi * fy
    dxx, dyy = wx / qx, wy / qy
    return GyroParameters(kxx=wx**2, kyy=wy**2, kxy=kxy * wx * wy, dxx=dxx, dyy=dyy,
                          dxy=dxy * math.sqrt(dxx * dyy), m=m)


HARD = {  # like the wide set's gyros 1 and 2 (seed 2026); the issue's kind of 3 kHz gyro
    "9 kHz, Q 8e4, 4000 + 1200 Hz": (gyro(9210, 9254, 7.96e4, 5.75e4, 0.054, 0.1, 1.1e-8),
                                     TwoToneDrive()),
    "16.6 kHz, Q 600, tones at its modes": (gyro(16594, 16694, 682, 478, 0.010, 0.1, 4.5e-8),
                                            TwoToneDrive(f1=16262, f2=16692)),
    "3 kHz, Q 5e3, 2500 + 1200 Hz": (gyro(3000, 3060, 5e3, 5e3, 0.05, 0.05, 1e-7),
                                     TwoToneDrive(f1=2500, f2=1200)),
}


def measurements(p: GyroParameters, u: np.ndarray) -> np.ndarray:
    plant = GyroPlantModel(p)
    s = np.empty((len(u), 4))
    for k, uk in enumerate(u):
        s[k] = plant.s
        plant.step(float(uk), 0.0, 1.0, H)
    return s[:, [0, 2]]


def driven(p: GyroParameters, drive: TwoToneDrive) -> tuple[np.ndarray, np.ndarray]:
    """The drive scaled to a peak displacement of 1e-8 m, and the positions it gives."""
    unit = drive.ux_many(np.arange(N) * H)
    u = unit * 1e-8 / np.abs(measurements(p, unit)[:, 0]).max()
    return u, measurements(p, u)


def guessed(p: GyroParameters, signs: np.ndarray) -> GyroParameters:
    """Each parameter 5 % off, with these signs."""
    return GyroParameters(**{k: getattr(p, k) * (1 + 0.05 * s)
                             for k, s in zip(PARAMETER_NAMES, signs, strict=True)})


@pytest.mark.parametrize("name", list(HARD))
def test_no_run_ends_far_off_with_status_ok(name: str) -> None:
    p, drive = HARD[name]
    u, clean = driven(p, drive)
    guess = guessed(p, np.random.default_rng(7).choice([-1, 1], size=len(PARAMETER_NAMES)))
    for seed in (1, 2):
        z = clean + np.random.default_rng(seed).standard_normal(clean.shape) \
            * 1e-4 * np.abs(clean).max(axis=0)
        obs = GyroStateObserver(guess, 0.0, 1, ObserverTuning())
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            for k in range(N):
                obs.step(float(u[k]), 0.0, float(z[k, 0]), float(z[k, 1]), H)
        row = obs.output_row()
        off = abs(row[4] - 1.0) / row[12]
        assert off <= 4.0 or obs.status != 0, (name, seed, off, obs.status)
        assert off <= 10.0, (name, seed, off, obs.status)  # flagged or not, not this far


def test_the_noise_estimate_does_not_leave_the_covariance_over_confident() -> None:
    """Issue 44's kind of gyro (3 kHz, Q 5e3, 2500 + 1200 Hz), 64 runs of 100 ms from
    guesses 5 % off (4 sign patterns x 16 noise seeds), noise 1e-4 estimated (the
    default). The gain's noise estimate starts at the first squared innovation, often far
    below the noise; the covariance takes in the larger of it and the plain mean of the
    squares so far (docs/observer-rate-model.md, "The covariance's noise"). Measured on
    these runs (deterministic): RMS error/sigma from 20 ms 1.19 with it, 1.56 with the
    gain's estimate in the covariance too; beyond 3 sigma 1.07 % and 3.81 %; the worst end
    3.7 and 6.9 sigma."""
    p, drive = HARD["3 kHz, Q 5e3, 2500 + 1200 Hz"]
    u, clean = driven(p, drive)
    ratios = []
    for pattern in range(4):
        guess = guessed(p, np.random.default_rng(100 + pattern).choice(
            [-1, 1], size=len(PARAMETER_NAMES)))
        for seed in range(16):
            z = clean + np.random.default_rng(1000 * pattern + seed).standard_normal(
                clean.shape) * 1e-4 * np.abs(clean).max(axis=0)
            obs = GyroStateObserver(guess, 0.0, 1, ObserverTuning())
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                for k in range(N):
                    obs.step(float(u[k]), 0.0, float(z[k, 0]), float(z[k, 1]), H)
                    if k >= N // 5 and k % 100 == 0:
                        row = obs.output_row()
                        ratios.append((row[4] - 1.0) / row[12])
    ratios = np.array(ratios)
    rms, beyond = float(np.sqrt(np.mean(ratios**2))), float(np.mean(np.abs(ratios) > 3))
    assert rms <= 1.3 and beyond <= 0.02, (rms, beyond)


def test_the_first_samples_noise_does_not_make_the_state_prior() -> None:
    """The wide set's gyro 9 (12 kHz, Q 5e3 / 1.8e3, 11 % coupling, 4000 + 1200 Hz) started
    at its true parameters, the constant rate model, noise 1e-4 estimated (the default).
    In relative noise mode the first nonzero sample starts the state's prior, and it is
    pure noise here (the plant starts at rest): its 1e-12 m made the state so well known
    that the first milliseconds' linearization error stayed, and noise seed 1 ended 7.45
    sigma off with status 0. The drive's prior (1 % of the static deflection) now follows
    at the first drive (fmu_src/core/gyro_observer.c, start_prior). Measured, seeds 0-7:
    end error/sigma RMS 2.7 -> 0.64, seed 1 +7.45 -> +0.55; the others move by <= 0.03."""
    p = gyro(11978, 11915, 5025, 1777, 0.1097, 0.1834, 3.58e-7)
    u, clean = driven(p, TwoToneDrive())
    for seed in range(4):
        z = clean + np.random.default_rng((9, seed, 100000, 0)).standard_normal(
            clean.shape) * 1e-4 * np.abs(clean).max(axis=0)
        obs = GyroStateObserver(p, 0.0, 1, ObserverTuning(rate_model=1))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            for k in range(N):
                obs.step(float(u[k]), 0.0, float(z[k, 0]), float(z[k, 1]), H)
        row = obs.output_row()
        assert abs(row[4] - 1.0) <= 3.0 * row[12], (seed, (row[4] - 1.0) / row[12], obs.status)


#: Issue 44's table on three gyros of its kind (benchmarks/observer_families.py --set issue,
#: docs/observer-rate-model.md): the runs that carried its share beyond 3 sigma before
#: (b508c7f^'s core, the same recipe in process): (gyro, its index there, seed, noise,
#: share of the window beyond 3 sigma with status 0 then)
ISSUE_RUNS = [
    (gyro(7100, 7460, 2e4, 2e4, 0.01, 0.1, 1e-8), 0, 7, 1e-5, 0.936),
    (HARD["3 kHz, Q 5e3, 2500 + 1200 Hz"][0], 1, 0, 1e-5, 0.328),
    (HARD["3 kHz, Q 5e3, 2500 + 1200 Hz"][0], 1, 2, 1e-4, 0.797),
]


@pytest.mark.parametrize(("p", "index", "seed", "noise", "before"), ISSUE_RUNS)
def test_the_issues_over_confident_runs_are_honest(p: GyroParameters, index: int, seed: int,
                                                   noise: float, before: float) -> None:
    """A constant 1 rad/s under the issue's 2500 + 1200 Hz from guesses 5 % off, noise
    estimated (the default): before, 33-94 % of the window from 20 ms lay beyond 3 sigma
    with status 0 on these runs (the issue's 2.26 % pooled came from such runs); measured
    now 0.0 % each, ending 0.1, 1.0 and 1.2 sigma off."""
    u, clean = driven(p, TwoToneDrive(f1=2500.0, f2=1200.0))
    guess = guessed(p, np.random.default_rng((index, seed, 11)).choice(
        [-1, 1], size=len(PARAMETER_NAMES)))
    z = clean + np.random.default_rng((index, seed, int(noise * 1e9))).standard_normal(
        clean.shape) * noise * np.abs(clean).max(axis=0)
    obs = GyroStateObserver(guess, 0.0, 1, ObserverTuning())
    beyond, judged = 0, 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for k in range(N):
            obs.step(float(u[k]), 0.0, float(z[k, 0]), float(z[k, 1]), H)
            if (k + 1) * H >= 0.02:
                row = obs.output_row()
                judged += 1
                beyond += obs.status == 0 and abs(row[4] - 1.0) > 3 * row[12]
    row = obs.output_row()
    assert beyond / judged < 0.05 < before, (beyond / judged, before)
    assert abs(row[4] - 1.0) < 2.5 * row[12], ((row[4] - 1.0) / row[12], obs.status)
