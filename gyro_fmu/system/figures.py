"""Figures in the manner of the patent's Fig. 3A-3E and Fig. 4A-4H, drawn from a few
thousand points whatever the run's length.

`FigureData` gathers what they draw from chunks of rows as the results are read: the
first and last `window` seconds at full rate (Fig. 3) and, per bin of log time
(BINS_PER_DECADE a decade), the smallest and largest |error| and sigma of each unknown
(Fig. 4, a min/max envelope: every excursion shows, however many steps fall in a bin).
"""

from __future__ import annotations

import math
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
#: A log axis' decade labels as plain text (10⁻³): matplotlib's default writes them in
#: mathtext, whose parser (pyparsing) took 0.3 s of the run's two figures.
_SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")


def decade_label(value: float, _pos: object = None) -> str:
    """"10ⁿ" for a power of ten, "" between (a log axis' major ticks are decades)."""
    if not value > 0.0 or not math.isfinite(value):
        return ""
    exponent = math.log10(value)
    if abs(exponent - round(exponent)) > 1e-9:
        return ""
    return "10" + str(round(exponent)).translate(_SUPERSCRIPT)


_MARGINS = {"left": 0.1, "right": 0.98, "bottom": 0.05, "top": 0.94, "hspace": 0.3,
            "wspace": 0.3}


#: Bins of log time a decade in Fig. 4: 200 are 1.2 % wide, about 2 pixels of its axes
#: at 7 decades; a bin keeps the min and max of each curve, so nothing narrow is lost.
BINS_PER_DECADE = 200

#: Bins of linear time in the rate figure (about a pixel each at its width).
RATE_BINS = 1000

#: The signals Fig. 3 draws: (gyroscope or drive column, observer column, label, unit).
_FIG3_ROWS = (("drive.ux", None, "$u_x$", "N"), ("plant.x", "observer.x_hat", "$x$", "m"),
              ("plant.y", "observer.y_hat", "$y$", "m"),
              ("plant.vx", "observer.vx_hat", r"$\dot x$", "m/s"),
              ("plant.vy", "observer.vy_hat", r"$\dot y$", "m/s"))


def _merge_bins(into: dict[int, np.ndarray], bins: np.ndarray, values: np.ndarray) -> None:
    """Fold rows (in time order, bins non-decreasing) into per-bin rows: the min of the
    even columns and the max of the odd ones (each quantity as a [min, max] pair)."""
    starts = np.concatenate([[0], np.flatnonzero(np.diff(bins)) + 1])
    low = np.zeros(values.shape[1], dtype=bool)
    low[0::2] = True
    merged = np.where(low, np.minimum.reduceat(values, starts, axis=0),
                      np.maximum.reduceat(values, starts, axis=0))
    for b, row in zip(bins[starts].tolist(), merged, strict=True):
        old = into.get(b)
        into[b] = row if old is None else np.where(low, np.fmin(old, row), np.fmax(old, row))


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
        # per linear-time bin: [t min, t max, Omega_z min, max, Omega_hat min, max,
        # Omega_hat - sigma min, Omega_hat + sigma max, error min, max, sigma min, max]
        self._rate: dict[int, np.ndarray] = {}

    def feed(self, chunk: dict[str, np.ndarray]) -> None:
        t = chunk["time"]
        fig3 = [c for row in _FIG3_ROWS for c in row[:2] if c]
        for keep, where in ((t <= self.t0 + self.window, self._early),
                            (t >= self.t_end - self.window, self._late)):
            if keep.any():
                where.append({c: chunk[c][keep] for c in ("time", *fig3)})
        self._feed_rate(chunk)
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
        _merge_bins(self._bins, np.floor(BINS_PER_DECADE * np.log10(t)).astype(np.int64),
                    np.column_stack(columns))

    def _feed_rate(self, chunk: dict[str, np.ndarray]) -> None:
        t, true = chunk["time"], chunk[TRUE_RATE]
        est, sig = chunk[estimate_column("Omega_z")], chunk[sigma_column("Omega_z")]
        span = max(self.t_end - self.t0, 1e-300)
        bins = np.minimum(np.floor((t - self.t0) / span * RATE_BINS), RATE_BINS - 1)
        err = est - true
        _merge_bins(self._rate, bins.astype(np.int64),
                    np.column_stack([t, t, true, true, est, est, est - sig, est + sig,
                                     err, err, sig, sig]))

    def window_rows(self, late: bool) -> dict[str, np.ndarray]:
        parts = self._late if late else self._early
        return {c: np.concatenate([p[c] for p in parts]) for c in parts[0]} if parts else {}

    def rate_envelope(self) -> np.ndarray:
        """Per linear-time bin, in time order: [t min, t max, Omega_z min, max, Omega_hat
        min, max, Omega_hat - sigma min, Omega_hat + sigma max, error min, max, sigma min,
        max]."""
        keys = sorted(self._rate)
        return np.array([self._rate[k] for k in keys]).reshape(len(keys), 12)

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
                # the gyroscope wide and light, the observer thin on top: both show where
                # they coincide (a dashed line under a solid one was hidden by it)
                ax.plot(t, rows[plant], "-", color="0.65" if obs else "k",
                        lw=3.0 if obs else 1.0, label="gyroscope" if obs else "drive")
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
    from matplotlib.ticker import FuncFormatter, NullLocator

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
        ax.xaxis.set_major_formatter(FuncFormatter(decade_label))
        ax.yaxis.set_major_formatter(FuncFormatter(decade_label))
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


def fig_rate(data: FigureData, path: Path) -> Path:
    """The rate as a control engineer reads it: Omega_hat with its 1-sigma band against
    the true Omega_z over the whole run, and below, the error Omega_hat - Omega_z within
    +-1 and +-3 sigma over the last 80 % (the tail the verdict judges is its last 20 %).
    Each curve is a min/max envelope over RATE_BINS bins of time, so nothing narrow is
    lost at any run length."""
    rows = data.rate_envelope()
    t = 0.5 * (rows[:, 0] + rows[:, 1]) * 1e3
    plt = pyplot()
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(11, 7.5))
    top.fill_between(t, rows[:, 6], rows[:, 7], color="r", alpha=0.2, lw=0,
                     label=r"$\hat\Omega \pm 1\sigma$ (the observer's own)")
    top.fill_between(t, rows[:, 4], rows[:, 5], color="r", lw=0.8)
    top.plot(t, rows[:, 4], "r-", lw=0.8, label=r"$\hat\Omega$ (observer)")
    top.fill_between(t, rows[:, 2], rows[:, 3], color="k", lw=1.2)
    top.plot(t, rows[:, 2], "k-", lw=1.2, label=r"$\Omega_z$ (true)")
    span = np.nanmax(rows[:, 3]) - np.nanmin(rows[:, 2])
    middle = 0.5 * (np.nanmax(rows[:, 3]) + np.nanmin(rows[:, 2]))
    half = max(span, 1e-3 * max(abs(middle), 1.0))  # the band may start wide: keep the rate
    top.set_ylim(middle - half, middle + half)
    top.set_ylabel("rate (rad/s)")
    top.set_xlabel("time (ms)")
    top.legend(loc="lower right", fontsize=8)
    top.grid(alpha=0.3)
    tail = t >= t[0] + 0.2 * (t[-1] - t[0]) if len(t) else t
    tt, err = t[tail], rows[tail]
    bottom.fill_between(tt, -3 * err[:, 11], 3 * err[:, 11], color="0.85", lw=0,
                        label=r"$\pm 3\sigma$")
    bottom.fill_between(tt, -err[:, 11], err[:, 11], color="0.65", lw=0,
                        label=r"$\pm 1\sigma$")
    bottom.fill_between(tt, err[:, 8], err[:, 9], color="r", lw=0.8)
    bottom.plot(tt, err[:, 8], "r-", lw=0.8, label=r"$\hat\Omega - \Omega_z$")
    bottom.set_ylabel("error (rad/s)")
    bottom.set_xlabel("time (ms)")
    bottom.legend(loc="upper right", fontsize=8)
    bottom.grid(alpha=0.3)
    top.set_title("the angular rate: the observer's estimate and its own 1-sigma against "
                  "the truth")
    bottom.set_title("its error over the last 80 % of the run, against its sigma")
    fig.subplots_adjust(left=0.1, right=0.98, bottom=0.07, top=0.95, hspace=0.35)
    save_figure(fig, path, dpi=110)
    plt.close(fig)
    return path
