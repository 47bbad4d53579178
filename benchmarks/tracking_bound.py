"""Tracking: the observer's Omega_z error against the posterior Cramér-Rao bound.

Default gyro (gyro_fmu.system.scenario.scenario("default"): park-horowitz, two-tone drive
4000 + 1200 Hz, positions measured every 5 us), noise 1e-5 and 1e-4 of each signal's own
peak (scenario.absolute_noise), rates

    constant 1 rad/s;  1 + 0.5 sin(2 pi 10 t);  sin(2 pi 100 t) (the patent's Table 1 case)

and, with --random, a first-order Gauss-Markov rate (std 0.5 rad/s, 10 Hz, mean 1 rad/s;
sampled every --knot-step steps and held; a new trajectory per seed).

For each case:
  bound     RMS over the window (default 80-100 ms) of the PCRB 1-sigma of Omega_z(t_k)
            (gyro_fmu.estimation.tracking_bound: constant or sine of known frequency with
            unknown offset, amplitude, phase; the observer's priors; Monte Carlo D-terms
            for the random rate);
  obs err   RMS over the window and the seeds of Omega_hat(t_k) - Omega_z(t_k), the
            observer run in-process (own loop over GyroPlantModel + GyroStateObserver, as
            gyro_fmu.system.inprocess.run_inprocess runs them, with a given rate tuning);
  obs sig   RMS of the observer's own 1-sigma of Omega_z over the same samples;
  err/bound the efficiency (>= 1 up to Monte Carlo spread; 1 is efficient), +- its
            standard error from the seed-to-seed spread (an error that is nearly constant
            over the window is one sample per seed);
  lost      seeds where the observer declared itself lost (left out of obs err).

Tunings: "user" = ObserverTuning() defaults with the noise std told (sigma_z1, sigma_z2),
plus the --tuning NAME=VALUE overrides; "fmu" = ObserverTuning() defaults plus the
overrides, the noise not told (estimated from the innovations since the adaptive rate
model; exactly what an FMU user gets); for constant rates also "scenario" =
gyro_fmu.system.scenario.observer_tuning (the constant-rate model, noise told).

    python benchmarks/tracking_bound.py [--seeds 32] [--noise 1e-5 1e-4] [--tuning q_Omega=1e8]
                                        [--random]
"""

from __future__ import annotations

import os

# one BLAS thread: the information matrices are small (<= a few hundred columns), and on a
# shared machine OpenBLAS's threads made the Gauss-Markov bound 7x slower (23 s vs 3 s)
for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import math  # noqa: E402
import time  # noqa: E402
from dataclasses import fields  # noqa: E402

import numpy as np  # noqa: E402

from gyro_fmu.estimation.observer import (  # noqa: E402
    GyroStateObserver,
    ObserverDivergedError,
    ObserverTuning,
)
from gyro_fmu.estimation.rate_processes import gauss_markov_rate  # noqa: E402
from gyro_fmu.model.parameters import GyroParameters  # noqa: E402
from gyro_fmu.model.plant import GyroPlantModel  # noqa: E402
from gyro_fmu.model.rate import RateProfile  # noqa: E402
from gyro_fmu.system.scenario import absolute_noise, observer_tuning, scenario  # noqa: E402
from gyro_fmu.system.tracking import tracking_bound_for_scenario  # noqa: E402

RATES = ("constant:1", "sine:0.5:10:1", "sine:1:100")
NOISE_LEVELS = (1e-5, 1e-4)


def parse_tuning(items: list[str]) -> dict[str, float]:
    names = {f.name: f.type for f in fields(ObserverTuning)}
    out: dict[str, float] = {}
    for item in items:
        k, _, v = item.partition("=")
        if k not in names:
            raise SystemExit(f"--tuning {item!r}: ObserverTuning has no field {k!r} "
                             f"(fields: {', '.join(names)})")
        out[k] = int(float(v)) if names[k] in ("int", "bool") else float(v)
    return out


def run_observer(sc, tuning: ObserverTuning, omega: np.ndarray, window: tuple[float, float]
                 ) -> tuple[np.ndarray, np.ndarray] | None:
    """(errors, sigmas) of Omega_hat over the window; None if the observer was lost.

    The loop of run_inprocess, with the rate taken from omega[k] (held over step k).
    """
    noise = absolute_noise(sc)
    plant = GyroPlantModel(sc.params, noise, sc.seed)
    obs = GyroStateObserver(GyroParameters(**sc.initial_guess), sc.Omega_z_0,
                            sc.measured_pair, tuning)
    drive, h = sc.the_drive, sc.step
    pair = (0, 2) if sc.measured_pair == 1 else (1, 3)
    k0, k1 = round(window[0] / h), round(window[1] / h)
    err, sig = [], []
    try:
        for k in range(sc.n_steps + 1):
            if k >= k0:
                row = obs.output_row()
                err.append(row[4] - omega[k])  # Omega_hat at t_k (used z_0 .. z_{k-1})
                sig.append(row[12])
            if k == min(k1, sc.n_steps):
                break
            ux = drive.ux(k * h)
            z = plant.measured()
            plant.step(ux, 0.0, float(omega[k]), h)
            obs.step(ux, 0.0, z[pair[0]], z[pair[1]], h)
    except ObserverDivergedError:
        return None
    return np.array(err), np.array(sig)


def rms(a) -> float:
    a = np.asarray(a, float)
    return float(np.sqrt(np.mean(a**2))) if a.size else math.nan


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=32)
    ap.add_argument("--noise", type=float, nargs="*", default=list(NOISE_LEVELS))
    ap.add_argument("--rates", nargs="*", default=list(RATES),
                    help="RateProfile.parse texts (constant:OFFSET, sine:AMP:FREQ[:OFFSET])")
    ap.add_argument("--window", type=float, nargs=2, default=(0.08, 0.1), metavar=("FROM", "TO"))
    ap.add_argument("--tuning", action="append", metavar="NAME=VALUE", default=[])
    ap.add_argument("--random", action="store_true",
                    help="add a Gauss-Markov rate (std 0.5 rad/s, 10 Hz, mean 1 rad/s)")
    ap.add_argument("--draws", type=int, default=8, help="Monte Carlo draws of a random rate")
    ap.add_argument("--knot-step", dest="knot_step", type=int, default=100,
                    help="the random rate is sampled every KNOT_STEP steps and held")
    args = ap.parse_args()
    overrides = parse_tuning(args.tuning)
    window = tuple(args.window)
    stop = window[1]
    print(f"tracking bound vs observer: default gyro, {args.seeds} seeds, window "
          f"{window[0] * 1e3:g}-{window[1] * 1e3:g} ms, tuning overrides {overrides}")
    print(f"ObserverTuning() defaults: {ObserverTuning()}")
    head = (f"{'rate':>22} {'noise':>6} {'tuning':>9} {'bound':>10} {'obs err':>10} "
            f"{'obs sig':>10} {'err/bound':>9} {'+-':>5} {'sig/bound':>9} {'lost':>4} {'s':>4}")
    print("\n" + head)
    cases: list[tuple[str, RateProfile | None]] = [(r, RateProfile.parse(r)) for r in args.rates]
    if args.random:
        cases.append((f"GM 0.5 rad/s 10 Hz /{args.knot_step}", None))
    for label, profile in cases:
        for noise in args.noise:
            t0 = time.perf_counter()
            sc = scenario("default", stop_time=stop, noise=noise,
                          rate=profile if profile is not None else RateProfile(offset=1.0))
            std = absolute_noise(sc)
            user = ObserverTuning(**{"sigma_z1": std.x, "sigma_z2": std.y, **overrides})
            t_eval = np.arange(round(window[0] / sc.step), sc.n_steps + 1, 10) * sc.step
            rate_model = None
            if profile is None:
                rate_model = gauss_markov_rate(sc.step, sc.n_steps, 0.5, 10.0, mean=1.0,
                                               knot_step=args.knot_step)
            bound = tracking_bound_for_scenario(sc, user, rate=rate_model, t_eval=t_eval,
                                                n_draws=args.draws)
            b = bound.rms_sigma(*window)
            tunings = [("user", user), ("fmu", ObserverTuning(**overrides))]
            if profile is not None and profile.kind.name == "constant":
                tunings.append(("scenario", ObserverTuning(**observer_tuning(sc, std))))
            for tname, tun in tunings:
                rng = np.random.default_rng(12345)  # the same rate draws for every tuning
                errs, sigs, lost = [], [], 0
                for seed in range(args.seeds):
                    s = sc.with_(seed=seed)
                    if rate_model is None:
                        omega = np.array([profile.Omega_z(k * sc.step)
                                          for k in range(sc.n_steps + 1)])
                    else:
                        omega = rate_model.trajectory(rate_model.draw(rng))
                    out = run_observer(s, tun, omega, window)
                    if out is None:
                        lost += 1
                        continue
                    errs.append(out[0])
                    sigs.append(out[1])
                e = rms(np.concatenate(errs)) if errs else math.nan
                sg = rms(np.concatenate(sigs)) if sigs else math.nan
                # standard error of e from the seed-to-seed spread of the mean squares
                ms = np.array([np.mean(x**2) for x in errs])
                se = (float(np.std(ms) / (2.0 * np.sqrt(ms.size) * np.mean(ms)))
                      if ms.size > 1 else math.nan)
                print(f"{label:>22} {noise:6.0e} {tname:>9} {b:10.3g} {e:10.3g} {sg:10.3g} "
                      f"{e / b:9.2f} {se * e / b:5.2f} {sg / b:9.2f} {lost:4d} "
                      f"{time.perf_counter() - t0:4.0f}", flush=True)


if __name__ == "__main__":
    main()
