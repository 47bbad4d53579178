"""TwoToneDrive.fmu and RateProfile.fmu reproduce their formulas at every communication point."""

from __future__ import annotations

import numpy as np
import pytest

from gyro_fmu.cosim.master import Component, run_cosimulation


def test_two_tone_drive_is_eq_10(models_dir):
    params = {"A1": 0.5, "f1": 2500.0, "A2": 2.0, "f2": 1200.0}
    r = run_cosimulation([Component("drive", models_dir / "TwoToneDrive.fmu", params)], [],
                         0.002, 5e-6)
    t = r["time"]
    expected = 0.5 * np.sin(2 * np.pi * 2500 * t) + 2.0 * np.sin(2 * np.pi * 1200 * t)
    assert np.max(np.abs(r["drive.ux"] - expected)) < 1e-12
    assert np.all(r["drive.uy"] == 0.0)


@pytest.mark.parametrize(
    ("params", "formula"),
    [
        ({"kind": 1, "offset": 0.7}, lambda t: 0.7 + 0 * t),
        ({"kind": 2, "offset": 0.1, "amplitude": 2.0, "t_start": 1e-3},
         lambda t: np.where(t < 1e-3, 0.1, 2.1)),
        ({"kind": 3, "offset": 0.0, "slope": 50.0, "t_start": 5e-4},
         lambda t: np.where(t < 5e-4, 0.0, 50.0 * (t - 5e-4))),
        ({"kind": 4, "offset": 0.0, "amplitude": 1.0, "frequency": 100.0},
         lambda t: np.sin(2 * np.pi * 100 * t)),
    ],
    ids=["constant", "step", "ramp", "sine"],
)
def test_rate_profiles(models_dir, params, formula):
    r = run_cosimulation([Component("rate", models_dir / "RateProfile.fmu", params)], [],
                         0.002, 5e-6)
    assert np.max(np.abs(r["rate.Omega_z"] - formula(r["time"]))) < 1e-12


def _ux_and_Omega(drive, rate) -> tuple[float, float]:
    return drive.ux(3.1e-4), rate.Omega_z(3.1e-4)


def test_the_library_drive_and_rate_profile_cross_a_process_pool():
    """They hold the core's struct (ctypes, not picklable): pickled as their fields, a
    worker process gets the same inputs (benchmarks/observer_families.py --jobs)."""
    import pickle
    from concurrent.futures import ProcessPoolExecutor

    from gyro_fmu.model.drive import TwoToneDrive
    from gyro_fmu.model.rate import RateKind, RateProfile

    drive = TwoToneDrive(A1=0.5, f1=2500.0, A2=2.0, f2=1200.0)
    rate = RateProfile(kind=RateKind.sine, offset=0.1, amplitude=2.0, frequency=100.0)
    assert pickle.loads(pickle.dumps(drive)) == drive
    assert pickle.loads(pickle.dumps(rate)) == rate
    with ProcessPoolExecutor(1) as pool:
        there = pool.submit(_ux_and_Omega, drive, rate).result()
    assert there == _ux_and_Omega(drive, rate)
    assert there[0] != 0.0 and there[1] != 0.1
