"""`gyro-fmu sweep`: the Monte Carlo over a production lot (system/sweep.py), its options
and its console report against the Cramer-Rao bound (docs/sweep-bound.md)."""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

from .. import options
from ..fmu.build import MODELS_DIR
from ..model.parameters import ParameterError
from ..outputs import holds_out_folder
from .scenario_args import SWEEP_STOP_TIME, scenario_from_args

_log = logging.getLogger(__name__)


def _print_bound(b: dict | None) -> None:
    """The sweep's comparison with the Cramer-Rao bound (an efficient estimator)."""
    if b is None:
        print("no Cramer-Rao comparison (noise off)")
        return

    def pct(v: float | None) -> str:
        return "n/a" if v is None else f"{v:.1%}"

    a = b["all"]
    print(f"against the Cramer-Rao bound at {b['deadline_s'] * 1e3:g} ms ({b['n']} gyros, "
          f"each its own inputs and noise; efficient = Gaussian with the bound):")
    print(f"  all 8 within tolerance {pct(a['fraction_within_tol'])} (efficient "
          f"{pct(a['efficient_fraction_within_tol'])}); within 2 bound-sigmas "
          f"{pct(a['fraction_within_2_crb'])} (efficient "
          f"{pct(a['efficient_fraction_within_2_crb'])})")
    if a.get("batch_n"):
        print(f"  batch ML identifier on the same data ({a['batch_n']} gyros): all 8 within "
              f"tolerance {pct(a['batch_fraction_within_tol'])}, within 2 bound-sigmas "
              f"{pct(a['batch_fraction_within_2_crb'])}; rms err/CRB " + ", ".join(
                  f"{n} {u['batch_rms_err_over_crb']:.2f}" for n, u in b["per_unknown"].items()
                  if "batch_rms_err_over_crb" in u))
    print(f"  {'unknown':>8} {'CRB/tol':>8} {'in tol':>7} {'effic.':>7} {'in 2CRB':>8} "
          f"{'rms e/CRB':>9} {'mean e/CRB':>10}")
    for name, u in b["per_unknown"].items():
        def num(v: float | None, fmt: str) -> str:
            return "n/a" if v is None else format(v, fmt)

        print(f"  {name:>8} {num(u['median_crb_over_tol'], '8.3g')} "
              f"{pct(u['fraction_within_tol']):>7} {pct(u['efficient_fraction_within_tol']):>7} "
              f"{pct(u['fraction_within_2_crb']):>8} {num(u['rms_err_over_crb'], '9.2f')} "
              f"{num(u['mean_err_over_crb'], '10.2f')}")

# --- in main(), after the `observability` subparser: ---------------------------------------


@holds_out_folder("runs/sweep")
def _cmd_sweep(args: argparse.Namespace) -> int:
    from ..model.parameters import PARAMETER_NAMES
    from ..model.rate import RateKind
    from .sweep import SweepSpec, ToleranceModel, run_sweep
    from .sweep_report import write_outputs

    sc = scenario_from_args(args)
    if sc.rate.kind is not RateKind.constant:
        raise ParameterError(f"the sweep runs a constant rate (--rate constant:VALUE), not "
                             f"{sc.rate.describe()}")
    spread = dict.fromkeys(PARAMETER_NAMES, args.spread)
    spread.update(dict(args.spread_of or ()))
    tolerances = ToleranceModel(sc.preset, dict(sc.overrides), spread, args.distribution,
                                args.tolerance_seed)
    spec = SweepSpec(tolerances, n=args.n, noise=sc.noise if args.noise is not None else 1e-5,
                     Omega_z=sc.rate.Omega_z(0.0), stop_time=sc.stop_time
                     if args.stop_time is not None else SWEEP_STOP_TIME, deadline=args.deadline,
                     step=sc.step, measured_pair=sc.measured_pair, noise_seed=sc.seed,
                     tuning=dict(sc.tuning), observer_tuning=args.observer_tuning,
                     drive=sc.drive, batch=args.batch)
    res = run_sweep(spec, Path(args.models), scheduler=args.scheduler, n_workers=args.workers)
    paths = write_outputs(res, Path(args.out), figures=not args.no_figures)
    s = res.summary()
    conv = s["convergence_time_s"]
    print(f"{s['n']} gyros ({s['ok']} ok, {s['failed']} failed) in {s['wall_s']:.0f} s on "
          f"{s['n_workers']} workers: {s['gyros_per_minute']:.1f} gyros/min "
          f"(observer tuning: {spec.observer_tuning})")
    def ms(v: float | None) -> str:
        return "n/a" if v is None else f"{v * 1e3:.2f} ms"

    print(f"all 8 within tolerance at {s['deadline_s'] * 1e3:g} ms: "
          f"{s['fraction_all_within_at_deadline']:.1%}; convergence time p50 "
          f"{ms(conv['p50'])}, p95 {ms(conv['p95'])}, never {conv['never']}"
          + ("" if conv["p50"] is not None else " (no gyro converged)"))
    share = f"{conv['deadline_fraction']:.0%}"
    print(f"deadline for {share} of the lot within tolerance: "
          + (ms(conv["deadline_for_fraction_s"]) if conv["deadline_for_fraction_s"] is not None
             else f"not reached ({conv['never_or_failed']} of {s['n']} never converge or "
                  f"failed)"))
    inst, eff = (conv[f"{k}_deadline_for_fraction_s"] for k in ("instant", "efficient"))
    print(f"{share} of the lot within tolerance at each time from: "
          + (ms(inst) if inst is not None else "not within the run")
          + f" ({len(s['within_curve']['t_s'])} points up to the deadline); an efficient "
          "estimator: " + (ms(eff) if eff is not None else "not within the run"
                           if s["bound"] else "n/a (noise off)"))
    _print_bound(s["bound"])
    for f in s["failures"]:
        print(f"  failed gyro {f['gyro']}: {f['reason']}")
    print("wrote " + ", ".join(str(p) for p in paths))
    if res.interrupted:
        raise KeyboardInterrupt(f"sweep {res.interrupted}; their rows and the partial "
                                f"summary are in {args.out}")
    if s["failed"]:  # a lot with failed members is not a clean result (exit 1, as a check)
        _log.error("%d of %d gyros failed (listed above, and in sweep.csv with their "
                   "reasons)", s["failed"], s["n"])
        return 1
    return 0


def register(sub: argparse._SubParsersAction, common: argparse.ArgumentParser) -> None:
    """Add the `sweep` command (its scenario options come with `common`)."""
    sw = sub.add_parser("sweep", parents=[common],
                        help="Monte Carlo over fabrication tolerances: N gyros, each a real "
                             "FMU co-simulation, on Dask")
    sw.add_argument("-n", "--n", type=options.count, default=200, help="number of gyros")
    sw.add_argument("--spread", type=options.non_negative, default=0.10,
                    help="relative spread of every parameter")
    sw.add_argument("--spread-of", dest="spread_of", action="append", metavar="NAME=S",
                    type=options.assignment(example="kxy=0.2"),
                    help="relative spread of one parameter")
    sw.add_argument("--distribution", choices=("uniform", "normal"), default="uniform",
                    help="uniform: nominal*(1+S*U(-1,1)); normal: nominal*(1+S*N(0,1))")
    sw.add_argument("--tolerance-seed", dest="tolerance_seed", type=options.seed, default=0)
    sw.add_argument("--deadline", type=options.positive,
                    help=f"s (default: the stop time, {SWEEP_STOP_TIME:g} s unless --stop-time)")
    sw.add_argument("--scheduler", help="address of an existing Dask scheduler "
                                        "(default: a local cluster)")
    sw.add_argument("--workers", type=options.count,
                    help="local cluster workers (default: all cores)")
    sw.add_argument("--models", default=str(MODELS_DIR),
                   help="folder of our FMUs")
    sw.add_argument("--out", default="runs/sweep", help="output folder")
    sw.add_argument("--no-figures", action="store_true", help="skip the histograms")
    sw.add_argument("--observer-tuning", dest="observer_tuning",
                    choices=("scenario", "fmu-rate", "fmu"), default="scenario",
                    help="scenario: the constant-rate model and the noise stds told; "
                    "fmu-rate: the FMU's default rate model, noise told; fmu: the "
                    "FMU's defaults (rate model and noise estimation); --tuning overrides")
    sw.add_argument("--batch", action="store_true",
                    help="also fit each gyro with the batch ML identifier (an estimator at "
                    "the bound, on the same data; a few seconds per gyro)")
    sw.set_defaults(func=_cmd_sweep)
