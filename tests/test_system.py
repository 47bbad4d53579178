"""The whole system through four FMUs: identical to the library, and the patent's claim."""

from __future__ import annotations

import numpy as np
import pytest

from gyro_fmu.system.inprocess import run_inprocess
from gyro_fmu.system.run import run_fmus, summary_of
from gyro_fmu.system.scenario import scenario


def test_fmu_run_reproduces_the_in_process_library_run_bit_for_bit(models_dir):
    """FMI, the master and the Jacobi hold add nothing: same numbers as plain library calls."""
    sc = scenario("default", stop_time=0.002, noise=1e-4, seed=3)
    fmu = run_fmus(sc, models_dir)
    lib = run_inprocess(sc)
    for name in lib.columns:
        assert np.array_equal(fmu[name], lib[name]), name


def _python_loop(sc):
    """The in-process run as 0.4's Python loop stepped it (the oracle of the C loop)."""
    from gyro_fmu.estimation.observer import GyroStateObserver, ObserverTuning
    from gyro_fmu.model.parameters import GyroParameters
    from gyro_fmu.model.plant import GyroPlantModel
    from gyro_fmu.system.inprocess import COLUMNS
    from gyro_fmu.system.scenario import absolute_noise, observer_tuning

    drive, rate, h, noise = sc.the_drive, sc.rate, sc.step, absolute_noise(sc)
    plant = GyroPlantModel(sc.params, noise, sc.seed)
    observer = GyroStateObserver(GyroParameters(**sc.initial_guess), sc.Omega_z_0,
                                 sc.measured_pair, ObserverTuning(**observer_tuning(sc, noise)))
    pair = (0, 2) if sc.measured_pair == 1 else (1, 3)
    data = np.empty((sc.n_steps + 1, len(COLUMNS)))
    t_eval = 0.0
    for k in range(sc.n_steps + 1):
        t = k * h
        ux, Om = drive.ux(t_eval), rate.Omega_z(t_eval)
        t_eval = t + h
        z = plant.output_row()
        data[k, 0:4] = t, ux, 0.0, Om
        data[k, 4:10] = z
        data[k, 10:] = [*observer.output_row(), *observer.rate_probabilities().values()]
        if k == sc.n_steps:
            break
        plant.step(ux, 0.0, Om, h)
        observer.step(ux, 0.0, z[pair[0]], z[pair[1]], h)
    return data


@pytest.mark.parametrize(("kind", "changes"), [
    ("constant model", {"noise": 1e-4, "seed": 3}),
    ("adaptive, sine, pair 2", {"noise": 1e-4, "seed": 5, "measured_pair": 2,
                                "tuning": {"rate_model": 0}}),
])
def test_the_c_loop_gives_the_python_loop_s_numbers_bit_for_bit(kind, changes):
    """run_inprocess steps the four in one C call (gyro_chain.c): the same numbers as the
    library's objects stepped from Python, whatever the rate model and measured pair."""
    from gyro_fmu.model.rate import RateProfile

    sc = scenario("default", stop_time=0.003, **{k: v for k, v in changes.items()
                                                  if k in ("noise", "seed")})
    sc = sc.with_(**{k: v for k, v in changes.items() if k not in ("noise", "seed")})
    if "sine" in kind:
        sc = sc.with_(rate=RateProfile.parse("sine:0.5:200"))
    assert np.array_equal(run_inprocess(sc).data, _python_loop(sc))


def test_a_refused_step_and_a_coarse_one_are_said_as_the_python_loop_said_them():
    from gyro_fmu.estimation.observer import CoarseStepWarning
    from gyro_fmu.estimation.observer_monitor import ObserverStepError

    sc = scenario("default", stop_time=0.0012)
    refused = sc.with_(step=1.2e-4)  # samples the resonance at omega h 2.7 > 2.5
    with pytest.raises(ObserverStepError) as c_loop:
        run_inprocess(refused)
    with pytest.raises(ObserverStepError) as python_loop:
        _python_loop(refused)
    assert str(c_loop.value) == str(python_loop.value)
    coarse = sc.with_(step=1e-4)  # omega h 2.25: a warning, and the run goes on
    with pytest.warns(CoarseStepWarning) as c_said:
        data = run_inprocess(coarse).data
    with pytest.warns(CoarseStepWarning) as python_said:
        assert np.array_equal(data, _python_loop(coarse))
    assert [str(w.message) for w in c_said] == [str(w.message) for w in python_said]


@pytest.mark.parametrize("name", ["patent", "default"])
def test_observer_reproduces_the_patent_claim(models_dir, name):
    """Noise off, 5 us, 100 ms: all 8 unknowns within 1% from 80 ms on (dyy = 0 within
    0.1 1/s), and the Omega_hat RMS error over 80-100 ms within 1% of the rate peak."""
    sc = scenario(name)
    summary = summary_of(sc, run_fmus(sc, models_dir))
    assert summary["finite"]
    for unknown, u in summary["unknowns"].items():
        assert u["max_abs_error_tail"] <= u["tolerance"], (unknown, u)
        assert u["converged_within_tolerance_at_s"] is not None
        assert u["converged_within_tolerance_at_s"] <= 0.08, (unknown, u)
    assert summary["unknowns"]["Omega_z"]["rms_error_tail_rel_to_peak"] <= 0.01


def test_a_long_run_shows_its_progress_and_a_short_one_does_not(models_dir, capsys,
                                                                 monkeypatch):
    """A co-simulation of at least run.PROGRESS_STEPS steps (about 2 s) draws a tqdm bar
    on stderr that reaches its total; a shorter one draws nothing."""
    import gyro_fmu.system.run as run

    sc = scenario(stop_time=0.002)  # 401 points
    run_fmus(sc, models_dir)
    assert "co-simulation" not in capsys.readouterr().err
    monkeypatch.setattr(run, "PROGRESS_STEPS", 100)
    run_fmus(sc, models_dir)
    err = capsys.readouterr().err
    assert "co-simulation" in err and "401/401" in err
