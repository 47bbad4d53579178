"""What the resonator's added physics does to the self-calibration (issue 14, points 4-6).

    python benchmarks/selfcal_imperfections.py                 # every case, ~4 min
    python benchmarks/selfcal_imperfections.py --only arw
    python benchmarks/selfcal_imperfections.py --only table --seeds 2

For each imperfection, on the default preset (4 kHz, Q 2e4) and on a resonator that is
not the preset (6 kHz, Q 5e4, loops retuned by hand: f_nominal, q_nominal, plant_gain):
the self-calibration's bias and scale factor against the rate table of the same
instrument (same imperfections, the same feed-forward correction, the noise terms off
for the table, as `gyro-fmu selfcal --compare-ratetable` does). Pick-off noise is off
throughout, so each row shows one term alone.

- (a) pick-off non-orthogonality beta_x = 1 and 5 mrad; a pure rotation of both
  pick-offs (beta_x = -beta_y) beside it;
- (b) cross-cubic stiffness k3xy = k3yx = k with 3 k a^2 / (8 omega) = 0.01 Hz at the
  1 um operating amplitude (the shift the same k would give as a Duffing term);
- (c) thermomechanical force noise, 300 K, modal mass 1e-9 kg (several seeds);
- (d) white noise on the drive voltages (several seeds);
- (e) a temperature ramp of 0.01 K/s, tc_f = -30e-6 /K (and tc_Q = -1e-3 /K): the
  ramp runs on through the whole sequence (each run starts where the previous ended);
  the table is static at the temperature of the middle of the calibration, and the
  table's own change between the start and the end temperature is shown.

`arw`: the closed-loop rate output with force noise only, its Allan deviation (slope
-1/2) against the thermomechanical ARW of a rebalanced gyro,
N = sqrt(k_B T dyy / m) / (kappa omega a) (docs/resonator-physics.md), and the same for
drive noise, N = By sigma sqrt(2 h) / (2 kappa omega a).
"""

from __future__ import annotations

import argparse
import math
import subprocess
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from gyro_fmu.model.loops import LoopSettings
from gyro_fmu.model.resonator import K_B, ResonatorParameters
from gyro_fmu.selfcal.inprocess import CarrierSimulation
from gyro_fmu.selfcal.ratetable import rate_table
from gyro_fmu.selfcal.sequence import (
    FeedForward,
    SelfCalConfig,
    estimate,
    measure_feedforward,
    record_mode,
)
from gyro_fmu.studies.allan import allan_deviation

BIAS_TARGET = 7.27e-5
SF_TARGET_PPM = 100.0
AMPLITUDE = 1e-6  #: m, operating amplitude (1 V pick-off setpoint / Px 1e6 V/m)
NOISE_OFF = {"noise": 0.0, "m_modal": 0.0, "drive_noise": 0.0}


def resonators() -> dict[str, tuple[ResonatorParameters, SelfCalConfig]]:
    preset = ResonatorParameters()
    other = replace(preset, f_x=6000.0, f_y=6000.25, Q_x=5e4, Q_y=4.8e4)
    w = 2 * math.pi * other.f_x
    loops = LoopSettings(f_nominal=6000.0, q_nominal=5e4,
                         plant_gain=other.Px * other.Bx / (2 * w))
    return {"4 kHz Q 2e4 (preset)": (preset, SelfCalConfig()),
            "6 kHz Q 5e4": (other, SelfCalConfig(loops=loops, settle=15.0))}


def cubic_for_shift(res: ResonatorParameters, shift_hz: float) -> float:
    """k (1/(m^2 s^2)) with 3 k a^2 / (8 omega) = 2 pi shift_hz at a = AMPLITUDE."""
    return 2 * math.pi * shift_hz * 8 * res.omega_x / (3 * AMPLITUDE**2)


def warmed(res: ResonatorParameters, dT: float) -> ResonatorParameters:
    """The same instrument dT kelvin later: start values moved by tc_f, tc_Q."""
    if dT == 0.0:
        return res
    sf, sq = 1 + res.tc_f * dT, 1 + res.tc_Q * dT
    return replace(res, f_x=res.f_x * sf, f_y=res.f_y * sf, Q_x=res.Q_x * sq,
                   Q_y=res.Q_y * sq, temperature=res.temperature + dT)


def calibrate(res: ResonatorParameters, cfg: SelfCalConfig, restart: bool = False):
    """self_calibrate's sequence, the temperature ramp running on across its runs (or,
    restart, each run from the start temperature, as self_calibrate runs them)."""
    start = time.perf_counter()
    rate, t = (0.0 if restart else res.temperature_rate), 0.0
    ff = measure_feedforward(res, cfg)
    t += cfg.ff_duration + 0.1
    data = []
    for mode in cfg.modes:
        data.append(record_mode(warmed(res, rate * t), cfg, mode, ff)[0])
        t += cfg.settle + cfg.record
    return estimate(data, ff, cfg, start), t


def compare(res: ResonatorParameters, cfg: SelfCalConfig, restart: bool = False) -> dict:
    try:
        sc, duration = calibrate(res, cfg, restart)
    except Exception as exc:  # a refusal or failure is a row, not the end of the table
        return {"error": f"{type(exc).__name__}: {str(exc)[:150]}"}
    ff = FeedForward(sc.feedthrough, sc.rho, sc.feedthrough * 0)
    static = replace(res, **NOISE_OFF, temperature_rate=0.0)
    ramp = res.temperature_rate * (cfg.settle + cfg.record if restart else duration)
    table = rate_table(warmed(static, ramp / 2), ff, cfg)
    out = {"bias": sc.bias, "sf": sc.scale_factor, "rt_bias": table.bias,
           "rt_sf": table.scale_factor, "d_bias": sc.bias - table.bias,
           "d_sf_ppm": (sc.scale_factor / table.scale_factor - 1) * 1e6,
           "sigma_bias": sc.sigma_bias,
           "sigma_sf_ppm": sc.sigma_scale_factor / sc.scale_factor * 1e6,
           "rms_residual": sc.rms_residual, "wall": sc.wall_time}
    if ramp:
        t0, t1 = (rate_table(warmed(static, d), ff, cfg) for d in (0.0, ramp))
        out["table_drift"] = (t1.bias - t0.bias, (t1.scale_factor / t0.scale_factor - 1) * 1e6,
                              ramp)
    return out


def row(label: str, r: dict) -> str:
    if "error" in r:
        return f"  {label:<40} {r['error']}"
    ok = abs(r["d_bias"]) < BIAS_TARGET and abs(r["d_sf_ppm"]) < SF_TARGET_PPM
    text = (f"  {label:<40} {r['bias']:+.4e} {r['rt_bias']:+.4e} {r['d_bias']:+.2e} "
            f"({r['sigma_bias']:.1e}) {r['d_sf_ppm']:+9.1f} ({r['sigma_sf_ppm']:5.1f}) "
            f"{r['rms_residual']:.1e} {'yes' if ok else 'NO '}")
    if "table_drift" in r:
        db, dsf, dT = r["table_drift"]
        text += f"  [table itself over {dT:.2f} K: {db:+.1e} rad/s, {dsf:+.1f} ppm]"
    return text


HEADER = (f"  {'case':<40} {'bias rad/s':<11} {'table':<11} {'bias-table':<9} (1σ)     "
          f"{'SF-table ppm':>9} (1σ)   misfit V targets")


def cases(res: ResonatorParameters, seeds: int) -> list[tuple[str, list[ResonatorParameters]]]:
    k = cubic_for_shift(res, 0.01)
    return [
        ("baseline (new terms off)", [res]),
        ("(a) beta_x = 1 mrad", [replace(res, beta_x=1e-3)]),
        ("(a) beta_x = 5 mrad", [replace(res, beta_x=5e-3)]),
        ("(a) beta_x = beta_y = 1 mrad", [replace(res, beta_x=1e-3, beta_y=1e-3)]),
        ("(a) rotation beta_x = -beta_y = 5 mrad", [replace(res, beta_x=5e-3, beta_y=-5e-3)]),
        (f"(b) k3xy = k3yx = {k:.2e} (0.01 Hz)", [replace(res, k3xy=k, k3yx=k)]),
        ("(b) k3yx alone (0.01 Hz)", [replace(res, k3yx=k)]),
        ("(b) k3xy = k3yx (0.001 Hz)", [replace(res, k3xy=k / 10, k3yx=k / 10)]),
        ("(c) force noise 300 K, 1e-9 kg", [replace(res, m_modal=1e-9)] * seeds),
        ("(d) drive noise 1e-3 V/sample", [replace(res, drive_noise=1e-3)] * seeds),
        ("(d) drive noise 1e-2 V/sample", [replace(res, drive_noise=1e-2)] * seeds),
        ("(e) ramp 0.01 K/s, tc_f -30e-6", [replace(res, temperature_rate=0.01, tc_f=-30e-6)]),
        ("(e) ramp 0.01 K/s, tc_f -30e-6, tc_Q -1e-3",
         [replace(res, temperature_rate=0.01, tc_f=-30e-6, tc_Q=-1e-3)]),
        ("(e) ramp 0.001 K/s, tc_f -30e-6", [replace(res, temperature_rate=1e-3, tc_f=-30e-6)]),
        ("(e) 0.01 K/s, each run restarting at T0",
         [replace(res, temperature_rate=0.01, tc_f=-30e-6)]),
    ]


def table(seeds: int) -> None:
    for name, (res, cfg) in resonators().items():
        print(f"\n## {name}: self-calibration vs the rate table (pick-off noise off)")
        print(HEADER)
        for label, variants in cases(res, seeds):
            rows = []
            for seed, r in enumerate(variants, start=1):
                rows.append(compare(r, replace(cfg, seed=seed), "restarting" in label))
                tag = f"{label}, seed {seed}" if len(variants) > 1 else label
                print(row(tag, rows[-1]), flush=True)
            good = [x for x in rows if "error" not in x]
            if len(good) > 1:
                rb = math.sqrt(np.mean([x["d_bias"] ** 2 for x in good]))
                rs = math.sqrt(np.mean([x["d_sf_ppm"] ** 2 for x in good]))
                zb = math.sqrt(np.mean([(x["d_bias"] / x["sigma_bias"]) ** 2 for x in good]))
                print(f"  {'':<40} RMS over {len(good)} seeds: {rb:.2e} rad/s, {rs:.1f} ppm; "
                      f"RMS(error/σ) bias {zb:.1f}")


def arw(duration: float = 120.0) -> None:
    print(f"\n## Angle random walk: closed-loop rate output, {duration:g} s, mode 1, "
          "no pick-off noise, Omega = 0")
    print(f"  {'case':<34} {'ADEV(1 s)':>10} {'ADEV(10 s)':>10} {'slope 0.1-10 s':>14} "
          f"{'ARW theory':>11} {'ratio':>6}  (rad/s, rad/sqrt(s))")
    base, cfg = resonators()["4 kHz Q 2e4 (preset)"]
    ff = measure_feedforward(base, cfg)
    quiet = rate_table(base, ff, cfg)
    lo = replace(cfg.loops, mode=1, ff_xx=ff.E[0, 0], ff_xy=ff.E[0, 1], ff_yx=ff.E[1, 0],
                 ff_yy=ff.E[1, 1])
    kwa = base.kappa * base.omega_x * AMPLITUDE
    h = cfg.step
    for label, res, theory in (
        ("force noise 300 K, 1e-9 kg", replace(base, m_modal=1e-9),
         math.sqrt(K_B * 300.0 * base.dyy / 1e-9) / kwa),
        ("force noise 300 K, 1e-8 kg", replace(base, m_modal=1e-8),
         math.sqrt(K_B * 300.0 * base.dyy / 1e-8) / kwa),
        ("drive noise 1e-2 V/sample", replace(base, drive_noise=1e-2),
         base.By * 1e-2 * math.sqrt(2 * h) / (2 * kwa)),
    ):
        sim = CarrierSimulation(res, lo, seed=4, step=h)
        sim.run(3.0)
        chunks = [sim.run(10.0, record_from=sim.k * h)["rate"][:-1].copy()
                  for _ in range(round(duration / 10))]
        rate = np.concatenate(chunks) / quiet.scale_factor - quiet.bias
        taus = np.array([0.1, 1.0, 10.0])
        adev = allan_deviation(rate, h, taus)
        slope = math.log(adev[2] / adev[0]) / math.log(100.0)
        print(f"  {label:<34} {adev[1]:10.3e} {adev[2]:10.3e} {slope:14.2f} {theory:11.3e} "
              f"{adev[1] / theory:6.2f}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--only", choices=("table", "arw"))
    ap.add_argument("--seeds", type=int, default=3, help="seeds of the noise cases")
    args = ap.parse_args()
    root = Path(__file__).resolve().parents[1]
    commit = subprocess.run(["git", "-C", str(root), "log", "-1", "--format=%h %s"],
                            capture_output=True, text=True).stdout.strip()[:90]
    dirty = subprocess.run(["git", "-C", str(root), "status", "--short", "--untracked-files=no"],
                           capture_output=True, text=True).stdout.strip()
    print(f"# selfcal imperfections, at {commit or '(no git)'}"
          f"{' + uncommitted changes' if dirty else ''}")
    start = time.perf_counter()
    if args.only in (None, "table"):
        table(args.seeds)
    if args.only in (None, "arw"):
        arw()
    print(f"\n# {time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    main()
