"""A sweep's result: its rows, summary, files and histograms (docs/sweep-bound.md)."""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..estimation.metrics import ESTIMATED
from ..outputs import (
    atomic_write,
    csv_writer,
    save_figure,
    table_columns,
    write_table_and_summary,
)

if TYPE_CHECKING:  # annotations only: sweep imports this module
    from .sweep import SweepSpec
from .lot_bound import curve_times

#: Fraction of the lot whose convergence time defines the sweep's deadline figure.
DEADLINE_FRACTION = 0.95


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
            "spec": spec_dict(self.spec),
        }



def log_bins(values: np.ndarray, n: int) -> np.ndarray:
    """n + 1 log-spaced edges holding every positive value, 1 included: the edges reach
    a little past both ends (10 ** log10(v) rounds above v for some v, and the
    smallest sample fell outside the first bin)."""
    lo, hi = float(np.min(values)), max(float(np.max(values)), 1.01)
    return np.logspace(math.log10(lo) - 1e-6, math.log10(hi) + 1e-6, n + 1)


def _pct(values: Sequence[float], q: float) -> float | None:
    return float(np.percentile(values, q)) if len(values) else None


def spec_dict(spec: SweepSpec) -> dict:
    d = asdict(spec)
    d["tolerances"]["nominal"] = spec.tolerances.nominal
    d["observer_tuning_overrides"] = dict(spec.base_scenario().tuning)  # before the noise
    return json.loads(json.dumps(d, default=str))


def write_outputs(res: SweepResult, out_dir: Path, figures: bool = True) -> list[Path]:
    """sweep.csv (every run) and summary.json naming it (gyro_fmu.outputs:
    write_table_and_summary), sweep.parquet (if pyarrow is installed), PNGs; each file
    whole under its name or not there."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    columns = table_columns(res.rows)
    (out / "sweep.parquet").unlink(missing_ok=True)  # an old run's, beside the new csv
    paths = list(write_table_and_summary(out, "sweep.csv", csv_writer(res.rows), res.summary(),
                                                 ("sweep_histograms.png",)))
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq

        table = pa.Table.from_pylist([{c: r.get(c) for c in columns} for r in res.rows])
        paths.append(atomic_write(out / "sweep.parquet",
                                  lambda p: pq.write_table(table, str(p))))
    except ImportError:
        pass
    if figures and res.rows:  # nothing to draw when interrupted before the first gyro
        paths.append(histograms(res, out / "sweep_histograms.png"))
    return paths


def histograms(res: SweepResult, path: Path) -> Path:
    from ..extras import pyplot

    plt = pyplot()

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
        ax.hist(v, bins=log_bins(v, 30) if v.size else 10, color="C1")
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
    save_figure(fig, path, dpi=110)
    plt.close(fig)
    return Path(path)
