"""Monte Carlo sweep on a local Dask cluster: real FMU runs, a failing gyro is recorded."""

from __future__ import annotations

import csv
import json

import pytest

pytest.importorskip("dask.distributed")

from gyro_fmu.system.sweep import SweepSpec, ToleranceModel, run_sweep, write_outputs


def test_tolerance_draws_are_seeded_and_bounded():
    tm = ToleranceModel(spread={"kxx": 0.1, "dxy": 0.5}, seed=3)
    a, b = tm.draw(50), tm.draw(50)
    assert a == b
    nominal = tm.nominal
    for d in a:
        assert abs(d["kxx"] / nominal["kxx"] - 1) <= 0.1
        assert abs(d["dxy"] / nominal["dxy"] - 1) <= 0.5
        assert d["kyy"] == nominal["kyy"]  # no spread given: no scatter
    assert ToleranceModel(seed=4).draw(1) != ToleranceModel(seed=5).draw(1)
    with pytest.raises(ValueError):  # ParameterError is a ValueError
        ToleranceModel(spread={"kzz": 0.1})


def test_three_gyro_sweep_with_one_failure(tmp_path, models_dir):
    spec = SweepSpec(tolerances=ToleranceModel(seed=1), n=2, stop_time=0.002, noise=1e-5)
    draws = spec.tolerances.draw(2)
    bad = {**draws[0], "kxy": 1e9}  # K not positive definite: the plant would diverge
    res = run_sweep(spec, models_dir, n_workers=2, draws=[draws[0], bad, draws[1]],
                    progress=False)
    assert [r["gyro"] for r in res.rows] == [0, 1, 2]
    assert [r["status"] for r in res.rows] == ["ok", "failed", "ok"]
    failed = res.rows[1]
    assert "positive definite" in failed["reason"]
    assert failed["true_kxy"] == 1e9  # its parameters are kept
    for r in res.ok:
        assert r["true_kxx"] != spec.tolerances.nominal["kxx"]
        assert abs(r["err_Omega_z"]) < 2.0 and r["wall_s"] > 0
    paths = write_outputs(res, tmp_path)
    with (tmp_path / "sweep.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 3 and rows[1]["status"] == "failed"
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["n"] == 3 and summary["failed"] == 1
    assert (tmp_path / "sweep_histograms.png").stat().st_size > 1000
    assert all(p.exists() for p in paths)
