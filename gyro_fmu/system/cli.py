"""`gyro-fmu` commands of the system layer: run, report, sweep, ssp, container, and the
estimation studies on a scenario (observability, identify, design-drive)."""

from __future__ import annotations

import argparse
import json
import logging
from dataclasses import fields, replace
from pathlib import Path

from .. import options
from ..extras import has, install_line
from ..fmu.build import MODELS_DIR
from ..model.parameters import PARAMETER_NAMES, PRESETS, ParameterError
from .scenario import SCENARIOS, Scenario
from .scenario_args import SWEEP_STOP_TIME, scenario_from_args

_log = logging.getLogger(__name__)


def _ensure_models(models: Path) -> None:
    """Build missing or stale FMUs into `models` and say where they are."""
    from .run import ensure_fmus

    built = ensure_fmus(models)
    _log.info("FMUs in %s%s", models.resolve(),
              f" (copied {', '.join(p.stem for p in built)})" if built else "")


def _cmd_run(args: argparse.Namespace) -> int:
    from .run import FIGURES, replaced_run, run_and_report

    sc = scenario_from_args(args)
    fmus = {}
    for item in args.fmu or []:
        name, sep, path = item.partition("=")
        if not sep or name not in ("drive", "rate", "plant", "observer"):
            raise ParameterError(f"--fmu {item!r} must read INSTANCE=PATH with INSTANCE one "
                                 "of drive, rate, plant, observer")
        fmus[name] = Path(path)
    out = Path(args.out or f"runs/{args.scenario}")
    replaced = replaced_run(out, sc, args.force)
    if set(fmus) != {"drive", "rate", "plant", "observer"}:  # ours for the others
        _ensure_models(Path(args.models))
    draw = not args.no_figures and has("matplotlib")
    summary = run_and_report(sc, out, Path(args.models), fmus, figures=draw,
                             ensure=False)  # _ensure_models did it
    for message in summary["warnings"]:
        _log.warning("%s", message)
    _print_summary(summary)
    record = summary["results"]
    written = [record["file"]] + ([record["binary"]["file"]] if "binary" in record else [])
    print(f"wrote {out}/{', '.join(written)}, summary.json" + (
        ", " + ", ".join(FIGURES) if draw else "") + (
        f" (replaced a run with {replaced})" if replaced else ""))
    if not args.no_figures and not draw:
        _log.warning("no figures: they need matplotlib, which is not installed here: %s "
                     "(or --no-figures)", install_line("figures"))
    return 0 if summary["verdict"]["passed"] else 1


def _check_beside_summary(results: Path) -> None:
    """A results.csv of `gyro-fmu run` with a summary.json beside it must be the one that
    summary describes (a new run's results beside an old summary are refused)."""
    from ..outputs import check_pair

    summary_path = results.parent / "summary.json"
    try:
        summary = json.loads(summary_path.read_text())
    except (OSError, ValueError):
        return  # any CSV of the user's own: nothing to match
    record = summary.get("results") if isinstance(summary, dict) else None
    if isinstance(record, dict) and record.get("file") == results.name:
        check_pair(summary, results)


def _cmd_report(args: argparse.Namespace) -> int:
    from ..model.parameters import GyroParameters
    from ..outputs import check_pair
    from ..results.writer import PARQUET
    from .run import make_figures, read_back

    run_dir = Path(args.run_dir)
    summary_path = run_dir / "summary.json"
    if not summary_path.exists():
        raise ParameterError(f"{summary_path} not found: give a folder written by `gyro-fmu run`")
    try:
        summary = json.loads(summary_path.read_text())
        _print_summary(summary)
        truth = GyroParameters(**summary["true_parameters"])
    except (ValueError, KeyError, TypeError, AttributeError) as exc:
        raise ParameterError(f"{summary_path} is damaged or not written by `gyro-fmu run` "
                             f"({type(exc).__name__}: {exc}): rerun the scenario") from None
    check_pair(summary, run_dir / "results.csv")  # the results this summary describes
    binary = summary["results"].get("binary")  # since 0.4.0; a 0.3 run has its CSV only
    _, data = read_back(run_dir / (PARQUET if binary else "results.csv"), truth)
    for path in make_figures(data, run_dir):
        print(f"wrote {path}")
    return 0


def _cmd_observability(args: argparse.Namespace) -> int:

    from ..estimation.observability import observability_report

    sc = scenario_from_args(args)
    drive = sc.the_drive
    drives = {"two tones": drive, f"tone 1 only ({drive.f1:g} Hz)": replace(drive, A2=0.0),
              f"tone 2 only ({drive.f2:g} Hz)": replace(drive, A1=0.0)}
    Omega = sc.rate.Omega_z(0.0)
    print(f"preset {sc.preset}, Omega_z {Omega:g} rad/s, measured pair {sc.measured_pair}, "
          f"window {args.window * 1e3:g} ms at {sc.step * 1e6:g} us (eq. 7, window test)")
    for start in ("steady", "rest"):
        for label, d in drives.items():
            rep = observability_report(sc.params, d, Omega, sc.measured_pair, args.window,
                                       sc.step, start=start)
            print(f"  {start:>6}, {label:<26} {rep.summary().split(': ', 1)[1]}")
    return 0


def _cmd_ssp(args: argparse.Namespace) -> int:
    from .run import ensure_fmus, run_fmus
    from .ssp import relative_differences, run_ssp_libcosim, write_ssp

    models = Path(args.models)
    ensure_fmus(models)
    if args.system == "platform":
        from .platform import platform_ssp

        return platform_ssp(models, Path(args.out) if args.out else None, args.run,
                            args.compare)
    sc = scenario_from_args(args)
    path = write_ssp(sc, models, Path(args.out) if args.out else None)
    print(f"wrote {path}")
    if args.run or args.compare:
        result = run_ssp_libcosim(path)
        print(f"libcosim: Omega_hat at {sc.stop_time:g} s = "
              f"{result['observer.Omega_hat'][-1]:.9g} rad/s")
        if args.compare:
            rel = relative_differences(result, run_fmus(sc, models))
            worst = sorted(rel.items(), key=lambda kv: -kv[1])[:3]
            print("max |libcosim - fmpy| / max |fmpy|, worst signals: "
                  + ", ".join(f"{name} {value:.3g}" for name, value in worst))
    return 0


def _cmd_container(args: argparse.Namespace) -> int:
    from .container import build_container
    from .run import ensure_fmus

    models = Path(args.models)
    ensure_fmus(models)
    path = build_container(models, Path(args.dest) if args.dest else None, args.step)
    print(f"built {path}")
    return 0


def _cmd_identify(args: argparse.Namespace) -> int:
    from ..estimation.identify import identify, read_record
    from ..model.parameters import GyroParameters

    sc = scenario_from_args(args)  # the start of the fit: --preset/--set (default: park-horowitz)
    _check_beside_summary(Path(args.results))
    rec = read_record(Path(args.results), args.measured_pair or 1, args.window)
    start = GyroParameters(**sc.initial_guess) if args.start_from_guess else sc.params
    ident = identify(rec, start, sc.Omega_z_0, noise_std=args.noise_std,
                     fit_initial_state=args.fit_initial_state)
    noise = "estimated from the residuals" if ident.noise_estimated else "given"
    print(f"{args.results}: {ident.n_samples} samples over {ident.window * 1e3:g} ms at "
          f"{rec.h * 1e6:g} us, pair {ident.measured_pair}; initial state "
          f"{'fitted' if ident.fit_initial_state else 'at rest'}; noise std "
          f"{ident.noise_std[0]:.3g}, {ident.noise_std[1]:.3g} ({noise})")
    print(ident.table())
    print(f"estimates +- Cramer-Rao 1-sigma at the solution; {ident.nfev} evaluations, "
          f"{ident.message}")
    if args.json:
        from ..outputs import write_json

        write_json(Path(args.json), {
            "estimates": ident.estimates, "crb_sigma": ident.crb_sigma,
            "noise_std": ident.noise_std, "noise_estimated": ident.noise_estimated,
            "initial_state": ident.initial_state, "window_s": ident.window})
        print(f"wrote {args.json}")
    return 0 if ident.success else 1


def _cmd_design_drive(args: argparse.Namespace) -> int:

    from ..estimation.excitation import crb, design_drive, frequency_grid, heat_map

    sc = scenario_from_args(args)
    weights = dict(args.weight) if args.weight else None
    freqs = frequency_grid(args.f_min, args.f_max, args.f_step)
    force = args.force_limit or (sc.the_drive.A1 + sc.the_drive.A2)
    Omega = sc.rate.Omega_z(0.0)
    noise = args.noise if args.noise is not None else 1e-4
    d = design_drive(sc.params, freqs, force, Omega, noise, args.window, sc.step,
                     sc.measured_pair, splits=args.splits, weights=weights,
                     noise_kind=args.noise_kind)
    current = crb(sc.params, sc.the_drive, Omega, noise, args.window, sc.step,
                  sc.measured_pair, args.noise_kind)
    p, best = d.proposal, d.proposal_sigma
    print(f"preset {sc.preset}, Omega_z {Omega:g} rad/s, window {args.window * 1e3:g} ms, "
          f"noise {noise:g} ({args.noise_kind}), force limit {force:g} N, "
          f"{len(freqs)} frequencies {freqs[0]:g}..{freqs[-1]:g} Hz, splits {list(args.splits)}")
    print(f"{'':>26}" + "".join(f"{n:>10}" for n in best))
    print(f"{'CRB, proposal':>26}" + "".join(f"{v:10.3g}" for v in best.values()))
    print(f"{f'CRB, {sc.the_drive.f1:g} + {sc.the_drive.f2:g} Hz':>26}"
          + "".join(f"{v:10.3g}" for v in current.values()))
    print(f"proposal: --drive f1={p.f1:g} --drive A1={p.A1:.4g} --drive f2={p.f2:g} "
          f"--drive A2={p.A2:.4g}")
    out = Path(args.out)
    if out.exists() and not out.is_file():  # /dev/full, a folder: not a figure's place
        raise ParameterError(f"--out {out} is not a file (a folder or a device): give the "
                             "path of a .png to write")
    heat_map(d, out)  # whole or not at all (0.2.0 reported "wrote /dev/full")
    print(f"wrote {out}")
    return 0


def _gyro_words(sc: dict) -> str:
    """The parameters actually used: the preset, or which of them --set replaced."""
    from ..model.parameters import PARAMETER_NAMES

    overridden = [n for n in PARAMETER_NAMES if n in sc["overrides"]]
    if len(overridden) == len(PARAMETER_NAMES):
        return "gyro: every parameter set by --set (no preset value used)"
    if overridden:
        return f"gyro: preset {sc['preset']} with {', '.join(overridden)} set by --set"
    return f"gyro: preset {sc['preset']}"


def _tuning_words(summary: dict) -> str:
    """The observer's tuning as run, and how it differs from GyroObserver.fmu's defaults."""
    from ..estimation.observer_tuning import ObserverTuning

    told = summary["scenario"]["observer_tuning"]
    if not told:
        return "observer: GyroObserver.fmu's defaults (noise estimated, adaptive rate model)"
    default = vars(ObserverTuning())
    said = ", ".join(f"{k}={v:.4g} (FMU default {default[k]:.4g})" for k, v in told.items())
    return (f"observer: {said}, as a designer who knows them would set them; --tuning "
            "NAME=VALUE sets others")


def _print_summary(summary: dict) -> None:
    sc = summary["scenario"]
    print(f"{_gyro_words(sc)}; rate {sc['rate']['text']} rad/s, "
          f"{sc['stop_time'] * 1e3:g} ms at {sc['step'] * 1e6:g} us, "
          f"noise {sc['noise_relative_to_peak']:g} of peak, wall {summary['wall_time_s']:.2f} s")
    print(_tuning_words(summary))
    a, b = summary["tail_window_s"]
    print(f"judged over the tail {a * 1e3:.4g}-{b * 1e3:.4g} ms: sigma is its RMS there; "
          "converged = within tol from before the tail to the end")
    print(f"{'unknown':>8} {'truth':>13} {'estimate':>13} {'sigma':>10} "
          f"{'max err tail':>12} {'tol':>10} {'conv. at':>9}")
    below = []
    for name, u in summary["unknowns"].items():
        conv = u["converged_within_tolerance_at_s"]
        mark = "*" if u["tolerance_below_sigma"] else " "
        if mark == "*":
            below.append(name)
        print(f"{name:>8} {u['truth_final']:13.6g} {u['estimate_final']:13.6g} "
              f"{u['sigma_rms_tail']:10.3g} {u['max_abs_error_tail']:12.3g} "
              f"{u['tolerance']:9.3g}{mark} "
              f"{'no' if conv is None else f'{conv * 1e3:.2f} ms':>9}")
    if below:
        print(f"* tol is below the observer's own sigma for {', '.join(below)}: the data "
              "cannot pin it that closely (the sigma is near the Cramer-Rao bound, "
              "docs/observer-soundness.md), so 'within tol' there is chance; run longer or "
              "with less noise")
    if summary.get("interrupted"):
        print(f"INTERRUPTED at t = {summary['interrupted']['at_s']:.9g} s: every figure above "
              "is over the part simulated")
    om = summary["unknowns"]["Omega_z"]
    print(f"Omega_hat RMS error over the last 20%: {om['rms_error_tail']:.3g} rad/s; "
          f"all within tolerance: {summary['all_within_tolerance_in_tail']}")
    v = summary.get("verdict")
    if v is not None:  # summaries written before the verdict have none
        print(f"verdict: {'pass' if v['passed'] else 'FAIL'} ({v['rule']})"
              + "".join(f"\n  {f}" for f in v["failures"]))


def _scenario_options(r: argparse.ArgumentParser) -> None:
    """Options that define a scenario (shared by run and observability)."""
    r.add_argument("--scenario", default="default", choices=sorted(SCENARIOS),
                   help="default: park-horowitz at 1 rad/s; patent: Table 1 corrected, "
                        "sin(2 pi 100 t) rad/s")
    r.add_argument("--preset", choices=sorted(PRESETS),
                   help="parameter preset (default: the scenario's)")
    r.add_argument("--set", action="append", metavar="NAME=VALUE", type=options.assignment(),
                   help=f"override a true parameter ({', '.join(PARAMETER_NAMES)}), SI")
    r.add_argument("--rate", help="rate profile: constant:1 | sine:AMP:FREQ[:OFFSET] | "
                   "step:AMP:T0[:OFFSET] | ramp:SLOPE:T0[:OFFSET] (rad/s, Hz, s)")
    r.add_argument("--drive", action="append", metavar="NAME=VALUE",
                   type=options.assignment(example="f1=4100"),
                   help="drive setting A1, f1, A2, f2 (N, Hz)")
    defaults = {f.name: f.default for f in fields(Scenario)}
    r.add_argument("--stop-time", dest="stop_time", type=options.positive,
                   help=f"s (default {defaults['stop_time']:g}; sweep: "
                        f"{SWEEP_STOP_TIME:g})")
    r.add_argument("--step", type=options.positive,
                   help=f"communication step, s (default {defaults['step']:g})")
    r.add_argument("--noise", type=options.non_negative,
                   help="measurement noise std as a fraction of each signal's peak "
                        f"(default {defaults['noise']:g})")
    r.add_argument("--seed", type=options.seed,
                   help=f"noise seed (default {defaults['seed']})")
    r.add_argument("--measured-pair", dest="measured_pair", type=int, choices=(1, 2),
                   help="1: positions x, y (default); 2: velocities vx, vy")
    r.add_argument("--initial", action="append", metavar="NAME=VALUE",
                   type=options.assignment(example="kxx=3.6e8"),
                   help="observer initial guess of a parameter (default: truth x factors)")
    r.add_argument("--Omega-z-0", dest="Omega_z_0", type=options.finite,
                   help=f"observer initial rate guess, rad/s (default "
                        f"{defaults['Omega_z_0']:g})")
    r.add_argument("--tuning", action="append", metavar="NAME=VALUE",
                   type=options.assignment(example="rate_model=2"),
                   help="observer tuning parameter (see GyroObserver.fmu)")


def register(sub: argparse._SubParsersAction) -> None:
    """Add this layer's commands to the gyro-fmu parser."""
    common = argparse.ArgumentParser(add_help=False)
    _scenario_options(common)
    r = sub.add_parser("run", parents=[common],
                       help="co-simulate a scenario through the FMUs with fmpy",
                       description="Co-simulate a scenario through the FMUs with fmpy. "
                       "Writes OUT/results.csv and results.parquet (every signal at every "
                       "communication point, streamed to disk as the run goes), "
                       "summary.json and the figures fig3_states.png, fig4_estimates.png and "
                       "rate_estimate.png.")
    r.add_argument("--fmu", action="append", metavar="INSTANCE=PATH",
                   help="use your FMU for an instance (drive, rate, plant, observer)")
    r.add_argument("--models", default=str(MODELS_DIR),
                   help="folder of our FMUs")
    r.add_argument("--out", help="output folder (default runs/SCENARIO)")
    r.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    r.add_argument("--force", action="store_true",
                   help="replace a run with other settings in the output folder")
    r.set_defaults(func=_cmd_run)


    o = sub.add_parser("observability", parents=[common],
                       help="rank and condition of the eq. 7 test, one tone vs two")
    o.add_argument("--window", type=options.positive, default=0.04, help="window length, s")
    o.set_defaults(func=_cmd_observability)

    i = sub.add_parser("identify", parents=[common],
                       help="batch least-squares fit of the 7 parameters and a constant "
                            "Omega_z to a recorded run, with the Cramer-Rao bound")
    i.add_argument("results", help="CSV with time, drive.ux[, drive.uy] and plant.x, plant.y "
                                   "(--measured-pair 1) or plant.vx, plant.vy (2)")
    i.add_argument("--noise-std", dest="noise_std", type=options.positive, nargs=2,
                   metavar=("STD1", "STD2"),
                   help="absolute noise std of the two measured signals (default: estimated "
                        "from the residuals)")
    i.add_argument("--window", type=options.positive,
                   help="use only the first WINDOW s of the record")
    i.add_argument("--fit-initial-state", dest="fit_initial_state", action="store_true",
                   help="fit the initial state too (default: the plant is at rest at the "
                        "first sample)")
    i.add_argument("--start-from-guess", dest="start_from_guess", action="store_true",
                   help="start from the observer's initial guess instead of the preset values")
    i.add_argument("--json", help="also write the estimates and bounds to this JSON file")
    i.set_defaults(func=_cmd_identify)

    dd = sub.add_parser("design-drive", parents=[common],
                        help="Cramer-Rao bound over a grid of two-tone drives; propose the "
                             "pair minimizing the bound on Omega_z (or a weighted sum)")
    dd.add_argument("--window", type=options.positive, default=0.04, help="window length, s")
    dd.add_argument("--f-min", dest="f_min", type=options.positive, default=500.0, help="Hz")
    dd.add_argument("--f-max", dest="f_max", type=options.positive, default=6000.0, help="Hz")
    dd.add_argument("--f-step", dest="f_step", type=options.positive, default=250.0, help="Hz")
    dd.add_argument("--force-limit", dest="force_limit", type=options.positive,
                    help="A1 + A2, N (default: the scenario drive's A1 + A2)")
    dd.add_argument("--splits", type=options.open_fraction, nargs="+", default=[0.25, 0.5, 0.75],
                    help="fractions of the force limit on tone 1")
    dd.add_argument("--noise-kind", dest="noise_kind", choices=("relative", "absolute"),
                    default="relative", help="--noise as a fraction of each signal's peak "
                    "(default 1e-4) or an absolute std in m (or m/s)")
    dd.add_argument("--weight", action="append", metavar="NAME=W",
                    type=options.assignment(example="Omega_z=1"),
                    help="objective: sum of W * sigma/tolerance (default Omega_z=1)")
    dd.add_argument("--out", default="runs/design-drive/crb_heatmap.png", help="heat map PNG")
    dd.set_defaults(func=_cmd_design_drive)

    from .sweep_cli import register as register_sweep

    register_sweep(sub, common)

    s = sub.add_parser("ssp", parents=[common],
                       help="write the scenario's system as an SSP package; --run: in libcosim")
    s.add_argument("--models", default=str(MODELS_DIR),
                   help="folder of our FMUs")
    s.add_argument("--out", help="package file (default MODELS/GyroSystem.ssp, or "
                   "MODELS/StabilizedPlatform.ssp)")
    s.add_argument("--system", choices=("gyro", "platform"), default="gyro",
                   help="gyro: the scenario's four FMUs (patent Fig. 2); platform: GyroSensor "
                        "in the rate loop of StabilizedPlatform on a swaying vehicle (2 s at "
                        "1 ms; the scenario options do not apply)")
    s.add_argument("--run", action="store_true", help="run the package in libcosim")
    s.add_argument("--compare", action="store_true",
                   help="run it in libcosim and in the fmpy master, print the differences")
    s.set_defaults(func=_cmd_ssp)

    c = sub.add_parser("container", help="build the patent's Fig. 2 system (its own rate "
                       "profile, a 5 us step) as one FMU (models/GyroSystem.fmu, "
                       "fmu-manipulation-toolbox); a rate in from your model: GyroSensor.fmu")
    c.add_argument("--models", default=str(MODELS_DIR),
                   help="folder of our FMUs")
    c.add_argument("--dest", help="container file (default MODELS/GyroSystem.fmu)")
    c.add_argument("--step", type=options.positive, default=Scenario.step,
                   help="internal fixed step, s")
    c.set_defaults(func=_cmd_container)

    rep = sub.add_parser("report", help="print the summary and redraw the figures of a run")
    rep.add_argument("run_dir", help="folder written by `gyro-fmu run`")
    rep.set_defaults(func=_cmd_report)
