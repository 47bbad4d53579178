"""Excitation design: the Cramer-Rao bound vs window and noise, the proposal, the heat map."""

from __future__ import annotations

import math

import pytest

from gyro_fmu.estimation.excitation import crb, design_drive, heat_map
from gyro_fmu.model.drive import TwoToneDrive
from gyro_fmu.model.parameters import preset

P = preset("park-horowitz")
DRIVE = TwoToneDrive()  # 4000 + 1200 Hz, 1e-7 N per tone


def test_bound_is_proportional_to_noise():
    a = crb(P, DRIVE, noise=1e-4, window=0.01)
    b = crb(P, DRIVE, noise=3e-4, window=0.01)
    for name in a:
        assert b[name] == pytest.approx(3.0 * a[name], rel=1e-9)
    c = crb(P, DRIVE, noise=1e-9, window=0.01, noise_kind="absolute")
    d = crb(P, DRIVE, noise=2e-9, window=0.01, noise_kind="absolute")
    assert d["Omega_z"] == pytest.approx(2.0 * c["Omega_z"], rel=1e-9)


def test_bound_shrinks_as_the_window_grows():
    sig = [crb(P, DRIVE, noise=1e-4, window=w)["Omega_z"] for w in (0.005, 0.01, 0.02)]
    assert sig[0] > sig[1] > sig[2]
    # on the periodic orbit the information grows linearly with the window
    # (4000 and 1200 Hz repeat every 2.5 ms): sigma proportional to 1/sqrt(window)
    s1 = crb(P, DRIVE, noise=1e-4, window=0.005, start="steady")
    s4 = crb(P, DRIVE, noise=1e-4, window=0.02, start="steady")
    for name in s1:
        assert s1[name] / s4[name] == pytest.approx(2.0, rel=1e-3)


def test_reproduces_the_documented_bounds():
    # README / drive.py: 40 ms, noise 1e-4 of each peak, plant from rest
    assert crb(P, DRIVE, noise=1e-4)["Omega_z"] == pytest.approx(0.0081, rel=0.01)
    old = crb(P, TwoToneDrive(f1=2500.0), noise=1e-4)
    assert old["Omega_z"] == pytest.approx(0.029, rel=0.02)
    assert old["dxy"] == pytest.approx(0.052, rel=0.02)


def test_design_proposes_the_grid_minimum_and_draws_it(tmp_path):
    freqs = (1200.0, 2500.0, 4000.0)
    d = design_drive(P, freqs, 2e-7, noise=1e-4, window=0.01, splits=(0.5,))
    best = d.proposal
    assert {best.f1, best.f2} <= set(freqs) and best.f1 != best.f2
    assert best.A1 + best.A2 == pytest.approx(2e-7)
    finite = [d.sigma_at(f1, f2)["Omega_z"] for f1 in freqs for f2 in freqs if f1 != f2]
    assert d.proposal_sigma["Omega_z"] == pytest.approx(min(finite))
    # the linear combination of single tones equals a direct two-tone computation
    direct = crb(P, best, noise=1e-4, window=0.01)
    assert d.proposal_sigma["Omega_z"] == pytest.approx(direct["Omega_z"], rel=1e-6)
    assert math.isnan(d.objective[0, 0, 0])
    path = heat_map(d, tmp_path / "map.png")
    assert path.stat().st_size > 5000
