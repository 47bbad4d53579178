"""Observer efficiency: the online observer vs the batch identifier vs the Cramer-Rao bound.

Default scenario (park-horowitz, constant Omega_z = 1 rad/s, drive 4000 + 1200 Hz,
positions measured, observer tuning of gyro_fmu.system.scenario.observer_tuning), noise
1e-6 .. 1e-3 of each signal's own peak (over the 80 ms noise-free run), several seeds.
Runs are in-process (gyro_fmu.system.inprocess.run_inprocess, bit-identical to the FMU run).

For each noise level and window (40 ms, 80 ms):
  CRB       Cramer-Rao 1-sigma at the truth for the same inputs and noise stds, plant
            from rest (gyro_fmu.estimation.identify.crb_at);
  obs err   RMS over seeds of the observer's error at the end of the window;
  obs sig   RMS over seeds of the observer's own 1-sigma at that time;
  batch err RMS over seeds of the batch output-error identifier's error on the same
            data (gyro_fmu.estimation.identify.identify, from the observer's initial guess);
  ratios    obs err / CRB (target <= 2 for Omega_z and dxy), obs err / obs sig
            (consistency, target within [1/2, 2]).

    python benchmarks/observer_efficiency.py [--seeds 8] [--tuning q_Omega=1e2 ...]
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from gyro_fmu.estimation.identify import crb_at, identify, record_from_result
from gyro_fmu.model.measurement import UNKNOWNS
from gyro_fmu.model.parameters import GyroParameters
from gyro_fmu.system.inprocess import run_inprocess
from gyro_fmu.system.run import estimate_column
from gyro_fmu.system.scenario import absolute_noise, scenario

NOISE_LEVELS = (1e-6, 1e-5, 1e-4, 1e-3)
WINDOWS = (0.04, 0.08)
SHOWN = ("Omega_z", "kxx", "kyy", "kxy", "dxx", "dyy", "dxy", "m")


def one_seed(noise: float, seed: int, tuning: dict[str, float]) -> dict:
    sc = scenario("default", stop_time=max(WINDOWS), noise=noise, seed=seed, tuning=tuning)
    std = absolute_noise(sc)
    result = run_inprocess(sc, std)
    truth = {"Omega_z": 1.0, **sc.params.as_dict()}
    t = result["time"]
    out: dict = {}
    start = GyroParameters(**sc.initial_guess)
    for w in WINDOWS:
        k = int(np.argmin(np.abs(t - w)))
        obs_err = {n: result[estimate_column(n)][k] - truth[n] for n in UNKNOWNS}
        obs_sig = {n: result[f"observer.sigma_{n}"][k] for n in UNKNOWNS}
        # the observer at t_k has used samples 0..k-1 (its estimate at k is the prediction)
        rec = record_from_result(result, sc.measured_pair, stop_time=w)
        ident = identify(rec, start, sc.Omega_z_0, noise_std=(std.x, std.y))
        batch_err = ident.error(sc.params, 1.0)
        out[w] = {"obs_err": obs_err, "obs_sig": obs_sig, "batch_err": batch_err,
                  "batch_sig": ident.crb_sigma}
        out[w]["crb"] = crb_at(sc.params, 1.0, rec, (std.x, std.y))
    return out


def rms(values: list[float]) -> float:
    return float(np.sqrt(np.mean(np.square(values))))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=8)
    ap.add_argument("--first-seed", dest="first_seed", type=int, default=0)
    ap.add_argument("--noise", type=float, nargs="*", default=list(NOISE_LEVELS))
    ap.add_argument("--tuning", action="append", metavar="NAME=VALUE", default=[])
    args = ap.parse_args()
    tuning = {k: float(v) for k, v in (s.split("=", 1) for s in args.tuning)}
    print(f"observer efficiency: default scenario, {args.seeds} seeds, tuning overrides {tuning}")
    summary_rows = []
    for noise in args.noise:
        t0 = time.perf_counter()
        runs = [one_seed(noise, s, tuning)
                for s in range(args.first_seed, args.first_seed + args.seeds)]
        for w in WINDOWS:
            crb = runs[0][w]["crb"]
            obs_e = {n: rms([r[w]["obs_err"][n] for r in runs]) for n in SHOWN}
            obs_s = {n: rms([r[w]["obs_sig"][n] for r in runs]) for n in SHOWN}
            bat_e = {n: rms([r[w]["batch_err"][n] for r in runs]) for n in SHOWN}
            print(f"\n== noise {noise:g} of peak, window {w * 1e3:g} ms, {args.seeds} seeds "
                  f"({time.perf_counter() - t0:.0f} s) ==")
            print(f"{'':>18}" + "".join(f"{n:>10}" for n in SHOWN))
            for label, row in (("CRB 1-sigma", crb), ("observer RMS err", obs_e),
                               ("observer RMS sig", obs_s), ("batch RMS err", bat_e)):
                print(f"{label:>18}" + "".join(f"{row[n]:10.3g}" for n in SHOWN))
            for label, num, den in (("obs err / CRB", obs_e, crb), ("batch err / CRB", bat_e, crb),
                                    ("obs sig / CRB", obs_s, crb),
                                    ("obs err / obs sig", obs_e, obs_s)):
                print(f"{label:>18}" + "".join(
                    f"{num[n] / den[n] if den[n] > 0 else math.nan:10.2f}" for n in SHOWN))
            summary_rows.append((noise, w, obs_e["Omega_z"] / crb["Omega_z"],
                                 obs_e["dxy"] / crb["dxy"], bat_e["Omega_z"] / crb["Omega_z"],
                                 bat_e["dxy"] / crb["dxy"],
                                 obs_e["Omega_z"] / obs_s["Omega_z"], obs_e["dxy"] / obs_s["dxy"]))
    print("\n== summary: ratios to the CRB (target observer <= 2) and observer err/sigma ==")
    print(f"{'noise':>8} {'window':>7} {'obsOm/CRB':>10} {'obsDxy/CRB':>11} {'batOm/CRB':>10} "
          f"{'batDxy/CRB':>11} {'Om err/sig':>11} {'dxy err/sig':>12}")
    for row in summary_rows:
        print(f"{row[0]:8.0e} {row[1] * 1e3:5.0f}ms " + " ".join(
            f"{v:10.2f}" for v in row[2:]))


if __name__ == "__main__":
    main()
