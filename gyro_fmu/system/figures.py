"""Figures in the manner of the patent's Fig. 3A-3E and Fig. 4A-4H, drawn from a few
thousand points whatever the run's length.

`FigureData` gathers what they draw from chunks of rows as the results are read: the
first and last `window` seconds at full rate (Fig. 3) and, per bin of log time
(BINS_PER_DECADE a decade), the smallest and largest |error| and sigma of each unknown
(Fig. 4, a min/max envelope: every excursion shows, however many steps fall in a bin).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..extras import pyplot
from ..model.measurement import UNKNOWNS
from ..model.parameters import PARAMETER_UNITS, GyroParameters
from ..outputs import save_figure
from ..results.columns import OBSERVED, TRUE_RATE, estimate_column, sigma_column

_LABELS = {
    "Omega_z": (r"$\Omega_z$", "rad/s"),
    **{n: (f"${n[0]}_{{{n[1:]}}}$" if n != "m" else "$m$", PARAMETER_UNITS[n].replace(
        "1/s2", r"1/s$^2$")) for n in PARAMETER_UNITS},
}


#: Fixed margins of the 11 x 11 in figures (tight_layout measured each one's text first:
#: 0.4 s of a 1 s figure).
_MARGINS = {"left": 0.1, "right": 0.98, "bottom": 0.05, "top": 0.94, "hspace": 0.3,
            "wspace": 0.3}


#: Bins of log time a decade in Fig. 4: 200 are 1.2 % wide, about 2 pixels of its axes
#: at 7 decades; a bin keeps the min and max of each curve, so nothing narrow is lost.
BINS_PER_DECADE = 200

#: The signals Fig. 3 draws: (gyroscope or drive column, observer column, label, unit).
_FIG3_ROWS = (("drive.ux", None, "$u_x$", "N"), ("plant.x", "observer.x_hat", "$x$", "m"),
              ("plant.y", "observer.y_hat", "$y$", "m"),
              ("plant.vx", "observer.vx_hat", r"$\dot x$", "m/s"),
              ("plant.vy", "observer.vy_hat", r"$\dot y$", "m/s"))


class FigureData:
    """What Fig. 3 and Fig. 4 draw, gathered from a run fed in chunks (`feed`, in time
    order), in memory bounded by the window and the decades of the run, not its steps.

    t0, t_end: the run's first and last time (the late window is [t_end - window, t_end]).
    """

    #: The columns `feed` needs.
    COLUMNS = (*OBSERVED, *dict.fromkeys(c for row in _FIG3_ROWS for c in row[:2] if c))

    def __init__(self, truth: GyroParameters, t0: float, t_end: float,
                 window: float = 0.002) -> None:
        self.truth, self.t0, self.t_end, self.window = truth, t0, t_end, window
        self._early: list[dict[str, np.ndarray]] = []
        self._late: list[dict[str, np.ndarray]] = []
        # per log-time bin: [t min, t max] + per unknown [err min (>0), err max,
        # sigma min, sigma max]
        self._bins: dict[int, np.ndarray] = {}

    def feed(self, chunk: dict[str, np.ndarray]) -> None:
        t = chunk["time"]
        fig3 = [c for row in _FIG3_ROWS for c in row[:2] if c]
        for keep, where in ((t <= self.t0 + self.window, self._early),
                            (t >= self.t_end - self.window, self._late)):
            if keep.any():
                where.append({c: chunk[c][keep] for c in ("time", *fig3)})
        positive = t > 0.0  # log time: the guess at t = 0 has no place
        if not positive.any():
            return
        t = t[positive]
        columns = [t, t]
        for name in UNKNOWNS:
            true = (chunk[TRUE_RATE][positive] if name == "Omega_z"
                    else getattr(self.truth, name))
            err = np.abs(chunk[estimate_column(name)][positive] - true)
            sig = chunk[sigma_column(name)][positive]
            columns += [np.where(err > 0.0, err, np.inf), err, sig, sig]
        values = np.column_stack(columns)
        bins = np.floor(BINS_PER_DECADE * np.log10(t)).astype(np.int64)
        starts = np.concatenate([[0], np.flatnonzero(np.diff(bins)) + 1])
        lows = np.minimum.reduceat(values, starts, axis=0)
        highs = np.maximum.reduceat(values, starts, axis=0)
        low = np.zeros(values.shape[1], dtype=bool)
        low[0::2] = True  # t min, err min, sigma min; the odd columns are maxima
        merged = np.where(low, lows, highs)
        for b, row in zip(bins[starts].tolist(), merged, strict=True):
            old = self._bins.get(b)
            self._bins[b] = row if old is None else np.where(low, np.fmin(old, row),
                                                             np.fmax(old, row))

    def window_rows(self, late: bool) -> dict[str, np.ndarray]:
        parts = self._late if late else self._early
        return {c: np.concatenate([p[c] for p in parts]) for c in parts[0]} if parts else {}

    def envelope(self) -> tuple[np.ndarray, np.ndarray]:
        """(bin times, rows): the geometric middle of each bin's samples, and per bin
        per unknown [err min, err max, sigma min, sigma max] (columns 4 i ... 4 i + 3)."""
        keys = sorted(self._bins)
        table = np.array([self._bins[k] for k in keys]).reshape(len(keys), -1)
        if not keys:
            return np.empty(0), np.empty((0, 4 * len(UNKNOWNS)))
        err_min = table[:, 2::4]
        table[:, 2::4] = np.where(np.isinf(err_min), np.nan, err_min)
        return np.sqrt(table[:, 0] * table[:, 1]), table[:, 2:]


def fig3_states(data: FigureData, path: Path) -> Path:
    """Fig. 3A-3E: drive ux, and plant (measured) vs observer x, y, vx, vy.

    Left column: the first `window` seconds, where the observer locks on;
    right column: the last `window` seconds, against the time to the run's end.
    """
    plt = pyplot()
    fig, axes = plt.subplots(len(_FIG3_ROWS), 2, figsize=(11, 11), sharex="col")
    for j, late in enumerate((False, True)):
        rows = data.window_rows(late)
        # the last window against the time to the end: 4998.25 ms ticks would collide
        t = (rows["time"] - (data.t_end if late else 0.0)) * 1e3 if rows else None
        for i, (plant, obs, label, unit) in enumerate(_FIG3_ROWS):
            ax = axes[i, j]
            if rows:
                ax.plot(t, rows[plant], "k--", lw=1.2,
                        label="gyroscope" if obs else "drive")
                if obs:
                    ax.plot(t, rows[obs], "r-", lw=0.8, label="observer")
            ax.set_ylabel(f"{label} ({unit})")
            ax.grid(alpha=0.3)
    axes[1, 0].legend(loc="upper right", fontsize=8)
    axes[-1, 0].set_xlabel("time (ms)")
    axes[-1, 1].set_xlabel(f"time before the end, t = {data.t_end:g} s (ms)")
    axes[0, 0].set_title(f"first {data.window * 1e3:g} ms")
    axes[0, 1].set_title(f"last {data.window * 1e3:g} ms")
    fig.suptitle("Fig. 3A-3E: drive, gyroscope outputs and observer estimates")
    fig.subplots_adjust(**_MARGINS)
    save_figure(fig, path, dpi=110)
    plt.close(fig)
    return path


def fig4_estimates(data: FigureData, path: Path) -> Path:
    """Fig. 4A-4H, as an engineer reads it: for each of the 8 unknowns, the estimate's
    error |estimate - truth| against the observer's own 1-sigma, both on log scales over
    log time, so the convergence (often under a millisecond) and whether the reported
    sigma covers the error both show, whatever the run's length. Each curve is a min/max
    envelope over bins of log time (`FigureData`)."""
    t, table = data.envelope()
    t = t * 1e3
    from matplotlib.ticker import NullLocator

    plt = pyplot()
    fig, axes = plt.subplots(4, 2, figsize=(11, 11), sharex=True)
    for i, (ax, name) in enumerate(zip(axes.flat, UNKNOWNS, strict=True)):
        emin, emax, smin, smax = (table[:, 4 * i + j] for j in range(4))
        ax.fill_between(t, smin, smax, color="0.45", alpha=0.5, lw=0)
        ax.fill_between(t, 0.0, smin, color="0.6", alpha=0.3, lw=0,
                        label="reported 1-sigma")
        shown = emax > 0.0  # an exact zero has no place on a log scale
        ax.fill_between(t, np.where(shown, emin, np.nan), np.where(shown, emax, np.nan),
                        color="r", alpha=0.35, lw=0)
        ax.plot(t[shown], emax[shown], "r-", lw=0.7, label="|estimate - truth|")
        ax.set_xscale("log")
        ax.set_yscale("log")
        # minor ticks: 0.6 of the figure's 0.9 s went into making them, over decades
        # that the major ticks already mark
        ax.xaxis.set_minor_locator(NullLocator())
        ax.yaxis.set_minor_locator(NullLocator())
        positive = np.concatenate([emax[shown], smax[smax > 0.0]])
        positive = positive[np.isfinite(positive)]
        if positive.size:
            # down to the smallest error or sigma (at most 14 decades): a noise-free run's
            # parameter errors fall 12 decades below their start
            ax.set_ylim(max(positive.min(), positive.max() * 1e-14) / 2, positive.max() * 2)
        label, unit = _LABELS[name]
        ax.set_ylabel(f"{label} error ({unit})")
        ax.grid(alpha=0.3)
    axes[0, 0].legend(loc="upper right", fontsize=8)
    for ax in axes[-1]:
        ax.set_xlabel("time (ms, log)")
    fig.suptitle("Fig. 4A-4H: each unknown's error against the observer's own 1-sigma "
                 f"(min-max over {100 * (10 ** (1 / BINS_PER_DECADE) - 1):.1f} % bins of "
                 "time)")
    fig.subplots_adjust(**_MARGINS)
    save_figure(fig, path, dpi=110)
    plt.close(fig)
    return path
