"""The observer-based gyro judged as a gyroscope: the figures of an inertial-sensor datasheet.

`measure_spec(cfg)` runs the plant and the observer in-process (the same library the
FMUs wrap, as system/inprocess.py does) and measures, from the rate estimate Omega_hat:

- angle random walk and bias instability from the overlapping Allan deviation of a
  record of `cfg.duration` seconds at a constant rate (IEEE Std 952-1997 Annex C;
  IEEE Std 1431-2004 clause 12.11, drift rate test series), and the bias (mean error);
- the start-up time to spec: when the output, averaged over a stated window, enters a
  stated band around the true rate for good (IEEE 1431 clauses 12.5 and 12.6);
- the rate bandwidth: the -3 dB point of the response to a stepped sine of the input
  rate (one sine at a time, IEEE 1431 clause 12.15, transfer function);
- scale-factor error and nonlinearity: least-squares line of the settled Omega_hat
  against the true rate over +-full scale (IEEE 1431 clause 12.9).

Definitions, citations and the measured default spec: docs/gyro-spec.md. Every function
states its contract; they raise SpecError (exit 2 on the command line) rather than
return a figure from a run that cannot be trusted (a lost observer, an estimate that
never settles).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field, fields

import numpy as np

from ..errors import GyroFmuError
from ..estimation.observer import GyroStateObserver, ObserverDivergedError, ObserverTuning
from ..model.measurement import UNKNOWNS
from ..model.parameters import DEFAULT_PRESET, GyroParameters, ParameterError
from ..model.plant import GyroPlantModel, MeasurementNoise
from ..selfcal.allan import allan_deviation
from ..system.scenario import Scenario, absolute_noise, default_initial_guess

#: rad/s/sqrt(Hz) (= rad/sqrt(s)) -> deg/sqrt(h)
ARW_DEG_PER_SQRT_H = math.degrees(1.0) * 60.0
#: rad/s -> deg/h
DEG_PER_H = math.degrees(1.0) * 3600.0
#: Flat minimum of the Allan deviation of bias instability B: sigma = B sqrt(2 ln 2 / pi)
BIAS_INSTABILITY_FACTOR = math.sqrt(2.0 * math.log(2.0) / math.pi)  # 0.664
#: Local log-log slope of the Allan deviation accepted as white rate noise: -1/2 +- this.
ARW_SLOPE_TOLERANCE = 0.15
#: Largest averaging time used, as a fraction of the record (few clusters beyond).
TAU_MAX_FRACTION = 0.2
#: The start-up window is chosen so that noise alone leaves the band at this many sigma.
STARTUP_SIGMAS = 6.0
#: Two halves of the settled record whose white-noise level differ by more than this
#: factor: the output is not stationary and its Allan deviation is no noise figure.
STATIONARITY_RATIO = 1.3
#: Steps between two samples of an adaptive observer's rate-model probabilities.
PROBABILITY_EVERY = 100
#: Index of Omega_z in GyroStateObserver.output_row().
_I_OMEGA = 4 + UNKNOWNS.index("Omega_z")
_TUNING_NAMES = tuple(f.name for f in fields(ObserverTuning))


class SpecError(GyroFmuError):
    """A spec that cannot be measured from this run: the message names the cause and
    the remedy (the observer was lost, or its estimate never settled)."""


def default_bw_frequencies() -> tuple[float, ...]:
    """16 log-spaced rate frequencies, 10 Hz to 5 kHz (Hz)."""
    return tuple(float(f) for f in np.round(np.geomspace(10.0, 5000.0, 16), 1))


@dataclass(frozen=True)
class SpecConfig:
    """What to measure and how. SI units (s, rad/s, Hz, m/sqrt(Hz)).

    Noise: `noise_density` (m/sqrt(Hz), one-sided, on x and y alike) when given, else
    `noise` relative to each measured signal's peak (the project's convention,
    system/scenario.py). The per-sample std of a density D at step h is D / sqrt(2 h):
    white noise of one-sided density D band-limited to the Nyquist frequency 1/(2 h).
    """

    preset: str = DEFAULT_PRESET
    overrides: dict[str, float] = field(default_factory=dict)
    tuning: dict[str, float] = field(default_factory=dict)
    noise: float = 1e-4
    noise_density: float | None = None
    seed: int = 0
    step: float = 5e-6
    duration: float = 20.0  #: Allan record (constant rate), s
    rate: float = 0.0  #: constant rate of the Allan and start-up run, rad/s
    full_scale: float = 5.0  #: rad/s; the scale-factor rates span +-full_scale
    sf_points: int = 11
    sf_record: float = 0.2  #: averaging time per scale-factor rate, s (after settling)
    bw_frequencies: tuple[float, ...] = field(default_factory=default_bw_frequencies)
    bw_amplitude: float = 1.0  #: rad/s, about `rate`
    bw_segment: float = 0.1  #: s per frequency (at least 5 periods)
    startup_band: float | None = None  #: rad/s; None: 1 % of full scale
    startup_window: float | None = None  #: s; None: chosen from the noise (STARTUP_SIGMAS)

    def __post_init__(self) -> None:
        positive = {"step": self.step, "duration": self.duration,
                    "full_scale": self.full_scale, "sf_record": self.sf_record,
                    "bw_amplitude": self.bw_amplitude, "bw_segment": self.bw_segment}
        for name in ("startup_band", "startup_window", "noise_density"):
            if getattr(self, name) is not None:
                positive[name] = getattr(self, name)
        for name, value in positive.items():
            if not (math.isfinite(value) and value > 0.0):
                raise ParameterError(f"{name}={value!r} must be a finite number > 0")
        if not (math.isfinite(self.noise) and self.noise >= 0.0):
            raise ParameterError(f"noise={self.noise!r} must be >= 0 (fraction of peak)")
        if not math.isfinite(self.rate):
            raise ParameterError(f"rate={self.rate!r} rad/s must be finite")
        if self.sf_points < 3:
            raise ParameterError(f"sf_points={self.sf_points} must be >= 3 for a line and "
                                 "its residuals")
        if len(self.bw_frequencies) < 2 or any(
                not (math.isfinite(f) and 0.0 < f < 0.25 / self.step)
                for f in self.bw_frequencies):
            raise ParameterError(
                f"bw_frequencies {list(self.bw_frequencies)} Hz: give at least 2, each > 0 "
                f"and below a quarter of the sampling rate ({0.25 / self.step:g} Hz)")
        if self.duration < 200 * self.step:
            raise ParameterError(f"duration={self.duration} s is shorter than 200 steps")
        unknown = sorted(set(self.tuning) - set(_TUNING_NAMES))
        if unknown:
            raise ParameterError(f"unknown observer tuning {unknown}: names are "
                                 f"{', '.join(_TUNING_NAMES)}")
        self.scenario  # noqa: B018 - a bad preset or override fails here

    @property
    def scenario(self) -> Scenario:
        """The project scenario of this gyro (preset, overrides, step; drive and initial
        guess by the project's rules). Its default stop time (0.1 s) is the record
        over which `noise` finds each signal's peak, as `gyro-fmu run --noise` does."""
        return Scenario(preset=self.preset, overrides=dict(self.overrides), step=self.step,
                        noise=self.noise, seed=self.seed)

    @property
    def band(self) -> float:
        return self.startup_band if self.startup_band is not None else 0.01 * self.full_scale


def density_to_std(density: float, h: float) -> float:
    """Per-sample std (m) of white noise of one-sided density `density` (m/sqrt(Hz))
    sampled every h s: density / sqrt(2 h) (variance = density^2 x Nyquist band 1/(2h))."""
    return density / math.sqrt(2.0 * h)


def pickoff_noise(cfg: SpecConfig) -> MeasurementNoise:
    """Std of the position pick-off noise (m) the plant adds to x and y. Velocities get
    none: the observer measures positions here (measured pair 1)."""
    if cfg.noise_density is not None:
        s = density_to_std(cfg.noise_density, cfg.step)
        return MeasurementNoise(x=s, y=s)
    if cfg.noise == 0.0:
        return MeasurementNoise()
    rel = absolute_noise(cfg.scenario)
    return MeasurementNoise(x=rel.x, y=rel.y)


def observer_tuning(cfg: SpecConfig, noise: MeasurementNoise) -> dict[str, float]:
    """The observer's tuning: its defaults, told the pick-off noise (sigma_z1, sigma_z2),
    then cfg.tuning. Unlike system.scenario.observer_tuning the rate is NOT declared
    constant: a gyro under test does not know its rate (docs/gyro-spec.md)."""
    base: dict[str, float] = {}
    if not noise.is_off:
        base = {"sigma_z1": noise.x, "sigma_z2": noise.y}
    return {**base, **cfg.tuning}


@dataclass
class Record:
    """One run: times t (s) of the estimates, the estimate Omega_hat and the true rate
    (rad/s) at those times, and the observer's warnings (time, text)."""

    t: np.ndarray
    omega_hat: np.ndarray
    omega_true: np.ndarray
    warnings: list[tuple[float, str]]
    wall_s: float
    #: rate models of an adaptive observer, and their probabilities every
    #: PROBABILITY_EVERY steps (rows), from the first step; empty without them
    rate_models: list[str] = field(default_factory=list)
    rate_probabilities: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))

    @property
    def error(self) -> np.ndarray:
        return self.omega_hat - self.omega_true


def simulate(cfg: SpecConfig, rate: Callable[[float], float], duration: float,
             what: str, seed: int | None = None) -> Record:
    """Run plant + observer for `duration` s under the rate profile rate(t) (rad/s).

    Same loop as system/inprocess.py: at each step the plant's measured x, y at t enter
    the observer, which corrects and predicts to t + h; the plant moves to t + h with the
    drive and rate at t held. The estimate after the step is Omega_hat(t + h); it is
    recorded with the true rate held over that step. Raises SpecError if the observer
    is lost (status 2, ObserverDivergedError), naming the run `what`.
    """
    sc = cfg.scenario
    h = cfg.step
    noise = pickoff_noise(cfg)
    plant = GyroPlantModel(sc.params, noise, cfg.seed if seed is None else seed)
    try:
        tuning = ObserverTuning(**observer_tuning(cfg, noise))
    except (TypeError, ValueError) as exc:
        raise ParameterError(f"observer tuning: {exc}") from None
    observer = GyroStateObserver(GyroParameters(**default_initial_guess(sc.params)),
                                 0.0, 1, tuning)
    drive = sc.the_drive
    n = round(duration / h)
    om_hat = np.empty(n)
    om_true = np.empty(n)
    warned: list[tuple[float, str]] = []
    # an adaptive observer's rate-model probabilities, sampled (where it has them)
    probs: list[list[float]] | None = [] if hasattr(observer, "rate_probabilities") else None
    status = 0
    start = time.perf_counter()
    t = 0.0
    k = 0
    try:
        for k in range(n):
            t = k * h
            ux = drive.ux(t)
            om = rate(t)
            z = plant.measured()
            observer.step(ux, 0.0, z[0], z[2], h)
            plant.step(ux, 0.0, om, h)
            om_hat[k] = observer.output_row()[_I_OMEGA]
            om_true[k] = om
            if probs is not None and k % PROBABILITY_EVERY == 0:
                probs.append(list(observer.rate_probabilities().values()))
            if observer.status != status:
                status = observer.status
                if status == 1:
                    warned.append((t + h, observer.warning or "innovations above their band"))
    except ObserverDivergedError as exc:
        raise SpecError(
            f"{what}: the observer was lost at t = {t:.4g} s (status 2): {exc}. No spec "
            "from this gyro at these settings: lower the noise, give a smaller --step, or "
            "loosen the observer (--tuning)") from None
    names = list(observer.rate_probabilities()) if probs is not None else []
    return Record((np.arange(n) + 1) * h, om_hat, om_true, warned,
                  time.perf_counter() - start, names,
                  np.array(probs) if probs else np.zeros((0, len(names))))


# ----------------------------------------------------------------- Allan deviation
def allan_taus(n: int, h: float, per_decade: int = 10,
               max_fraction: float = TAU_MAX_FRACTION) -> np.ndarray:
    """Averaging times (s): whole multiples m h of the step, log-spaced, from h up to
    max_fraction of the record of n samples (unique m)."""
    m_max = max(1, int(max_fraction * n))
    count = max(2, int(per_decade * math.log10(max(m_max, 10))))
    m = np.unique(np.rint(np.geomspace(1, m_max, count))).astype(int)
    return m * h


def adev_uncertainty(n: int, h: float, taus: np.ndarray) -> np.ndarray:
    """Relative 1-sigma error of an Allan deviation estimate at each tau from n samples:
    1 / sqrt(2 (n / m - 1)) with m = tau / h samples per cluster (IEEE 952 Annex C);
    conservative for the overlapping estimator."""
    clusters = n / np.rint(np.asarray(taus) / h)
    return 1.0 / np.sqrt(2.0 * np.maximum(clusters - 1.0, 1.0))


def local_slopes(taus: np.ndarray, adev: np.ndarray) -> np.ndarray:
    """d log(adev) / d log(tau) at each tau (central differences, one-sided at the ends)."""
    return np.gradient(np.log(adev), np.log(taus))


def angle_random_walk(taus: np.ndarray, adev: np.ndarray, n: int, h: float) -> dict:
    """Angle random walk N (rad/s/sqrt(Hz) = rad/sqrt(s)): the -1/2-slope line
    sigma(tau) = N / sqrt(tau) read at tau = 1 s (IEEE 952 Annex C).

    The line is fitted to the taus whose local slope is -1/2 +- ARW_SLOPE_TOLERANCE
    (white rate noise), weighting each sigma sqrt(tau) by its inverse variance
    (adev_uncertainty). Returns {"N": ..., "tau_range": [lo, hi], "points": k}; N is None
    when no tau shows white rate noise.
    """
    slopes = local_slopes(taus, adev)
    sel = np.abs(slopes + 0.5) <= ARW_SLOPE_TOLERANCE
    if not sel.any():
        return {"N": None, "tau_range": None, "points": 0}
    w = 1.0 / adev_uncertainty(n, h, taus[sel]) ** 2
    log_n = np.sum(w * np.log(adev[sel] * np.sqrt(taus[sel]))) / np.sum(w)
    return {"N": float(np.exp(log_n)), "tau_range": [float(taus[sel][0]), float(taus[sel][-1])],
            "points": int(sel.sum())}


def bias_instability(taus: np.ndarray, adev: np.ndarray) -> dict:
    """Bias instability B (rad/s) = the Allan deviation's flat minimum / 0.664
    (sigma = B sqrt(2 ln 2 / pi) on the flat part; IEEE 952 Annex C).

    The minimum is sought beyond the deviation's first maximum: below it the output is
    smoothed by the observer's own bandwidth (the deviation rises with tau there, a
    filter's signature, not a bias). "resolved" is True when the minimum lies inside
    the tau range (not in its last two points) with a local slope within +-0.25 there;
    otherwise the record is too short (the deviation still falls) and B is an upper
    bound: the last deviation / 0.664.
    """
    falls = np.flatnonzero(np.diff(adev) < 0.0)
    i0 = int(falls[0]) if falls.size else 0
    i = i0 + int(np.argmin(adev[i0:]))
    slopes = local_slopes(taus, adev)
    resolved = i < len(adev) - 2 and abs(slopes[i]) <= 0.25
    return {"B": float(adev[i] / BIAS_INSTABILITY_FACTOR), "tau_min": float(taus[i]),
            "adev_min": float(adev[i]), "resolved": bool(resolved),
            "slope_at_min": float(slopes[i])}


def moving_mean(x: np.ndarray, m: int) -> np.ndarray:
    """Trailing mean over m samples; element j is the mean of x[j : j + m]."""
    c = np.concatenate([[0.0], np.cumsum(x)])
    return (c[m:] - c[:-m]) / m


def startup_time(t: np.ndarray, error: np.ndarray, band: float, window: float,
                 h: float) -> float | None:
    """Start-up time to spec (s): the earliest time from which the error Omega_hat -
    Omega, averaged over the trailing `window` s, stays within +-band to the end of the
    record (IEEE 1431 12.5/12.6: turn-on and warm-up time). None if the last window is
    outside the band (the estimate never settles to it). The result is at least
    `window` (the first average is complete then)."""
    m = max(1, round(window / h))
    avg = moving_mean(error, m)  # the average ending at t[j + m - 1]
    outside = np.flatnonzero(np.abs(avg) > band)
    if outside.size == 0:
        return float(t[m - 1])
    j = int(outside[-1])
    if j == len(avg) - 1:
        return None
    return float(t[j + m])


def check_stationary(error: np.ndarray, h: float, taus: Sequence[float]) -> dict:
    """Compare the white-noise level (sigma(tau) sqrt(tau), median over taus) of the first
    and second half of the settled record. A ratio beyond STATIONARITY_RATIO (or its
    inverse) means a non-stationary output: an estimate whose bandwidth keeps shrinking
    (a constant-rate model averages forever) or grows; its Allan deviation is no noise
    figure."""
    half = len(error) // 2
    taus = np.asarray([tau for tau in taus if 2 * round(tau / h) <= half // 10] or [h])
    a = allan_deviation(error[:half], h, taus) * np.sqrt(taus)
    b = allan_deviation(error[half:], h, taus) * np.sqrt(taus)
    ratio = float(np.median(a) / np.median(b)) if np.median(b) > 0 else math.inf
    ok = 1.0 / STATIONARITY_RATIO <= ratio <= STATIONARITY_RATIO
    return {"ratio_first_to_second_half": ratio, "stationary": bool(ok),
            "taus": [float(x) for x in taus]}


def allan_study(rec: Record, cfg: SpecConfig) -> dict:
    """ARW, bias instability, bias and start-up time of a constant-rate record.

    The start-up part is cut before the Allan deviation: first a provisional 10 % of the
    record, then the measured start-up time if longer. The start-up window (unless
    given) is the one whose noise-only average stays inside the band at STARTUP_SIGMAS
    sigma: window = (STARTUP_SIGMAS N / band)^2, at least 1 ms, at most a tenth of the
    record. Raises SpecError when the estimate never settles into the band.
    """
    h = cfg.step
    err = rec.error
    n_all = len(err)

    def adev_after(k0: int) -> tuple[np.ndarray, np.ndarray, int]:
        e = err[k0:]
        taus = allan_taus(len(e), h)
        return taus, allan_deviation(e, h, taus), len(e)

    k0 = int(0.1 * n_all)
    taus, adev, n = adev_after(k0)
    arw = angle_random_walk(taus, adev, n, h)
    band = cfg.band
    N = arw["N"]
    if cfg.startup_window is not None:
        window = cfg.startup_window
    elif N is None:
        window = 0.01
    else:
        window = min(max((STARTUP_SIGMAS * N / band) ** 2, 1e-3), 0.1 * cfg.duration)
    t_on = startup_time(rec.t, err, band, window, h)
    if t_on is None:
        final = float(np.mean(err[-max(1, round(window / h)):]))
        raise SpecError(
            f"start-up run: the rate estimate never settles within +-{band:g} rad/s of the "
            f"true {cfg.rate:g} rad/s (averaged over {window:g} s, the last average is "
            f"{final:+.3g} rad/s off after {cfg.duration:g} s); no spec from this run. "
            "Cause: a bias beyond the band or noise too large for it; remedy: a wider "
            "--startup-band, a longer --startup-window, less noise, or another --tuning")
    k_on = round(t_on / h)
    if k_on > k0:
        if n_all - k_on < 400:
            raise SpecError(
                f"start-up run: settled only at {t_on:.3g} s of {cfg.duration:g} s, too "
                "little record for an Allan deviation: give a longer --duration")
        k0 = k_on
        taus, adev, n = adev_after(k0)
        arw = angle_random_walk(taus, adev, n, h)
    settled = err[k0:]
    bi = bias_instability(taus, adev)
    stat = check_stationary(settled, h, [tau for tau in taus if tau >= 1e-3][:6])
    N = arw["N"]
    remedy = ("--tuning rate_model=2 --tuning rate_bandwidth=HZ (a tracking model of stated "
              "bandwidth)" if "rate_model" in _TUNING_NAMES else
              "--tuning q_Omega=Q (a tracking model, omega_order 2)")
    refused = None
    if not stat["stationary"]:
        refused = (
            "the settled output is not stationary (white-noise level of the first / second "
            f"half {stat['ratio_first_to_second_half']:.3g}): the observer's rate bandwidth "
            "changes during the record (a constant rate model, or an adaptive one settling "
            "into it, averages ever longer), so its Allan deviation describes this record, "
            f"not a noise of the gyro. For noise figures at a stated bandwidth: {remedy}")
    elif N is None:
        refused = ("no white-rate-noise (-1/2) region in the Allan deviation of this record: "
                   f"give a longer --duration or a rate model of stated bandwidth: {remedy}")
    if refused:
        N = None
    sigma_bias = (N / math.sqrt(len(settled) * h)) if N else None
    B = None if refused else bi["B"]
    return {
        "rate_rad_s": cfg.rate,
        "record_s": cfg.duration,
        "settled_from_s": float(k0 * h),
        "bias_rad_s": float(np.mean(settled)),
        "bias_sigma_rad_s": sigma_bias,
        "std_rad_s": float(np.std(settled)),
        "arw_rad_s_per_sqrt_hz": N,
        "arw_deg_per_sqrt_h": None if N is None else N * ARW_DEG_PER_SQRT_H,
        "arw_tau_range_s": arw["tau_range"],
        "adev_at_1s_rad_s": None if N is None else N,
        "noise_figures_refused": refused,
        # properties of this record's Allan deviation, whether or not it is a noise figure
        "record_adev_min_rad_s": bi["adev_min"],
        "record_adev_min_tau_s": bi["tau_min"],
        "record_adev_at_1s_rad_s": (float(np.interp(0.0, np.log(taus), adev))
                                    if taus[0] <= 1.0 <= taus[-1] else None),
        "bias_instability_rad_s": B,
        "bias_instability_deg_h": None if B is None else B * DEG_PER_H,
        "bias_instability_resolved": bi["resolved"],
        "bias_instability_tau_s": bi["tau_min"],
        "adev_slope_at_min": bi["slope_at_min"],
        "stationarity": stat,
        "startup_time_s": t_on,
        "startup_band_rad_s": band,
        "startup_window_s": window,
        "settled_by_s": max(0.0, t_on - window),
        "taus_s": taus.tolist(),
        "adev_rad_s": adev.tolist(),
        "adev_rel_sigma": adev_uncertainty(n, h, taus).tolist(),
    }


# ----------------------------------------------------------------- rate response
@dataclass(frozen=True)
class SineSegment:
    t0: float  #: s
    length: float  #: s, whole periods
    f: float  #: Hz


def sine_plan(cfg: SpecConfig, t_start: float) -> list[SineSegment]:
    """One segment per frequency, back to back from t_start: at least cfg.bw_segment s
    and 5 periods, rounded up to whole periods."""
    out, t = [], t_start
    for f in sorted(cfg.bw_frequencies):
        length = math.ceil(max(cfg.bw_segment, 5.0 / f) * f) / f
        out.append(SineSegment(t, length, f))
        t += length
    return out


def stepped_sine_rate(base: float, amplitude: float,
                      plan: Sequence[SineSegment]) -> Callable[[float], float]:
    """Omega(t) = base + amplitude sin(2 pi f (t - t0)) in each segment, base outside."""
    starts = np.array([s.t0 for s in plan])

    def rate(t: float) -> float:
        i = int(np.searchsorted(starts, t, side="right")) - 1
        if i < 0:
            return base
        s = plan[i]
        if t >= s.t0 + s.length:
            return base
        return base + amplitude * math.sin(2.0 * math.pi * s.f * (t - s.t0))
    return rate


def sine_response(rec: Record, plan: Sequence[SineSegment], amplitude: float,
                  h: float, discard: float = 0.3) -> list[dict]:
    """Complex gain Omega_hat / Omega at each segment's frequency: a least-squares fit of
    a sin + b cos + c to Omega_hat over the segment's last (1 - discard) part (the
    transient of the frequency change dropped). The true rate over step k is held at
    its value at t_k, so a held sine lags half a step; that lag is taken out so that
    the phase is the observer's own."""
    out = []
    t_in = rec.t - h  # the rate over the step ending at rec.t started at rec.t - h
    for s in plan:
        sel = (t_in >= s.t0 + discard * s.length) & (t_in < s.t0 + s.length)
        # the estimate at rec.t responds to the held input; compare with the continuous
        # sine at the middle of the hold (a ZOH delays by h / 2)
        tau = rec.t[sel] - s.t0 - 0.5 * h
        w = 2.0 * math.pi * s.f
        X = np.column_stack([np.sin(w * tau), np.cos(w * tau), np.ones(tau.size)])
        coef, *_ = np.linalg.lstsq(X, rec.omega_hat[sel], rcond=None)
        g = complex(coef[0], coef[1]) / amplitude
        out.append({"f_hz": s.f, "gain": abs(g), "gain_db": 20.0 * math.log10(max(abs(g), 1e-12)),
                    "phase_deg": math.degrees(math.atan2(g.imag, g.real))})
    return out


def bandwidth_3db(response: Sequence[dict]) -> dict:
    """-3 dB bandwidth (Hz): the lowest frequency at which the gain, relative to the
    lowest frequency's gain, falls through -3 dB (linear interpolation of dB in log f).
    "below"/"above": the gain was already under -3 dB at the lowest / never fell under
    it up to the highest frequency tested; the value is then that frequency."""
    f = np.array([r["f_hz"] for r in response])
    g = np.array([r["gain_db"] for r in response])
    ref = g[0]
    rel = g - ref
    peak = float(rel.max())
    if ref < -3.0:
        return {"f_3db_hz": float(f[0]), "bound": "below", "peaking_db": peak,
                "reference_gain_db": float(ref)}
    below = np.flatnonzero(rel < -3.0)
    if below.size == 0:
        return {"f_3db_hz": float(f[-1]), "bound": "above", "peaking_db": peak,
                "reference_gain_db": float(ref)}
    j = int(below[0])
    x0, x1 = math.log(f[j - 1]), math.log(f[j])
    y0, y1 = rel[j - 1], rel[j]
    x = x0 + (-3.0 - y0) * (x1 - x0) / (y1 - y0)
    return {"f_3db_hz": float(math.exp(x)), "bound": None, "peaking_db": peak,
            "reference_gain_db": float(ref)}


# ----------------------------------------------------------------- scale factor
def scale_factor_fit(rates: Sequence[float], outputs: Sequence[float],
                     full_scale: float) -> dict:
    """Least-squares line outputs = SF rates + offset (IEEE 1431 12.9).

    Returns the scale factor SF (1: Omega_hat is in rad/s), its error (SF - 1) in ppm,
    the offset (rad/s), the residuals (rad/s and ppm of full scale) and the
    nonlinearity: the largest |residual| in ppm of full scale.
    """
    r = np.asarray(rates, dtype=float)
    y = np.asarray(outputs, dtype=float)
    if r.size < 3 or np.ptp(r) == 0.0:
        raise ValueError("need at least 3 distinct rates for a line and its residuals")
    X = np.column_stack([r, np.ones_like(r)])
    (sf, offset), *_ = np.linalg.lstsq(X, y, rcond=None)
    res = y - (sf * r + offset)
    res_ppm = res / full_scale * 1e6
    return {"scale_factor": float(sf), "sf_error_ppm": float((sf - 1.0) * 1e6),
            "offset_rad_s": float(offset), "rates_rad_s": r.tolist(),
            "outputs_rad_s": y.tolist(), "residuals_rad_s": res.tolist(),
            "residuals_ppm_fs": res_ppm.tolist(),
            "nonlinearity_ppm_fs": float(np.max(np.abs(res_ppm)))}


def scale_factor_study(cfg: SpecConfig, settle: float,
                       progress: Callable[[str], None]) -> dict:
    """One run per rate in +-full scale, each from power-on with the same noise seed
    (common random numbers: the noise, which enters the estimate almost independently
    of the rate, cancels in the line, leaving the rate-dependent error), averaging
    Omega_hat over sf_record s after `settle` s. A plateau whose two halves differ by
    more than 6 sigma of noise plus 1 % of the band has not settled: SpecError."""
    rates = np.linspace(-cfg.full_scale, cfg.full_scale, cfg.sf_points)
    h = cfg.step
    means, drifts = [], []
    for i, om in enumerate(rates):
        rec = simulate(cfg, lambda t, om=float(om): om, settle + cfg.sf_record,
                       f"scale-factor run at {om:+g} rad/s")
        e = rec.omega_hat[round(settle / h):]
        half = len(e) // 2
        a, b = float(np.mean(e[:half])), float(np.mean(e[half:]))
        means.append(float(np.mean(e)))
        drifts.append(b - a)
        progress(f"  rate {om:+8.4g} rad/s: mean Omega_hat {means[-1]:+.7g} rad/s "
                 f"({i + 1}/{len(rates)}, {rec.wall_s:.1f} s)")
    fit = scale_factor_fit(rates, means, cfg.full_scale)
    fit["settle_s"] = settle
    fit["record_s"] = cfg.sf_record
    # a drift common to all rates (the same noise, the same convergence) moves only the
    # offset; what differs between rates would move the line
    common = float(np.mean(drifts))
    i = int(np.argmax(np.abs(np.array(drifts) - common)))
    fit["half_record_drift_rad_s"] = drifts
    fit["common_drift_rad_s"] = common
    fit["worst_drift"] = {"rate_rad_s": float(rates[i]), "drift_rad_s": drifts[i] - common}
    return fit


# ----------------------------------------------------------------- the whole spec
def measure_spec(cfg: SpecConfig, progress: Callable[[str], None] = lambda s: None) -> dict:
    """The datasheet of this gyro + observer (a JSON-ready dict). SpecError if a run
    cannot be trusted (see the module docstring)."""
    start = time.perf_counter()
    noise = pickoff_noise(cfg)
    tuning = observer_tuning(cfg, noise)
    tun = ObserverTuning(**tuning)
    h = cfg.step
    progress(f"allan/start-up run: {cfg.duration:g} s at {cfg.rate:g} rad/s "
             f"({round(cfg.duration / h):,} steps)")
    rec = simulate(cfg, lambda t: cfg.rate, cfg.duration, "Allan/start-up run")
    progress(f"  done in {rec.wall_s:.1f} s")
    allan = allan_study(rec, cfg)
    allan["rate_model_probabilities"] = (
        probability_summary(rec, allan["settled_from_s"], h)
        if int(getattr(tun, "rate_model", -1)) == 0 else None)  # only the adaptive mixes
    trace = startup_trace(rec, allan["startup_window_s"], h)
    warnings_ = warning_summary("Allan/start-up run", rec)
    del rec

    settle = max(0.05, 2.0 * allan["startup_time_s"])
    plan = sine_plan(cfg, settle)
    t_end = plan[-1].t0 + plan[-1].length
    progress(f"rate-response run: {len(plan)} sines of {cfg.bw_amplitude:g} rad/s, "
             f"{plan[0].f:g}-{plan[-1].f:g} Hz, {t_end:.3g} s")
    rec = simulate(cfg, stepped_sine_rate(cfg.rate, cfg.bw_amplitude, plan), t_end,
                   "rate-response run", seed=cfg.seed + 1)
    progress(f"  done in {rec.wall_s:.1f} s")
    response = sine_response(rec, plan, cfg.bw_amplitude, h)
    bw = bandwidth_3db(response)
    warnings_ += warning_summary("rate-response run", rec)
    del rec

    progress(f"scale-factor runs: {cfg.sf_points} rates in +-{cfg.full_scale:g} rad/s, "
             f"{settle:.3g} s settling + {cfg.sf_record:g} s each")
    sf = scale_factor_study(cfg, settle, progress)
    noise_sigma = (allan["arw_rad_s_per_sqrt_hz"] or 0.0) / math.sqrt(cfg.sf_record)
    limit = 6.0 * 2.0 * noise_sigma + 0.01 * cfg.band  # 6 sigma of a difference of halves
    worst = sf["worst_drift"]
    if abs(worst["drift_rad_s"]) > limit:
        raise SpecError(
            f"scale-factor run at {worst['rate_rad_s']:+g} rad/s: Omega_hat still drifts by "
            f"{worst['drift_rad_s']:+.3g} rad/s more than the other rates' runs between the two "
            f"halves of its {cfg.sf_record:g} s plateau after {settle:.3g} s of settling (noise "
            f"allows {limit:.3g}, 6 sigma + 1 % of the start-up band): the estimate has not "
            "settled, its mean is no scale-factor point. Remedy: a longer --sf-record, a wider "
            "--startup-band, or another --tuning")

    p = cfg.scenario.params
    return {
        "what": "gyro-fmu spec: the observer-based gyro measured as a gyroscope "
                "(docs/gyro-spec.md)",
        "gyro": {"preset": cfg.preset, "overrides": dict(cfg.overrides),
                 "parameters": p.as_dict(), "drive": asdict(cfg.scenario.the_drive),
                 "initial_guess": default_initial_guess(p)},
        "noise": {"relative_to_peak": None if cfg.noise_density is not None else cfg.noise,
                  "density_m_per_sqrt_hz": cfg.noise_density,
                  "std_x_m": noise.x, "std_y_m": noise.y,
                  "density_x_m_per_sqrt_hz": noise.x * math.sqrt(2.0 * h),
                  "density_y_m_per_sqrt_hz": noise.y * math.sqrt(2.0 * h),
                  "convention": "std = density / sqrt(2 step): one-sided density, white "
                                "to the Nyquist frequency"},
        "observer_tuning": asdict(tun),
        "rate_model": rate_model_text(tun),
        "step_s": h,
        "seed": cfg.seed,
        "allan": allan,
        "rate_response": {"amplitude_rad_s": cfg.bw_amplitude, "about_rad_s": cfg.rate,
                          "method": "stepped sine, one frequency at a time",
                          "points": response, **bw},
        "scale_factor": {**sf, "full_scale_rad_s": cfg.full_scale,
                         "method": "one run per rate, same noise seed, mean of the "
                                   "settled estimate; least-squares line"},
        "warnings": warnings_,
        "wall_time_s": time.perf_counter() - start,
        "_startup_trace": trace,  # for the figure; not written to summary.json
    }


def probability_summary(rec: Record, t_from: float, h: float) -> dict | None:
    """Mean over the settled record and final probability of each rate model of an
    adaptive observer (None for an observer without them)."""
    if not rec.rate_models or rec.rate_probabilities.size == 0:
        return None
    p = rec.rate_probabilities
    k0 = min(len(p) - 1, int(t_from / (h * PROBABILITY_EVERY)))
    return {name: {"mean": float(np.mean(p[k0:, j])), "final": float(p[-1, j])}
            for j, name in enumerate(rec.rate_models)}


def warning_summary(what: str, rec: Record) -> list[str]:
    """One line per run with status-1 episodes of the observer (innovations above their
    chi-square band): how many, and the first one in words."""
    if not rec.warnings:
        return []
    t, text = rec.warnings[0]
    return [f"{what}: {len(rec.warnings)} innovation warning(s) (status 1) in "
            f"{rec.t[-1]:.3g} s; the first at t = {t:.4g} s: {text}"]


def startup_trace(rec: Record, window: float, h: float, points: int = 400) -> dict:
    """The trailing-window mean of the error at log-spaced times (for the figure)."""
    out = {}
    for key, w in (("", window), ("_1ms", 1e-3)):
        m = max(1, round(w / h))
        avg = moving_mean(rec.error, m)
        j = np.unique(np.geomspace(1, len(avg), points).astype(int) - 1)
        out[f"t_s{key}"] = rec.t[j + m - 1].tolist()
        out[f"error_rad_s{key}"] = avg[j].tolist()
    return out


def rate_model_text(tun: ObserverTuning) -> str:
    """The observer's rate model in words, for the ObserverTuning at hand: with a
    rate_model field (0 adaptive, 1 constant, 2 tracking, 3 expert) or without one
    (q_Omega on the omega_order-th derivative only)."""
    d = asdict(tun)
    if "rate_model" not in d:
        return f"q_Omega {d['q_Omega']:g}, omega_order {d['omega_order']:g}"
    kind = int(d["rate_model"])
    follow = (f"rate_bandwidth {d.get('rate_bandwidth', float('nan')):g} Hz, "
              f"rate_span {d.get('rate_span', float('nan')):g} rad/s")
    if kind == 0:
        return (f"rate_model 0 (adaptive: constant/slow/agile mixed), {follow}, "
                f"rate_dwell {d.get('rate_dwell', float('nan')):g} s")
    if kind == 1:
        return "rate_model 1 (constant)"
    if kind == 2:
        return f"rate_model 2 (tracking), {follow}"
    return f"rate_model {kind} (expert), q_Omega {d['q_Omega']:g}, omega_order {d['omega_order']:g}"
