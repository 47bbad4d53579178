"""Batch output-error identification: recovery from clean runs, CRB, the CSV path."""

from __future__ import annotations

import numpy as np
import pytest

from gyro_fmu.estimation.identify import (
    IdentificationError,
    crb_at,
    identify,
    read_record,
    record_from_result,
)
from gyro_fmu.model.measurement import UNKNOWNS
from gyro_fmu.model.parameters import GyroParameters
from gyro_fmu.system.inprocess import run_inprocess
from gyro_fmu.system.scenario import absolute_noise, scenario


def _truth(sc):
    return {"Omega_z": 1.0, **sc.params.as_dict()}


@pytest.mark.parametrize("pair", [1, 2])
def test_recovers_known_parameters_from_a_short_clean_run(tmp_path, pair):
    sc = scenario("default", stop_time=0.01, measured_pair=pair)
    result = run_inprocess(sc)
    result.write_csv(tmp_path / "results.csv")
    rec = read_record(tmp_path / "results.csv", measured_pair=pair)
    ident = identify(rec, GyroParameters(**sc.initial_guess), 0.0)  # observer's start
    truth = _truth(sc)
    assert ident.success
    assert abs(ident.estimates["Omega_z"] - 1.0) < 1e-8
    for name in UNKNOWNS[1:]:
        assert ident.estimates[name] == pytest.approx(truth[name], rel=1e-8), name
    assert ident.noise_estimated and max(ident.residual_rms) < 1e-12 * np.abs(rec.z).max()


def test_noisy_fit_is_consistent_with_its_bound():
    sc = scenario("default", stop_time=0.01, noise=1e-4, seed=3)
    std = absolute_noise(sc)
    result = run_inprocess(sc, std)
    rec = record_from_result(result)
    ident = identify(rec, GyroParameters(**sc.initial_guess), 0.0)
    truth = _truth(sc)
    bound = crb_at(sc.params, 1.0, rec, (std.x, std.y))
    for name in UNKNOWNS:
        assert abs(ident.estimates[name] - truth[name]) < 5 * bound[name], name
        assert ident.crb_sigma[name] == pytest.approx(bound[name], rel=0.1), name
    # the noise estimated from residuals matches the noise put in
    assert ident.noise_std[0] == pytest.approx(std.x, rel=0.05)
    assert ident.noise_std[1] == pytest.approx(std.y, rel=0.05)


def test_fit_initial_state_from_a_record_that_starts_moving():
    sc = scenario("default", stop_time=0.012)
    result = run_inprocess(sc)
    rec = record_from_result(result)
    k = 400  # drop the first 2 ms: the plant is not at rest at the first sample
    moving = type(rec)(rec.time[k:], rec.u[k:], rec.z[k:], rec.measured_pair)
    ident = identify(moving, GyroParameters(**sc.initial_guess), 0.0, fit_initial_state=True)
    assert abs(ident.estimates["Omega_z"] - 1.0) < 1e-6
    assert ident.estimates["dxy"] == pytest.approx(2.0, rel=1e-6)
    assert ident.initial_state[0] == pytest.approx(result["plant.x"][k], rel=1e-6)


def test_bad_records_are_refused(tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text("time,drive.ux\n0,0\n")
    with pytest.raises(IdentificationError, match="missing column"):
        read_record(path)
