"""The observer's re-fit test: an estimate the recent data reject is flagged and restarted.

A stiffness step the parameters' random walk cannot follow (kxx +2e-5 relative at 40 ms,
what 0.7 K does at -30 ppm/K) leaves a filter whose covariance has collapsed around the
old value. Without the re-fit test (measured with its threshold disabled) kxx stays 390
sigma off for 200 ms and the status is back to 0 at 245 ms with kxx 138 sigma off; with
it the estimate is restarted along the re-fit's move and kxx is within 0.3 sigma by
125 ms. On data the model fits, the test stays quiet (docs/observer-soundness.md).
"""

from __future__ import annotations

import ctypes
import math
import re

import numpy as np
import pytest
from fmu_harness import Instance

from gyro_fmu.estimation.observer import GyroStateObserver
from gyro_fmu.fmu.build import prebuilt_fmu
from gyro_fmu.model import plant as plant_module
from gyro_fmu.model.drive import TwoToneDrive
from gyro_fmu.model.parameters import PARAMETER_NAMES, GyroParameters
from gyro_fmu.model.plant import GyroPlantModel

H = 5e-6
#: A gyro that is no preset (benchmarks/observer_families.py's gyro 0: 3020 / 2792 Hz,
#: Q 1.3e3 / 1.2e3, 10 % cross stiffness).
GYRO = GyroParameters(kxx=359989103.563186, kyy=307737642.2025489, kxy=34810551.41064013,
                      dxx=14.677196084924928, dyy=15.112569394435534, dxy=1.2067850862111655,
                      m=2.89390083275495e-09)


def data(n: int, noise: float, step_at: int | None = None, kxx_step: float = 0.0):
    """Drive (default tones, 1e-8 m peak), measured x, y with white noise of `noise` x each
    peak; Omega_z = 1 rad/s; kxx x (1 + kxx_step) from step `step_at` (state carried)."""
    d = TwoToneDrive()
    unit = np.array([d.ux(k * H) for k in range(n)])
    probe = GyroPlantModel(GYRO)
    peak = 0.0
    for k in range(n):
        peak = max(peak, abs(probe.s[0]))
        probe.step(unit[k], 0.0, 1.0, H)
    u = unit * 1e-8 / peak
    plant, s = GyroPlantModel(GYRO), np.empty((n, 4))
    for k in range(n):
        if k == step_at:
            state = plant.s
            plant = GyroPlantModel(GyroParameters(**{**vars(GYRO),
                                                     "kxx": GYRO.kxx * (1 + kxx_step)}))
            ctypes.memmove(ctypes.addressof(plant._buf) + plant_module._STATE_OFFSET,
                           state.ctypes.data, 32)
            assert np.array_equal(plant.s, state)
        s[k] = plant.s
        plant.step(u[k], 0.0, 1.0, H)
    z = s[:, [0, 2]]
    z = z + np.random.default_rng(5).standard_normal(z.shape) * noise * np.abs(z).max(axis=0)
    return u, z


def test_a_stiffness_step_is_flagged_and_the_estimate_restarted():
    n, step_at = 50000, 8000
    u, z = data(n, 1e-5, step_at, 2e-5)
    obs = GyroStateObserver(GYRO, 0.0, 1)
    kxx_true = GYRO.kxx * (1 + 2e-5)
    words, flagged_until = set(), 0.0
    for k in range(n):
        obs.step(u[k], 0.0, z[k, 0], z[k, 1], H)
        if obs.status == 1:
            flagged_until = (k + 1) * H
            words.add((obs.warning or "").split(": ")[1][:20])
    row = obs.output_row()
    kxx_z = (row[5] - kxx_true) / row[13]
    assert obs.restarts >= 1
    assert any(w.startswith("a re-fit of the last") for w in words), words
    assert "restarted along that move" in obs.restart_message
    assert abs(kxx_z) < 3, kxx_z
    assert obs.status == 0 and flagged_until < 0.2, flagged_until
    assert 0 <= obs._c.refit.last_T < 40


def test_the_re_fit_test_is_quiet_where_the_model_fits():
    """Constant rate, noise 1e-4, 60 ms, guesses 5 % off: judged, below its threshold
    (chi-square 8 dof: median ~7), never restarted, status 0 throughout."""
    n = 12000
    u, z = data(n, 1e-4)
    guess = GyroParameters(**{k: getattr(GYRO, k) * (1.05 if i % 2 else 0.95)
                              for i, k in enumerate(PARAMETER_NAMES)})
    obs = GyroStateObserver(guess, 0.0, 1)
    T = []
    for k in range(n):
        obs.step(u[k], 0.0, z[k, 0], z[k, 1], H)
        assert obs.status == 0, (k, obs.warning)
        if k % 200 == 199 and obs._c.refit.last_T >= 0:
            T.append(obs._c.refit.last_T)
    assert len(T) >= 30 and max(T) < 40 and 2 < float(np.median(T)) < 20, T
    assert obs.restarts == 0 and obs.restart_message is None


def test_the_fmu_logs_the_re_fit_and_its_status():
    """GyroObserver.fmu (same core): status 1 after the step, the re-fit's words once in
    its log with the move named, status 0 again by the end."""
    n, step_at = 30000, 8000
    u, z = data(n, 1e-5, step_at, 2e-5)
    start = {f"{k}_0": getattr(GYRO, k) for k in PARAMETER_NAMES}
    inst = Instance(prebuilt_fmu("GyroObserver"), "refit", start)
    status = np.empty(n)
    for k in range(n):
        inst.set({"ux": u[k], "x_meas": z[k, 0], "y_meas": z[k, 1]})
        assert inst.step(H) == 0
        status[k] = inst.get(["status"])[0]
    log = inst.messages()
    inst.close()
    assert status[:step_at].max() == 0
    assert status[step_at:step_at + 4000].max() == 1
    assert "a re-fit of the last 20 ms of data rejects its estimate" in log, log[-2000:]
    assert re.search(r"would move kxx by [+-]\d", log), log[-2000:]


@pytest.mark.parametrize("grade", [3.0, 10.0, 100.0])
def test_the_graded_rough_models_are_the_cores(grade):
    """The adaptive set names its graded rough models from the core's table."""
    from gyro_fmu.core.observer import rough_grades

    assert grade in rough_grades()
    assert f"rough x{grade:g}" in GyroStateObserver(GYRO).rate_models
    assert math.isfinite(grade)
