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

import math
import time
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np

from ..estimation.metrics import ESTIMATED, convergence_time, tolerance
from ..model.drive import TwoToneDrive
from ..model.interfaces import SEED_MAX
from ..model.parameters import PARAMETER_NAMES, ParameterError, preset
from .lot_bound import bound_figures, curve_indices
from .scenario import Scenario, scenario
from .sweep_report import SweepResult

#: Estimates beyond this many tolerances at the end count as diverged.
DIVERGED_TOLERANCES = 1e3


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
        if not 0 <= self.noise_seed <= SEED_MAX - (self.n - 1):
            raise ParameterError(
                f"noise seeds {self.noise_seed} .. {self.noise_seed + self.n - 1} (one per "
                f"gyro) leave [0, {SEED_MAX}], the range of GyroPlant.fmu's seed: give "
                f"--seed <= {SEED_MAX - (self.n - 1)}")
        if self.deadline is not None and not (
                math.isfinite(self.deadline) and 0.0 < self.deadline <= self.stop_time):
            # a deadline past the stop time was judged at the last sample ("100 % within
            # tolerance at 1000 ms" of a 4 ms run)
            raise ParameterError(f"deadline={self.deadline!r} s must be > 0 and at most the "
                                 f"stop time {self.stop_time:g} s: give a deadline inside "
                                 "the run, or a longer --stop-time")

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
        out.update(bound_figures(sc, result, spec, noise, k_dead, out, seed=i))
    return out


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
