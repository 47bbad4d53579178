"""Robustness over fabrication tolerances (issue 3, item 5), real FMU co-simulations on Dask.

200 gyros, every parameter +-10 % uniform around park-horowitz, noise 1e-5 of each
signal's peak, constant Omega_z = 1 rad/s, observer initialised at the nominal
values, 80 ms: the fraction whose 8 estimates are all within 1 % at 80 ms, and the
throughput (gyros per minute) with 1 and 2 workers (LocalCluster, one thread each).

    python benchmarks/robustness.py --n 200 --workers 2 --out runs/robustness
    python benchmarks/robustness.py --n 10 --workers 1 --out runs/robustness-1w
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from gyro_fmu.fmu.build import MODELS_DIR
from gyro_fmu.model.parameters import PARAMETER_NAMES
from gyro_fmu.system.sweep import SweepSpec, ToleranceModel, run_sweep
from gyro_fmu.system.sweep_report import write_outputs


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, default=200)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default="runs/robustness")
    ap.add_argument("--tuning", action="append", metavar="NAME=VALUE", default=[])
    args = ap.parse_args()
    tuning = {k: float(v) for k, v in (s.split("=", 1) for s in args.tuning)}
    spec = SweepSpec(
        tolerances=ToleranceModel("park-horowitz", spread=dict.fromkeys(PARAMETER_NAMES, 0.10),
                                  distribution="uniform", seed=args.seed),
        n=args.n, noise=1e-5, Omega_z=1.0, stop_time=0.08, tuning=tuning)
    res = run_sweep(spec, MODELS_DIR, n_workers=args.workers)
    paths = write_outputs(res, Path(args.out))
    s = res.summary()
    print(json.dumps({k: s[k] for k in ("n", "ok", "failed", "fraction_all_within_at_deadline",
                                        "convergence_time_s", "wall_s", "n_workers",
                                        "gyros_per_minute")}, indent=1))
    for name, u in s["per_unknown"].items():
        print(f"{name:>8} within {u['fraction_within']:.1%}  p95 |err|/tol "
              f"{u['p95_err_over_tol']:.3g}  max {u['max_err_over_tol']:.3g}")
    print("wrote", ", ".join(str(p) for p in paths))


if __name__ == "__main__":
    main()
