"""The self-calibration's resonator and loops on the C core against gyro_fmu 0.3.0's numba
implementation (tests/oracle_selfcal), on resonators that are not the preset, and the
native FMUs against the library.

Tolerances: the loops keep the numba kernel's operation order and compare bit for bit.
The resonator's step matrices come from another matrix exponential (each within 1e-14
of a 40-digit one, test_resonator_physics.py), and the closed loops integrate what the
last bits change: over 0.05 s of the closed loops the records stay within 1e-9 of each
signal's range (measured: 3e-11 on the preset over 0.5 s, the largest of the five below
is printed by `pytest -s`).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from oracle_selfcal import inprocess as oracle_inprocess
from oracle_selfcal import loops as oracle_loops
from oracle_selfcal import resonator as oracle_resonator

from gyro_fmu.model.loops import LoopSettings, LoopsModel
from gyro_fmu.model.resonator import ResonatorParameters
from gyro_fmu.selfcal.inprocess import COLUMNS, CarrierSimulation
from gyro_fmu.selfcal.run import run_fmus

H = 25e-6
RTOL = 1e-9


def random_resonators(n: int, seed: int = 23) -> list[tuple[ResonatorParameters, LoopSettings]]:
    """n resonators around 3-25 kHz, Q 3e3-1e5, splits 0.01-3 Hz, with every seed
    imperfection drawn, and loops tuned to their nominal frequency and Q."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        f = float(rng.uniform(3e3, 25e3))
        q = float(10 ** rng.uniform(3.5, 5))
        split = float(10 ** rng.uniform(-2, 0.5))
        w = 2 * np.pi * f
        p = ResonatorParameters(
            f_x=f, f_y=f + split, Q_x=q, Q_y=q * rng.uniform(0.8, 1.2),
            dxy=float(rng.uniform(-1, 1) * w / q * 0.05), kxy=float(rng.uniform(-1, 1) * w * 2),
            Bx=float(rng.uniform(0.02, 0.08)), By=float(rng.uniform(0.02, 0.08)),
            alpha_x=float(rng.normal(0, 2e-3)), alpha_y=float(rng.normal(0, 2e-3)),
            Px=float(rng.uniform(0.5e6, 2e6)), Py=float(rng.uniform(0.5e6, 2e6)),
            phi_x=float(rng.uniform(0, 0.05)), phi_y=float(rng.uniform(0, 0.05)),
            Exx=float(rng.uniform(0, 3e-3)), Exy=float(rng.uniform(0, 1e-3)),
            Eyx=float(rng.uniform(0, 1e-3)), Eyy=float(rng.uniform(0, 3e-3)),
            beta_x=float(rng.normal(0, 2e-3)), beta_y=float(rng.normal(0, 2e-3)))
        lo = LoopSettings(f_nominal=f, q_nominal=q, mode=int(rng.integers(1, 3)),
                          plant_gain=float(1e6 * 0.05 / (2 * w)), sideband_index=0.04,
                          sideband_spacing=0.4, sideband_count=3, demod_cutoff=min(500, f / 8),
                          rebalance_cutoff=min(2000, f / 2))
        out.append((p, lo))
    return out


CASES = random_resonators(5)


def _step(p: ResonatorParameters) -> float:
    return 1.0 / (10 * p.f_x)


def _oracle(p, lo, duration, h, Omega_z):
    # the oracle predates the warm-up and the temperature sensor: they stay at their
    # defaults (no warm-up, no sensor noise) in these cases
    known = {f.name for f in dataclasses.fields(oracle_resonator.ResonatorParameters)}
    res = oracle_resonator.ResonatorParameters(
        **{k: v for k, v in dataclasses.asdict(p).items() if k in known})
    loops = oracle_loops.LoopSettings(**dataclasses.asdict(lo))
    return oracle_inprocess.CarrierSimulation(res, loops, step=h, Omega_z=Omega_z).run(duration)


@pytest.mark.parametrize("case", range(len(CASES)))
def test_the_core_carrier_run_follows_the_numba_one(case):
    p, lo = CASES[case]
    h = _step(p)
    ref = _oracle(p, lo, 0.05, h, 0.2).data
    got = CarrierSimulation(p, lo, step=h, Omega_z=0.2).run(0.05).data
    assert got.shape == ref.shape
    worst = 0.0
    for j, name in enumerate(COLUMNS[1:], start=1):
        scale = np.abs(ref[:, j]).max()
        d = np.abs(got[:, j] - ref[:, j]).max() / (scale if scale else 1.0)
        worst = max(worst, d)
        assert d <= RTOL, (name, d)
    print(f"resonator {case}: f {p.f_x:.0f} Hz, Q {p.Q_x:.3g}, mode {lo.mode}: "
          f"max relative difference {worst:.2e}")
    # the loops act and the resonator answers (ringing up takes Q / (pi f) = 0.1-2 s here)
    assert got[:, COLUMNS.index("gain")].max() > 0.0 and np.ptp(got[:, COLUMNS.index("Vpx")]) > 0.0


def test_the_core_loops_equal_the_numba_ones_bit_for_bit():
    rng = np.random.default_rng(4)
    for mode in (0, 1, 2):
        s = dict(mode=mode, sideband_index=0.04, sideband_count=5, ff_xx=1e-3, ff_yx=2e-3,
                 osc_phase=0.01)
        a, b = oracle_loops.LoopsModel(oracle_loops.LoopSettings(**s)), LoopsModel(
            LoopSettings(**s))
        for k in range(5000):
            t = k * H
            px = np.cos(2 * np.pi * 4000 * t + 0.3) + 1e-3 * rng.standard_normal()
            py = 0.01 * np.sin(2 * np.pi * 4000.2 * t)
            assert np.array_equal(a.step(px, py, t, H), b.step(px, py, t, H)), (mode, k)


@pytest.mark.parametrize("case", range(len(CASES)))
def test_the_native_fmus_equal_the_library_bit_for_bit(models_dir, case):
    p, lo = CASES[case]
    p = dataclasses.replace(p, noise=1e-4 * p.Px * 1e-6, m_modal=1e-10, drive_noise=1e-4)
    h = _step(p)
    ref = CarrierSimulation(p, lo, seed=case, step=h, Omega_z=0.2).run(0.01)
    fmu = run_fmus(p, lo, 0.01, step=h, Omega_z=0.2, seed=case, models_dir=models_dir)
    assert np.array_equal(fmu.data, ref.data)
