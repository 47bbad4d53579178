"""Monte Carlo over fabrication tolerances: many gyroscopes, each a real FMU co-simulation, on Dask.

A :class:`ToleranceModel` (a preset as nominal, a relative spread per parameter,
normal or uniform, a seed) draws N gyroscopes. Each one runs as a real
co-simulation of the four FMUs (:func:`gyro_fmu.system.run.run_fmus`) with the drawn
parameters as the plant's truth and the **nominal** values as the observer's
initial guess, and is reduced to one row: the drawn parameters, final estimates
and errors, the convergence time of each unknown (stays within tolerance to the
end of the run: 1% of its truth, 0.1 1/s for a zero damping, 1% of the peak
rate; :mod:`gyro_fmu.estimation.metrics`), whether all 8 are within tolerance at the
deadline, the wall time, and a status ``ok`` or ``failed`` with the reason.

Each row also carries the Cramer-Rao bound at the deadline for that gyro's own
inputs and noise (:func:`gyro_fmu.estimation.identify.crb_at` on the record of its
run, samples before the deadline) and the observer's error in units of it. The
summary compares the lot with an efficient estimator: the fraction within 2
bound-sigmas per unknown and for all 8 (beside what an efficient estimator would
reach, 95.4 % per unknown and the joint Gaussian probability for all 8), the RMS of
err/CRB, the fraction an efficient estimator would have within tolerance (the
probability P(|e| < tol), e ~ N(0, CRB), averaged over the lot; for all 8 the joint
probability with the bound's correlations) beside the measured fraction, and the
deadline by which 95 % of the lot are within tolerance (docs/sweep-bound.md).

The runs are Dask tasks: a ``dask.distributed.LocalCluster`` (one single-threaded
worker process per core) by default, or an existing scheduler by address
(``scheduler="tcp://host:8786"``); nothing else changes. Workers need gyro_fmu
installed; the FMUs are found through the absolute ``models_dir`` each task
receives (on a remote cluster that path must exist on the workers, e.g. a shared
file system). A run that fails (unusable parameters, FMU error, NaN, divergence,
even a worker crash) becomes a row with its reason: it is never lost and never
stops the sweep.
"""

from __future__ import annotations

import csv
import json
import math
import time
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np

from ..estimation.metrics import ESTIMATED, convergence_time, tolerance
from ..model.drive import TwoToneDrive
from ..model.parameters import PARAMETER_NAMES, ParameterError, preset
from .scenario import Scenario, scenario

#: Estimates beyond this many tolerances at the end count as diverged.
DIVERGED_TOLERANCES = 1e3

#: Fraction of the lot whose convergence time defines the sweep's deadline figure.
DEADLINE_FRACTION = 0.95

#: Gaussian draws per gyro for the joint probabilities of an efficient estimator.
JOINT_DRAWS = 20000

#: Points of the within-tolerance curve, evenly spaced up to the deadline (and the
#: draws per point for an efficient estimator's curve).
CURVE_POINTS, CURVE_DRAWS = 40, 4000

#: What the observer is told, before SweepSpec.tuning: "scenario" = what
#: gyro_fmu.system.scenario.observer_tuning sets for the scenario (the constant-rate
#: model and the pick-off noise stds); "fmu-rate" = the same with its rate settings put
#: back to the observer FMU's defaults (the noise stays told); "fmu" = the FMU's
#: defaults for everything observer_tuning sets (rate model and noise estimation).
OBSERVER_TUNINGS = ("scenario", "fmu-rate", "fmu")


@dataclass(frozen=True)
class ToleranceModel:
    """Nominal part (a preset with optional overrides) and the fabrication scatter.

    spread: relative spread per parameter (a name missing from it does not scatter);
    uniform: value = nominal * (1 + spread * U(-1, 1)); normal: nominal * (1 + spread *
    N(0, 1)). Where the nominal is 0 the spread is absolute (value = spread * U or N).
    """

    preset: str = "park-horowitz"
    overrides: Mapping[str, float] = field(default_factory=dict)
    spread: Mapping[str, float] = field(
        default_factory=lambda: dict.fromkeys(PARAMETER_NAMES, 0.10))
    distribution: Literal["uniform", "normal"] = "uniform"
    seed: int = 0

    def __post_init__(self) -> None:
        unknown = sorted(set(self.spread) - set(PARAMETER_NAMES))
        if unknown:
            raise ParameterError(
                f"unknown parameter(s) {unknown} in spread: {list(PARAMETER_NAMES)}")
        if self.distribution not in ("uniform", "normal"):
            raise ParameterError(f"distribution must be 'uniform' or 'normal', not "
                             f"{self.distribution!r}")
        bad = {k: v for k, v in self.spread.items() if not (math.isfinite(v) and v >= 0)}
        if bad:
            raise ParameterError(f"spreads must be finite and >= 0: {bad}")

    @property
    def nominal(self) -> dict[str, float]:
        return preset(self.preset, **self.overrides).as_dict()

    def draw(self, n: int) -> list[dict[str, float]]:
        """n parameter sets, reproducible from the seed (same seed, same first n draws)."""
        rng = np.random.default_rng(self.seed)
        nominal = self.nominal
        shape = (n, len(PARAMETER_NAMES))
        unit = rng.uniform(-1.0, 1.0, shape) if self.distribution == "uniform" \
            else rng.standard_normal(shape)
        out = []
        for row in unit:
            d = {}
            for j, name in enumerate(PARAMETER_NAMES):
                s, v = self.spread.get(name, 0.0), nominal[name]
                d[name] = float(v * (1.0 + s * row[j]) if v != 0.0 else s * row[j])
            out.append(d)
        return out


@dataclass(frozen=True)
class SweepSpec:
    """What every gyro of the sweep runs: the base scenario and the deadline."""

    tolerances: ToleranceModel = field(default_factory=ToleranceModel)
    n: int = 200
    noise: float = 1e-5  #: of each signal's peak
    Omega_z: float = 1.0  #: constant rate, rad/s
    stop_time: float = 0.08  #: s
    deadline: float | None = None  #: s; None: stop_time
    step: float = 5e-6
    measured_pair: int = 1
    noise_seed: int = 1000  #: gyro i gets noise seed noise_seed + i
    tuning: Mapping[str, float] = field(default_factory=dict)
    observer_tuning: Literal["scenario", "fmu-rate", "fmu"] = "scenario"
    drive: TwoToneDrive | None = None  #: None: the preset's default tones
    #: also fit each gyro's record with the batch maximum-likelihood identifier (from
    #: the observer's start, noise told; a few seconds per gyro): an estimator that
    #: reaches the bound on the same data, to tell the bound's tail from the observer's
    batch: bool = False

    def __post_init__(self) -> None:
        if self.observer_tuning not in OBSERVER_TUNINGS:
            raise ParameterError(f"observer_tuning must be one of {OBSERVER_TUNINGS}, not "
                                 f"{self.observer_tuning!r}")

    @property
    def the_deadline(self) -> float:
        return self.stop_time if self.deadline is None else self.deadline

    def base_scenario(self) -> Scenario:
        from ..model.rate import RateKind, RateProfile

        sc = scenario(
            "default", preset=self.tolerances.preset, stop_time=self.stop_time, step=self.step,
            noise=self.noise, measured_pair=self.measured_pair, drive=self.drive,
            rate=RateProfile(RateKind.constant, offset=self.Omega_z))
        reset = {} if self.observer_tuning == "scenario" else \
            fmu_default_tuning(sc, noise_too=self.observer_tuning == "fmu")
        return sc.with_(tuning={**reset, **self.tuning})

    def scenario_for(self, i: int, drawn: Mapping[str, float]) -> Scenario:
        return self.base_scenario().with_(
            overrides={**self.tolerances.overrides, **drawn},
            initial=self.tolerances.nominal, seed=self.noise_seed + i)


def fmu_default_tuning(sc: Scenario, noise_too: bool = False) -> dict[str, float]:
    """What observer_tuning sets for sc (its rate settings; with noise_too, the noise
    stds too), at the observer FMU's own defaults."""
    from dataclasses import fields

    from ..estimation.observer_tuning import ObserverTuning
    from ..model.plant import MeasurementNoise
    from .scenario import observer_tuning

    defaults = {f.name: getattr(ObserverTuning(), f.name) for f in fields(ObserverTuning)}
    # with the noise off observer_tuning sets only its rate settings; a unit noise shows
    # which settings it makes from the noise
    chosen = observer_tuning(sc.with_(tuning={}),
                             MeasurementNoise(1.0, 1.0, 1.0, 1.0) if noise_too
                             else MeasurementNoise())
    return {k: defaults[k] for k in chosen if k in defaults}


def run_gyro(i: int, drawn: Mapping[str, float], spec: SweepSpec, models_dir: str) -> dict:
    """One gyroscope through the FMUs; always returns a row (status ok or failed)."""
    row: dict = {"gyro": i, "status": "failed", "reason": "",
                 **{f"true_{k}": float(v) for k, v in drawn.items()}}
    start = time.perf_counter()
    try:
        from ..model.parameters import validate_for_plant
        from .run import run_fmus
        from .scenario import absolute_noise

        sc = spec.scenario_for(i, drawn)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            validate_for_plant(sc.params)
            noise = absolute_noise(sc)
            result = run_fmus(sc, Path(models_dir), noise=noise, ensure=False)  # host ensured
        row["warnings"] = " | ".join(str(w.message) for w in caught)
        row.update(_reduce(sc, result, spec, noise, i))
    except Exception as exc:  # recorded, never raised: the sweep goes on
        row["reason"] = f"{type(exc).__name__}: {exc}".replace("\n", " ")[:500]
    row["wall_s"] = time.perf_counter() - start
    return row


def _reduce(sc: Scenario, result, spec: SweepSpec, noise=None, i: int = 0) -> dict:
    from .run import estimate_column

    t = result["time"]
    k_dead = int(np.argmin(np.abs(t - spec.the_deadline)))
    k_curve = curve_indices(k_dead)
    within_curve = np.ones(k_curve.size, bool)
    truth = sc.params
    out: dict = {}
    conv_all: float | None = 0.0
    within_all = True
    worst = 0.0
    for name in ESTIMATED:
        true_series = result["rate.Omega_z"] if name == "Omega_z" else \
            np.full(t.shape, getattr(truth, name))
        est = result[estimate_column(name)]
        err = est - true_series
        tol = tolerance(name, true_series)
        if not np.all(np.isfinite(est)):
            return {"status": "failed", "reason": f"NaN/inf in the estimate of {name}"}
        conv = convergence_time(t, err, tol)
        within = bool(abs(err[k_dead]) <= tol)
        worst = max(worst, abs(err[-1]) / tol)
        out[f"est_{name}"] = float(est[-1])
        out[f"err_{name}"] = float(err[-1])
        out[f"err_over_tol_{name}"] = float(abs(err[-1]) / tol)
        out[f"sigma_{name}"] = float(result[f"observer.sigma_{name}"][-1])
        out[f"conv_s_{name}"] = conv
        out[f"tol_{name}"] = tol
        out[f"err_dead_{name}"] = float(err[k_dead])
        within_all &= within
        within_curve &= np.abs(err[k_curve]) <= tol
        conv_all = None if conv is None or conv_all is None else max(conv_all, conv)
    if not np.all(np.isfinite(result.data)):
        return {**out, "status": "failed", "reason": "NaN/inf in the co-simulation outputs"}
    if worst > DIVERGED_TOLERANCES:
        return {**out, "status": "failed",
                "reason": f"diverged: final error {worst:.3g} tolerances"}
    out.update(status="ok", reason="", within_at_deadline=within_all, conv_s_all=conv_all,
               within_all_curve=[bool(v) for v in within_curve])
    if noise is not None and not noise.is_off:
        out.update(_bound(sc, result, spec, noise, k_dead, out, seed=i))
    return out


def _bound(sc: Scenario, result, spec: SweepSpec, noise, k_dead: int, out: dict,
           seed: int = 0) -> dict:
    """Cramer-Rao 1-sigma at the deadline for this gyro's inputs and noise, err / CRB, and
    what an efficient estimator would reach (module docstring)."""
    from ..estimation.identify import crb_at, record_from_result

    pair = ("x", "y") if sc.measured_pair == 1 else ("vx", "vy")
    std = tuple(float(getattr(noise, c)) for c in pair)
    # the estimate at t_k has used the measurements at t_0 .. t_{k-1}
    record = record_from_result(result, sc.measured_pair).head(max(k_dead, 10))
    crb = crb_at(sc.params, spec.Omega_z, record, std)
    row: dict = {"noise_std_z1": std[0], "noise_std_z2": std[1]}
    sig = np.array([crb[n] for n in ESTIMATED])
    tol = np.array([out[f"tol_{n}"] for n in ESTIMATED])
    err = np.array([out[f"err_dead_{n}"] for n in ESTIMATED])
    finite = bool(np.all(np.isfinite(sig)) and np.all(sig > 0))
    for j, name in enumerate(ESTIMATED):
        row[f"crb_{name}"] = float(sig[j])
        row[f"err_over_crb_{name}"] = float(err[j] / sig[j]) if sig[j] > 0 else None
        row[f"p_eff_{name}"] = float(math.erf(tol[j] / (math.sqrt(2.0) * sig[j]))) \
            if sig[j] > 0 else 1.0
    row["within_2crb_all"] = bool(np.all(np.abs(err) <= 2.0 * sig))
    row["p_eff_all"] = row["p_eff_2crb_all"] = None
    if finite:
        J = _weighted_sensitivities(sc, spec.Omega_z, record, std)
        corr = _correlation(fisher_covariance(J))
        e = _gaussian_draws(corr, np.random.default_rng(seed))  # in units of each CRB
        row["p_eff_all"] = float(np.mean(np.all(np.abs(e) * sig <= tol, axis=1)))
        row["p_eff_2crb_all"] = float(np.mean(np.all(np.abs(e) <= 2.0, axis=1)))
        row["p_eff_all_curve"] = _efficient_curve(J, curve_indices(k_dead), tol, seed)
    if spec.batch:
        row.update(_batch(sc, record, std, sig, tol))
    return row


def _batch(sc: Scenario, record, std, sig: np.ndarray, tol: np.ndarray) -> dict:
    """The batch ML identifier on the same samples: its errors, in tolerances and CRBs."""
    from ..estimation.identify import identify
    from ..model.parameters import GyroParameters

    try:
        ident = identify(record, GyroParameters(**sc.initial_guess), sc.Omega_z_0,
                         noise_std=std)
    except Exception as exc:  # recorded: the observer's row stays valid
        return {"batch_reason": f"{type(exc).__name__}: {exc}"[:300]}
    err = ident.error(sc.params, float(sc.rate.Omega_z(0.0)))
    row: dict = {"batch_success": ident.success}
    for j, name in enumerate(ESTIMATED):
        row[f"batch_err_{name}"] = float(err[name])
        row[f"batch_err_over_crb_{name}"] = float(err[name] / sig[j]) if sig[j] > 0 else None
    e = np.array([err[n] for n in ESTIMATED])
    row["batch_within_all"] = bool(np.all(np.abs(e) <= tol))
    row["batch_within_2crb_all"] = bool(np.all(np.abs(e) <= 2.0 * sig))
    return row


def curve_indices(k_dead: int, points: int = CURVE_POINTS) -> np.ndarray:
    """Sample indices of the within-tolerance curve: evenly spaced, the last the deadline."""
    return np.unique(np.clip(np.round(np.arange(1, points + 1) * k_dead / points), 1,
                             max(k_dead, 1)).astype(int))


def curve_times(spec: SweepSpec) -> list[float]:
    k_dead = round(min(spec.the_deadline, spec.stop_time) / spec.step)
    return [float(k * spec.step) for k in curve_indices(k_dead)]


def _weighted_sensitivities(sc: Scenario, Omega_z: float, record, std) -> np.ndarray:
    """(N, 2, 8) c_i dz/dtheta_i / noise std: the exact sensitivities crb_at uses (its
    Jacobian, in the units of the scales c_i), sample by sample."""
    from ..estimation.sensitivity import ScaledSensitivitySystem
    from ..model.measurement import MeasuredPair

    sys = ScaledSensitivitySystem.build(sc.params, Omega_z, record.h)
    sigma = sys.simulate(np.zeros(sys.Phi.shape[0]), record.u)
    _, dS = sys.unscale(sigma)  # (N, 8, 4): c_i ds/dtheta_i
    rows = list(MeasuredPair(record.measured_pair).state_rows)
    dz = np.moveaxis(dS[:, :, rows], 1, 2) / np.asarray(std, float)[None, :, None]
    return dz / sys.scales  # SI: dz/dtheta_i / std


def fisher_covariance(J: np.ndarray, n: int | None = None) -> np.ndarray:
    """Cramer-Rao covariance (SI) from the first n samples of _weighted_sensitivities."""
    from ..estimation import fisher

    J = J if n is None else J[:n]
    return fisher.covariance(J.reshape(-1, J.shape[-1]))


def _correlation(cov: np.ndarray) -> np.ndarray:
    d = np.sqrt(np.diag(cov))
    return cov / d[:, None] / d[None, :]


def _bound_correlation(sc: Scenario, Omega_z: float, record, std) -> np.ndarray:
    """Correlation matrix of the Cramer-Rao bound of the 8 unknowns (crb_at gives the
    diagonal only): the same exact sensitivities, weighted by the noise stds."""
    return _correlation(fisher_covariance(_weighted_sensitivities(sc, Omega_z, record, std)))


def _efficient_curve(J: np.ndarray, k_curve: np.ndarray, tol: np.ndarray,
                     seed: int) -> list[float | None]:
    """P(all 8 within tolerance) for an efficient estimator at each point of the curve:
    the bound from the samples before that point (None where it is not finite)."""
    rng = np.random.default_rng(seed)
    out: list[float | None] = []
    for k in k_curve:
        cov = fisher_covariance(J, int(k))
        sig = np.sqrt(np.diag(cov))
        if not (np.all(np.isfinite(sig)) and np.all(sig > 0)):
            out.append(None)
            continue
        e = _gaussian_draws(_correlation(cov), rng, CURVE_DRAWS)
        out.append(float(np.mean(np.all(np.abs(e) * sig <= tol, axis=1))))
    return out


def _gaussian_draws(corr: np.ndarray, rng: np.random.Generator,
                    n: int = JOINT_DRAWS) -> np.ndarray:
    """n draws of N(0, corr) (corr may be near singular)."""
    w, V = np.linalg.eigh(corr)
    root = V * np.sqrt(np.clip(w, 0.0, None))
    return rng.standard_normal((n, corr.shape[0])) @ root.T


# --------------------------------------------------------------------------- driver


@dataclass
class SweepResult:
    rows: list[dict]
    spec: SweepSpec
    wall_s: float
    n_workers: int
    interrupted: str | None = None  #: why the sweep stopped early (Ctrl-C), else None

    @property
    def ok(self) -> list[dict]:
        return [r for r in self.rows if r["status"] == "ok"]

    @property
    def failed(self) -> list[dict]:
        return [r for r in self.rows if r["status"] != "ok"]

    def fraction_within(self) -> float:
        """Fraction of ALL gyros (failed ones count as not converged) within tol at deadline."""
        return sum(bool(r.get("within_at_deadline")) for r in self.rows) / max(1, len(self.rows))

    def deadline_for(self, fraction: float = DEADLINE_FRACTION) -> dict:
        """Earliest time by which `fraction` of ALL gyros have all 8 unknowns within
        tolerance to the end of the run (their convergence times; a failed or never
        converged gyro counts as infinitely late): None ("not reached") when more than
        1 - fraction of the lot never converge."""
        times = sorted(math.inf if r.get("conv_s_all") is None else r["conv_s_all"]
                       for r in self.rows)
        late = sum(math.isinf(v) for v in times)
        value = None
        if times:
            v = times[max(0, math.ceil(fraction * len(times) - 1e-9) - 1)]
            value = None if math.isinf(v) else float(v)
        return {"deadline_fraction": fraction, "deadline_for_fraction_s": value,
                "never_or_failed": late}

    def within_curve(self) -> dict:
        """Fraction of ALL gyros with all 8 within tolerance at evenly spaced times up to
        the deadline, beside an efficient estimator's expected fraction at those times
        (the bound from the samples before each; over the gyros with a bound)."""
        t = curve_times(self.spec)
        observed = [r["within_all_curve"] for r in self.ok
                    if len(r.get("within_all_curve") or ()) == len(t)]
        efficient = [r["p_eff_all_curve"] for r in self.ok
                     if len(r.get("p_eff_all_curve") or ()) == len(t)]
        n = max(1, len(self.rows))
        frac = [sum(c[j] for c in observed) / n for j in range(len(t))] if self.rows else []
        eff = []
        for j in range(len(t)):
            v = [c[j] for c in efficient if c[j] is not None]
            eff.append(float(np.mean(v)) if v else None)
        return {"t_s": t, "fraction_within_tol": frac,
                "efficient_fraction_within_tol": eff if efficient else None}

    def curve_deadlines(self, fraction: float = DEADLINE_FRACTION) -> dict:
        """From within_curve: the first time from which the observed fraction stays at or
        above `fraction` to the deadline, and the first time an efficient estimator's
        expected fraction reaches it (None: not within the run)."""
        c = self.within_curve()
        t, obs, eff = c["t_s"], c["fraction_within_tol"], c["efficient_fraction_within_tol"]
        instant = None
        for j in range(len(obs) - 1, -1, -1):
            if obs[j] < fraction:
                break
            instant = t[j]
        efficient = None
        for tj, v in zip(t, eff or [], strict=False):
            if v is not None and v >= fraction:
                efficient = tj
                break
        return {"instant_deadline_for_fraction_s": instant,
                "efficient_deadline_for_fraction_s": efficient}

    def bound_summary(self) -> dict | None:
        """The lot against the Cramer-Rao bound at the deadline (None without noise)."""
        rows = [r for r in self.ok if r.get("crb_Omega_z") is not None]
        if not rows:
            return None

        def mean(values) -> float | None:
            values = [v for v in values if v is not None]
            return float(np.mean(values)) if values else None

        per = {}
        for name in ESTIMATED:
            z = np.array([r[f"err_over_crb_{name}"] for r in rows
                          if r[f"err_over_crb_{name}"] is not None], float)
            per[name] = {
                "median_crb_over_tol": _pct([r[f"crb_{name}"] / r[f"tol_{name}"]
                                             for r in rows], 50),
                "fraction_within_2_crb": float(np.mean(np.abs(z) <= 2.0)) if z.size else None,
                "rms_err_over_crb": float(np.sqrt(np.mean(z**2))) if z.size else None,
                "mean_err_over_crb": float(np.mean(z)) if z.size else None,
                "fraction_within_tol": mean(abs(r[f"err_dead_{name}"]) <= r[f"tol_{name}"]
                                            for r in rows),
                "efficient_fraction_within_tol": mean(r[f"p_eff_{name}"] for r in rows),
            }
            zb = np.array([r[f"batch_err_over_crb_{name}"] for r in rows
                           if r.get(f"batch_err_over_crb_{name}") is not None], float)
            if zb.size:
                per[name].update(
                    batch_fraction_within_tol=mean(abs(r[f"batch_err_{name}"])
                                                   <= r[f"tol_{name}"] for r in rows
                                                   if f"batch_err_{name}" in r),
                    batch_fraction_within_2_crb=float(np.mean(np.abs(zb) <= 2.0)),
                    batch_rms_err_over_crb=float(np.sqrt(np.mean(zb**2))))
        efficient_2 = mean(r["p_eff_2crb_all"] for r in rows)
        return {
            "n": len(rows), "deadline_s": self.spec.the_deadline,
            "efficient_fraction_within_2_crb_per_unknown": math.erf(2.0 / math.sqrt(2.0)),
            "all": {
                "fraction_within_tol": mean(bool(r["within_at_deadline"]) for r in rows),
                "efficient_fraction_within_tol": mean(r["p_eff_all"] for r in rows),
                "efficient_fraction_within_tol_product": mean(
                    float(np.prod([r[f"p_eff_{n}"] for n in ESTIMATED])) for r in rows),
                "fraction_within_2_crb": mean(bool(r["within_2crb_all"]) for r in rows),
                "efficient_fraction_within_2_crb": efficient_2,
                "batch_n": sum("batch_within_all" in r for r in rows),
                "batch_fraction_within_tol": mean(r.get("batch_within_all") for r in rows),
                "batch_fraction_within_2_crb": mean(r.get("batch_within_2crb_all")
                                                    for r in rows),
            },
            "per_unknown": per,
        }

    def throughput_per_min(self) -> float:
        return 60.0 * len(self.rows) / self.wall_s if self.wall_s > 0 else math.nan

    def summary(self) -> dict:
        ok = self.ok
        conv = [r["conv_s_all"] for r in ok if r.get("conv_s_all") is not None]
        per = {}
        for name in ESTIMATED:
            e = [r[f"err_over_tol_{name}"] for r in ok]
            per[name] = {"p50_err_over_tol": _pct(e, 50), "p95_err_over_tol": _pct(e, 95),
                         "max_err_over_tol": max(e) if e else None,
                         "fraction_within": (sum(v <= 1 for v in e) / len(self.rows))
                         if self.rows else None}
        return {
            "n": len(self.rows), "ok": len(ok), "failed": len(self.failed),
            "n_requested": self.spec.n, "interrupted": self.interrupted,
            "fraction_all_within_at_deadline": self.fraction_within(),
            "deadline_s": self.spec.the_deadline,
            "convergence_time_s": {"p50": _pct(conv, 50), "p95": _pct(conv, 95),
                                   "never": len(ok) - len(conv),
                                   **self.deadline_for(DEADLINE_FRACTION),
                                   **self.curve_deadlines(DEADLINE_FRACTION)},
            "per_unknown": per,
            "bound": self.bound_summary(),
            "within_curve": self.within_curve(),
            "wall_s": self.wall_s, "n_workers": self.n_workers,
            "gyros_per_minute": self.throughput_per_min(),
            "failures": [{"gyro": r["gyro"], "reason": r["reason"]} for r in self.failed],
            "spec": _spec_dict(self.spec),
        }


def _pct(values: Sequence[float], q: float) -> float | None:
    return float(np.percentile(values, q)) if len(values) else None


def _spec_dict(spec: SweepSpec) -> dict:
    d = asdict(spec)
    d["tolerances"]["nominal"] = spec.tolerances.nominal
    d["observer_tuning_overrides"] = dict(spec.base_scenario().tuning)  # before the noise
    return json.loads(json.dumps(d, default=str))


def run_sweep(
    spec: SweepSpec,
    models_dir: Path,
    scheduler: str | None = None,
    n_workers: int | None = None,
    draws: Sequence[Mapping[str, float]] | None = None,
    progress: bool = True,
    on_row: Callable[[dict], None] | None = None,
) -> SweepResult:
    """Run the sweep on Dask and return every row (ok or failed), in gyro order.

    scheduler: address of an existing Dask scheduler; None starts a LocalCluster with
    n_workers single-threaded worker processes (default: all cores).
    draws: explicit parameter sets instead of spec.tolerances.draw(spec.n).
    """
    from ..studies.tasks import run_tasks
    from .run import ensure_fmus

    models = Path(models_dir).resolve()
    ensure_fmus(models)
    draws = list(draws) if draws is not None else spec.tolerances.draw(spec.n)

    def lost(i: int, exc: BaseException) -> dict:
        return {"gyro": i, "status": "failed",
                "reason": f"task error {type(exc).__name__}: {exc}"[:500],
                **{f"true_{k}": float(v) for k, v in draws[i].items()}}

    rows, wall, n_workers, interrupted = run_tasks(
        run_gyro, [(i, d, spec, str(models)) for i, d in enumerate(draws)], lost,
        scheduler, n_workers, progress, on_row)
    if interrupted:
        interrupted = interrupted.replace(" runs", " gyros")
    return SweepResult(rows, spec, wall, n_workers, interrupted)


# --------------------------------------------------------------------------- outputs


def write_outputs(res: SweepResult, out_dir: Path, figures: bool = True) -> list[Path]:
    """sweep.csv (every run), sweep.parquet (if pyarrow is installed), summary.json, PNGs."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    columns: list[str] = []
    for r in res.rows:
        columns += [c for c in r if c not in columns]
    paths = [out / "sweep.csv"]
    with paths[0].open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=columns)
        w.writeheader()
        for r in res.rows:
            w.writerow({c: "" if r.get(c) is None else r.get(c) for c in columns})
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq

        table = pa.Table.from_pylist([{c: r.get(c) for c in columns} for r in res.rows])
        pq.write_table(table, out / "sweep.parquet")
        paths.append(out / "sweep.parquet")
    except ImportError:
        pass
    (out / "summary.json").write_text(json.dumps(res.summary(), indent=2))
    paths.append(out / "summary.json")
    if figures and res.rows:  # nothing to draw when interrupted before the first gyro
        paths.append(histograms(res, out / "sweep_histograms.png"))
    return paths


def histograms(res: SweepResult, path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ok = res.ok
    fig, axes = plt.subplots(3, 4, figsize=(14, 9))
    ax = axes[0, 0]
    conv = [r["conv_s_all"] * 1e3 for r in ok if r.get("conv_s_all") is not None]
    ax.hist(conv, bins=30, color="C0")
    dl = res.spec.the_deadline * 1e3
    ax.axvline(dl, color="k", ls="--", lw=1, label=f"deadline {dl:g} ms")
    ax.set_xlabel("time all 8 within tolerance (ms)")
    ax.set_ylabel("gyros")
    ax.set_title(f"{len(conv)}/{len(res.rows)} converged")
    ax.legend(fontsize=8)
    for j, name in enumerate(ESTIMATED):
        ax = axes.flat[1 + j]
        v = np.array([r[f"err_over_tol_{name}"] for r in ok])
        v = np.clip(v, 1e-6, None)
        bins = np.logspace(math.log10(v.min()), math.log10(max(v.max(), 1.01)), 30) \
            if v.size else 10
        ax.hist(v, bins=bins, color="C1")
        ax.set_xscale("log")
        ax.axvline(1.0, color="k", ls="--", lw=1)
        ax.set_xlabel(f"|error {name}| / tolerance at end")
        ax.set_ylabel("gyros")
    ax = axes.flat[9]
    wall = [r["wall_s"] for r in res.rows]
    ax.hist(wall, bins=20, color="C2")
    ax.set_xlabel("wall time per gyro (s)")
    ax.set_ylabel("gyros")
    axes.flat[10].axis("off")
    ax = axes.flat[11]
    curve = res.within_curve()
    if curve["t_s"]:
        t_ms = np.array(curve["t_s"]) * 1e3
        ax.plot(t_ms, np.array(curve["fraction_within_tol"]) * 100, "C0", label="observer")
        if curve["efficient_fraction_within_tol"] is not None:
            eff = [np.nan if v is None else 100 * v
                   for v in curve["efficient_fraction_within_tol"]]
            ax.plot(t_ms, eff, "k--", label="efficient (CRB)")
        ax.axhline(100 * DEADLINE_FRACTION, color="grey", lw=0.8)
        ax.set_ylim(0, 102)
        ax.legend(fontsize=8)
    ax.set_xlabel("time (ms)")
    ax.set_ylabel("% of gyros, all 8 within tolerance")
    axes.flat[10].text(0, 0.5, f"{res.summary()['fraction_all_within_at_deadline']:.1%} all "
                       f"within 1% at {dl:g} ms\n{len(res.failed)} failed\n"
                       f"{res.throughput_per_min():.1f} gyros/min on {res.n_workers} workers",
                       fontsize=11, va="center")
    fig.suptitle(f"Monte Carlo over fabrication tolerances: {len(res.rows)} gyros, "
                 f"{res.spec.tolerances.preset}, {res.spec.tolerances.distribution}")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)
