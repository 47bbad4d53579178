"""The observer's held-step reuse (fmu_src/core/gyro_observer_held.c, HELD_TOL = 1e-7):
the maps are built at one point and reused, corrected to first order, while the
linearization point stays within ||dA_aug h|| <= 1e-7 of it.

Tolerances (docs/results/performance.md). On the default system over 1 s, reuse moved every
output by at most 2.5e-9 of its peak and Omega_hat by 3.4e-7 of its own sigma (0.2 s, this
test's run: 5.6e-10 and 3.4e-7); the same exact filter with kxx_0 one ulp off moved them
by 1.2e-12 and 1.0e-10. The tests allow 20-30x the reuse's measured effect over 1 s: a
wrong map, a wrong correction or a cache that outlives its point shows as differences of
the order of the noise, 1e-5 of a peak and a sigma and more.
"""

from __future__ import annotations

import ctypes

import numpy as np
import pytest

from gyro_fmu.estimation.observer import GyroStateObserver, ObserverTuning
from gyro_fmu.model.parameters import GyroParameters
from gyro_fmu.model.plant import GyroPlantModel
from gyro_fmu.system.inprocess import COLUMNS, run_chain
from gyro_fmu.system.scenario import absolute_noise, observer_tuning, scenario

STEPS = 40_000  # 0.2 s at 5 us: converged enough that most steps reuse the maps


def chain(rate_model: int, steps: int, tol: float | None, observer=None, sc_out=None):
    """The default system in the C loop; tol overrides the observer's held.tol."""
    sc = scenario("default", stop_time=steps * 5e-6, noise=1e-4).with_(
        tuning={"rate_model": rate_model})
    noise = absolute_noise(sc)
    plant = GyroPlantModel(sc.params, noise, sc.seed)
    obs = observer or GyroStateObserver(GyroParameters(**sc.initial_guess), sc.Omega_z_0,
                                        sc.measured_pair,
                                        ObserverTuning(**observer_tuning(sc, noise)))
    if tol is not None:
        obs.c_struct.held.tol = tol
    out = np.empty((steps + 1, len(COLUMNS)))
    rows, _ = run_chain(sc.the_drive, sc.rate, plant, obs, sc.measured_pair, sc.step, steps,
                        out)
    assert rows == steps + 1
    if sc_out is not None:
        sc_out.extend([sc, plant])
    return out, obs


def go_on(obs: GyroStateObserver, sc, plant: GyroPlantModel, t0: float, steps: int):
    """The same system stepped on from t0 through the Python API: the observer's rows."""
    rows, h = [], sc.step
    for k in range(steps):
        t = t0 + k * h
        ux = sc.the_drive.ux(t)
        z = plant.measured()
        obs.step(ux, 0.0, float(z[0]), float(z[2]), h)
        plant.step(ux, 0.0, sc.Omega_z_0, h)
        rows.append(obs.output_row())
    return np.array(rows)


@pytest.mark.parametrize("rate_model", [1, 0], ids=["constant", "adaptive"])
def test_reuse_stays_within_its_measured_effect_of_the_exact_filter(rate_model: int) -> None:
    exact, e = chain(rate_model, STEPS, 0.0)
    reused, r = chain(rate_model, STEPS, None)
    assert e.c_struct.held.reused == 0
    assert r.c_struct.held.reused > 0.4 * STEPS, r.c_struct.held.reused  # it is exercised
    cols = [i for i, c in enumerate(COLUMNS)
            if c.startswith("observer.") and "p_rate" not in c]
    for i in cols:
        peak = np.max(np.abs(exact[:, i])) or 1.0
        worst = np.max(np.abs(reused[:, i] - exact[:, i])) / peak
        assert worst <= 5e-8, (COLUMNS[i], worst)
    om, sig = COLUMNS.index("observer.Omega_hat"), COLUMNS.index("observer.sigma_Omega_z")
    late = slice(1000, None)
    assert np.max(np.abs(reused[late, om] - exact[late, om]) / exact[late, sig]) <= 1e-5


def test_the_maps_reproduce_the_exact_held_step_at_and_near_their_point() -> None:
    """The cached decomposition (Phi, psi, Sk) against gyro_observer_held_step itself."""
    _, obs = chain(1, STEPS, None)
    held = obs.c_struct.held
    assert held.valid == 1.0
    xc = np.array(held.xc)
    Phi_c = np.ctypeslib.as_array(held.Phi).copy()
    psi = np.ctypeslib.as_array(held.psi).copy()
    Sk = np.ctypeslib.as_array(held.Sk).copy()
    rng = np.random.default_rng(3)
    T = np.array([1.0, 1.0 / obs.wx, 1.0, 1.0 / obs.wy])  # the filter's scaling of s
    for _ in range(5):
        s = rng.normal(size=4) * 1e-6
        ux, uy = rng.normal(size=2) * 1e-9
        w = np.array([*(s * T), ux, uy])
        for d in (np.zeros(8), rng.normal(size=8) * 1e-9):
            x = xc + d
            theta = obs.theta0 + obs.scale * x[:7]
            s1, Phi, S = obs.held_step(s, ux, uy, held.h, theta=theta, Omega_z=x[7])
            S_map = np.tensordot(w, Sk, axes=1)
            s1_map = (Phi_c @ (s * T) + psi.T @ [ux, uy] + S_map @ d) / T
            Phi_map = Phi_c + np.einsum("kiq,q->ik", Sk[:4], d)
            scale = np.abs(s1).max()
            np.testing.assert_allclose(s1_map, s1, rtol=0, atol=1e-13 * scale)
            np.testing.assert_allclose(Phi_map, Phi * T[:, None] / T[None, :], rtol=0,
                                       atol=1e-13)  # in the filter's scaling: entries ~1
            S_scaled = S * T[:, None]
            # S is taken at the maps' point: off by O(d), 1e-9 here, relative
            np.testing.assert_allclose(S_map, S_scaled, rtol=0,
                                       atol=1e-7 * np.abs(S_scaled).max())


def test_a_restored_state_goes_on_bit_for_bit_with_the_maps_rebuilt() -> None:
    got: list = []
    _, a = chain(1, STEPS, None, sc_out=got)
    sc, plant = got
    assert a.c_struct.held.valid == 1.0 and sc.measured_pair == 1
    b = GyroStateObserver(GyroParameters(**sc.initial_guess), 0.0, 1, a.tuning)
    b.set_state(a.get_state())
    for name in ("valid", "h", "xc", "steady", "tol", "norm", "Phi", "psi", "Sk"):
        va, vb = getattr(a.c_struct.held, name), getattr(b.c_struct.held, name)
        assert (va == vb) if isinstance(va, float) else bytes(va) == bytes(vb), name
    twin = GyroPlantModel(sc.params, absolute_noise(sc), sc.seed)
    twin.set_state(plant.get_state())
    reused = a.c_struct.held.reused
    ra = go_on(a, sc, plant, STEPS * sc.step, 500)
    rb = go_on(b, sc, twin, STEPS * sc.step, 500)
    assert a.c_struct.held.reused > reused  # the maps were used after the restore
    assert np.array_equal(ra, rb)


@pytest.mark.parametrize("field, value", [("tol", 5.0), ("steady", -1.0), ("xc", [np.nan] * 8),
                                          ("valid", 0.5)])
def test_a_saved_cache_out_of_range_is_refused(field: str, value) -> None:
    _, a = chain(1, 2000, None)
    state = a.get_state()
    state["held"][field] = value
    b = GyroStateObserver(GyroParameters(**scenario("default").initial_guess), 0.0, 1,
                          a.tuning)
    with pytest.raises(ValueError, match="held-step cache"):
        b.set_state(state)


def test_a_state_without_the_cache_starts_it_empty() -> None:
    """States saved before the cache (no "held") restore with an empty one."""
    _, a = chain(1, STEPS, None)
    state = a.get_state()
    del state["held"]
    b = GyroStateObserver(GyroParameters(**scenario("default").initial_guess), 0.0, 1,
                          a.tuning)
    b.set_state(state)
    assert b.c_struct.held.valid == 0.0 and b.c_struct.held.tol == a.c_struct.held.tol
    assert ctypes.sizeof(b.c_struct) == ctypes.sizeof(a.c_struct)


def test_the_sensor_step_reuses_the_maps_once_converged() -> None:
    """GyroSensor's chain at its 20 us internal step (in process): by 0.3 s most steps
    reuse the maps (HELD_TOL = 1e-8 reused 18 % of the first 0.6 s there, 1e-7 86 %: the
    speed of GyroSensor.fmu), and Omega_hat stays within 1e-5 of its sigma of the exact
    filter (measured over 1 s at the three presets: 1.4e-7 to 1.5e-6)."""
    from gyro_fmu.sensor.inprocess import chain_parts, defaults

    def run(tol: float | None) -> tuple[np.ndarray, float]:
        plant, obs, drive, h = chain_parts(defaults())
        if tol is not None:
            obs.c_struct.held.tol = tol
        n, rows, reused = 15_000, [], 0.0
        for k in range(n):
            ux = drive.ux(k * h)
            z = plant.output_row()
            obs.step(ux, 0.0, z[0], z[2], h)
            plant.step(ux, 0.0, 1.0 if k * h >= 0.05 else 0.0, h)
            rows.append((obs.estimates()["Omega_z"], obs.sigmas()["Omega_z"]))
            if k == n // 2:
                reused = obs.c_struct.held.reused
        return np.array(rows), (obs.c_struct.held.reused - reused) / (n - n // 2 - 1)

    exact, none = run(0.0)
    got, share = run(None)
    assert none == 0.0
    assert share > 0.8, share
    late = slice(2500, None)
    assert np.max(np.abs(got[late, 0] - exact[late, 0]) / exact[late, 1]) <= 1e-5
