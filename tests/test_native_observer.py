"""The observer on the C core against gyro_fmu 0.3.0's numba implementation, and
GyroObserver.fmu (native FMI 2.0 / 3.0, pythonfmu flavour) against the library.

Tolerance 0: the core keeps the numba kernels' operation order and is compiled with
-ffp-contract=off, so the outputs are compared bit for bit; a failure means the arithmetic
changed. (The oracle's one change, loops for numpy's matrix product in split held steps,
is in tests/oracle_observer/__init__.py with what it changes.)
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from native_host import NativeRun
from oracle_observer.observer import GyroStateObserver as Oracle
from test_native_fmus import random_gyro

from gyro_fmu.estimation.interface import OUTPUTS
from gyro_fmu.estimation.observer import GyroStateObserver, ObserverTuning
from gyro_fmu.fmu.build import prebuilt_fmu
from gyro_fmu.model.parameters import (
    PRESETS,
    GyroParameters,
    UnstablePlantWarning,
    default_initial_guess,
)
from gyro_fmu.model.plant import GyroPlantModel, MeasurementNoise

#: The cases draw steps up to omega h = 2 on purpose (split held steps): above 1.2 each new
#: step size is a CoarseStepWarning, which these bit-for-bit comparisons do not judge.
pytestmark = pytest.mark.filterwarnings(
    "ignore::gyro_fmu.estimation.observer_monitor.CoarseStepWarning")

RATE_OUT = ("p_rate_constant", "p_rate_rough", "p_rate_slow", "p_rate_agile", "status")


def measurements(p: GyroParameters, steps: np.ndarray, ux: np.ndarray, Omega: np.ndarray,
                 noise: float, seed: int) -> np.ndarray:
    """Plant outputs [x, vx, y, vy] at t_k (k = 0..n-1) with white noise of `noise` times
    each signal's peak (a first noise-free pass gives the peaks)."""
    def run(sigma: MeasurementNoise) -> np.ndarray:
        plant = GyroPlantModel(p, sigma, seed=seed)
        rows = []
        for k, h in enumerate(steps):
            rows.append(plant.output_row()[:4])
            plant.step(float(ux[k]), 0.0, float(Omega[k]), float(h))
        return np.array(rows)

    clean = run(MeasurementNoise())
    if noise == 0.0:
        return clean
    return run(MeasurementNoise(*(noise * np.max(np.abs(clean), axis=0))))


def case(rng: np.random.Generator, rate_model: int, pair: int):
    """A random gyro, a guess 2-10 % off, two tones near its modes, steps in 2-20 us (below
    the observer's refusal, omega h <= 2), a rate of 1 rad/s plus a 100 Hz sine, noise
    1e-5 or 1e-4."""
    p = random_gyro(rng)
    w = math.sqrt(max(p.kxx, p.kyy))
    n = 300
    steps = rng.uniform(2e-6, min(20e-6, 2.0 / w), n)
    t = np.concatenate([[0.0], np.cumsum(steps)[:-1]])
    fx, fy = math.sqrt(p.kxx) / (2 * math.pi), math.sqrt(p.kyy) / (2 * math.pi)
    A = 1e-3 * p.m * p.kxx * 1e-9  # a few nm of motion
    ux = A * (np.sin(2 * np.pi * 0.9 * fx * t) + np.sin(2 * np.pi * 1.1 * fy * t))
    Omega = 1.0 + 0.5 * np.sin(2 * np.pi * 100 * t)
    z = measurements(p, steps, ux, Omega, rng.choice([1e-5, 1e-4]), int(rng.integers(2**31)))
    guess = GyroParameters(*(getattr(p, n) * f for n, f in zip(
        ("kxx", "kyy", "kxy", "dxx", "dyy", "dxy", "m"), rng.uniform(0.9, 1.1, 7),
        strict=True)))
    tun = ObserverTuning(rate_model=rate_model)
    cols = (0, 2) if pair == 1 else (1, 3)
    return guess, tun, steps, ux, z[:, cols[0]], z[:, cols[1]], w


def rows_of(obs, steps, ux, z1, z2) -> np.ndarray:
    if hasattr(obs, "c_struct"):  # the core's held-step reuse is not 0.3.0's: exact steps
        obs.c_struct.held.tol = 0.0
    rows = []
    for k, h in enumerate(steps):
        obs.step(float(ux[k]), 0.0, float(z1[k]), float(z2[k]), float(h))
        rows.append([*obs.output_row(), *obs.rate_probabilities().values(), obs.status])
    return np.array(rows)


def relative(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a - b) / np.maximum(np.abs(b), 1e-300)))


@pytest.mark.parametrize("case_name", ["default", "patent"])
@pytest.mark.parametrize("rate_model", [0, 1, 2, 3])
def test_the_core_observer_equals_the_numba_one_bit_for_bit(case_name: str,
                                                             rate_model: int) -> None:
    """The default scenario (park-horowitz, guess 5-20 % off, 1 rad/s) and the patent's
    (Table 1 corrected, sin(2 pi 100 t)), positions measured, 400 steps of 5 us: every
    output, the rate probabilities and the status equal 0.3.0's."""
    h, n = 5e-6, 400
    steps = np.full(n, h)
    t = np.arange(n) * h
    if case_name == "default":
        p, A, Omega = PRESETS["park-horowitz"], 1e-7, np.ones(n)
    else:
        p, A, Omega = PRESETS["patent-table1-corrected"], 1.0, np.sin(2 * np.pi * 100 * t)
    ux = A * (np.sin(2 * np.pi * 4000 * t) + np.sin(2 * np.pi * 1200 * t))
    if case_name == "patent":  # Table 1's damping matrix is indefinite: the plant says so
        with pytest.warns(UnstablePlantWarning, match="indefinite"):
            z = measurements(p, steps, ux, Omega, 1e-5, 7)
    else:
        z = measurements(p, steps, ux, Omega, 1e-5, 7)
    guess = GyroParameters(**default_initial_guess(p))
    tun = ObserverTuning(rate_model=rate_model)
    got = rows_of(GyroStateObserver(guess, 0.0, 1, tun), steps, ux, z[:, 0], z[:, 2])
    want = rows_of(Oracle(guess, 0.0, 1, tun), steps, ux, z[:, 0], z[:, 2])
    assert np.array_equal(got, want), relative(got, want)


def test_the_core_observer_on_20_random_gyros() -> None:
    """20 gyros that are no preset (modes 1-12 kHz), each rate model and measured pair,
    steps drawn in 2-20 us (most with held steps split in sub-steps), noisy measurements:
    every output, the rate probabilities and the status equal 0.3.0's bit for bit."""
    rng = np.random.default_rng(20261202)
    coarse = 0
    for i in range(20):
        rate_model, pair = i % 4, 1 + (i // 4) % 2
        guess, tun, steps, ux, z1, z2, w = case(rng, rate_model, pair)
        got = rows_of(GyroStateObserver(guess, 0.0, pair, tun), steps, ux, z1, z2)
        want = rows_of(Oracle(guess, 0.0, pair, tun), steps, ux, z1, z2)
        assert np.array_equal(got, want), (i, relative(got, want))
        coarse += bool(np.any(w * steps > 0.5))
    assert coarse >= 10, coarse  # the split held step is exercised


def test_get_state_and_set_state_round_trip_in_the_core() -> None:
    """A JSON snapshot restored into an observer built differently goes on bit for bit."""
    rng = np.random.default_rng(5)
    guess, tun, steps, ux, z1, z2, _ = case(rng, 0, 1)
    a = GyroStateObserver(guess, 0.0, 1, tun)
    rows_of(a, steps[:150], ux, z1, z2)
    b = GyroStateObserver(PRESETS["park-horowitz"], 0.3, 1, tun)
    b.set_state(a.get_state())
    ra = rows_of(a, steps[150:], ux[150:], z1[150:], z2[150:])
    rb = rows_of(b, steps[150:], ux[150:], z1[150:], z2[150:])
    assert np.array_equal(ra, rb)
    state = a.get_state()
    for bad in (-1, 3, "x"):  # the auto prior's state: 0, 1 or 2 (2: the drive's to come)
        state["monitor"][-1] = bad
        with pytest.raises(ValueError, match="auto prior's state 0, 1 or 2"):
            GyroStateObserver(PRESETS["park-horowitz"], 0.3, 1, tun).set_state(state)


def fmu_rows(version: int, guess: GyroParameters, tun: ObserverTuning, pair: int, steps,
             ux, z1, z2, fmu=None) -> np.ndarray:
    run = NativeRun(fmu or prebuilt_fmu("GyroObserver", version))
    try:
        params = {f"{n}_0": getattr(guess, n) for n in ("kxx", "kyy", "kxy", "dxx", "dyy",
                                                         "dxy", "m")}
        params.update({k: (int(v) if isinstance(v, bool | int) else v)
                       for k, v in vars(tun).items()}, measured_pair=pair)
        run.initialize(**params)
        names = ("x_meas", "y_meas") if pair == 1 else ("vx_meas", "vy_meas")
        rows = run.run(steps, [*OUTPUTS, *RATE_OUT], {"ux": ux, names[0]: z1, names[1]: z2})
        return rows[1:]
    finally:
        run.close()


@pytest.mark.parametrize("version", [2, 3])
def test_the_native_fmu_equals_the_library(version: int) -> None:
    """GyroObserver.fmu through fmpy (FMI 2.0 and 3.0) on 4 random gyros (each rate model,
    both pairs): every output equals the in-process observer's, bit for bit (one core)."""
    rng = np.random.default_rng(version)
    for i in range(4):
        pair = 1 + i % 2
        guess, tun, steps, ux, z1, z2, _ = case(rng, i, pair)
        want = rows_of(GyroStateObserver(guess, 0.0, pair, tun), steps, ux, z1, z2)
        got = fmu_rows(version, guess, tun, pair, steps, ux, z1, z2)
        assert np.array_equal(got, want), (i, relative(got, want))


def test_the_pythonfmu_flavour_equals_the_native_fmu(pythonfmu_models) -> None:
    """The pythonfmu adapter over the same core: the same outputs as the native FMU."""
    rng = np.random.default_rng(11)
    guess, tun, steps, ux, z1, z2, _ = case(rng, 0, 2)
    native = fmu_rows(2, guess, tun, 2, steps, ux, z1, z2)
    flavour = fmu_rows(2, guess, tun, 2, steps, ux, z1, z2,
                       fmu=pythonfmu_models / "GyroObserver.fmu")
    assert np.array_equal(native, flavour)


def test_the_held_steps_table_is_the_factorials_quotient() -> None:
    """The held step's generated tables (gyro_tables.h, from gyro_fmu/core/structs/tables.py)
    as compiled into the core: the factorials are the correctly rounded k!, and every weight
    equals j! m! / (j + m + 1)! computed from them in double precision (Python's float
    arithmetic is IEEE's)."""
    import math

    from gyro_fmu.core.observer import observer_core

    lib = observer_core()
    f = [lib.gyro_observer_factorial(k) for k in range(48)]
    assert f == [float(math.factorial(k)) for k in range(48)]
    for j in range(24):
        for m in range(24):
            assert lib.gyro_observer_beta(j, m) == f[j] * f[m] / f[j + m + 1], (j, m)
    assert lib.gyro_observer_beta(24, 0) == lib.gyro_observer_beta(0, -1) == -1.0


def test_the_partial_covariance_is_the_whole_mixtures_bits() -> None:
    """After a step with the adaptive set the core keeps only the diagonal of P and the
    measured rows' columns (gyro_observer_imm.c, combine_partial); the rest is made on
    reading. Every step of 2 ms of the default gyro: those entries, as the step left them,
    are the whole mixture's (gyro_observer_combine of the filters with the predicted c)
    bit for bit, and so is P made whole. (The oracle test above compares P read through
    the library, so made whole, with the numba observer's full P.)"""
    import ctypes

    p = PRESETS["park-horowitz"]
    obs = GyroStateObserver(GyroParameters(**default_initial_guess(p)), 0.0, 1,
                            ObserverTuning())
    plant = GyroPlantModel(p, MeasurementNoise(x=1e-13, y=1e-13), 3)
    h, n, i0 = 5e-6, obs.n, obs.c_struct.i0
    raw = np.ctypeslib.as_array(obs.c_struct.P)[:n, :n]  # the struct's P, not made whole
    for k in range(400):
        ux = 1e-7 * math.sin(2 * math.pi * 4000 * k * h)
        z = plant.output_row()
        obs.step(ux, 0.0, z[0], z[2], h)
        plant.step(ux, 0.0, 1.0, h)
        partial = bool(obs.c_struct.P_partial)
        kept = [raw.diagonal().copy(), raw[:, i0].copy(), raw[:, i0 + 2].copy()]
        x, P = np.zeros(14), np.zeros((14, 14))
        ptr = ctypes.POINTER(ctypes.c_double)
        obs._lib.gyro_observer_combine(ctypes.byref(obs.c_struct),
                                       obs.c.ctypes.data_as(ptr), x.ctypes.data_as(ptr),
                                       P.ctypes.data_as(ptr))
        P = P[:n, :n]
        assert np.array_equal(kept[0], P.diagonal()), k
        assert np.array_equal(kept[1], P[:, i0]) and np.array_equal(kept[2], P[:, i0 + 2]), k
        assert np.array_equal(obs.P, P), k  # made whole on reading
        assert partial or k % 200 == 199, k  # whole only where the monitor needed it
