"""The gyroscope system of patent Fig. 2 (drive, rate, plant, observer) co-simulated
through the FMUs by gyro_fmu's master, from Python, on a gyro that is no preset.

    python examples/cosimulate_from_python.py --stop-time 0.05

ensure_fmus copies the native FMUs into --models (they are prebuilt in the wheel),
fmu_system wires them; run_cosimulation steps them (Jacobi, fixed step) and returns every output.
"""

from __future__ import annotations

import argparse

from gyro_fmu import fmu_system, run_cosimulation, scenario
from gyro_fmu.system.run import ensure_fmus


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--stop-time", type=float, default=0.05, help="s")
    ap.add_argument("--models", default="models", help="folder for the FMUs")
    args = ap.parse_args()
    # the default gyro (1 rad/s) with other couplings: any parameter
    # of the preset, of the rate profile or of the drive can be overridden
    sc = scenario(stop_time=args.stop_time, overrides={"kxy": 3e7, "dxy": 2.0})
    ensure_fmus(args.models)
    components, connections = fmu_system(sc, args.models)
    result = run_cosimulation(components, connections, sc.stop_time, sc.step)
    true, estimate = result["rate.Omega_z"][-1], result["observer.Omega_hat"][-1]
    sigma = result["observer.sigma_Omega_z"][-1]
    print(f"Omega_z {true:g} rad/s, Omega_hat {estimate:.6f} rad/s (1-sigma {sigma:.2g}) "
          f"after {sc.stop_time:g} s; kxy_hat {result['observer.kxy_hat'][-1]:.4g} 1/s2")


if __name__ == "__main__":
    main()
