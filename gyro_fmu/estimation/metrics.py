"""How well the observer did: errors, RMS and convergence times for summary.json.

Judged over the tail (the last 20 % of the run): convergence means within tolerance from
a time before the tail starts to the end; sigma is reported as its RMS over the tail
beside the last sample's.

Tolerance rule ("within 1%"): 1% of |truth| for each parameter; where the truth
is 0 (e.g. dyy of Table 1) an absolute 0.1 1/s for dampings; for Omega_z, whose
truth may cross zero, 1% of the largest |Omega_z| of the run.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from ..model.measurement import UNKNOWNS
from ..model.parameters import GyroParameters

ESTIMATED = UNKNOWNS
#: The verdict's band in the observer's own sigmas: an estimate passes within max(tol,
#: SIGMA_BAND x its RMS sigma over the tail). Its sigma sits at the Cramer-Rao bound
#: (docs/observer-soundness.md), so a healthy noisy run whose sigma exceeds tol passes;
#: the tail's errors are slow (a few independent values), so 4 sigma is a 1e-4 to 1e-3
#: chance per unknown for an honest filter.
SIGMA_BAND = 4.0
RELATIVE_TOLERANCE = 0.01
ZERO_DAMPING_TOLERANCE = 0.1  #: 1/s, where a damping's truth is 0


def tolerance(name: str, truth: np.ndarray) -> float:
    """Allowed |error| for `name` (same unit), by the rule in the module docstring."""
    scale = float(np.max(np.abs(truth)))
    if scale == 0.0:
        return ZERO_DAMPING_TOLERANCE if name.startswith("d") else RELATIVE_TOLERANCE
    return RELATIVE_TOLERANCE * scale


def convergence_time(time: np.ndarray, error: np.ndarray, tol: float,
                     judged_from: float | None = None) -> float | None:
    """First time after which |error| stays within tol to the end; None if never, or if
    that time is later than judged_from (the start of the judged tail: an error that only
    comes within tol in the tail's last samples has not converged)."""
    outside = np.nonzero(~(np.abs(error) <= tol))[0]
    if outside.size == 0:
        return float(time[0])
    if outside[-1] == time.size - 1:
        return None
    t = float(time[outside[-1] + 1])
    return None if judged_from is not None and t > judged_from else t


def summarize(
    time: np.ndarray,
    estimates: Mapping[str, np.ndarray],
    sigmas: Mapping[str, np.ndarray],
    truth: GyroParameters,
    Omega_true: np.ndarray,
    tail: float = 0.2,
) -> dict:
    """Metrics of summary.json; `tail` is the final fraction of the run (0.2: last 20%).
    The arrays whole: RunMetrics fed one chunk."""
    metrics = RunMetrics(truth, tail)
    metrics.scan(time, Omega_true)
    metrics.judge(time, estimates, sigmas, Omega_true)
    return metrics.summary()


class _Judged:
    """One unknown's running figures over the second pass."""

    def __init__(self, tol: float) -> None:
        self.tol = tol
        self.max_err = self.scale = self.sum_sigma2 = self.sum_err2 = self.sum_ratio2 = 0.0
        self.n_tail = self.n_ratio = 0
        self.outside = False  # any sample outside tol so far
        self.converged_at: float | None = None  # the sample after the last outside one
        self.pending = False  # the last outside sample ended the previous chunk
        self.final = (math.nan, math.nan, math.nan)  # truth, estimate, sigma

    def feed(self, time: np.ndarray, err: np.ndarray, est: np.ndarray, sigma: np.ndarray,
             true: np.ndarray, last: np.ndarray) -> None:
        if self.pending:
            self.converged_at, self.pending = float(time[0]), False
        out = np.nonzero(~(np.abs(err) <= self.tol))[0]  # NaN counts as outside
        if out.size:
            self.outside = True
            if out[-1] == time.size - 1:
                self.pending, self.converged_at = True, None
            else:
                self.converged_at = float(time[out[-1] + 1])
        elif not self.outside and self.converged_at is None:
            self.converged_at = float(time[0])
        self.final = (float(true[-1]), float(est[-1]), float(sigma[-1]))
        if not last.any():
            return
        e, s = err[last], sigma[last]
        # np.max, not max(): a NaN error must stay NaN in the summary
        self.max_err = float(np.max([self.max_err, np.max(np.abs(e))]))
        self.scale = float(np.max([self.scale, np.max(np.abs(true[last]))]))
        self.sum_sigma2 += float(np.sum(s ** 2))
        self.sum_err2 += float(np.sum(e ** 2))
        self.n_tail += int(e.size)
        ok = s > 0
        self.sum_ratio2 += float(np.sum((e[ok] / s[ok]) ** 2))
        self.n_ratio += int(ok.sum())


class RunMetrics:
    """summarize's figures from a run fed in chunks (memory flat in its length), in two
    passes since the judged tail and Omega_z's tolerance depend on the whole run: every
    chunk to scan(), then every chunk again to judge(); then summary()."""

    def __init__(self, truth: GyroParameters, tail: float = 0.2) -> None:
        self.truth, self.tail = truth, tail
        self.t0 = self.t_end = math.nan
        self.Omega_max = 0.0
        self.rows = 0
        self._judged: dict[str, _Judged] | None = None
        self.tail_first = math.nan

    def scan(self, time: np.ndarray, Omega_true: np.ndarray) -> None:
        """First pass: the run's span and largest |Omega_z|."""
        if not time.size:
            return
        if math.isnan(self.t0):
            self.t0 = float(time[0])
        self.t_end = float(time[-1])
        self.Omega_max = float(np.max([self.Omega_max, np.max(np.abs(Omega_true))]))
        self.rows += int(time.size)

    @property
    def tail_start(self) -> float:
        return self.t0 + (1.0 - self.tail) * (self.t_end - self.t0)

    def judge(self, time: np.ndarray, estimates: Mapping[str, np.ndarray],
              sigmas: Mapping[str, np.ndarray], Omega_true: np.ndarray) -> None:
        """Second pass, the same chunks in the same order."""
        if self._judged is None:
            self._judged = {n: _Judged(self._tolerance(n)) for n in ESTIMATED}
        if not time.size:
            return
        last = time >= self.tail_start
        if last.any() and math.isnan(self.tail_first):
            self.tail_first = float(time[last][0])
        for name, judged in self._judged.items():
            true = Omega_true if name == "Omega_z" else np.full(time.shape,
                                                                getattr(self.truth, name))
            err = estimates[name] - true
            judged.feed(time, err, estimates[name], sigmas[name], true, last)

    def _tolerance(self, name: str) -> float:
        if name == "Omega_z":
            return tolerance(name, np.array([self.Omega_max]))
        return tolerance(name, np.array([getattr(self.truth, name)]))

    def summary(self) -> dict:
        if self._judged is None:
            raise ValueError("RunMetrics.summary before judge(): feed the run twice")
        out: dict = {"tail_window_s": [self.tail_first, self.t_end], "unknowns": {}}
        for name, j in self._judged.items():
            sigma_rms = math.sqrt(j.sum_sigma2 / j.n_tail) if j.n_tail else math.nan
            converged = j.converged_at
            if converged is not None and converged > self.tail_first:
                converged = None  # within tol only in the tail's last samples
            ratio = math.sqrt(j.sum_ratio2 / j.n_ratio) if j.n_ratio else None
            entry = {
                "truth_final": j.final[0],
                "estimate_final": j.final[1],
                "sigma_final": j.final[2],
                "sigma_rms_tail": sigma_rms,
                "tolerance": j.tol,
                # the observer's own sigma sits at the Cramer-Rao bound (0.97-1.08 of it,
                # docs/observer-soundness.md): a tolerance below it is luck, not a target
                "tolerance_below_sigma": bool(j.tol < sigma_rms),
                "max_abs_error_tail": j.max_err,
                "max_rel_error_tail": j.max_err / j.scale if j.scale > 0 else None,
                "converged_within_tolerance_at_s": converged,
                "error_over_sigma_rms_tail": ratio if ratio is None or math.isfinite(ratio)
                else None,
            }
            if name == "Omega_z":
                entry["rms_error_tail"] = math.sqrt(j.sum_err2 / j.n_tail)
                entry["rms_error_tail_rel_to_peak"] = (
                    entry["rms_error_tail"] / j.scale if j.scale > 0 else None)
            out["unknowns"][name] = entry
        out["all_within_tolerance_in_tail"] = all(
            u["max_abs_error_tail"] <= u["tolerance"] for u in out["unknowns"].values())
        out["verdict"] = verdict(out["unknowns"])
        return out


def verdict(unknowns: Mapping[str, dict]) -> dict:
    """The run's verdict: passed when every unknown's largest tail error is within its
    band, max(tol, SIGMA_BAND x sigma RMS); else the failures, each in words. A NaN error
    or sigma fails."""
    failures = []
    for name, u in unknowns.items():
        sigma = u["sigma_rms_tail"]
        band = max(u["tolerance"], SIGMA_BAND * sigma) if math.isfinite(sigma) else math.nan
        u["band"] = band
        if not (u["max_abs_error_tail"] <= band):
            failures.append(f"{name}: error {u['max_abs_error_tail']:.3g} beyond its band "
                            f"{band:.3g} (tol {u['tolerance']:.3g}, {SIGMA_BAND:g} x sigma "
                            f"{sigma:.3g})")
    return {"passed": not failures, "failures": failures,
            "rule": f"every unknown within max(tol, {SIGMA_BAND:g} x its own sigma) over "
                    "the tail"}
