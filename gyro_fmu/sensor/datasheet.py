"""GyroSensor's datasheet, measured from the FMU's own output (IEEE Std 952 / 1431 terms).

`measure_datasheet(fmu, settings)` runs GyroSensor.fmu (FMI 2.0 through fmpy, one
instance per seed, seeds in parallel processes) under one fixed protocol per seed:

- power-on at rate 0, a warm-up of WARM_UP s (the observer learns the gyro), then a
  record of RECORD s at rate 0: bias, output noise, Allan deviation -> upper bounds of
  the angle random walk, bias instability and rate random walk (the deviation of an
  observer's output need not have the slopes that read them off: docs/datasheet.md);
- from the state at the end of the warm-up (FMU state get/set): a step of STEP_RATE
  (latency: 50 % of the step; rise time 10-90 %; overshoot), stepped sines of
  SINE_AMPLITUDE (gain and phase -> the -3 dB bandwidth, peaking, group delay) and the
  constant rates +-SF_RATE (scale-factor error, with the record's rate 0 as the third
  point);

every run with `resolution` 0 (the quantization is declared, not measured: it would
hide noise below one bit). A figure is the mean over the seeds, its uncertainty the
standard deviation of one seed's figure (the run-to-run spread), with the seeds'
values. `check_datasheet` holds a new measurement (other seeds) against a datasheet:
a problem list, empty when every figure agrees within the t-distribution's 99.9 %
prediction interval of the spread.

What the figures mean for an observer-based gyro, and what they are not: docs/datasheet.md.
"""

from __future__ import annotations

import math
import os
import tempfile
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from multiprocessing import get_context
from pathlib import Path

import numpy as np

from ..cosim.instances import LogCollector, fmi2_callbacks
from ..errors import GyroFmuError
from ..studies.allan import BIAS_INSTABILITY_FACTOR, allan_deviation, allan_taus
from ..studies.response import bandwidth_3db, sine_gain

#: The protocol (s, rad/s, Hz). Host steps: 1 ms for the records, 0.2 ms for the step
#: and the sines (their hold lags h/2, taken out of the phase).
WARM_UP, RECORD, RECORD_STEP = 2.0, 8.0, 1e-3
FAST_STEP = 2e-4
STEP_RATE, STEP_LENGTH = 1.0, 0.05
SINE_AMPLITUDE = 1.0
SINE_FREQUENCIES = (5.0, 10.0, 20.0, 40.0, 60.0, 80.0, 100.0, 120.0, 150.0, 200.0)
SINE_MIN_LENGTH, SINE_MIN_PERIODS, SINE_SKIP = 0.1, 5, 0.3
SF_RATE, SF_SETTLE, SF_RECORD = 10.0, 0.5, 0.5
#: A vehicle's sway: a small slow sine, fitted over its last SWAY_LENGTH - SWAY_SKIP s
#: (the figures above are for 1 rad/s; the observer's adaptive rate models take a motion
#: this small for a constant rate: docs/gyro-sensor.md, "What falls short").
SWAY_AMPLITUDE, SWAY_FREQUENCY, SWAY_LENGTH, SWAY_SKIP = 0.05, 2.0, 1.5, 0.5
#: Seeds of the shipped datasheet; a check uses others.
SEEDS = (1, 2, 3, 4, 5, 6)
CHECK_SEEDS = (101, 102)
#: Coverage of the check: two-sided probability of the prediction interval.
CHECK_PROBABILITY = 0.999
DATASHEET = "documentation/datasheet.json"
DATASHEET_TEXT = "documentation/datasheet.md"
#: The preset whose datasheet is DATASHEET: the FMU's own defaults.
DEFAULT_PRESET = "consumer"
FORMAT = "gyro_fmu datasheet 1"


class DatasheetError(GyroFmuError):
    """A run that gives no datasheet (the observer lost, a bad setting)."""


@dataclass(frozen=True)
class Term:
    """One datasheet term: its unit, how it is measured, and its direction (the bound
    the value is: None for a plain figure, "upper" when the value bounds the true term
    from above)."""

    unit: str
    how: str
    bound: str | None = None


TERMS: dict[str, Term] = {
    "bias": Term("rad/s", f"mean output at rate 0 over {RECORD:g} s after a {WARM_UP:g} s "
                 "warm-up from power-on"),
    "noise_rms": Term("rad/s", "standard deviation of the output at rate 0 over the same "
                      "record (the output filter's bandwidth)"),
    "arw": Term("rad/s/sqrt(Hz)", "angle random walk N (IEEE 952: sigma = N / sqrt(tau)): "
                "the largest the Allan deviation allows, min over tau >= 2 / bandwidth of "
                "sigma(tau) sqrt(tau)", "upper"),
    "bias_instability": Term("rad/s", "bias instability B (IEEE 952: sigma = 0.664 B on the "
                             "flat part): the largest the Allan deviation allows, min over "
                             "tau >= 2 / bandwidth of sigma(tau) / 0.664", "upper"),
    "rate_random_walk": Term("rad/s/sqrt(s)", "rate random walk K (IEEE 952: sigma = K "
                             "sqrt(tau / 3)): the largest the Allan deviation allows, min "
                             "over tau >= 2 / bandwidth of sigma(tau) sqrt(3 / tau)", "upper"),
    "adev_1s": Term("rad/s", "Allan deviation of the same record at tau = 1 s"),
    "scale_factor_error": Term("ppm", f"(SF - 1) 1e6, SF the slope of the line through the "
                               f"mean outputs at -{SF_RATE:g}, 0, +{SF_RATE:g} rad/s"),
    "latency": Term("s", f"time from a {STEP_RATE:g} rad/s input step to 50 % of it in the "
                    "output"),
    "rise_time": Term("s", "10 % to 90 % of the same step"),
    "overshoot": Term("1", "largest output after the step over its final value, minus 1"),
    "bandwidth": Term("Hz", f"-3 dB point of stepped sines of {SINE_AMPLITUDE:g} rad/s "
                      "(IEEE 1431 12.15), relative to the lowest frequency's gain"),
    "peaking": Term("dB", "largest gain of the sines over the lowest frequency's"),
    "group_delay": Term("s", f"-phase / (2 pi f) of the {SINE_FREQUENCIES[0]:g} Hz sine"),
    "sway_gain": Term("1", f"gain of the output at {SWAY_FREQUENCY:g} Hz for a sine of "
                      f"{SWAY_AMPLITUDE:g} rad/s from the warm-up (a vehicle's sway: the "
                      f"figures above are for 1 rad/s), over its last "
                      f"{SWAY_LENGTH - SWAY_SKIP:g} s"),
    "sway_error": Term("rad/s", "RMS of the output minus the input rate over the same "
                       "window (compare noise_rms: the error at rest)"),
}


# ---- one seed ----------------------------------------------------------------------------
class _Instance:
    """GyroSensor.fmu (FMI 2.0) through fmpy, stepped by hand: FMU state saved and
    restored for the runs that start from the warm-up."""

    def __init__(self, unzipped: str, settings: Mapping[str, float]):
        from fmpy import read_model_description
        from fmpy.fmi2 import FMU2Slave
        from fmpy.simulation import apply_start_values

        md = read_model_description(unzipped)
        self.log = LogCollector()  # the FMU's messages: warnings counted, not printed
        self.callbacks = fmi2_callbacks(self.log)  # kept: the FMU calls it until freed
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzipped,
                             modelIdentifier=md.coSimulation.modelIdentifier,
                             instanceName="datasheet")
        self.fmu.instantiate(callbacks=self.callbacks)
        self.fmu.setupExperiment(startTime=0.0)
        self.fmu.enterInitializationMode()
        apply_start_values(self.fmu, md, dict(settings))
        self.fmu.exitInitializationMode()
        self.t = 0.0
        self.out = [self.vr[n] for n in ("Omega_meas", "status")]

    def run(self, rate: Callable[[float], float], length: float, h: float,
            what: str) -> tuple[np.ndarray, np.ndarray]:
        """Step `length` s at host step h with the input rate(t - start) held over each
        step; returns the times and Omega_meas after each step."""
        n = round(length / h)
        t0 = self.t
        y = np.empty(n)
        for i in range(n):
            self.fmu.setReal([self.vr["Omega_z"]], [rate(i * h)])
            self.fmu.doStep(self.t, h)
            self.t = t0 + (i + 1) * h
            y[i], status = self.fmu.getReal(self.out)
            if status == 2.0:
                raise DatasheetError(f"{what}: the observer lost the gyro at t={self.t:.6g} s "
                                     "(status 2): no datasheet for these settings")
        return t0 + h * np.arange(1, n + 1), y

    def save(self) -> tuple[object, float]:
        return self.fmu.getFMUstate(), self.t

    def restore(self, saved: tuple[object, float]) -> None:
        self.fmu.setFMUstate(saved[0])
        self.t = saved[1]


def _step_response(t: np.ndarray, y: np.ndarray, t_step: float) -> dict:
    """Latency (50 %), rise time (10-90 %) and overshoot of the outputs y at times t after
    an input step at t_step (on the host's grid: the held input is the step itself) to
    STEP_RATE from the level before it; crossings interpolated linearly."""
    before = float(np.mean(y[(t > t_step - 0.01) & (t <= t_step)]))
    after = t > t_step
    tt, yy = t[after], (y[after] - before) / STEP_RATE
    final = float(np.mean(yy[tt >= tt[-1] - 0.01]))

    def crossing(level: float) -> float:
        i = int(np.argmax(yy >= level * final))
        if i == 0 or yy[i] < level * final:
            raise DatasheetError(f"step response: the output never reached {level:.0%} of "
                                 "the step")
        return float(np.interp(level * final, yy[i - 1:i + 1], tt[i - 1:i + 1]))

    t10, t50, t90 = (crossing(x) for x in (0.1, 0.5, 0.9))
    return {"latency": t50 - t_step, "rise_time": t90 - t10,
            "overshoot": float(np.max(yy) / final - 1.0)}


def _sine_from_warm(inst: _Instance, warm: tuple[object, float], f: float, amplitude: float,
                    length: float, h: float, skip: float, what: str
                    ) -> tuple[np.ndarray, np.ndarray]:
    """A sine of `amplitude` at f Hz for `length` s at host step h from the warm-up state:
    each output's input time (held over the step before it) and the output, from `skip`."""
    inst.restore(warm)
    w = 2.0 * math.pi * f
    t, y = inst.run(lambda s: amplitude * math.sin(w * s), length, h, what)
    s = t - warm[1] - h
    keep = s >= skip
    return s[keep], y[keep]


def _sine_response(inst: _Instance, warm: tuple[object, float]) -> tuple[list[dict], dict]:
    """Gain and phase of each stepped sine, each from the warm-up state."""
    h = FAST_STEP
    response = []
    for f in SINE_FREQUENCIES:
        length = math.ceil(max(SINE_MIN_LENGTH, SINE_MIN_PERIODS / f) * f) / f
        s, y = _sine_from_warm(inst, warm, f, SINE_AMPLITUDE, length, h, SINE_SKIP * length,
                               f"the {f:g} Hz sine")
        # the held input lags the continuous sine by h / 2
        response.append(sine_gain(s + h / 2, y, f, SINE_AMPLITUDE))
    bw = bandwidth_3db(response)
    if bw["bound"] is not None:
        raise DatasheetError(f"stepped sines: the gain is {bw['bound']} -3 dB over "
                             f"{SINE_FREQUENCIES[0]:g}-{SINE_FREQUENCIES[-1]:g} Hz: the "
                             "bandwidth is outside what the datasheet measures")
    first = response[0]
    delay = -math.radians(first["phase_deg"]) / (2 * math.pi * first["f_hz"])
    return response, {"bandwidth": bw["f_3db_hz"], "peaking": bw["peaking_db"],
                      "group_delay": delay}


def _sway_response(inst: _Instance, warm: tuple[object, float]) -> dict:
    """sway_gain and sway_error (TERMS) from the warm-up state, at the records' host step."""
    h, w = RECORD_STEP, 2.0 * math.pi * SWAY_FREQUENCY
    s, y = _sine_from_warm(inst, warm, SWAY_FREQUENCY, SWAY_AMPLITUDE, SWAY_LENGTH, h,
                           SWAY_SKIP - 1e-9, "the sway")
    gain = sine_gain(s + h / 2, y, SWAY_FREQUENCY, SWAY_AMPLITUDE)["gain"]
    error = y - SWAY_AMPLITUDE * np.sin(w * s)
    return {"sway_gain": gain, "sway_error": float(np.sqrt(np.mean(error**2)))}


def measure_seed(unzipped: str, settings: Mapping[str, float], seed: int,
                 bandwidth: float) -> dict:
    """Every figure of one seed, with the curves they come from (see the module);
    bandwidth: the output filter's (Hz), below whose time scale no white noise is read."""
    s = {**settings, "seed": seed, "resolution": 0.0}
    inst = _Instance(unzipped, s)
    inst.run(lambda _: 0.0, WARM_UP, RECORD_STEP, "the warm-up")
    warm = inst.save()
    _, y = inst.run(lambda _: 0.0, RECORD, RECORD_STEP, "the rate-0 record")
    h = RECORD_STEP
    taus = allan_taus(len(y), h, max_fraction=0.25)
    adev = allan_deviation(y, h, taus)
    # each IEEE 952 term alone bounds the deviation from below at every tau beyond the
    # output filter's time scale: its largest value the curve allows is its bound
    white = taus >= 2.0 / bandwidth
    tw, aw = taus[white], adev[white]
    figures = {"bias": float(np.mean(y)), "noise_rms": float(np.std(y)),
               "arw": float(np.min(aw * np.sqrt(tw))),
               "bias_instability": float(np.min(aw) / BIAS_INSTABILITY_FACTOR),
               "rate_random_walk": float(np.min(aw * np.sqrt(3.0 / tw))),
               "adev_1s": float(np.interp(0.0, np.log(taus), adev))}
    means = {}
    for rate in (-SF_RATE, SF_RATE):
        inst.restore(warm)
        _, yr = inst.run(lambda _, r=rate: r, SF_SETTLE + SF_RECORD, h, f"the {rate:+g} rad/s run")
        means[rate] = float(np.mean(yr[round(SF_SETTLE / h):]))
    rates = np.array([-SF_RATE, 0.0, SF_RATE])
    outs = np.array([means[-SF_RATE], float(np.mean(y[:round(SF_RECORD / h)])), means[SF_RATE]])
    sf = float(np.polyfit(rates, outs, 1)[0])
    figures["scale_factor_error"] = (sf - 1.0) * 1e6
    inst.restore(warm)
    t_step = 0.01
    t, ys = inst.run(lambda s_: STEP_RATE if s_ >= t_step - 1e-12 else 0.0,
                     t_step + STEP_LENGTH, FAST_STEP, "the step")
    figures.update(_step_response(t - warm[1], ys, t_step))
    response, sines = _sine_response(inst, warm)
    figures.update(sines)
    figures.update(_sway_response(inst, warm))
    inst.fmu.terminate()
    inst.fmu.freeInstance()
    warnings = [m for _, status, _, m in inst.log.messages if status == 1]
    return {"seed": seed, "figures": figures, "warnings": warnings,
            "curves": {"taus": taus.tolist(), "adev": adev.tolist(),
                       "step_t": (t - warm[1] - t_step).tolist(),
                       "step_y": ys.tolist(), "response": response}}


# ---- the datasheet -----------------------------------------------------------------------
def measure_datasheet(fmu: Path, settings: Mapping[str, float] | None = None,
                      seeds: Sequence[int] = SEEDS, workers: int | None = None) -> dict:
    """The datasheet of GyroSensor.fmu at `settings` (its parameters by name; the FMU's
    own start values for the rest): each figure's mean over `seeds` and the standard
    deviation of one seed's figure. Raises DatasheetError when a run cannot give one."""
    from fmpy import extract, read_model_description

    if len(set(seeds)) < 2 or len(set(seeds)) != len(seeds):
        raise DatasheetError(f"seeds {list(seeds)}: give at least 2 different ones, each "
                             "once (their spread is the uncertainty; a repeated seed repeats "
                             "its run and shrinks it)")
    md = read_model_description(str(fmu))
    names = {v.name for v in md.modelVariables}
    missing = sorted({"Omega_z", "Omega_meas", "status", "bandwidth"} - names)
    if missing:
        raise DatasheetError(f"{Path(fmu).name} ({md.modelName}) has no {missing}: a "
                             "datasheet is measured from GyroSensor.fmu")
    starts = {v.name: float(v.start) for v in md.modelVariables
              if v.causality == "parameter" and v.start is not None}
    unknown = sorted(set(settings or {}) - set(starts))
    if unknown:
        raise DatasheetError(f"not parameters of {Path(fmu).name}: {unknown}; its parameters "
                             f"are {sorted(starts)}")
    full = {**starts, **(settings or {})}
    workers = workers or min(len(seeds), os.cpu_count() or 1)
    with tempfile.TemporaryDirectory(prefix="gyro_fmu-datasheet-") as tmp:
        unzipped = extract(str(fmu), unzipdir=tmp)
        with ProcessPoolExecutor(workers, mp_context=get_context("spawn")) as pool:
            per_seed = list(pool.map(measure_seed, [unzipped] * len(seeds),
                                     [dict(settings or {})] * len(seeds), seeds,
                                     [full["bandwidth"]] * len(seeds)))
    figures = {}
    for name, term in TERMS.items():
        values = np.array([r["figures"][name] for r in per_seed])
        figures[name] = {"value": float(values.mean()), "uncertainty": float(values.std(ddof=1)),
                         "unit": term.unit, "seeds": values.tolist(), "how": term.how,
                         **({"bound": term.bound} if term.bound else {})}
    declared = {
        "full_scale": {"value": full["full_scale"], "unit": "rad/s",
                       "how": "declared (parameter full_scale): the output is clamped to it"},
        "resolution": {"value": full["resolution"], "unit": "rad/s",
                       "how": "declared (parameter resolution): one output bit; its noise "
                              "resolution / sqrt(12) adds to noise_rms"},
    }
    return {"format": FORMAT, "model": md.modelName,
            "observer_warnings": {str(r["seed"]): len(r["warnings"]) for r in per_seed},
            "settings": {k: full[k] for k in sorted(settings or {})},
            "protocol": {"warm_up_s": WARM_UP, "record_s": RECORD, "record_step_s": RECORD_STEP,
                         "fast_step_s": FAST_STEP, "sine_frequencies_hz": list(SINE_FREQUENCIES),
                         "sf_rate_rad_s": SF_RATE, "seeds": list(seeds),
                         "uncertainty": "standard deviation of one seed's figure (k = 1)"},
            "figures": {**figures, **declared},
            "curves": {str(r["seed"]): r["curves"] for r in per_seed}}


def check_datasheet(reference: dict, measured: dict,
                    probability: float = CHECK_PROBABILITY) -> list[str]:
    """Problems of `measured` (other seeds) against `reference`: each figure's mean must lie
    within t * u * sqrt(1/K + 1/M) of the reference's, u the reference's spread over its
    K seeds, t the Student-t quantile of `probability` with K - 1 degrees of freedom
    (a prediction interval for a mean of M new seeds). Empty when all agree."""
    from scipy.stats import t as student

    shared = sorted(set(reference["protocol"]["seeds"]) & set(measured["protocol"]["seeds"]))
    if shared:  # the same runs again: agreement would say nothing
        return [f"seeds {shared} made the datasheet too: check with other seeds"]
    problems = []
    k = len(reference["protocol"]["seeds"])
    m = len(measured["protocol"]["seeds"])
    q = float(student.ppf(0.5 + probability / 2, k - 1))
    for name in TERMS:
        ref, new = reference["figures"][name], measured["figures"][name]
        tol = q * ref["uncertainty"] * math.sqrt(1 / k + 1 / m)
        diff = new["value"] - ref["value"]
        if not abs(diff) <= tol:
            problems.append(f"{name}: measured {new['value']:.4g} {ref['unit']} against the "
                            f"datasheet's {ref['value']:.4g} +- {ref['uncertainty']:.2g} "
                            f"(allowed +-{tol:.2g} at {probability:.1%})")
    return problems
