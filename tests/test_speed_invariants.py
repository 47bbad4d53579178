"""What the speed work (docs/results/performance.md) must not change; no timings here."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm

from gyro_fmu.cosim.master import Component, run_cosimulation
from gyro_fmu.model.dynamics import held_input_maps, state_scaling
from gyro_fmu.model.parameters import GyroParameters, preset, system_matrix
from gyro_fmu.system.scenario import CONNECTIONS, INSTANCE_FMUS, scenario


def _scipy_maps(p: GyroParameters, om: float, h: float) -> tuple[np.ndarray, np.ndarray]:
    """The Van Loan exponential by scipy, in the scaling of dynamics.state_scaling."""
    T = state_scaling(p)
    M = np.zeros((6, 6))
    M[:4, :4] = system_matrix(p, om) * T[:, None] / T[None, :] * h
    M[1, 4] = T[1] / p.m * h
    M[3, 5] = T[3] / p.m * h
    E = expm(M)
    return E[:4, :4] / T[:, None] * T[None, :], E[:4, 4:] / T[:, None]


@pytest.mark.parametrize("name", ["park-horowitz", "patent-table1-corrected"])
@pytest.mark.parametrize("h", [5e-6, 3.3e-5, 2e-4, 1e-3])  # the longer ones need squaring
@pytest.mark.parametrize("om", [0.0, 1.0, -250.0])
def test_compiled_held_input_maps_equal_scipy_expm(name: str, h: float, om: float) -> None:
    p = preset(name)
    Phi, Gamma = held_input_maps(p, om, h)
    Phi_ref, Gamma_ref = _scipy_maps(p, om, h)
    for got, ref in ((Phi, Phi_ref), (Gamma, Gamma_ref)):
        T = np.abs(ref).max(axis=1, keepdims=True)  # per row: positions vs velocities
        np.testing.assert_allclose(got / T, ref / T, rtol=0, atol=1e-13)


def test_recording_any_subset_in_any_order_gives_the_same_numbers(models_dir):
    """The master's row layout (each FMU's outputs contiguous) is invisible to the user:
    a recording list that interleaves instances, repeats a name and leaves out connected
    outputs returns exactly the columns of the default recording."""
    sc = scenario("default")
    components = [Component(n, models_dir / f) for n, f in INSTANCE_FMUS.items()]
    full = run_cosimulation(components, CONNECTIONS, 2e-4, sc.step)
    record = ["observer.Omega_hat", "drive.ux", "plant.ay", "observer.Omega_hat", "rate.Omega_z"]
    part = run_cosimulation(components, CONNECTIONS, 2e-4, sc.step, record=record)
    assert part.columns == ("time", *record)
    for name in part.columns:
        assert np.array_equal(part[name], full[name]), name
    assert np.array_equal(full["time"], np.arange(41) * sc.step)
