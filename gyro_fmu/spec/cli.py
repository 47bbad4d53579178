"""`gyro-fmu spec`: the observer-based gyro measured as a gyroscope datasheet would be.

Writes summary.json and spec.png to --out (default runs/spec). Exit 0 with the spec
printed; exit 2 (one line naming cause and remedy) on a bad input or a run that cannot
be trusted (the observer lost, the estimate never settled): no spec is printed then.
"""

from __future__ import annotations

import argparse
import logging
import math
import time
from pathlib import Path

from .. import options
from ..model.parameters import PARAMETER_NAMES, PRESETS, ParameterError
from ..outputs import holds_out_folder, save_figure, write_json

_log = logging.getLogger(__name__)


def _frequencies(text: str) -> tuple[float, ...]:
    try:
        return tuple(float(v) for v in text.split(",") if v.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: give Hz values separated by commas, "
                                         "e.g. 10,100,1000") from None


def _tuning_names() -> tuple[str, ...]:
    from dataclasses import fields

    from ..estimation.observer import ObserverTuning

    return tuple(f.name for f in fields(ObserverTuning))


def config_from(args: argparse.Namespace):

    from .config import SpecConfig

    values: dict[str, object] = {
        "preset": args.preset,
        "overrides": dict(args.set or ()),
        "tuning": dict(args.tuning or ()),
    }
    if args.noise is not None and args.noise_density is not None:
        raise ParameterError("give --noise (relative) or --noise-density (m/sqrt(Hz)), "
                             "not both")
    for name in ("noise", "noise_density", "seed", "step", "duration", "rate", "full_scale",
                 "sf_points", "sf_record", "bw_frequencies", "bw_amplitude", "bw_segment",
                 "startup_band", "startup_window"):
        value = getattr(args, name)
        if value is not None:
            values[name] = value
    return SpecConfig(**values)


def _fmt(x: float | None, spec: str = ".3g") -> str:
    return "n/a" if x is None else format(x, spec)


def print_spec(s: dict) -> None:
    a, r, f = s["allan"], s["rate_response"], s["scale_factor"]
    n = s["noise"]
    noise = (f"density {n['density_m_per_sqrt_hz']:g} m/sqrt(Hz)" if n["density_m_per_sqrt_hz"]
             else f"{n['relative_to_peak']:g} of peak")
    print(f"gyro {s['gyro']['preset']}"
          + (f" with {s['gyro']['overrides']}" if s["gyro"]["overrides"] else "")
          + f", pick-off noise {noise} (x {n['std_x_m']:.3g} m, y {n['std_y_m']:.3g} m per "
          f"{s['step_s']:g} s sample = {n['density_x_m_per_sqrt_hz']:.3g}, "
          f"{n['density_y_m_per_sqrt_hz']:.3g} m/sqrt(Hz))")
    print(f"observer rate model: {s['rate_model']}")
    probs = s["allan"].get("rate_model_probabilities")
    if probs:
        print("  model probabilities at the constant rate (mean after start-up / final): "
              + ", ".join(f"{k} {v['mean']:.3f}/{v['final']:.3f}" for k, v in probs.items()))
    arw = a["arw_rad_s_per_sqrt_hz"]
    if arw is None:
        print("  angle random walk    n/a (below)")
    else:
        print(f"  angle random walk    {arw:.3g} rad/s/sqrt(Hz) = {a['arw_deg_per_sqrt_h']:.3g}"
              f" deg/sqrt(h)   (-1/2 line at tau = 1 s, fitted over {_tau_range(a)})")
    bi = "" if a["bias_instability_resolved"] else "< "
    if a["bias_instability_rad_s"] is None:
        print("  bias instability     n/a")
    else:
        print(f"  bias instability     {bi}{a['bias_instability_rad_s']:.3g} rad/s = {bi}"
              f"{a['bias_instability_deg_h']:.3g} deg/h   (ADEV minimum / 0.664 at tau "
              f"{a['bias_instability_tau_s']:.3g} s"
              + ("" if a["bias_instability_resolved"] else
                 f"; not reached: the deviation still falls, slope "
                 f"{a['adev_slope_at_min']:+.2f}, at the longest tau") + ")")
    print(f"  bias at {a['rate_rad_s']:g} rad/s      {a['bias_rad_s']:+.3g} rad/s "
          f"+- {_fmt(a['bias_sigma_rad_s'])} (1 sigma, {a['record_s'] - a['settled_from_s']:.3g}"
          " s mean)")
    print(f"  rate noise (rms)     {a['std_rad_s']:.3g} rad/s   (std of Omega_hat - Omega after "
          "start-up, at the observer's own output bandwidth)")
    bound = {"below": "< ", "above": "> ", None: ""}[r["bound"]]
    print(f"  bandwidth (-3 dB)    {bound}{r['f_3db_hz']:.4g} Hz   (stepped sine of "
          f"{r['amplitude_rad_s']:g} rad/s; peaking {r['peaking_db']:+.2f} dB)")
    print(f"  scale-factor error   {f['sf_error_ppm']:+.4g} ppm   (line over +-"
          f"{f['full_scale_rad_s']:g} rad/s, {len(f['rates_rad_s'])} rates; offset "
          f"{f['offset_rad_s']:+.3g} rad/s)")
    print(f"  nonlinearity         {f['nonlinearity_ppm_fs']:.3g} ppm of full scale")
    w, by = a["startup_window_s"], a["settled_by_s"]
    inside = ("already inside over the first window" if by < 0.01 * w
              else f"the estimate itself inside from {by:.3g} s")
    print(f"  start-up time        {a['startup_time_s']:.3g} s   (to +-{a['startup_band_rad_s']:g}"
          f" rad/s, output averaged over {w:.3g} s; {inside})")
    if a["noise_figures_refused"]:
        at1 = a.get("record_adev_at_1s_rad_s")
        print(f"  n/a: {a['noise_figures_refused']}. This record's Allan deviation, for what "
              f"it is: minimum {a['record_adev_min_rad_s']:.3g} rad/s at tau "
              f"{a['record_adev_min_tau_s']:.3g} s" + ("" if at1 is None else
                                                       f", {at1:.3g} rad/s at tau = 1 s"))
    for w in s["warnings"]:
        _log.warning("%s", w)


def _tau_range(a: dict) -> str:
    rng = a["arw_tau_range_s"]
    return "no -1/2 region" if not rng else f"{rng[0]:.3g}-{rng[1]:.3g} s"


def spec_figure(s: dict, path: Path) -> Path:
    """Allan deviation with its slope lines, rate response, SF residuals, start-up."""
    from ..extras import pyplot

    plt = pyplot()
    import numpy as np

    a, r, f = s["allan"], s["rate_response"], s["scale_factor"]
    fig, ax = plt.subplots(2, 2, figsize=(11, 8))
    taus, adev = np.array(a["taus_s"]), np.array(a["adev_rad_s"])
    rel = np.array(a["adev_rel_sigma"])
    p = ax[0, 0]
    p.loglog(taus, adev, "k.-", label=r"overlapping Allan deviation of $\hat\Omega-\Omega$")
    p.fill_between(taus, adev * (1 - rel), adev * (1 + rel), color="0.8", label="1 sigma")
    N = a["arw_rad_s_per_sqrt_hz"]
    t_line = np.geomspace(taus[0], max(taus[-1], 1.0), 50)
    if N:
        p.loglog(t_line, N / np.sqrt(t_line), "b--",
                 label=f"slope -1/2: ARW N = {N:.3g} rad/s/$\\sqrt{{Hz}}$")
        p.plot([1.0], [N], "bo")
    B = a["bias_instability_rad_s"]
    if B is not None:
        p.axhline(0.664 * B, color="r", ls=":",
                  label=("slope 0: 0.664 B, B = " if a["bias_instability_resolved"]
                         else "bound: 0.664 B, B < ") + f"{B:.3g} rad/s")
    else:
        p.text(0.02, 0.02, "no noise figures\n(summary.json: allan.noise_figures_refused)",
               transform=p.transAxes, fontsize=7, color="r")
    p.set_xlabel(r"averaging time $\tau$ (s)")
    p.set_ylabel(r"Allan deviation $\sigma(\tau)$ (rad/s)")
    p.set_title(f"noise at {a['rate_rad_s']:g} rad/s, {a['record_s']:g} s record")
    p.legend(fontsize=7)
    p.grid(True, which="both", alpha=0.3)

    p = ax[0, 1]
    fr = np.array([q["f_hz"] for q in r["points"]])
    g = np.array([q["gain_db"] for q in r["points"]]) - r["reference_gain_db"]
    p.semilogx(fr, g, "ko-", label="gain")
    p.axhline(-3.0, color="r", ls=":", label="-3 dB")
    p.axvline(r["f_3db_hz"], color="b", ls="--",
              label=f"{ {'below': '< ', 'above': '> ', None: ''}[r['bound']] }"
                    f"{r['f_3db_hz']:.4g} Hz")
    p.set_xlabel("rate frequency (Hz)")
    p.set_ylabel(r"gain $|\hat\Omega/\Omega|$ (dB)")
    q = p.twinx()
    phase = np.degrees(np.unwrap(np.radians([x["phase_deg"] for x in r["points"]])))
    q.semilogx(fr, phase, "g.--", label="phase")
    q.set_ylabel("phase (deg)", color="g")
    p.set_title(f"rate response, stepped sine of {r['amplitude_rad_s']:g} rad/s")
    p.legend(fontsize=7, loc="lower left")
    p.grid(True, which="both", alpha=0.3)

    p = ax[1, 0]
    p.plot(f["rates_rad_s"], f["residuals_ppm_fs"], "ko-")
    p.axhline(0.0, color="0.5", lw=0.5)
    p.set_xlabel(r"input rate $\Omega$ (rad/s)")
    p.set_ylabel("residual from the line (ppm of full scale)")
    p.set_title(f"scale factor: error {f['sf_error_ppm']:+.3g} ppm, nonlinearity "
                f"{f['nonlinearity_ppm_fs']:.3g} ppm FS")
    p.grid(True, alpha=0.3)

    p = ax[1, 1]
    su = s.get("_startup_trace")
    if su and abs(a["startup_window_s"] - 1e-3) > 1e-6:
        p.plot(su["t_s_1ms"], su["error_rad_s_1ms"], "-", color="0.65", lw=0.6,
               label="error averaged over 1 ms")
    if su:
        p.plot(su["t_s"], su["error_rad_s"], "k-", lw=0.8,
               label=f"error averaged over {a['startup_window_s']:.3g} s")
    band = a["startup_band_rad_s"]
    p.axhline(band, color="r", ls=":")
    p.axhline(-band, color="r", ls=":", label=f"+-{band:g} rad/s")
    p.axvline(a["startup_time_s"], color="b", ls="--",
              label=f"start-up {a['startup_time_s']:.3g} s")
    p.set_xscale("log")
    p.set_ylim(-5.0 * band, 5.0 * band)
    p.set_xlabel("time from power-on (s)")
    p.set_ylabel(r"$\hat\Omega-\Omega$ (rad/s)")
    p.set_title("start-up to spec")
    p.legend(fontsize=7)
    p.grid(True, which="both", alpha=0.3)
    fig.suptitle(f"gyro-fmu spec: {s['gyro']['preset']}, {s['rate_model']}", fontsize=9)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)
    return path


@holds_out_folder("runs/spec")
def _cmd_spec(args: argparse.Namespace) -> int:
    from .measure import measure_spec

    cfg = config_from(args)
    out = Path(args.out)
    start = time.perf_counter()

    def progress(line: str) -> None:
        if not args.quiet:
            print(f"[{time.perf_counter() - start:6.1f} s] {line}", flush=True)

    summary = measure_spec(cfg, progress)
    out.mkdir(parents=True, exist_ok=True)
    trace = summary.pop("_startup_trace", None)
    write_json(out / "summary.json", summary, allow_nan=True)
    print_spec(summary)
    written = [out / "summary.json"]
    if not args.no_figure:
        if trace:
            summary["_startup_trace"] = trace
        written.append(spec_figure(summary, out / "spec.png"))
    wall = time.perf_counter() - start
    print(f"wrote {', '.join(str(p) for p in written)}; wall time {wall:.1f} s "
          f"({math.floor(wall / 60):d} min {wall % 60:.0f} s)")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    """Add `gyro-fmu spec` to the command line."""
    from .config import SpecConfig

    d = SpecConfig.__dataclass_fields__
    sp = sub.add_parser(
        "spec", help="measure the observer-based gyro like a datasheet: angle random walk, "
        "bias instability (Allan deviation), bandwidth, scale factor, start-up time",
        description="Runs plant + observer in-process (seconds of simulated time) and "
        "measures the rate estimate as IEEE Std 1431-2004 / IEEE Std 952-1997 do; "
        "definitions in docs/gyro-spec.md. Exit 2 without a spec when a run cannot be "
        "trusted (observer lost, estimate never settled).")
    sp.add_argument("--preset", choices=sorted(PRESETS), default=d["preset"].default,
                    help="parameter preset (default %(default)s)")
    sp.add_argument("--set", action="append", metavar="NAME=VALUE",
                    type=options.assignment(PARAMETER_NAMES, "kxy=5e7", "a gyro parameter"),
                    help="override a gyro parameter (kxx, kyy, kxy: 1/s2; dxx, dyy, dxy: "
                         "1/s; m: kg); repeatable")
    sp.add_argument("--tuning", action="append", metavar="NAME=VALUE",
                    type=options.assignment(_tuning_names, "rate_model=2",
                                            "an observer tuning field"),
                    help="observer tuning field (ObserverTuning), e.g. rate_model=2; "
                         "repeatable")
    sp.add_argument("--noise", type=options.non_negative,
                    help="pick-off noise std as a fraction of each signal's peak "
                         "(default 1e-4)")
    sp.add_argument("--noise-density", dest="noise_density", type=options.non_negative,
                    help="pick-off noise of x and y in m/sqrt(Hz), one-sided; per-sample "
                         "std = density / sqrt(2 step). Replaces --noise")
    sp.add_argument("--seed", type=options.seed, help="noise seed (default 0)")
    sp.add_argument("--step", type=options.positive, help="s (default 5e-6)")
    sp.add_argument("--duration", type=options.positive,
                    help="s of the constant-rate Allan/start-up record (default 20)")
    sp.add_argument("--rate", type=options.finite, help="rad/s of that record (default 0)")
    sp.add_argument("--full-scale", dest="full_scale", type=options.positive,
                    help="rad/s; scale-factor rates span +-full scale (default 5)")
    sp.add_argument("--sf-points", dest="sf_points", type=options.count,
                    help="number of scale-factor rates (default 11)")
    sp.add_argument("--sf-record", dest="sf_record", type=options.positive,
                    help="s averaged per scale-factor rate (default 0.2)")
    sp.add_argument("--bw-frequencies", dest="bw_frequencies", type=_frequencies,
                    help="Hz, comma-separated (default 16 from 10 to 5000)")
    sp.add_argument("--bw-amplitude", dest="bw_amplitude", type=options.positive,
                    help="rad/s of each rate sine (default 1)")
    sp.add_argument("--bw-segment", dest="bw_segment", type=options.positive,
                    help="s per frequency, at least 5 periods (default 0.1)")
    sp.add_argument("--startup-band", dest="startup_band", type=options.positive,
                    help="rad/s around the true rate (default 1 %% of full scale)")
    sp.add_argument("--startup-window", dest="startup_window", type=options.positive,
                    help="s the output is averaged over for the start-up time (default: "
                         "from the noise, so that noise alone stays in the band)")
    sp.add_argument("--out", default="runs/spec", help="output folder")
    sp.add_argument("--no-figure", dest="no_figure", action="store_true",
                    help="skip spec.png")
    sp.add_argument("--quiet", action="store_true", help="no progress lines")
    sp.set_defaults(func=_cmd_spec)
