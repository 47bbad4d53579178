"""A warm-up through the calibration sequence: the resonator's temperature runs on
across the records (ResonatorParameters.later), every channel is demodulated on the
loops' smoothed NCO phase, and the second record's frequencies are shifted by the
carriers' own drift (phasors.carrier_shifts). Judged against a rate table of the
instrument held at the temperature of the mode-1 record (the read-out's)."""

from __future__ import annotations

from dataclasses import replace

import pytest

import gyro_fmu.selfcal.stream as stream
from gyro_fmu.model.resonator import ResonatorParameters
from gyro_fmu.selfcal.alarms import CalibrationRefusedError
from gyro_fmu.selfcal.design import design
from gyro_fmu.selfcal.ratetable import rate_table
from gyro_fmu.selfcal.sequence import FeedForward, self_calibrate

RAMP, TC_F = 0.05, -30e-6  # K/s (5x the fastest warm-up of the issue), 1/K
WARMING = replace(ResonatorParameters(), temperature_rate=RAMP, tc_f=TC_F)
SHORT = dict(settle=3.0, record=5.0, sideband_spacing=0.4, sideband_count=3,
             ff_duration=0.2, auto_record=False)


def test_the_temperature_history_is_the_cores() -> None:
    later = WARMING.later(40.0)  # 2 K on: f by tc_f, Q by tc_Q (gyro_resonator_at_temperature)
    assert later.temperature == pytest.approx(302.0, abs=1e-12)
    assert later.f_x / WARMING.f_x - 1 == pytest.approx(2 * TC_F, rel=1e-9)
    assert replace(WARMING, tc_Q=-1e-3).later(40.0).Q_y / WARMING.Q_y - 1 == pytest.approx(-2e-3)
    assert later.temperature_rate == RAMP  # the ramp goes on from there
    assert ResonatorParameters().later(40.0) == ResonatorParameters()  # no ramp, no change


def test_a_warm_up_through_the_sequence_is_calibrated() -> None:
    cfg = design(WARMING, **SHORT)
    result = self_calibrate(WARMING, cfg)
    m1, m2 = result.modes
    assert m2.t_center - m1.t_center == pytest.approx(cfg.settle + cfg.record)
    for md in result.modes:  # the PLL follows the resonator: tc_f dT/dt
        assert md.drift == pytest.approx(TC_F * RAMP, rel=0.01)
    assert m2.shift == pytest.approx(TC_F * RAMP * (m2.t_center - m1.t_center), rel=0.01)
    ff = FeedForward(result.feedthrough, result.rho, result.feedthrough * 0)
    held = replace(WARMING.later(m1.t_center).without_noise(), temperature_rate=0.0)
    table = rate_table(held, ff, cfg)
    # noise-free records: what is left is the model's, well inside the targets
    assert abs(result.bias - table.bias) < 7.27e-5 / 100
    assert abs(result.scale_factor / table.scale_factor - 1) * 1e6 < 100 / 20
    assert result.misfit_ratio < 2.0


def test_demodulating_at_a_fixed_frequency_is_refused(monkeypatch) -> None:
    # what the demodulation on the NCO phase fixes: at the record's mean frequency the
    # drifting carrier smears the sidebands (misfit 35-2,357 against white noise alone).
    # The smear reaches the bins between the tones too, where the noise model measures
    # it as force noise: the 1-sigmas grow past the targets and it is refused
    smoothed = stream.nco_phase

    def fixed(*args):
        return replace(smoothed(*args), c2=0.0, c3=0.0)

    monkeypatch.setattr(stream, "nco_phase", fixed)
    with pytest.raises(CalibrationRefusedError) as refused:
        self_calibrate(WARMING, design(WARMING, **SHORT))
    untrusted = refused.value.result
    assert untrusted.sigma_bias > 10 * 7.27e-5 / 3


def test_a_lot_with_a_warm_up_holds_the_same_resonators() -> None:
    from gyro_fmu.selfcal.lot import LotModel

    still, warming = LotModel().draw(5), LotModel(ramp_max=0.01).draw(5)
    for a, b in zip(still, warming, strict=True):
        assert "temperature_rate" not in a["instrument"]
        rest = {k: v for k, v in b["instrument"].items() if k not in ("temperature_rate", "tc_f")}
        assert rest == a["instrument"]
        assert 0.0 <= b["instrument"]["temperature_rate"] <= 0.01
        assert -40e-6 <= b["instrument"]["tc_f"] <= -20e-6


def test_a_rate_that_changes_between_the_records_is_refused_by_name(monkeypatch) -> None:
    # the simulator's history is a steady ramp: make the second record's carrier drift
    # read 200 times the first's (a rate changing between the records; 20 times left
    # a 1-sigma of 4.2e-6 rad/s from the shift, under a third of the target: calibrated)
    smoothed, calls = stream.nco_phase, []

    def changing(*args):
        nco = smoothed(*args)
        calls.append(nco.drift)
        return replace(nco, drift=nco.drift * (200.0 if len(calls) % 2 == 0 else 1.0))

    monkeypatch.setattr(stream, "nco_phase", changing)
    with pytest.raises(CalibrationRefusedError, match="rate changed between the records"):
        self_calibrate(WARMING, design(WARMING, **SHORT))


def test_calibrations_during_a_warm_up_follow_the_rate_table(tmp_path) -> None:
    """Back to back through 1.5 K at 0.05 K/s (16.3 s per SHORT sequence: 0.8 K each),
    noise-free: each point is checked against the rate table at its own temperature,
    whose scale factor falls by tc_f per kelvin (the bias by what tc_Q moves)."""
    from gyro_fmu.selfcal.warmup import warmup_curve, write_curve

    res = replace(WARMING, tc_Q=-1e-3)
    cfg = design(res, **SHORT)
    points = warmup_curve(res, cfg, 1.5)
    assert [p.status for p in points] == ["good", "good"]
    warmer = points[1].temperature - points[0].temperature
    assert warmer == pytest.approx(RAMP * (cfg.ff_duration + 0.1 + 2 * (3.0 + 5.0)), rel=1e-6)
    drop = points[1].table_sf_ppm - points[0].table_sf_ppm
    assert drop == pytest.approx(TC_F * 1e6 * warmer, abs=3.0)  # -24 ppm
    for p in points:
        assert abs(p.d_bias) < 7.27e-5 / 20 and abs(p.d_sf_ppm) < 100 / 10
    paths = write_curve(points, tmp_path, {"span_K": 1.5})
    assert [p.name for p in paths] == ["warmup.csv", "summary.json", "warmup.png"]
    assert len((tmp_path / "warmup.csv").read_text().splitlines()) == 3



def test_a_lot_with_matched_modes_holds_the_same_resonators_else() -> None:
    from gyro_fmu.selfcal.lot import LotModel

    split, matched = LotModel().draw(40), LotModel(split_zero=0.25).draw(40)
    zero = [b["instrument"]["f_y"] == b["instrument"]["f_x"] for b in matched]
    assert 4 <= sum(zero) <= 18  # 10 expected
    for a, b, z in zip(split, matched, zero, strict=True):
        assert a["instrument"]["f_y"] != a["instrument"]["f_x"]
        rest = {k: v for k, v in b["instrument"].items() if k != "f_y"}
        assert rest == {k: v for k, v in a["instrument"].items() if k != "f_y"}
        assert z or b["instrument"]["f_y"] == a["instrument"]["f_y"]
