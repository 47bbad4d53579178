"""Monte Carlo sweep on a local Dask cluster: real FMU runs, a failing gyro is recorded."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

pytest.importorskip("dask.distributed")

from gyro_fmu.system.sweep import SweepSpec, ToleranceModel, run_sweep
from gyro_fmu.system.sweep_report import write_outputs


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
    # the bound: each ok gyro against its own Cramer-Rao bound, the failed one without
    for r in res.ok:
        assert r["crb_Omega_z"] > 0 and np.isfinite(r["err_over_crb_Omega_z"])
        assert 0 < r["p_eff_Omega_z"] <= 1 and 0 < r["p_eff_all"] <= r["p_eff_Omega_z"] + 0.02
    assert "crb_Omega_z" not in failed
    b = summary["bound"]
    assert b["n"] == 2 and set(b["per_unknown"]) == set(summary["per_unknown"])
    assert 0 <= b["all"]["efficient_fraction_within_tol"] <= 1
    assert b["per_unknown"]["Omega_z"]["rms_err_over_crb"] > 0
    conv = summary["convergence_time_s"]
    assert conv["never_or_failed"] >= 1  # the failed gyro never converges
    curve = summary["within_curve"]
    assert len(curve["t_s"]) == len(curve["fraction_within_tol"]) == 40
    assert curve["t_s"][-1] == pytest.approx(spec.stop_time)
    assert all(0 <= v <= 1 for v in curve["efficient_fraction_within_tol"] if v is not None)
    from gyro_fmu.system.sweep_cli import _print_bound

    _print_bound(b)
    _print_bound(None)


# --------------------------------------------------------------------------- the bound


def _drive_record(p, h=5e-6, window=0.02):
    """Record of the scenario's drive (crb_at needs only the inputs; z is not used)."""
    from gyro_fmu.estimation.identify import make_record
    from gyro_fmu.system.scenario import scenario

    drive = scenario("default").the_drive
    t = np.arange(round(window / h)) * h
    ux = np.array([drive.ux(tk) for tk in t])
    return make_record(t, ux, np.zeros_like(t), np.zeros((t.size, 2)))


@pytest.mark.parametrize("m", [0.5, 1e3])
def test_crb_at_keeps_its_precision_at_tiny_displacements(m):
    """A heavy proof mass on the same drive: displacements 1e-15 .. 1e-18 m and noise
    1e-19 .. 1e-22 m. The problem only scales (z and the noise by m0/m), so the bounds
    relative to each unknown (and Omega_z absolute) must not change."""
    from gyro_fmu.estimation.identify import crb_at
    from gyro_fmu.model.parameters import preset
    from gyro_fmu.system.lot_bound import bound_correlation
    from gyro_fmu.system.scenario import scenario

    p0 = preset("park-horowitz")
    p1 = preset("park-horowitz", m=m)
    rec = _drive_record(p0)
    std0 = (6.6e-13, 4.8e-13)  # noise 1e-4 of the default run's peaks
    scale = p0.m / m
    std1 = (std0[0] * scale, std0[1] * scale)
    a = crb_at(p0, 1.0, rec, std0)
    b = crb_at(p1, 1.0, rec, std1)
    assert 1e-4 < a["Omega_z"] < 1.0  # a genuine, finite bound
    for name in a:
        ref = 1.0 if name == "Omega_z" else getattr(p0, name)
        ref1 = 1.0 if name == "Omega_z" else getattr(p1, name)
        assert b[name] / ref1 == pytest.approx(a[name] / ref, rel=1e-9), name
    c0 = bound_correlation(scenario("default"), 1.0, rec, std0)
    c1 = bound_correlation(scenario("default", overrides={"m": m}), 1.0, rec, std1)
    assert np.allclose(np.diag(c0), 1.0) and np.allclose(c0, c0.T)
    assert np.allclose(c1, c0, atol=1e-9)


def test_bound_covariance_matches_crb_at():
    """The sweep's covariance (correlations, the curve) is crb_at's: same sensitivities,
    same diagonal, over the whole record and over its first samples."""
    from gyro_fmu.estimation.identify import crb_at
    from gyro_fmu.system.lot_bound import fisher_covariance, weighted_sensitivities
    from gyro_fmu.system.scenario import scenario

    sc = scenario("default")
    rec = _drive_record(sc.params)
    std = (6.6e-13, 4.8e-13)
    J = weighted_sensitivities(sc, 1.0, rec, std)
    for n in (rec.time.size, 1000):
        sig = np.sqrt(np.diag(fisher_covariance(J, n)))
        crb = crb_at(sc.params, 1.0, rec.head(n), std)
        assert sig == pytest.approx([crb[k] for k in crb], rel=1e-6)


def _result(conv):
    from gyro_fmu.system.sweep_report import SweepResult

    rows = [{"gyro": i, "status": "ok", "conv_s_all": c} for i, c in enumerate(conv)]
    return SweepResult(rows, SweepSpec(n=len(rows)), 1.0, 1)


def test_within_curve_and_its_deadlines():
    from gyro_fmu.system.lot_bound import curve_times
    from gyro_fmu.system.sweep_report import SweepResult

    spec = SweepSpec(n=4, stop_time=0.004, step=1e-4)
    t = curve_times(spec)
    assert t[-1] == pytest.approx(0.004) and len(t) == 40
    rows = [{"gyro": i, "status": "ok", "within_all_curve": [j >= 10 * i for j in range(40)],
             "p_eff_all_curve": [min(1.0, 0.03 * j) for j in range(40)]} for i in range(4)]
    res = SweepResult(rows, spec, 1.0, 1)
    c = res.within_curve()
    assert c["fraction_within_tol"][0] == 0.25 and c["fraction_within_tol"][-1] == 1.0
    d = res.curve_deadlines(0.95)
    assert d["instant_deadline_for_fraction_s"] == pytest.approx(t[30])  # all 4 from j 30
    assert d["efficient_deadline_for_fraction_s"] == pytest.approx(t[32])  # 0.03 j >= 0.95
    rows[0]["within_all_curve"][-1] = False  # one gyro leaves at the end: not within
    assert res.curve_deadlines(0.95)["instant_deadline_for_fraction_s"] is None


def test_deadline_for_95_percent_of_the_lot():
    times = [0.001 * (k + 1) for k in range(40)]  # 1 .. 40 ms
    d = _result(times).deadline_for(0.95)
    assert d["deadline_for_fraction_s"] == pytest.approx(0.038)  # 38 of 40
    assert d["never_or_failed"] == 0
    d = _result([*times[:38], None, None]).deadline_for(0.95)  # 2 of 40 never: 5 %
    assert d["deadline_for_fraction_s"] == pytest.approx(0.038)
    d = _result([*times[:37], None, None, None]).deadline_for(0.95)  # 7.5 % never
    assert d["deadline_for_fraction_s"] is None and d["never_or_failed"] == 3
    assert _result([]).deadline_for()["deadline_for_fraction_s"] is None


def test_fmu_tunings_put_back_the_observer_defaults():
    from gyro_fmu.estimation.observer_tuning import ObserverTuning
    from gyro_fmu.system.scenario import absolute_noise, observer_tuning

    d = ObserverTuning()
    scen = SweepSpec(noise=1e-4).base_scenario()
    told = observer_tuning(scen, absolute_noise(scen))  # constant-rate model, noise told
    assert told["sigma_z1"] > 0 and set(told) - {"sigma_z1", "sigma_z2"}
    rate = SweepSpec(noise=1e-4, observer_tuning="fmu-rate").base_scenario()
    assert set(rate.tuning) == set(told) - {"sigma_z1", "sigma_z2"}
    assert all(v == getattr(d, k) for k, v in rate.tuning.items())
    fmu = SweepSpec(noise=1e-4, observer_tuning="fmu").base_scenario()
    assert set(fmu.tuning) == set(told)
    assert observer_tuning(fmu, absolute_noise(fmu)) == {k: getattr(d, k) for k in told}
    key = next(iter(rate.tuning))
    user = SweepSpec(observer_tuning="fmu", tuning={key: 3}).base_scenario()
    assert user.tuning[key] == 3  # --tuning wins
    with pytest.raises(ValueError):
        SweepSpec(observer_tuning="adaptive-ish")


def test_a_heavy_proof_mass_gives_the_same_gyro_and_bound(models_dir):
    """--set m=0.5 (displacements ~1e-15 m): the same observer errors and bound in units
    of each unknown as the nominal part, through the real FMUs."""
    from gyro_fmu.system.sweep import run_gyro

    rows = []
    for over in ({}, {"m": 0.5}):
        spec = SweepSpec(tolerances=ToleranceModel(overrides=over, seed=2), n=1,
                         stop_time=0.01, noise=1e-4, batch=True)
        rows.append(run_gyro(0, spec.tolerances.draw(1)[0], spec, str(models_dir)))
    a, b = rows
    assert a["status"] == b["status"] == "ok", (a["reason"], b["reason"])
    assert b["true_m"] / a["true_m"] == pytest.approx(0.5 / 1.8e-7)
    assert b["noise_std_z1"] / a["noise_std_z1"] == pytest.approx(a["true_m"] / b["true_m"])
    for name in ("Omega_z", "kxx", "dxy", "m"):
        assert b[f"err_over_crb_{name}"] == pytest.approx(a[f"err_over_crb_{name}"],
                                                          rel=1e-5, abs=1e-6), name
        assert b[f"p_eff_{name}"] == pytest.approx(a[f"p_eff_{name}"], rel=1e-9)
    assert 0.0 < a["p_eff_all"] <= 1.0 and b["p_eff_all"] == a["p_eff_all"]
    # the batch ML identifier on the same samples: at the bound, at either scale
    assert a["batch_success"] and b["batch_success"]
    for name in ("Omega_z", "dxy"):
        assert abs(a[f"batch_err_over_crb_{name}"]) < 4.0
        assert b[f"batch_err_over_crb_{name}"] == pytest.approx(
            a[f"batch_err_over_crb_{name}"], abs=1e-3)


def test_the_drive_reaches_every_gyro():
    from gyro_fmu.model.drive import TwoToneDrive

    drive = TwoToneDrive(A1=2e-7, A2=1e-7, f1=3000.0, f2=1500.0)
    spec = SweepSpec(drive=drive)
    assert spec.scenario_for(3, spec.tolerances.draw(4)[3]).the_drive == drive
    assert SweepSpec().base_scenario().the_drive.f1 != 3000.0


def test_the_log_histogram_bins_hold_every_sample():
    """The sweep's log histograms could drop the smallest sample: 10 ** log10(v) rounds
    above v for about 1 value in 20,000, 1.9871236148527986 among them."""
    from gyro_fmu.system.sweep_report import log_bins

    v = np.array([1.9871236148527986, 3.0, 40.0])
    edges = np.logspace(math.log10(v.min()), math.log10(v.max()), 31)
    assert np.histogram(v, bins=edges)[0].sum() == 2  # the smallest one lost
    assert np.histogram(v, bins=log_bins(v, 30))[0].sum() == 3
    rng = np.random.default_rng(5)
    for _ in range(200):
        v = 10.0 ** rng.uniform(-6, 3, size=int(rng.integers(1, 50)))
        counts, _ = np.histogram(v, bins=log_bins(v, 30))
        assert counts.sum() == v.size
