"""The streaming demodulator (gyro_fmu.selfcal.stream over the core's gyro_demod.c):
its filter against numpy's convolution of the same record, its response against pure
tones, the noise between the grid's tones, the lock statistics against the rows, the
phasors of a real record against the full-record demodulation it replaced
(tests/oracle_selfcal/full_rate.py), and the FMU path bit for bit against in-process.

Tolerances: the filter is the same arithmetic as numpy's up to summation order (1e-12
of the signal); a tone's image at -2 omega0 is attenuated to (1 / (B sin(2 pi f0 h)))^5,
below 1e-9 here; against the full record, the phasors differ by a common phase (the NCO
fit on other samples) that cancels in the transfer functions eq. 19 fits; with it
removed, every phasor agrees within 0.05 of its own noise (measured; 0.2 asked).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from oracle_selfcal import full_rate

from gyro_fmu.core import selfcal as c
from gyro_fmu.model.resonator import ResonatorError, ResonatorParameters
from gyro_fmu.selfcal.inprocess import COLUMNS, CarrierSimulation
from gyro_fmu.selfcal.phasors import baseband_off_grid
from gyro_fmu.selfcal.sequence import SelfCalConfig, measure_feedforward, record_mode
from gyro_fmu.selfcal.stream import Demodulator, decimation, stream_record

H = 25e-6
F0 = 4000.3
COL = {name: i for i, name in enumerate(COLUMNS)}


def synthetic(r0: int, n: int, band: float, signals: dict, seed: int = 0,
              drive_limit: float = 5.0) -> tuple[Demodulator, np.ndarray]:
    """A Demodulator fed rows whose columns are signals[name](t) (others random), in
    chunks of random sizes; (demodulator, rows)."""
    dem = Demodulator(H, r0, n, band, drive_limit)
    k = np.arange(dem.last_step + 1)
    t = k * H
    rng = np.random.default_rng(seed)
    rows = rng.normal(size=(len(k), len(COLUMNS)))
    rows[:, COL["time"]] = t
    rows[:, COL["omega"]] = 2 * math.pi * F0
    rows[:, COL["theta"]] = np.mod(2 * math.pi * F0 * t, 2 * math.pi)
    for name, fn in signals.items():
        rows[:, COL[name]] = fn(t)
    start = 0
    while start < len(rows):
        size = int(rng.integers(1, 50_000))
        dem.feed(rows[start:start + size], start)
        start += size
    return dem, rows


def tone(f: float, amp: complex):
    return lambda t: np.real(amp * np.exp(2j * math.pi * (F0 + f) * t))


def test_kernel_is_cascaded_boxcars() -> None:
    lib = c.selfcal_core()
    for B in (1, 2, 7, 250):
        got = np.zeros(c.DEMOD_ORDER * B)
        lib.gyro_demod_kernel(B, got.ctypes.data_as(c.POINTER(c.c_double)))
        want = np.ones(1)
        for _ in range(c.DEMOD_ORDER):
            want = np.convolve(want, np.ones(B) / B)
        np.testing.assert_allclose(got[: len(want)], want, rtol=0, atol=1e-15)
        assert not got[len(want):].any() and got.sum() == pytest.approx(1.0, abs=1e-14)


def test_filter_is_numpys_convolution_and_tones_come_out_times_the_response() -> None:
    tones = {-30.0: 0.3 - 0.2j, -4.2: 1.0, 0.0: 0.5j, 1.4: -0.7, 12.6: 0.05 + 0.1j}
    vx = lambda t: sum(tone(f, a)(t) for f, a in tones.items())  # noqa: E731
    r0, n = 4000, 80_000
    dem, rows = synthetic(r0, n, 10.0, {"Vx": vx})
    rec = dem.result()
    assert rec.B == decimation(n, H, 10.0) and n % rec.B == 0 and len(rec.base) == n // rec.B
    # numpy: mix down, convolve with the same (symmetric) kernel, read at the last step
    # of each output's window (first_step + b B .. + ORDER (B - 1))
    z = rows[:, COL["Vx"]] * np.exp(-1j * 2 * math.pi * F0 * rows[:, COL["time"]])
    y = np.convolve(z, dem.kernel[: c.DEMOD_ORDER * (rec.B - 1) + 1])
    last = dem.first_step + np.arange(len(rec.base)) * rec.B + c.DEMOD_ORDER * (rec.B - 1)
    np.testing.assert_allclose(rec.base[:, 0], y[last], rtol=0, atol=1e-12)
    # each tone comes out at the output's centre time, times the filter's response
    t = rec.t_base
    want = sum(0.5 * a * rec.response(np.array(f)) * np.exp(2j * math.pi * f * t)
               for f, a in tones.items())
    assert np.max(np.abs(rec.base[:, 0] - want)) < 1e-9
    assert rec.response(np.array(12.6)) < 1.0 and rec.response(np.array(0.0)) == 1.0


def test_off_grid_bins_hold_the_noise_not_the_tones() -> None:
    """The grid's tones leave nothing between its bins; white noise of variance s^2 per
    full-rate sample leaves E|2 Y / n|^2 = 4 s^2 / N there (the mean of 12 records x 60
    bins: 4 % standard error)."""
    spacing, std = 0.4, 1e-3
    n = round(4 / spacing / H)  # 4 FFT bins per grid step
    js = np.arange(-10, 11)
    rng = np.random.default_rng(2)
    amps = rng.normal(size=js.size) + 1j * rng.normal(size=js.size)
    clean = lambda t: sum(tone(j * spacing, a)(t) for j, a in zip(js, amps, strict=True))  # noqa: E731

    def off(signal) -> tuple[np.ndarray, np.ndarray]:
        rec = synthetic(4000, n, 10.0, {"Vx": signal}, seed=int(rng.integers(1 << 30)))[0].result()
        return baseband_off_grid(rec.base[:, 0], rec.B * H, np.zeros(len(rec.base)), spacing,
                                 js, lambda j: rec.response(j * spacing))

    where, values = off(clean)
    assert where.size == 60 and np.all(where % 1 != 0)
    assert np.max(np.abs(values)) < 1e-9 * np.max(np.abs(amps))
    power = [np.abs(off(lambda t: clean(t) + std * rng.standard_normal(len(t)))[1]) ** 2
             for _ in range(12)]
    assert np.mean(power) / (4 * std**2 / n) == pytest.approx(1.0, abs=0.12)


def test_lock_statistics_nco_phase_and_tail_are_the_records() -> None:
    r0, n = 3000, 50_000
    theta = lambda t: np.mod(2 * math.pi * (F0 + 0.7) * t + 0.3 * np.sin(9 * t), 2 * math.pi)  # noqa: E731
    dem, rows = synthetic(r0, n, 20.0, {"gain": lambda t: np.sin(40 * t) * 6.0,
                                        "theta": theta}, seed=5, drive_limit=5.0)
    rec = dem.result()
    part = rows[r0:r0 + n]
    assert rec.worst_phase_error == np.max(np.abs(part[:, COL["phase_error"]]))
    assert rec.mean_amplitude == pytest.approx(np.mean(part[:, COL["amplitude"]]), rel=1e-12)
    assert rec.pinned_fraction == np.mean(part[:, COL["gain"]] >= 5.0)
    assert rec.gain_peak == np.max(part[:, COL["gain"]])
    assert rec.gain_mean == pytest.approx(np.mean(part[:, COL["gain"]]), rel=1e-9, abs=1e-12)
    assert np.array_equal(rec.tail, part[-len(rec.tail):, [COL["Vpx"], COL["Vpy"]]])
    # the NCO phase less omega0 t, unwrapped and filtered like the channels
    t = rows[dem.first_step:, COL["time"]]
    departure = np.unwrap(rows[dem.first_step:, COL["theta"]] - 2 * math.pi * F0 * t)
    y = np.convolve(departure, dem.kernel[: c.DEMOD_ORDER * (rec.B - 1) + 1])
    last = np.arange(len(rec.base)) * rec.B + c.DEMOD_ORDER * (rec.B - 1)
    turns = (rec.theta[0] - y[last[0]]) / (2 * math.pi)
    assert turns == pytest.approx(round(turns), abs=1e-9)
    # (numpy subtracts omega0 t from 1e3 rad each step: its rounding is 1e-12 rad)
    np.testing.assert_allclose(rec.theta - 2 * math.pi * round(turns), y[last], rtol=0,
                               atol=1e-8)
    want = 2 * math.pi * 0.7 * rec.t_base + 0.3 * np.sin(9 * rec.t_base) * rec.response(
        np.array(9 / (2 * math.pi)))
    offset = rec.theta - want
    assert np.ptp(offset - 2 * math.pi * np.round(offset / (2 * math.pi))) < 1e-6


def test_a_missing_step_and_a_record_without_room_are_refused() -> None:
    dem = Demodulator(H, 4000, 40_000, 10.0, 5.0)
    rows = np.zeros((10, len(COLUMNS)))
    dem.feed(rows, dem.first_step)
    with pytest.raises(ResonatorError, match=f"step {dem.first_step + 11} fed where "
                                             f"{dem.first_step + 10} was expected"):
        dem.feed(rows, dem.first_step + 11)
    with pytest.raises(ResonatorError, match="settle for at least"):
        Demodulator(H, 10, 40_000, 10.0, 5.0)
    with pytest.raises(ResonatorError, match="ended early"):
        dem.result()


def test_memory_does_not_grow_with_the_record() -> None:
    """What a 120 s record keeps, at 4 and 30 kHz (400 B per step held whole: 1.9 and
    14 GB)."""
    for f in (4000, 30000):
        h = 1.0 / (10 * f)
        dem = Demodulator(h, 10_000, round(120 / h), 3 * 7 * 2.0 + 5.0, 5.0)
        kept = sum(a.nbytes for a in (dem.base, dem.theta, dem.tail, dem.kernel))
        assert kept < 20e6, (f, kept)


@pytest.fixture(scope="module")
def preset_records():
    res = replace(ResonatorParameters(), noise=2.5e-4)
    cfg = SelfCalConfig(record=10.0, settle=8.0, ff_duration=1.0, auto_record=False)
    ff = measure_feedforward(res, cfg)
    return res, cfg, ff


@pytest.mark.parametrize("mode", [1, 2])
def test_streamed_phasors_match_the_full_record(preset_records, mode: int) -> None:
    res, cfg, ff = preset_records
    streamed, _ = record_mode(res, cfg, mode, ff)
    lo = replace(cfg.loops, mode=mode, sideband_index=cfg.sideband_index,
                 sideband_spacing=cfg.sideband_spacing, sideband_first=1,
                 sideband_count=cfg.sideband_count, sideband_start=0.0,
                 ff_xx=ff.E[0, 0], ff_xy=ff.E[0, 1], ff_yx=ff.E[1, 0], ff_yy=ff.E[1, 1])
    whole = CarrierSimulation(res, lo, seed=cfg.seed + mode, step=cfg.step).run(
        cfg.settle + cfg.record, record_from=cfg.settle)
    oracle = full_rate.mode_phasors(whole, mode, ff.E, cfg.sideband_spacing,
                                    cfg.sideband_count)
    # the NCO fit on filtered samples against every 10th raw one (whose ripple at twice
    # the carrier aliases near 0 Hz): within 2e-3 of the grid's step
    assert abs(streamed.omega_osc - oracle.omega_osc) < 2e-3 * 2 * math.pi * cfg.sideband_spacing
    primary = mode - 1
    # a common phase (the NCO fits differ by ~4e-4 rad/s): removed, every phasor within
    # a fraction of its channel's noise (a Hann phasor's 1-sigma: sqrt(6 / 4) times the
    # rms of the rectangular phasors between the tones)
    common = np.vdot(oracle.D[:, primary], streamed.D[:, primary]) / np.vdot(
        oracle.D[:, primary], oracle.D[:, primary])
    assert abs(abs(common) - 1) < 1e-6
    for name in ("D", "PO"):
        sigma = np.sqrt(1.5 * np.mean(np.abs(getattr(oracle, "off_" + name)) ** 2, axis=0))
        diff = np.abs(getattr(streamed, name) / common - getattr(oracle, name)) / sigma
        assert np.max(diff) < 0.2, (name, np.max(diff, axis=0))  # measured 0.05
    # the transfer functions eq. 19 fits, at the carrier and its sidebands: within 1e-5
    # (measured 1.9e-6 beside the carrier, whose PLL phase noise the two see differently)
    tones = np.abs(np.round((oracle.omega - oracle.omega_osc) / (
        2 * math.pi * cfg.sideband_spacing))) <= cfg.sideband_count
    np.testing.assert_allclose((streamed.PO / streamed.D[:, [primary]])[tones, primary],
                               (oracle.PO / oracle.D[:, [primary]])[tones, primary], rtol=1e-5)
    # the noise between the tones: the same level (the full record's rectangular FFT
    # also holds some of the carrier's image; the filter rejects it)
    for name in ("off_D", "off_PO"):
        got = np.sqrt(np.mean(np.abs(getattr(streamed, name)) ** 2, axis=0))
        want = np.sqrt(np.mean(np.abs(getattr(oracle, name)) ** 2, axis=0))
        assert got[primary] == pytest.approx(want[primary], rel=0.05)


def test_the_fmu_path_streams_the_same_record(models_dir) -> None:
    res = replace(ResonatorParameters(), noise=2.5e-4)
    cfg = SelfCalConfig(record=0.5, sideband_spacing=2.0, settle=0.3, ff_duration=0.5,
                        auto_record=False)
    lo = replace(cfg.loops, sideband_spacing=2.0)
    ours = stream_record(res, lo, cfg, 3, cfg.settle, cfg.record)
    fmu = stream_record(res, lo, replace(cfg, engine="fmu", models_dir=str(models_dir)), 3,
                        cfg.settle, cfg.record)
    for name in ("base", "theta", "tail"):
        assert np.array_equal(getattr(ours, name), getattr(fmu, name)), name
    stats = ("worst_phase_error", "mean_amplitude", "pinned_fraction", "gain_peak", "gain_mean")
    assert [getattr(ours, s) for s in stats] == [getattr(fmu, s) for s in stats]
