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
