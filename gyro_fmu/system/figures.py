"""Figures in the manner of the patent's Fig. 3A-3E and Fig. 4A-4H."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from ..cosim.master import CoSimulationResult
from ..model.measurement import UNKNOWNS
from ..model.parameters import PARAMETER_UNITS, GyroParameters
from ..outputs import save_figure

_LABELS = {
    "Omega_z": (r"$\Omega_z$", "rad/s"),
    **{n: (f"${n[0]}_{{{n[1:]}}}$" if n != "m" else "$m$", PARAMETER_UNITS[n].replace(
        "1/s2", r"1/s$^2$")) for n in PARAMETER_UNITS},
}


#: Fixed margins of the 11 x 11 in figures (tight_layout measured each one's text first:
#: 0.4 s of a 1 s figure).
_MARGINS = {"left": 0.1, "right": 0.98, "bottom": 0.05, "top": 0.94, "hspace": 0.3,
            "wspace": 0.3}


def fig3_states(result: CoSimulationResult, path: Path, window: float = 0.002) -> Path:
    """Fig. 3A-3E: drive ux, and plant (measured) vs observer x, y, vx, vy.

    Left column: the first `window` seconds, where the observer locks on;
    right column: the last `window` seconds.
    """
    t = result["time"]
    rows = [("drive.ux", None, "$u_x$", "N"), ("plant.x", "observer.x_hat", "$x$", "m"),
            ("plant.y", "observer.y_hat", "$y$", "m"), ("plant.vx", "observer.vx_hat",
            r"$\dot x$", "m/s"), ("plant.vy", "observer.vy_hat", r"$\dot y$", "m/s")]
    fig, axes = plt.subplots(len(rows), 2, figsize=(11, 11), sharex="col")
    early, late = t <= t[0] + window, t >= t[-1] - window
    for i, (plant, obs, label, unit) in enumerate(rows):
        for j, sel in enumerate((early, late)):
            ax = axes[i, j]
            ax.plot(t[sel] * 1e3, result[plant][sel], "k--", lw=1.2,
                    label="gyroscope (measured)" if obs else "drive")
            if obs:
                ax.plot(t[sel] * 1e3, result[obs][sel], "r-", lw=0.8, label="observer")
            ax.set_ylabel(f"{label} ({unit})")
            ax.grid(alpha=0.3)
        if i == 1:
            axes[i, 0].legend(loc="upper right", fontsize=8)
    for j in range(2):
        axes[-1, j].set_xlabel("time (ms)")
    axes[0, 0].set_title(f"first {window * 1e3:g} ms")
    axes[0, 1].set_title(f"last {window * 1e3:g} ms")
    fig.suptitle("Fig. 3A-3E: drive, gyroscope outputs and observer estimates")
    fig.subplots_adjust(**_MARGINS)
    save_figure(fig, path, dpi=110)
    plt.close(fig)
    return path


#: Points drawn per curve of a long run: more than the figure has pixels across (1210)
#: changes nothing on the page and cost 1.2 KB and ~0.1 ms of drawing per step.
MAX_POINTS = 2000


def plotted(n: int) -> np.ndarray:
    """Row indices a figure draws of n rows: all of a short run; of a long one the first
    MAX_POINTS (where the observer converges) and MAX_POINTS spread over the whole run."""
    if n <= 2 * MAX_POINTS:
        return np.arange(n)
    spread = np.linspace(0, n - 1, MAX_POINTS).round().astype(np.intp)
    return np.union1d(np.arange(MAX_POINTS), spread)


def fig4_estimates(result: CoSimulationResult, truth: GyroParameters, path: Path) -> Path:
    """Fig. 4A-4H, as an engineer reads it: for each of the 8 unknowns, the estimate's
    error |estimate - truth| against the observer's own 1-sigma, both on log scales over
    log time, so the convergence (often under a millisecond) and whether the reported
    sigma covers the error both show, whatever the run's length."""
    rows = plotted(len(result["time"]))
    t = result["time"][rows]
    keep = t > 0.0  # log time: the first point is the guess at t = 0
    t = t[keep] * 1e3
    fig, axes = plt.subplots(4, 2, figsize=(11, 11), sharex=True)
    for ax, name in zip(axes.flat, UNKNOWNS, strict=True):
        column = "observer.Omega_hat" if name == "Omega_z" else f"observer.{name}_hat"
        est, sig = result[column][rows][keep], result[f"observer.sigma_{name}"][rows][keep]
        true = (result["rate.Omega_z"][rows][keep] if name == "Omega_z"
                else np.full(t.shape, getattr(truth, name)))
        err = np.abs(est - true)
        shown = err > 0.0  # an exact zero has no place on a log scale
        ax.fill_between(t, 0.0, sig, color="0.6", alpha=0.35, lw=0, label="reported 1-sigma")
        ax.plot(t[shown], err[shown], "r-", lw=0.8, label="|estimate - truth|")
        ax.set_xscale("log")
        ax.set_yscale("log")
        positive = np.concatenate([err[shown], sig[sig > 0.0]])
        if positive.size:
            ax.set_ylim(max(positive.min(), positive.max() * 1e-9) / 2, positive.max() * 2)
        label, unit = _LABELS[name]
        ax.set_ylabel(f"{label} error ({unit})")
        ax.grid(alpha=0.3)
    axes[0, 0].legend(loc="upper right", fontsize=8)
    for ax in axes[-1]:
        ax.set_xlabel("time (ms, log)")
    fig.suptitle("Fig. 4A-4H: each unknown's error against the observer's own 1-sigma")
    fig.subplots_adjust(**_MARGINS)
    save_figure(fig, path, dpi=110)
    plt.close(fig)
    return path
