"""gyro-fmu spec: the datasheet figures of the observer-based gyro (gyro_fmu/spec/).

The measurement functions against signals of known answer (white rate noise of known
density, a rate random walk of known intensity, a known line, a first-order response,
a known start-up), then the command's exit codes on short runs.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from gyro_fmu import spec
from gyro_fmu.cli import main
from gyro_fmu.estimation.observer import GyroStateObserver, ObserverDivergedError
from gyro_fmu.model.parameters import ParameterError
from gyro_fmu.studies.allan import allan_deviation

#: A short but complete spec run (about 0.9 s simulated); a band wide enough that the
#: noise of a 0.04 s start-up window cannot leave it.
SHORT = ["--duration", "0.4", "--sf-points", "3", "--sf-record", "0.03",
         "--bw-frequencies", "50,3000", "--bw-segment", "0.05", "--startup-band", "0.2",
         "--quiet"]


def test_allan_deviation_of_white_rate_noise_gives_its_density():
    # white rate noise of per-sample std s at step h: N = s sqrt(h) (sigma(tau) = N/sqrt(tau))
    rng = np.random.default_rng(1)
    h, s = 1e-3, 0.02
    x = rng.standard_normal(200_000) * s
    taus = spec.allan_taus(len(x), h)
    adev = allan_deviation(x, h, taus)
    fit = spec.angle_random_walk(taus, adev, len(x), h)
    assert fit["N"] == pytest.approx(s * math.sqrt(h), rel=0.02)
    # on the -1/2 line everywhere: within the estimate's own 1-sigma x 3
    expect = s * math.sqrt(h) / np.sqrt(taus)
    rel = spec.adev_uncertainty(len(x), h, taus)
    assert np.all(np.abs(adev / expect - 1.0) < 3.0 * rel + 0.01)
    # white noise has no flat minimum in the record: only an upper bound
    bi = spec.bias_instability(taus, adev)
    assert not bi["resolved"] and bi["tau_min"] == pytest.approx(taus[-1], rel=0.3)
    # smoothed (an observer's bandwidth): the deviation rises first; no minimum at tau = h
    smooth = np.convolve(x, np.ones(50) / 50, mode="valid")
    adev = allan_deviation(smooth, h, taus[taus < 0.2 * smooth.size * h])
    bi = spec.bias_instability(taus[: adev.size], adev)
    assert bi["tau_min"] > 50 * h and not bi["resolved"]


def test_allan_deviation_of_a_rate_random_walk_gives_its_intensity():
    # rate random walk K (rad/s/sqrt(s)): sigma^2(tau) = K^2 tau / 3 (IEEE 952 Annex C)
    h, K = 1e-3, 0.5
    taus = np.array([0.02, 0.05, 0.1, 0.2])
    ratios = []
    for seed in range(4):
        rng = np.random.default_rng(10 + seed)
        x = np.cumsum(rng.standard_normal(100_000)) * K * math.sqrt(h)
        ratios.append(allan_deviation(x, h, taus) / (K * np.sqrt(taus / 3.0)))
    assert np.mean(ratios, axis=0) == pytest.approx(np.ones(len(taus)), rel=0.12)
    assert np.all(np.abs(spec.local_slopes(taus, np.mean(ratios, axis=0)
                                           * K * np.sqrt(taus / 3.0)) - 0.5) < 0.15)


def test_noise_density_convention():
    # one-sided density D white to Nyquist 1/(2h): variance D^2 / (2h)
    assert spec.density_to_std(1e-14, 5e-6) == pytest.approx(1e-14 / math.sqrt(1e-5))
    cfg = spec.SpecConfig(noise_density=2e-15)
    n = spec.pickoff_noise(cfg)
    assert n.x == n.y == pytest.approx(2e-15 / math.sqrt(2 * 5e-6)) and n.vx == n.vy == 0.0
    told = spec.observer_tuning(cfg, n)
    assert told["sigma_z1"] == n.x and "q_Omega" not in told  # the rate is not declared


def test_scale_factor_fit_of_a_known_line_and_curve():
    r = np.linspace(-5.0, 5.0, 11)
    fit = spec.scale_factor_fit(r, 1.0002 * r + 0.01, 5.0)
    assert fit["sf_error_ppm"] == pytest.approx(200.0, abs=1e-6)
    assert fit["offset_rad_s"] == pytest.approx(0.01, abs=1e-12)
    assert fit["nonlinearity_ppm_fs"] < 1e-6
    # + c r^2 on a symmetric grid: slope unchanged, residual c (r^2 - mean r^2)
    c = 1e-4
    fit = spec.scale_factor_fit(r, r + c * r**2, 5.0)
    m2 = np.mean(r**2)
    assert fit["sf_error_ppm"] == pytest.approx(0.0, abs=1e-6)
    assert fit["offset_rad_s"] == pytest.approx(c * m2)
    assert fit["nonlinearity_ppm_fs"] == pytest.approx(c * (25.0 - m2) / 5.0 * 1e6)
    with pytest.raises(ValueError):
        spec.scale_factor_fit([1.0, 1.0, 1.0], [1.0, 1.0, 1.0], 5.0)


def test_bandwidth_of_a_first_order_response():
    fc = 230.0
    f = np.geomspace(10.0, 5000.0, 16)
    pts = [{"f_hz": x, "gain_db": -10 * math.log10(1 + (x / fc) ** 2)} for x in f]
    bw = spec.bandwidth_3db(pts)
    assert bw["bound"] is None and bw["f_3db_hz"] == pytest.approx(fc, rel=0.05)
    assert spec.bandwidth_3db(pts[:3])["bound"] == "above"
    low = [{"f_hz": x, "gain_db": -10 * math.log10(1 + (x / 1.0) ** 2)} for x in f]
    assert spec.bandwidth_3db(low)["bound"] == "below"


def test_startup_time_of_a_known_transient():
    h, t1, A, band, W = 1e-4, 0.05, 1.0, 0.1, 0.01
    t = (np.arange(2000) + 1) * h
    err = np.where(t <= t1, A, 0.0)
    t_on = spec.startup_time(t, err, band, W, h)
    # the trailing mean A (t1 - (t - W)) / W drops to the band at t = t1 + W (1 - band/A)
    assert t_on == pytest.approx(t1 + W * (1 - band / A), abs=2 * h)
    assert spec.startup_time(t, err + 0.5, band, W, h) is None  # a bias beyond the band


def test_stationarity_check_tells_a_tracking_output_from_a_growing_average():
    rng = np.random.default_rng(3)
    h = 1e-4
    w = rng.standard_normal(100_000)
    taus = [1e-3, 2e-3, 5e-3]
    assert spec.check_stationary(w, h, taus)["stationary"]
    # the error of an estimate that averages forever: the running mean of the noise
    running = np.cumsum(w) / np.arange(1, w.size + 1)
    assert not spec.check_stationary(running[1000:], h, taus)["stationary"]


def test_allan_study_refuses_noise_figures_of_a_growing_average():
    # what a constant rate model does: Omega_hat the running mean of the information
    rng = np.random.default_rng(4)
    h, n = 1e-4, 100_000
    err = np.cumsum(rng.standard_normal(n) * 0.1) / np.arange(1, n + 1)
    rec = spec.Record((np.arange(n) + 1) * h, err, np.zeros(n), [], 0.0)
    cfg = spec.SpecConfig(step=h, duration=n * h, startup_band=0.05, bw_frequencies=(10, 100))
    a = spec.allan_study(rec, cfg)
    assert a["arw_rad_s_per_sqrt_hz"] is None and a["bias_instability_rad_s"] is None
    assert "not stationary" in a["noise_figures_refused"]
    # white noise of the same record length: the figures are given
    w = rng.standard_normal(n) * 0.01
    a = spec.allan_study(spec.Record(rec.t, w, np.zeros(n), [], 0.0), cfg)
    assert a["noise_figures_refused"] is None
    assert a["arw_rad_s_per_sqrt_hz"] == pytest.approx(0.01 * math.sqrt(h), rel=0.05)


def test_config_refuses_bad_inputs():
    with pytest.raises(ParameterError, match="unknown observer tuning"):
        spec.SpecConfig(tuning={"no_such_field": 1.0})
    with pytest.raises(ParameterError, match="bw_frequencies"):
        spec.SpecConfig(bw_frequencies=(10.0, 1e6))
    with pytest.raises(ParameterError):
        spec.SpecConfig(duration=-1.0)


def test_cli_measures_a_short_spec(tmp_path, capsys):
    out = tmp_path / "spec"
    assert main(["spec", *SHORT, "--out", str(out)]) == 0
    text = capsys.readouterr().out
    for figure in ("angle random walk", "bias instability", "bandwidth (-3 dB)",
                   "scale-factor error", "nonlinearity", "start-up time", "wall time"):
        assert figure in text
    s = json.loads((out / "summary.json").read_text())
    assert (out / "spec.png").stat().st_size > 10_000
    a = s["allan"]
    if a["noise_figures_refused"] is None:  # a rate model of stated bandwidth
        assert 1e-4 < a["arw_rad_s_per_sqrt_hz"] < 1e-1  # noise 1e-4 of peak: ~2.5e-3
        assert a["arw_deg_per_sqrt_h"] == pytest.approx(
            a["arw_rad_s_per_sqrt_hz"] * math.degrees(1) * 60)
    else:  # an observer that averages ever longer at a constant rate
        assert a["arw_rad_s_per_sqrt_hz"] is None and "n/a" in text
    assert abs(s["scale_factor"]["sf_error_ppm"]) < 1e3
    assert s["rate_response"]["f_3db_hz"] > 50.0
    assert "_startup_trace" not in s


def test_cli_exit_2_on_bad_tuning_name(tmp_path, capsys):
    assert main(["spec", "--tuning", "nonsense=1", "--out", str(tmp_path / "x")]) == 2
    assert "nonsense" in capsys.readouterr().err
    assert main(["spec", "--noise", "1e-4", "--noise-density", "1e-15",
                 "--out", str(tmp_path / "x")]) == 2


def test_cli_exit_2_when_the_estimate_never_settles(tmp_path, capsys):
    out = tmp_path / "spec"
    assert main(["spec", *SHORT, "--startup-band", "1e-6", "--startup-window", "0.01",
                 "--duration", "0.2", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "never settles" in err and "remedy" in err
    assert not (out / "summary.json").exists()


def test_cli_exit_2_when_the_observer_is_lost(tmp_path, capsys, monkeypatch):
    real = GyroStateObserver.step
    calls = {"n": 0}

    def step(self, *args):
        calls["n"] += 1
        if calls["n"] > 2000:
            raise ObserverDivergedError("covariance lost positive definiteness (test)")
        return real(self, *args)

    monkeypatch.setattr(GyroStateObserver, "step", step)
    out = tmp_path / "spec"
    assert main(["spec", *SHORT, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "observer was lost" in err and "status 2" in err
    assert not (out / "summary.json").exists()
