"""`gyro-fmu selfcal` and `gyro-fmu ratetable`: the calibration and its ground truth."""

from __future__ import annotations

import argparse
import json
import logging
import math
from dataclasses import fields, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .. import options
from ..model.loops import LoopsError
from ..model.parameters import ParameterError
from ..model.resonator import EARTH_RATE, ResonatorError, ResonatorParameters, check_resonator
from ..outputs import holds_out_folder, write_json
from . import defaults

_log = logging.getLogger(__name__)

if TYPE_CHECKING:  # the parser is built without the calibration's stack (scipy.optimize)
    from .alarms import CalibrationRefusedError
    from .sequence import FeedForward, SelfCalConfig

RESONATOR_NAMES = tuple(f.name for f in fields(ResonatorParameters))


def _user_loops() -> tuple[str, ...]:
    from .design import USER_LOOPS

    return USER_LOOPS


def _lot_fields() -> tuple[str, ...]:
    from .lot import LotModel

    return tuple(sorted({f.name for f in fields(LotModel)} - {"seed"}))


def _resonator(args: argparse.Namespace) -> ResonatorParameters:
    changes = dict(args.set or ())
    if args.noise is not None:
        changes["noise"] = args.noise
    res = replace(ResonatorParameters(), **changes)
    if args.drift:
        res = res.drifted(args.drift[0], args.drift[1])
    problems = check_resonator(res)
    if problems:
        raise ParameterError("; ".join(problems))
    return res


def _loop_overrides(args: argparse.Namespace) -> dict[str, float]:
    return dict(getattr(args, "loop", None) or ())


def _config(args: argparse.Namespace, res: ResonatorParameters) -> SelfCalConfig:
    """The calibration designed for the resonator given (its values are the nominal
    ones the loops are designed from), with the command line's overrides."""
    from .design import design

    omega = 0.0
    if args.latitude is not None:  # in [-90, 90]: options.latitude
        omega = EARTH_RATE * math.sin(math.radians(args.latitude))
    values = {"seed": args.seed, "Omega_z": omega, "engine": getattr(args, "engine", "inprocess")}
    for name in ("record", "settle", "sideband_count", "sideband_index", "sideband_spacing",
                 "kappa", "max_record", "target_bias", "target_sf_ppm"):
        value = getattr(args, name, None)
        if value is not None:
            values[name] = value
    if getattr(args, "record", None) is not None:
        values["auto_record"] = False  # the user's record length, checked, not changed
    if getattr(args, "sideband_index", None) is not None:
        values["auto_index"] = False  # the user's index, not raised
    return design(res, loops=_loop_overrides(args), **values)


def _feedforward_from(path: Path) -> FeedForward:
    """Step 1's result from a selfcal summary.json, each defect named with the file."""
    from .sequence import FeedForward

    remedy = "give the summary.json a `gyro-fmu selfcal` wrote"
    try:
        s = json.loads(path.read_bytes().decode("utf-8"))
        rho = s["relative_pickoff_gain"] * np.exp(1j * s["relative_pickoff_phase_rad"])
        E = np.array(s["feedthrough_V_per_V"], dtype=float)
    except OSError as exc:
        raise ParameterError(f"--feedforward-from {path}: {exc.strerror}: {remedy}") from None
    except UnicodeDecodeError as exc:
        raise ParameterError(f"--feedforward-from {path} is not UTF-8 text (byte "
                             f"{exc.object[exc.start]:#04x} at {exc.start}): {remedy}") from None
    except (ValueError, KeyError, TypeError) as exc:
        raise ParameterError(f"--feedforward-from {path} holds no feed-forward "
                             f"({type(exc).__name__}: {exc}): {remedy}") from None
    if E.shape != (2, 2) or not (np.all(np.isfinite(E)) and np.isfinite(rho)):
        raise ParameterError(f"--feedforward-from {path}: feedthrough_V_per_V must be 2 x 2 "
                             f"and every value finite: {remedy}")
    return FeedForward(E, complex(rho), np.zeros((2, 2)))


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--set", action="append", metavar="NAME=VALUE",
                   type=options.assignment(RESONATOR_NAMES, "Q_x=3e4", "a resonator parameter"),
                   help="resonator parameter (f_x, Q_x, dxy, kxy, Px, phi_y, Exy, ...)")
    p.add_argument("--noise", type=options.non_negative,
                   help="pick-off noise, V per sample (2.5e-4: Allan deviation 13 deg/h at 1 s)")
    p.add_argument("--drift", type=options.finite, nargs=2, metavar=("DF_HZ", "DAMPING_FACTOR"),
                   help="temperature-like drift: shift both modes by DF_HZ, scale dampings")
    p.add_argument("--latitude", type=options.latitude,
                   help="deg: earth rate times sin(latitude) about the sense axis")
    p.add_argument("--loop", action="append", metavar="NAME=VALUE",
                   type=options.assignment(_user_loops, "pll_bandwidth=30",
                                           "a loop setting the sequence leaves to you "
                                           "(sidebands: --index, --spacing, --sidebands)"),
                   help="loop setting instead of the one designed for the resonator "
                        "(f_nominal, q_nominal, plant_gain, amplitude, pll_bandwidth, ...)")
    p.add_argument("--seed", type=options.seed, default=1, help="noise seed")
    p.add_argument("--out", help="output folder")


@holds_out_folder("runs/selfcal")
def _cmd_selfcal(args: argparse.Namespace) -> int:
    from .alarms import CalibrationRefusedError
    from .phasors import PhasorError
    from .ratetable import table_at_readout
    from .sequence import self_calibrate

    try:
        res = _resonator(args)
        cfg = _config(args, res)
        result = self_calibrate(res, cfg)
    except (ResonatorError, LoopsError, PhasorError) as exc:
        raise ParameterError(str(exc)) from None
    except CalibrationRefusedError as exc:
        _write_refusal(args, exc)
        raise
    out = Path(args.out or "runs/selfcal")
    out.mkdir(parents=True, exist_ok=True)
    summary = {"resonator": res.as_dict(), "config": cfg.as_dict(), **result.summary()}
    s = result.summary()
    raised = " (raised into the drive's headroom)" if \
        result.sideband_index > cfg.sideband_index else ""
    print(f"self-calibration ({len(cfg.modes)} modes, {result.record:g} s records"
          f"{' (chosen for the targets)' if cfg.auto_record else ''}, "
          f"{cfg.sideband_count} sidebands of index {result.sideband_index:.3g}{raised}, "
          f"{cfg.engine}): {s['wall_time_s']:.1f} s wall")
    print(f"  bias          {s['bias_rad_s']:+.4e} rad/s  (1 sigma {s['sigma_bias_rad_s']:.1e})")
    print(f"  scale factor  {s['scale_factor_V_per_rad_s']:.6f} V/(rad/s)  (1 sigma "
          f"{s['sigma_scale_factor_V_per_rad_s'] / s['scale_factor_V_per_rad_s'] * 1e6:.1f} ppm)")
    print(f"  checks: loops locked, misfit {result.misfit_ratio:.2f} x noise, "
          f"pick-off noise {result.pickoff_noise:.2e} V; step {cfg.step:.3g} s, loops for "
          f"{cfg.loops.f_nominal:.6g} Hz, amplitude {cfg.loops.amplitude:.3g} V")
    print(f"  dxy {s['dxy']:.4e} 1/s, kxy {s['kxy']:.4e} 1/s^2, background rate "
          f"{s['Omega_z']:+.3e} rad/s (1 sigma {s['sigma_Omega_z']:.1e}), |Py/Px| "
          f"{s['relative_pickoff_gain']:.5f}, phase {s['relative_pickoff_phase_rad']:+.2e} rad")
    if args.compare_ratetable:
        table = table_at_readout(res, result, cfg)  # held at the mode-1 record's temperature
        d_bias = result.bias - table.bias
        d_sf = (result.scale_factor / table.scale_factor - 1) * 1e6
        print(f"  rate table (noise-free, same feed-forward): bias {table.bias:+.4e} rad/s, "
              f"SF {table.scale_factor:.6f}; difference {d_bias:+.2e} rad/s, {d_sf:+.1f} ppm "
              f"(table unsettled by {table.unsettled:.1e} rad/s)")
        summary["ratetable"] = table.summary()
        summary["difference"] = {"bias_rad_s": d_bias, "scale_factor_ppm": d_sf}
    (out / "sidebands.png").unlink(missing_ok=True)  # an old run's, never beside this one
    write_json(out / "summary.json", summary, default=_json)
    if not args.no_figures:
        from .figures import sideband_figure

        print(f"  figure: {sideband_figure(result, out / 'sidebands.png')}")
    print(f"  summary: {out / 'summary.json'}")
    return 0


def _write_refusal(args: argparse.Namespace, exc: CalibrationRefusedError) -> None:
    """A refused calibration leaves its reasons on disk, and no number."""
    out = Path(args.out or "runs/selfcal")
    out.mkdir(parents=True, exist_ok=True)
    write_json(out / "summary.json", {"refused": exc.problems, "calibrated": False})
    for problem in exc.problems[1:]:
        _log.error("also: %s", problem)


@holds_out_folder("runs/ratetable")
def _cmd_ratetable(args: argparse.Namespace) -> int:
    from .phasors import PhasorError
    from .ratetable import DEFAULT_RATES, RateTableError, rate_table
    from .sequence import measure_feedforward

    rates = tuple(args.rates) if args.rates else DEFAULT_RATES
    if len(set(rates)) < 2 or not all(math.isfinite(r) for r in rates):
        raise ParameterError(f"--rates {list(rates)} needs at least two distinct finite rates")
    try:
        res = _resonator(args)
        cfg = _config(args, res)
        if args.feedforward_from:
            ff = _feedforward_from(Path(args.feedforward_from))
        else:
            ff = measure_feedforward(res, cfg)
        table = rate_table(res, ff, cfg, rates=rates, dwell=args.dwell, average=args.average)
    except (ResonatorError, LoopsError, PhasorError, RateTableError) as exc:
        raise ParameterError(str(exc)) from None
    out = Path(args.out or "runs/ratetable")
    out.mkdir(parents=True, exist_ok=True)
    write_json(out / "summary.json", {"resonator": res.as_dict(), **table.summary()},
               default=_json)
    print(f"rate table, {len(rates)} rates: bias {table.bias:+.4e} rad/s (1 sigma "
          f"{table.sigma_bias:.1e}), scale factor {table.scale_factor:.6f} V/(rad/s) "
          f"(1 sigma {table.sigma_scale_factor / table.scale_factor * 1e6:.1f} ppm), "
          f"largest nonlinearity {table.max_nonlinearity:.1e} rad/s, unsettled "
          f"{table.unsettled:.1e} rad/s; {table.wall_time:.1f} s")
    print(f"  summary: {out / 'summary.json'}")
    return 0


@holds_out_folder("runs/selfcal_lot")
def _cmd_lot(args: argparse.Namespace) -> int:
    from .lot import LotModel, run_lot, write_lot

    if args.n < 1:
        raise ParameterError(f"-n {args.n!r} must be at least 1")
    changes = dict(args.model or ())
    res = run_lot(args.n, LotModel(seed=args.seed, **changes), args.scheduler, args.workers,
                  progress=not args.quiet)
    paths = write_lot(res, Path(args.out or "runs/selfcal_lot"), figures=not args.no_figures)
    s = res.summary()
    print(f"self-calibration lot of {s['n']}: {s['n_good']} good "
          f"({s['fraction_good']:.0%}), {s['n_refused']} refused, {s['n_WRONG']} WRONG, "
          f"{s['n_failed']} failed; RMS(error/sigma) bias {s['rms_z_bias'] or math.nan:.2f}, "
          f"SF {s['rms_z_sf'] or math.nan:.2f}; {s['wall_s_per_resonator_median']:.1f} s "
          f"median per calibration, {s['wall_s']:.0f} s on {s['n_workers']} workers")
    for reason in s["refusal_reasons"] + s["failures"]:
        print(f"  refused/failed: {reason[:160]}")
    for p in paths:
        print(f"  {p}")
    if res.interrupted:
        raise KeyboardInterrupt
    return 1 if s["n_WRONG"] else 0


@holds_out_folder("runs/selfcal_warmup")
def _cmd_warmup(args: argparse.Namespace) -> int:
    from .phasors import PhasorError
    from .warmup import WarmupError, warmup_curve, write_curve

    try:
        res = _resonator(args)
        cfg = _config(args, res)
        points = warmup_curve(res, cfg, args.span, progress=None if args.quiet else lambda p: print(
            f"  {p.temperature:8.3f} K  {p.status:7s}  bias {p.d_bias:+.2e} rad/s, "
            f"SF {p.d_sf_ppm:+6.1f} ppm off the table (1 sigma {p.sigma_bias:.1e}, "
            f"{p.sigma_sf_ppm:.1f})", flush=True))
    except (ResonatorError, LoopsError, PhasorError, WarmupError) as exc:
        raise ParameterError(str(exc)) from None
    good = sum(p.status == "good" for p in points)
    wrong = sum(p.status == "WRONG" for p in points)
    summary = {"resonator": res.as_dict(), "config": cfg.as_dict(), "span_K": args.span,
               "n": len(points), "n_good": good, "n_WRONG": wrong,
               "largest_bias_difference_rad_s": max((abs(p.d_bias) for p in points
                                                     if p.status == "good"), default=None),
               "largest_sf_difference_ppm": max((abs(p.d_sf_ppm) for p in points
                                                 if p.status == "good"), default=None)}
    paths = write_curve(points, Path(args.out or "runs/selfcal_warmup"), summary,
                        figure=not args.no_figures)
    print(f"calibration during a warm-up of {args.span:g} K: {good} of {len(points)} in "
          f"spec against the rate table, {len(points) - good - wrong} refused, {wrong} WRONG")
    for p in paths:
        print(f"  {p}")
    return 1 if wrong else 0


def _json(value: object) -> object:
    if isinstance(value, complex):
        return [value.real, value.imag]
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"not JSON: {value!r}")


def register(sub: argparse._SubParsersAction) -> None:
    """Add the selfcal and ratetable commands to `gyro-fmu`."""
    sc = sub.add_parser("selfcal", help="self-calibrate bias and scale factor without "
                        "rotation (US 9,482,553), carrier-level")
    _common(sc)
    sc.add_argument("--record", type=options.positive,
                    help=f"s per mode, whole periods of the spacing (default: "
                         f"{defaults.RECORD:g} s, longer when the 1-sigmas need it, up to "
                         "--max-record)")
    sc.add_argument("--max-record", dest="max_record", type=options.positive,
                    help=f"s, longest record chosen for the targets (default "
                         f"{defaults.MAX_RECORD:g})")
    sc.add_argument("--target-bias", dest="target_bias", type=options.positive,
                    help=f"rad/s, bias 1-sigma to reach (default earth rate / 3, "
                         f"{defaults.TARGET_BIAS:.3g})")
    sc.add_argument("--target-sf-ppm", dest="target_sf_ppm", type=options.positive,
                    help=f"ppm, scale-factor 1-sigma to reach (default "
                         f"{defaults.TARGET_SF_PPM:g})")
    sc.add_argument("--settle", type=options.non_negative,
                    help=f"s before each record (default {defaults.SETTLE:g})")
    sc.add_argument("--sidebands", dest="sideband_count", type=options.count,
                    help=f"number of sideband tones (default {defaults.SIDEBAND_COUNT})")
    sc.add_argument("--index", dest="sideband_index", type=options.positive,
                    help=f"modulation index per tone (default {defaults.SIDEBAND_INDEX:g}, "
                         "raised into the drive's headroom when the 1-sigmas need it; "
                         "given: fixed)")
    sc.add_argument("--spacing", dest="sideband_spacing", type=options.positive,
                    help="Hz between tones (default: 3/4 of the mode's half-width, 0.2-2 Hz "
                         "on a 0.1 Hz grid: selfcal/design.py)")
    sc.add_argument("--kappa", type=options.positive,
                    help=f"Bryant factor from the factory (default {defaults.KAPPA:g})")
    sc.add_argument("--compare-ratetable", dest="compare_ratetable", action="store_true",
                    help="also run the rate table on the same gyro and print the differences")
    sc.add_argument("--engine", choices=("inprocess", "fmu"), default="inprocess",
                    help="fmu: run GyroResonator.fmu + GyroLoops.fmu through the project's "
                         "master (bit-identical to inprocess; about 2-2.5x its time)")
    sc.add_argument("--no-figures", dest="no_figures", action="store_true")
    sc.set_defaults(func=_cmd_selfcal)

    lot = sub.add_parser("selfcal-lot", help="self-calibrate a lot of resonators drawn "
                         "from a tolerance model (3-15 kHz, Q 5e3-2e5), each checked "
                         "against its rate table, on Dask")
    lot.add_argument("-n", type=options.count, default=100, help="resonators")
    lot.add_argument("--seed", type=options.seed, default=2026, help="seed of the draw")
    lot.add_argument("--model", action="append", metavar="NAME=VALUE",
                     type=options.assignment(_lot_fields, "Q_max=1e5",
                                             "a tolerance-model field"),
                     help="tolerance model field (f_min, Q_max, split_max, "
                          "cubic_shift_max, noise_density, ...; see selfcal/lot.py)")
    lot.add_argument("--workers", type=options.count,
                     help="local Dask workers (default: all cores)")
    lot.add_argument("--scheduler", help="address of an existing Dask scheduler")
    lot.add_argument("--out", help="output folder (default runs/selfcal_lot)")
    lot.add_argument("--quiet", action="store_true", help="no progress line")
    lot.add_argument("--no-figures", dest="no_figures", action="store_true")
    lot.set_defaults(func=_cmd_lot)

    wu = sub.add_parser("selfcal-warmup", help="calibrate back to back while the "
                        "resonator warms (--set temperature_rate=K/s, tc_f, tc_Q) over "
                        "--span K, each checked against the rate table at its temperature")
    _common(wu)
    wu.add_argument("--span", type=options.positive, default=10.0,
                    help="K of warm-up to calibrate through")
    wu.add_argument("--quiet", action="store_true", help="no line per calibration")
    wu.add_argument("--no-figures", dest="no_figures", action="store_true")
    wu.set_defaults(func=_cmd_warmup)

    rt = sub.add_parser("ratetable", help="conventional calibration on a simulated rate "
                        "table (the ground truth of selfcal)")
    _common(rt)
    rt.add_argument("--rates", type=options.finite, nargs="+",
                    help="rad/s (default -1 .. 1, 7 rates)")
    rt.add_argument("--dwell", type=options.positive, default=None,
                    help="s at each rate (default: max(1, 3 / slowest loop bandwidth))")
    rt.add_argument("--average", type=options.positive, default=None,
                    help="s averaged at each rate (default: the second half of the dwell)")
    rt.add_argument("--feedforward-from", dest="feedforward_from",
                    help="summary.json of a selfcal run: use its feed-forward correction")
    rt.set_defaults(func=_cmd_ratetable)
