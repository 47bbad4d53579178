"""Observability of eq. 7 (US 2011/0314910 A1): one tone is not enough, two tones are."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gyro_fmu.estimation.observability import (
    DEFAULT_RTOL,
    UNKNOWNS,
    drive_tones,
    lie_observability_matrix,
    max_identifiable_combinations,
    observability_report,
    pointwise_report,
    steady_state,
    w_kd,
    window_jacobian,
)
from gyro_fmu.model.drive import TwoToneDrive
from gyro_fmu.model.dynamics import HeldInputStepper, held_input_maps
from gyro_fmu.model.parameters import PRESET_DRIVE_AMPLITUDE, GyroParameters, preset

PRESETS = ["park-horowitz", "patent-table1-corrected"]
H = 5e-6


def two_tones(name: str) -> TwoToneDrive:
    a = PRESET_DRIVE_AMPLITUDE[name]
    return TwoToneDrive(A1=a, f1=2500.0, A2=a, f2=1200.0)


def one_tone(name: str, f: float = 2500.0) -> TwoToneDrive:
    return TwoToneDrive(A1=PRESET_DRIVE_AMPLITUDE[name], f1=f, A2=0.0, f2=1200.0)


def _with_param(p: GyroParameters, Om: float, i: int, value: float) -> tuple[GyroParameters, float]:
    if i == 0:
        return p, value
    return p.with_overrides(**{UNKNOWNS[i]: value}), Om


def _theta(p: GyroParameters, Om: float) -> np.ndarray:
    return np.array([Om, p.kxx, p.kyy, p.kxy, p.dxx, p.dyy, p.dxy, p.m])


# --- window test (empirical Gramian) ------------------------------------------------------


@pytest.mark.parametrize("name", PRESETS)
def test_two_tones_full_rank_one_tone_rank_four(name: str) -> None:
    p = preset(name)
    two = observability_report(p, two_tones(name))
    assert two.rank == 8 and two.full_rank
    assert two.condition_number < 2e3  # 561 park-horowitz, 10 table 1 corrected
    assert min(two.singular_values) > 1e3 * DEFAULT_RTOL
    for f in (2500.0, 1200.0):
        one = observability_report(p, one_tone(name, f))
        assert one.rank == 4 == max_identifiable_combinations(1)
        sv = one.singular_values
        assert sv[3] > 1e-2 and sv[4] < DEFAULT_RTOL / 10  # clear gap
        assert one.condition_number > 1e11
        assert all(math.isinf(v) for v in one.one_sigma(1e-4).values())


@pytest.mark.parametrize("pair", [1, 2])
def test_augmented_twelve_states(pair: int) -> None:
    name = "park-horowitz"
    p = preset(name)
    two = observability_report(p, two_tones(name), measured_pair=pair, unknowns="augmented")
    one = observability_report(p, one_tone(name), measured_pair=pair, unknowns="augmented")
    assert len(two.names) == 12
    assert (two.rank, one.rank) == (12, 8)


def test_one_tone_nullspace_is_that_of_the_frequency_responses() -> None:
    """One tone: the data see only Hx(z), Hy(z) at z = e^{jwh}: 4 real combinations.

    The frequency responses of the held-input model are built independently from
    dynamics.held_input_maps and differentiated by finite differences; their
    4-dimensional null space must be the window Jacobian's null space.
    """
    name = "patent-table1-corrected"
    p, Om, f = preset(name), 1.0, 2500.0
    rep = observability_report(p, one_tone(name, f), Omega_z=Om)
    z = np.exp(2j * math.pi * f * H)

    def response(pp: GyroParameters, om: float) -> np.ndarray:
        Phi, Gamma = held_input_maps(pp, om, H)
        return np.linalg.solve(z * np.eye(4) - Phi, Gamma[:, 0])[[0, 2]]

    g0 = np.abs(response(p, Om))  # fixed per-channel normalization

    def responses(pp: GyroParameters, om: float) -> np.ndarray:
        G = response(pp, om) / g0
        return np.concatenate([G.real, G.imag])

    theta = _theta(p, Om)
    cols = []
    for i in range(8):
        d = 1e-6 * rep.scales[i]
        pp, op = _with_param(p, Om, i, theta[i] + d)
        pm, om = _with_param(p, Om, i, theta[i] - d)
        cols.append((responses(pp, op) - responses(pm, om)) / 2e-6)
    Jh = np.array(cols).T  # (4, 8), per unit c_i
    assert np.linalg.matrix_rank(Jh / np.linalg.norm(Jh, axis=0), tol=1e-6) == 4
    null_h = np.linalg.svd(Jh)[2][4:].T  # (8, 4)
    J = rep.jacobian
    # every unobservable direction of the frequency responses leaves the window data unchanged
    ratio = np.linalg.norm(J @ null_h, axis=0) / np.linalg.norm(J, 2)
    assert np.all(ratio < 1e-7), ratio


def test_sensitivities_match_finite_differences_of_the_held_input_plant() -> None:
    name = "park-horowitz"
    p, Om, drive = preset(name), 1.0, two_tones(name)
    n = 200
    z, dz, scales = window_jacobian(p, drive, Om, measured_pair=1, window=n * H, start="rest")

    def outputs(pp: GyroParameters, om: float) -> np.ndarray:
        stepper = HeldInputStepper(pp)
        s = np.zeros(4)
        out = np.empty((n, 2))
        for k in range(n):
            out[k] = s[[0, 2]]
            s = stepper.step(s, drive.ux(k * H), 0.0, om, H)
        return out

    np.testing.assert_allclose(z, outputs(p, Om), rtol=0, atol=1e-12 * np.abs(z).max())
    theta = _theta(p, Om)
    for i in range(8):
        d = 1e-4 * scales[i]
        pp, op = _with_param(p, Om, i, theta[i] + d)
        pm, om = _with_param(p, Om, i, theta[i] - d)
        fd = (outputs(pp, op) - outputs(pm, om)) / 2e-4
        # each channel weighed by its own peak, as in the Gramian
        peak = np.abs(z).max(axis=0)
        err = np.abs((fd - dz[:, :, i]) / peak).max() / np.abs(dz[:, :, i] / peak).max()
        assert err < 1e-6, (UNKNOWNS[i], err)


def test_steady_orbit_is_periodic_under_the_held_input_stepper() -> None:
    name = "patent-table1-corrected"
    p, drive, Om = preset(name), two_tones(name), 1.0
    s = steady_state(p, drive, Om, 0.0, h=H)
    stepper = HeldInputStepper(p)
    n = 400
    for k in range(n):
        s = stepper.step(s, drive.ux(k * H), 0.0, Om, H)
    expected = steady_state(p, drive, Om, n * H, h=H)
    np.testing.assert_allclose(s, expected, rtol=0, atol=1e-9 * np.abs(expected).max())


def test_omega_enters_x_only_at_second_order() -> None:
    """Hx = (s^2 + dyy s + kyy) / (m Delta) and Delta depends on Omega_z only via
    4 Omega_z^2: at Omega_z = 0 the x part of the Omega_z column vanishes exactly."""
    name = "park-horowitz"
    p = preset(name)
    _, dz, _ = window_jacobian(p, two_tones(name), Omega_z=0.0)
    x_part, y_part = np.abs(dz[:, 0, 0]).max(), np.abs(dz[:, 1, 0]).max()
    assert x_part < 1e-10 * y_part
    _, dz1, _ = window_jacobian(p, two_tones(name), Omega_z=1.0)
    assert 1e-5 < np.abs(dz1[:, 0, 0]).max() / np.abs(dz1[:, 1, 0]).max() < 1e-2


def test_omega_and_dxy_nearly_collinear_for_park_horowitz() -> None:
    """To first order Omega_z and dxy enter Hy together as dxy + 2 Omega_z."""
    ph = observability_report(preset("park-horowitz"), two_tones("park-horowitz"))
    t1 = observability_report(
        preset("patent-table1-corrected"), two_tones("patent-table1-corrected")
    )
    assert 5.0 < ph.angle_deg("Omega_z", "dxy") < 25.0  # 14.2 degrees
    assert ph.angle_deg("Omega_z", "dxy") < t1.angle_deg("Omega_z", "dxy")  # 59.9 degrees
    assert math.isclose(
        math.cos(math.radians(ph.angle_deg("Omega_z", "dxy"))),
        ph.cosine("Omega_z", "dxy"),
        rel_tol=1e-9,
    )
    weakest = dict(ph.weakest_direction)
    assert {n for n, _ in ph.weakest_direction[:2]} == {"Omega_z", "dxy"}
    assert weakest["Omega_z"] * weakest["dxy"] < 0  # the pair moves in opposite directions


def test_start_from_rest_transient_acts_as_extra_tones() -> None:
    """From rest the free modes (decaying at about dxx/2 = 5 1/s) are still in the
    40 ms window: one tone is then locally observable too."""
    name = "park-horowitz"
    rep = observability_report(preset(name), one_tone(name), start="rest")
    assert rep.rank == 8 and rep.condition_number < 1e4


@pytest.mark.parametrize(
    ("name", "om", "dxy"),
    [("park-horowitz", 0.029, 0.052), ("patent-table1-corrected", 0.033, 0.059)],
)
def test_cramer_rao_agrees_with_field_notes(name: str, om: float, dxy: float) -> None:
    """docs/observability.md: 40 ms, 200 kHz, 2500 + 1200 Hz, noise 1e-4 of each peak."""
    sig = observability_report(preset(name), two_tones(name), start="rest").one_sigma(1e-4)
    assert sig["Omega_z"] == pytest.approx(om, rel=0.05)
    assert sig["dxy"] == pytest.approx(dxy, rel=0.05)


# --- pointwise test of eq. 7 ----------------------------------------------------------------


@pytest.mark.parametrize("pair", [1, 2])
@pytest.mark.parametrize("name", PRESETS)
def test_pointwise_on_the_orbit(name: str, pair: int) -> None:
    p = preset(name)
    for t in (0.0, 1.234e-3):
        two = pointwise_report(p, two_tones(name), measured_pair=pair, t=t)
        one = pointwise_report(p, one_tone(name), measured_pair=pair, t=t)
        assert (two.rank, one.rank) == (12, 8)
        assert one.singular_values[8] < 1e-12
        for rep, expected in ((two, 8), (one, 4)):
            Wkd = w_kd(rep.jacobian)
            sv = np.linalg.svd(Wkd / np.linalg.norm(Wkd, axis=0), compute_uv=False)
            assert int(np.sum(sv > DEFAULT_RTOL * sv[0])) == expected


def test_pointwise_off_the_orbit_one_tone_looks_full_rank() -> None:
    name = "park-horowitz"
    p, drive = preset(name), one_tone(name)
    s = steady_state(p, drive, 1.0, 0.0, h=None)
    off = s + np.array([0.3, 0.0, 0.0, 0.0]) * np.abs(s[0])
    assert pointwise_report(p, drive, state=off).rank == 12


def test_lie_matrix_first_rows_are_c1_of_eq7() -> None:
    """Velocities measured: rows 0-3 over the state columns are C1 of eq. 7 plus the
    damping/Coriolis terms the printed C1 omits."""
    p, Om = preset("patent-table1-corrected"), 1.0
    W = lie_observability_matrix(p, [1e-9, 0.0, 0.0, 0.0], Om, [0.0] * 5, measured_pair=2)
    expected = np.array(
        [
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
            [-p.kxx, -p.dxx, -p.kxy, 2 * Om - p.dxy],
            [-p.kxy, -p.dxy - 2 * Om, -p.kyy, -p.dyy],
        ]
    )
    np.testing.assert_allclose(W[:4, :4], expected)
    np.testing.assert_allclose(W[:2, 4:], 0.0)
    # d(x'')/dkxx = -x
    assert W[2, 5] == pytest.approx(-1e-9)


# --- inputs -----------------------------------------------------------------------------------


def test_drive_tones_and_validation() -> None:
    assert drive_tones(TwoToneDrive(1.0, 100.0, 0.0, 200.0)) == [(1.0, 100.0)]
    assert drive_tones(TwoToneDrive(1.0, 100.0, 2.0, 100.0)) == [(3.0, 100.0)]
    assert drive_tones([(1.0, 100.0), (1.0, 0.0)]) == [(1.0, 100.0)]
    assert max_identifiable_combinations(3) == 8
    p = preset()
    with pytest.raises(ValueError, match="measured_pair"):
        observability_report(p, two_tones("park-horowitz"), measured_pair=3)
    with pytest.raises(ValueError, match="start"):
        observability_report(p, two_tones("park-horowitz"), start="later")  # type: ignore[arg-type]
