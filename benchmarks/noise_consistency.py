"""Observer under pick-off noise, through the FMUs: stability, errors, sigma consistency.

    python benchmarks/noise_consistency.py [--noise 1e-4] [--stop-time 0.2] [--seeds 5]

For each scenario and seed: no NaN, no divergence; then, pooled over seeds, the
RMS over the last 20% of the run of each unknown's error and of error / sigma
(1 for a consistent filter; the issue asks for a factor 3 either way).
"""

from __future__ import annotations

import argparse

import numpy as np

from gyro_fmu.estimation.metrics import ESTIMATED
from gyro_fmu.system.run import estimate_column, run_fmus
from gyro_fmu.system.scenario import scenario


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--noise", type=float, default=1e-4)
    ap.add_argument("--stop-time", type=float, default=0.2)
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--scenario", action="append", choices=["default", "patent"])
    args = ap.parse_args()
    print(f"noise {args.noise:g} of each signal's peak, {args.stop_time * 1e3:g} ms, "
          f"{args.seeds} seeds; pooled over the last 20% of each run")
    for name in args.scenario or ["default", "patent"]:
        errors, ratios, finite = {n: [] for n in ESTIMATED}, {n: [] for n in ESTIMATED}, True
        for seed in range(1, args.seeds + 1):
            sc = scenario(name, noise=args.noise, stop_time=args.stop_time, seed=seed)
            r = run_fmus(sc)
            finite &= bool(np.all(np.isfinite(r.data)))
            tail = r["time"] >= 0.8 * sc.stop_time
            truth = sc.params
            for n in ESTIMATED:
                true = r["rate.Omega_z"] if n == "Omega_z" else getattr(truth, n)
                err = (r[estimate_column(n)] - true)[tail]
                errors[n].append(err)
                ratios[n].append(err / r[f"observer.sigma_{n}"][tail])
        print(f"\nscenario {name}: all finite {finite}")
        print(f"{'unknown':>8} {'RMS error':>11} {'RMS err/sigma':>14}")
        for n in ESTIMATED:
            e, z = np.concatenate(errors[n]), np.concatenate(ratios[n])
            print(f"{n:>8} {np.sqrt(np.mean(e**2)):11.3g} {np.sqrt(np.mean(z**2)):14.2f}")


if __name__ == "__main__":
    main()
