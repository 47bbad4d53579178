"""The calibration sequence of US 9,482,553 (its flow diagram), run at carrier level.

1. loops off: off-resonant tones on Vx, Vy and the ring; the feed-forward terms E
   and the relative pick-off gain and phase rho follow from least-squares phasors;
2. x oscillator, y rebalanced, sidebands on: settle, record;
3. modes reversed (y oscillator, x rebalanced): settle, record;
4. demodulate at the sideband frequencies, fit eq. 19 (estimator.py), compute cross
   damping, cross stiffness, the background rate, bias and scale factor;
5. when the 1-sigmas miss the targets, record again for as long as the pilot's
   uncertainty says they need, the sideband index raised first into the drive's
   headroom (choose_excitation), then check everything (alarms.py):
   a calibration that cannot be trusted raises CalibrationRefusedError, never a number.

The loops use the measured E in every closed-loop step, as the instrument would.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from ..errors import GyroFmuError
from ..model.loops import LoopSettings
from ..model.resonator import ResonatorParameters
from ..options import SEED_MAX
from . import alarms, defaults
from .estimator import (
    ModeData,
    NoiseModel,
    SidebandFit,
    bias_and_scale_factor,
    bias_and_scale_factor_sigma,
    cubic_terms,
    fit_sidebands,
)
from .inprocess import DEFAULT_STEP, MAX_STEPS, CarrierRecord, CarrierSimulation
from .phasors import carrier_shifts, phasors, phasors_and_variances, white_phasor_variance
from .result import SelfCalResult
from .stream import StreamedRecord, mode_phasors, stream_record


@dataclass(frozen=True)
class SelfCalConfig:
    """Record lengths and excitation of one calibration."""

    step: float = DEFAULT_STEP  #: s, communication step
    ff_duration: float = 2.0  #: s, loops-off record (whole periods of 10 Hz)
    settle: float = defaults.SETTLE  #: s, before each sideband record (5 ring-down times)
    record: float = defaults.RECORD  #: s, each sideband record (whole periods of the spacing)
    auto_record: bool = True  #: lengthen the records until the 1-sigmas meet the targets
    max_record: float = defaults.MAX_RECORD  #: s, longest record auto_record may choose
    target_bias: float = defaults.TARGET_BIAS  #: rad/s, bias 1-sigma to reach
    target_sf_ppm: float = defaults.TARGET_SF_PPM  #: ppm, scale-factor 1-sigma to reach
    sideband_index: float = defaults.SIDEBAND_INDEX  #: modulation index per tone
    #: when the 1-sigmas miss the targets, raise the index into the drive's headroom
    #: before lengthening the records (choose_excitation)
    auto_index: bool = True
    sideband_spacing: float = 0.2  #: Hz (two Hann bins of a 10 s record)
    sideband_count: int = defaults.SIDEBAND_COUNT  #: tones at 1..count times the spacing
    Omega_z: float = 0.0  #: rad/s, background rate during calibration (earth rate)
    seed: int = 1
    kappa: float = defaults.KAPPA  #: Bryant factor from the factory calibration (seed: constant)
    ring_amplitude: float = 3.0  #: V, each ring tone of step 1 (0.3 V at the pick-offs)
    ring_offset: float = 260.0  #: Hz, ring tones at f_nominal -/+ this
    fit_feedthrough: bool = True  #: fit the feed-through left after the correction
    #: fit the cubic terms (eqs. 24-27). Always: a cubic too small to raise the misfit
    #: (a 7e-6 Hz shift) still moved the SF by -17 ppm on a lot resonator (-0.9 with
    #: them); they cost +15 % of bias 1-sigma on the preset
    cubic: bool = True
    modes: tuple[int, ...] = (1, 2)  #: (1,) = no mode reversal
    fixed_rate: float | None = None  #: hold Omega_z at this value (no reversal: 0)
    engine: str = "inprocess"  #: "inprocess" or "fmu" (GyroResonator + GyroLoops FMUs)
    models_dir: str | None = None  #: folder of the FMUs (engine "fmu"; default models/)
    loops: LoopSettings = field(default_factory=LoopSettings)

    def __post_init__(self) -> None:
        problems = self.problems()
        if problems:
            raise SelfCalConfigError("; ".join(problems))

    def problems(self) -> list[str]:
        """What makes this calibration unusable, each naming the value and the remedy."""
        out = []
        positive = ("step", "record", "max_record", "target_bias", "target_sf_ppm",
                    "sideband_spacing", "kappa", "ring_offset")
        non_negative = ("ff_duration", "settle", "sideband_index", "ring_amplitude")
        for name in (*positive, *non_negative, "Omega_z"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                out.append(f"{name}={value!r} is not a number: give a number")
            elif not math.isfinite(value):
                out.append(f"{name}={value!r} is not finite: give a finite number")
            elif name in positive and not value > 0.0:
                out.append(f"{name}={value!r} must be > 0")
            elif name in non_negative and value < 0.0:
                out.append(f"{name}={value!r} must be >= 0")
        for name, low, high in (("sideband_count", 1, 1000), ("seed", 0, MAX_SEED)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or not \
                    low <= value <= high:
                out.append(f"{name}={value!r} must be a whole number in [{low}, {high}]")
        if out:
            return out
        longest = max(self.record, self.max_record)
        if max(self.settle + longest, self.ff_duration) / self.step > MAX_STEPS:
            out.append(f"a record of {self.settle + longest:g} s (settle + record or "
                       f"max_record) at {self.step:g} s steps is more than the "
                       f"{MAX_STEPS:.3g} steps a run may take: shorten settle, record or "
                       "max_record, or lengthen the step")
        if self.kappa > 1.0:
            out.append(f"kappa={self.kappa:g} is no Bryant factor (the fraction of the "
                       "Coriolis coupling the vibrating mass carries): give one in (0, 1]")
        if self.sideband_count * self.sideband_index >= 1.0:
            out.append(f"sideband_count x sideband_index = {self.sideband_count} x "
                       f"{self.sideband_index:g} >= 1 modulates the carrier's amplitude "
                       "through zero: keep their product below 1 (default 5 x 0.04)")
        nyquist = 0.5 / self.step
        if self.sideband_count * self.sideband_spacing >= nyquist:
            out.append(f"sidebands up to {self.sideband_count} x sideband_spacing = "
                       f"{self.sideband_count * self.sideband_spacing:g} Hz from the carrier "
                       f"reach the Nyquist frequency {nyquist:g} Hz of the {self.step:g} s "
                       "step: give a smaller sideband_spacing")
        if 1.0 / self.sideband_spacing > longest:
            out.append(f"sideband_spacing={self.sideband_spacing:g} Hz: one period "
                       f"({1.0 / self.sideband_spacing:g} s) is longer than the longest "
                       f"record ({longest:g} s): give a larger spacing or a longer record")
        if self.engine not in ("inprocess", "fmu"):
            out.append(f"engine={self.engine!r}: use 'inprocess' or 'fmu'")
        return out

    def as_dict(self) -> dict:
        d = asdict(self)
        d["loops"] = self.loops.as_dict()
        return d


class SelfCalConfigError(GyroFmuError, ValueError):
    """A calibration setting is unusable; the message names it and the remedy."""


#: Largest seed: the calibration's seeds (seed + 0..10) reach the FMUs' 32-bit Integer.
MAX_SEED = SEED_MAX - 16


@dataclass
class FeedForward:
    """Step 1's result: feed-through (V/V) and relative pick-off gain rho = Py/Px."""

    E: np.ndarray
    rho: complex
    imag_E: np.ndarray  #: imaginary parts left after the delay (quality check)
    #: 1-sigma of Re(rho) and of Im(rho) each, from the pick-off noise the ring-tone
    #: fit leaves (rho's error is circular: the two are equal and uncorrelated)
    sigma_rho: float = 0.0


def measure_feedforward(res: ResonatorParameters, cfg: SelfCalConfig) -> FeedForward:
    """Loops off: E from the drive tones, rho from the ring tones (both -/+ offsets).
    It runs first in the sequence, from t = 0 on res's temperature history."""
    lo = replace(cfg.loops, mode=0)
    h = cfg.step
    f0 = lo.f_nominal
    res = replace(res, ring_amplitude=cfg.ring_amplitude,
                  ring_frequency_1=f0 - cfg.ring_offset, ring_frequency_2=f0 + cfg.ring_offset)
    rec = simulate(res, lo, cfg, cfg.seed, cfg.ff_duration + 0.1, 0.1)
    t0, data = rec.time[0], rec.data[:-1]
    cols = CarrierRecord(data, h)
    w0 = 2 * math.pi * lo.f_nominal
    offs = {"x": lo.excitation_offset_x, "y": lo.excitation_offset_y, "ring": cfg.ring_offset}
    grid = 10.0
    harm = np.array(sorted({s * round(o / grid) for o in offs.values() for s in (-1, 1)} | {0}))
    ph = {n: phasors(cols[n], t0, h, w0, grid, harm) for n in ("Vx", "Vy")}
    var = {}
    for n in ("Vpx", "Vpy"):
        ph[n], var[n] = phasors_and_variances(cols[n], t0, h, w0, grid, harm)
    index = {j: i for i, j in enumerate(harm)}
    E = np.zeros((2, 2), complex)
    for col, drive in enumerate(("x", "y")):
        entries = []
        for sgn in (-1, 1):
            j = index[sgn * round(offs[drive] / grid)]
            w = w0 + harm[j] * 2 * math.pi * grid
            v = ph[f"V{drive}"][j]
            entries.append((w, np.array([ph["Vpx"][j], ph["Vpy"][j]]) / v * np.exp(1j * w * h)))
        # H e^{i w h} = E + R e^{i w h} / (w0^2 - w^2): solve for E and R per pick-off
        A = np.array([[1.0, np.exp(1j * w * h) / (w0**2 - w**2)] for w, _ in entries])
        for row in range(2):
            sol = np.linalg.solve(A, np.array([e[1][row] for e in entries]))
            E[row, col] = sol[0]
    ratios, ratio_vars = [], []
    for sgn in (-1, 1):
        j = index[sgn * round(offs["ring"] / grid)]
        r = ph["Vpy"][j] / ph["Vpx"][j]
        ratios.append(r)  # dr/r = dVpy/Vpy - dVpx/Vpx, the two channels' noise independent
        ratio_vars.append(abs(r) ** 2 * (var["Vpy"][j] / abs(ph["Vpy"][j]) ** 2
                                         + var["Vpx"][j] / abs(ph["Vpx"][j]) ** 2))
    sigma_rho = math.sqrt(sum(ratio_vars) / 4 / 2)  # mean of two; E|d rho|^2 split Re/Im
    return FeedForward(E.real.copy(), complex(np.mean(ratios)), E.imag.copy(), sigma_rho)


def record_mode(res: ResonatorParameters, cfg: SelfCalConfig, mode: int,
                ff: FeedForward, t_start: float = 0.0) -> tuple[ModeData, StreamedRecord]:
    """Run one mode with sidebands from t_start (s) on the sequence's clock (the
    resonator's temperature history, ResonatorParameters.later), demodulated as it
    runs (stream.py); return its phasors and the streamed record."""
    lo = replace(cfg.loops, mode=mode, sideband_index=cfg.sideband_index,
                 sideband_spacing=cfg.sideband_spacing, sideband_first=1,
                 sideband_count=cfg.sideband_count, sideband_start=0.0,
                 ff_xx=ff.E[0, 0], ff_xy=ff.E[0, 1], ff_yx=ff.E[1, 0], ff_yy=ff.E[1, 1])
    rec = stream_record(res.later(t_start), lo, cfg, cfg.seed + mode, cfg.settle, cfg.record)
    md = mode_phasors(rec, mode, ff, cfg)
    md.t_center = t_start + cfg.settle + cfg.record / 2
    return md, rec


def simulate(res: ResonatorParameters, lo: LoopSettings, cfg: SelfCalConfig, seed: int,
             duration: float, record_from: float) -> CarrierRecord:
    """One run from rest on the configured engine, recorded whole (the loops-off step):
    in process, or the two FMUs through the master (bit-identical,
    tests/test_selfcal_fmu.py)."""
    if cfg.engine == "fmu":
        from .run import run_fmus

        models = Path(cfg.models_dir) if cfg.models_dir else None
        return run_fmus(res, lo, duration, cfg.step, cfg.Omega_z, seed, record_from, models)
    sim = CarrierSimulation(res, lo, seed=seed, step=cfg.step, Omega_z=cfg.Omega_z)
    return sim.run(duration, record_from=record_from)


def self_calibrate(res: ResonatorParameters, cfg: SelfCalConfig | None = None) -> SelfCalResult:
    """The whole sequence at carrier level, checked: raises alarms.CalibrationRefusedError
    (every problem named, the untrusted result attached) rather than return a
    calibration whose loops did not lock, whose model does not fit or whose
    uncertainty misses the targets."""
    cfg = cfg or SelfCalConfig()
    start = time.perf_counter()
    ff = measure_feedforward(res, cfg)
    clock = cfg.ff_duration + 0.1  # s, the sequence's time: the warm-up runs through it
    result, problems, clock = _calibrate(res, cfg, ff, start, clock)
    used = cfg
    for _ in range(3 if cfg.auto_record else 0):  # sigma falls about as 1/sqrt(record)
        if problems:
            break
        record, index = choose_excitation(result, used)
        if record <= used.record and index <= used.sideband_index:
            break
        used = replace(used, record=record, sideband_index=index)
        result, problems, clock = _calibrate(res, used, ff, start, clock)
    if not problems:
        problems = alarms.uncertainty_problems(result.sigma_bias, result.sigma_sf_ppm,
                                               cfg.target_bias, cfg.target_sf_ppm,
                                               result.record)
    if problems:
        raise alarms.CalibrationRefusedError(problems, result)
    return result


#: largest sum of the tones' indices choose_excitation raises to: at 7 tones on the
#: preset, 0.07 each moved the mean amplitude 5 % off its setpoint and the drive's peak
#: to 0.54 of its limit, 0.1 each 14 % (the lock alarm's limit is 10 %) and 0.81
#: (the drive's excursion grows faster than the index past 0.05)
MAX_MODULATION = 0.5
#: fraction of the drive limit the gain's peak may reach under a raised index
DRIVE_TARGET = 0.8
#: departure of the mean amplitude from its setpoint a raised index may bring (half
#: the lock alarm's tolerance)
AMPLITUDE_ROOM = 0.5 * alarms.AMPLITUDE_TOLERANCE


def drive_use(rec: StreamedRecord, cfg: SelfCalConfig) -> float:
    """How much of its room the sidebands take, on a scale where the index may grow as
    1 / use: the larger of the drive gain's excursion, (peak - mean) over
    (DRIVE_TARGET limit - mean), which grows as the index, and the mean amplitude's
    departure from its setpoint over AMPLITUDE_ROOM, to the power 1/3: it grows as the
    index cubed (preset: 1.0 % at 0.04, 5.6 % at 0.071; a Q 5e4 resonator at 3.7 kHz:
    3.9 % and 12.7 %, which the lock alarm refused)."""
    lo = cfg.loops
    up = DRIVE_TARGET * lo.drive_limit - rec.gain_mean
    departure = abs(rec.mean_amplitude / lo.amplitude - 1.0)
    if not up > 0.0:
        return math.inf
    return max((rec.gain_peak - rec.gain_mean) / up, (departure / AMPLITUDE_ROOM) ** (1 / 3))


def choose_excitation(result: SelfCalResult, cfg: SelfCalConfig) -> tuple[float, float]:
    """(record s, sideband index) that bring the pilot's 1-sigmas to the targets.

    The 1-sigmas fall as 1 / index (measured on a Q 9.35e3 resonator with force noise:
    1.11e-4 rad/s at 0.04, 5.7e-5 at 0.08) and the drive's excursion above its mean
    grows as the index: with cfg.auto_index the index is first raised until the
    pilot's largest excursion would reach DRIVE_TARGET of its room (drive_use; at most
    MAX_MODULATION / sideband_count), then the record is chosen for what is left
    (choose_record). self_calibrate asks again after each record (at most 3 times)."""
    need = max((result.sigma_bias / cfg.target_bias) ** 2,
               (result.sigma_sf_ppm / cfg.target_sf_ppm) ** 2)
    index = cfg.sideband_index
    if cfg.auto_index and need > 1.0 and result.drive_use > 0.0:
        top = MAX_MODULATION / cfg.sideband_count
        index = max(index, min(top, index / result.drive_use))
    raised = replace(cfg, sideband_index=index)
    return choose_record(result, raised, need * (cfg.sideband_index / index) ** 2), index


def choose_record(result: SelfCalResult, cfg: SelfCalConfig,
                  need: float | None = None) -> float:
    """Record length (s) that brings the pilot's 1-sigmas to the targets: they fall as
    1 / sqrt(record), so record * (sigma / target)^2 with 10 % margin, in whole
    record_units, at most cfg.max_record; `need`: that (sigma / target)^2 if not the
    pilot's own."""
    if need is None:
        need = max((result.sigma_bias / cfg.target_bias) ** 2,
                   (result.sigma_sf_ppm / cfg.target_sf_ppm) ** 2)
    if not need > 1.0:
        return cfg.record
    unit = record_unit(cfg.sideband_spacing)
    longer = math.ceil(cfg.record * need * 1.1 / unit) * unit
    return min(longer, max(cfg.record, math.floor(cfg.max_record / unit) * unit))


def record_unit(spacing: float) -> float:
    """Shortest record (s) holding whole periods of the spacing and whole seconds (the
    step grid, design.step_for, makes every whole second a whole number of steps):
    5 s for 0.2 Hz, 10 s for 0.9 Hz; 1/spacing for a spacing off the 0.1 Hz grid."""
    tenths = round(spacing * 10)
    if tenths < 1 or abs(spacing * 10 - tenths) > 1e-9:
        return 1.0 / spacing
    return 10.0 / math.gcd(tenths, 10)


def _calibrate(res: ResonatorParameters, cfg: SelfCalConfig, ff: FeedForward,
               start: float, clock: float = 0.0
               ) -> tuple[SelfCalResult | None, list[str], float]:
    """Record every mode from clock (s, the sequence's time), check its loops, fit;
    (result or None, problems, the clock at the end)."""
    data, problems, noise, drive = [], [], [], []
    for m in cfg.modes:
        md, rec = record_mode(res, cfg, m, ff, clock)
        clock += cfg.settle + cfg.record
        secondary = float(np.abs(md.PO[md.omega.size // 2, 2 - m])) if m in (1, 2) else 0.0
        problems += alarms.lock_problems(m, rec.worst_phase_error, rec.mean_amplitude,
                                         rec.pinned_fraction,
                                         secondary / max(md.amplitude, 1e-300),
                                         cfg.loops.amplitude, cfg.loops.drive_limit)
        f_osc = md.omega_osc / (2 * math.pi)
        noise += [alarms.pickoff_noise(rec.tail[:, i], cfg.step, f_osc) ** 2 for i in (0, 1)]
        drive.append(drive_use(rec, cfg))
        data.append(md)
    if problems:  # no fit of records whose loops did not hold
        return None, problems, clock
    noise_level = math.sqrt(float(np.mean(noise)))
    n = round(cfg.record / cfg.step)
    per_phasor = white_phasor_variance(n, round(cfg.record * cfg.sideband_spacing))
    model = NoiseModel(np.reshape(noise, (-1, 2)) * per_phasor,
                       alarms.MODEL_FLOOR * cfg.loops.amplitude)
    carrier_shifts(data)
    try:
        with np.errstate(all="raise"):
            result = estimate(data, ff, cfg, start, model)
    except (np.linalg.LinAlgError, ValueError, ZeroDivisionError, FloatingPointError) as exc:
        return None, [f"the sideband fit failed numerically ({type(exc).__name__}: {exc}): "
                      "the records do not determine the model; check the loops lock "
                      "(--loop) and raise the sideband index (--index)"], clock
    result.pickoff_noise = noise_level
    result.sideband_index, result.drive_use = cfg.sideband_index, max(drive)
    result.misfit_ratio, problems = alarms.misfit_problems(result.fit)
    phys = result.fit.physical()
    split = abs(phys["f_y"] - phys["f_x"])
    singular = alarms.conditioning_problems(result.fit.conditioning, result.fit.weakest,
                                            split)
    problems += singular or alarms.carrier_shift_problems(  # a singular fit: no shift
        [md.drift for md in data], result.sigma_bias_shift,
        abs(result.sigma_scale_factor_shift / result.scale_factor) * 1e6, cfg.target_bias,
        cfg.target_sf_ppm, split)
    if cfg.cubic:
        x = result.fit.x
        gamma = {(md.mode, kind): g for md in data if md.mode in (1, 2)
                 for kind, g in zip(("auto", "cross"), cubic_terms(x, md.mode), strict=True)}
        dxx, dyy = x[2], x[3]  # CORE: the dampings of each mode
        problems += alarms.cubic_problems(gamma, {1: dxx, 2: dyy}, {1: dyy, 2: dxx},
                                          result.fit.omega_ref)
    return result, problems, clock


def estimate(data: list[ModeData], ff: FeedForward, cfg: SelfCalConfig,
             start: float | None = None, noise: NoiseModel | None = None) -> SelfCalResult:
    """Step 4: fit eq. 19 (with the cubic terms of eqs. 24-27 if cfg.cubic), weighted by
    the noise model when given (its force noise fitted), and compute bias and scale
    factor of the mode-1 read-out; the refits for rho and the shift keep its weights."""
    lo = cfg.loops

    def fit_with(rho: complex, records: list[ModeData] = data) -> SidebandFit:
        return fit_sidebands(records, rho, cfg.kappa, cfg.step, lo.plant_gain, lo.q_nominal,
                             cfg.fit_feedthrough, cfg.fixed_rate, cfg.cubic, noise)

    fit = fit_with(ff.rho)
    noise = fit.noise  # measured now: fit_with's refits below are weighted by it as it is
    m1 = next((d for d in data if d.mode == 1), data[0])
    omega_r, amp = m1.omega_osc, lo.amplitude
    bias, sf = bias_and_scale_factor(fit, omega_r, amp)
    s_bias, s_sf = bias_and_scale_factor_sigma(fit, omega_r, amp)
    moved = []  # rho moved by its 1-sigma along Re and along Im, refitted
    for d_rho in (ff.sigma_rho, 1j * ff.sigma_rho) if ff.sigma_rho > 0.0 else ():
        refit = fit_with(ff.rho + d_rho)
        moved.append(np.subtract(bias_and_scale_factor(refit, omega_r, amp), (bias, sf)))
    s_bias_rho, s_sf_rho = np.sqrt(np.sum(np.square(moved), axis=0)) if moved else (0.0, 0.0)
    # the shift between records moved by its uncertainty, refitted (the temperature)
    shifted = []
    for i, md in enumerate(data):
        if md.sigma_shift > 0.0:
            moved_data = [replace(d, shift=d.shift + d.sigma_shift) if j == i else d
                          for j, d in enumerate(data)]
            refit = fit_with(ff.rho, moved_data)
            shifted.append(np.subtract(bias_and_scale_factor(refit, omega_r, amp), (bias, sf)))
    s_bias_t, s_sf_t = np.sqrt(np.sum(np.square(shifted), axis=0)) if shifted else (0.0, 0.0)
    wall = time.perf_counter() - start if start is not None else float("nan")
    result = SelfCalResult(bias, sf, math.hypot(s_bias, s_bias_rho, s_bias_t),
                           math.hypot(s_sf, s_sf_rho, s_sf_t), float(s_bias_rho),
                           float(s_sf_rho), fit.physical(), ff.rho, ff.E, omega_r, amp,
                           fit.rms_residual, wall, fit, data, record=cfg.record,
                           cubic=cfg.cubic)
    result.sigma_bias_shift, result.sigma_scale_factor_shift = float(s_bias_t), float(s_sf_t)
    return result
