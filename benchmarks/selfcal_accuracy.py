"""Self-calibration (US 9,482,553) against the rate table, measured one factor at a time.

    python benchmarks/selfcal_accuracy.py            # every study, ~3 min
    python benchmarks/selfcal_accuracy.py --seeds 3 --only headline
    python benchmarks/selfcal_accuracy.py --only uncertainty --sigma-seeds 16

Studies: headline (default preset, realistic noise, several seeds), whether the
reported 1-sigmas match the scatter over seeds, noise, record
length, model mismatch, earth rate, temperature-like drift. The rate table is run on
the same instrument with the same feed-forward correction; "truth" is the rate table
without noise (the instrument's bias and scale factor), and a noisy rate table with
2 s per rate is shown beside it as the conventional measurement.
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from gyro_fmu.model.resonator import EARTH_RATE, ResonatorParameters
from gyro_fmu.selfcal.alarms import CalibrationRefusedError
from gyro_fmu.selfcal.ratetable import rate_table
from gyro_fmu.selfcal.sequence import FeedForward, SelfCalConfig, self_calibrate

NOISE = 2.5e-4  #: V per pick-off sample: Allan deviation 13 deg/h at 1 s (rate_noise)
EARTH_LATITUDE = 42.36  #: deg (Cambridge, MA)
BIAS_TARGET = 7.27e-5
SF_TARGET_PPM = 100.0


def compare(res: ResonatorParameters, cfg: SelfCalConfig, noisy_table: bool = False) -> dict:
    t = time.perf_counter()
    try:
        sc, verdict = self_calibrate(res, cfg), ""
    except CalibrationRefusedError as exc:  # the number it would have given, marked
        if exc.result is None:
            raise
        sc, verdict = exc.result, "refused: " + exc.problems[0][:70]
    wall = time.perf_counter() - t
    ff = FeedForward(sc.feedthrough, sc.rho, sc.feedthrough * 0)
    truth = rate_table(replace(res, noise=0.0), ff, cfg)
    out = {
        "bias": sc.bias, "sigma_bias": sc.sigma_bias, "sf": sc.scale_factor,
        "sigma_sf_ppm": sc.sigma_scale_factor / sc.scale_factor * 1e6,
        "sigma_bias_rho": sc.sigma_bias_rho,
        "sigma_sf_rho_ppm": sc.sigma_scale_factor_rho / sc.scale_factor * 1e6,
        "rt_bias": truth.bias, "rt_sf": truth.scale_factor,
        "d_bias": sc.bias - truth.bias,
        "d_sf_ppm": (sc.scale_factor / truth.scale_factor - 1) * 1e6,
        "Omega_hat": sc.physical["Omega_z"], "sigma_Omega": sc.physical["sigma_Omega_z"],
        "wall": wall, "rms_residual": sc.rms_residual, "verdict": verdict,
    }
    if noisy_table:
        rt = rate_table(res, ff, cfg, dwell=2.5, average=2.0)
        out["nrt_d_bias"] = sc.bias - rt.bias
        out["nrt_d_sf_ppm"] = (sc.scale_factor / rt.scale_factor - 1) * 1e6
    return out


def row(label: str, r: dict) -> str:
    ok = abs(r["d_bias"]) < BIAS_TARGET and abs(r["d_sf_ppm"]) < SF_TARGET_PPM
    return (f"{label:<34} {r['d_bias']:+.2e} ({r['sigma_bias']:.1e})  "
            f"{r['d_sf_ppm']:+8.1f} ({r['sigma_sf_ppm']:6.1f})  {r['wall']:5.1f}  "
            f"{'yes' if ok else 'NO'}  {r.get('verdict', '')}")


HEADER = (f"{'case':<34} {'bias - table rad/s (1σ)':<24} {'SF - table ppm (1σ)':<20} "
          f"{'wall s':>6}  targets")


def headline(seeds: int) -> None:
    print(f"\n## Headline: default preset, every imperfection on, pick-off noise {NOISE} V")
    print(HEADER)
    rows = []
    for seed in range(1, seeds + 1):
        r = compare(replace(ResonatorParameters(), noise=NOISE), SelfCalConfig(seed=seed),
                    noisy_table=True)
        rows.append(r)
        print(row(f"seed {seed}", r), f"| vs noisy table: {r['nrt_d_bias']:+.2e} rad/s, "
              f"{r['nrt_d_sf_ppm']:+.1f} ppm")
    db = np.array([r["d_bias"] for r in rows])
    ds = np.array([r["d_sf_ppm"] for r in rows])
    print(f"RMS over {seeds} seeds: bias {np.sqrt(np.mean(db**2)):.2e} rad/s "
          f"(max {np.abs(db).max():.2e}), SF {np.sqrt(np.mean(ds**2)):.1f} ppm "
          f"(max {np.abs(ds).max():.1f}); table: bias {rows[0]['rt_bias']:.4e} rad/s, "
          f"SF {rows[0]['rt_sf']:.6f} V/(rad/s)")


def one_at_a_time() -> None:
    base = ResonatorParameters()
    print("\n## One factor at a time (seed 1)")
    print(HEADER)
    for noise in (0.0, 2.5e-4, 1e-3, 4e-3):
        print(row(f"noise {noise} V, record chosen", compare(replace(base, noise=noise),
                                                            SelfCalConfig())))
    for record in (5.0, 10.0, 20.0, 40.0):
        print(row(f"noise 1e-3 V, record {record:g} s",
                  compare(replace(base, noise=1e-3),
                          SelfCalConfig(record=record, auto_record=False))))
    print(row("no noise, settle 2 s (transients)",
              compare(base, SelfCalConfig(settle=2.0))))
    print(row("no noise, feed-through residual not fit",
              compare(base, SelfCalConfig(fit_feedthrough=False))))
    print(row("no noise, Bryant factor 1e-4 off",
              compare(base, SelfCalConfig(kappa=0.8 * (1 + 1e-4)))))
    print(row("no noise, cubic stiffness 0.01 Hz/um",
              compare(replace(base, k3x=4.2e15, k3y=4.2e15), SelfCalConfig())))
    print(row("no noise, 5 tones (0.2..1.0 Hz)",
              compare(base, SelfCalConfig(sideband_count=5))))
    slow = SelfCalConfig()
    slow = replace(slow, loops=replace(slow.loops, agc_bandwidth=0.5))
    print(row("no noise, AGC 0.5 Hz (table dwell 6 s)", compare(base, slow)))
    ff = FeedForward(np.zeros((2, 2)), 1.0, np.zeros((2, 2)))
    short = rate_table(base, ff, slow, dwell=1.0, average=0.5)
    settled = rate_table(base, ff, slow)
    off = (short.scale_factor / settled.scale_factor - 1) * 1e6
    print(f"   the same table with 1 s dwells: SF {off:+.1f} ppm, unsettled "
          f"{short.unsettled:.1e} rad/s (settled: {settled.unsettled:.1e})")


def earth_rate() -> None:
    earth = EARTH_RATE * math.sin(math.radians(EARTH_LATITUDE))
    print(f"\n## Earth rate {earth:.3e} rad/s (latitude {EARTH_LATITUDE} deg) during "
          "calibration; the table has none")
    print(HEADER)
    res = replace(ResonatorParameters(), noise=NOISE)
    r = compare(res, SelfCalConfig(Omega_z=earth))
    print(row("both modes, rate fitted", r),
          f"| Omega_hat {r['Omega_hat']:.3e} ± {r['sigma_Omega']:.1e} rad/s")
    r = compare(res, SelfCalConfig(Omega_z=earth, fixed_rate=0.0))
    print(row("both modes, rate assumed 0", r), "| earth rate taken for bias")


def drift() -> None:
    print("\n## Temperature-like drift: both modes +0.4 Hz, dampings +5 %")
    print(HEADER)
    base = replace(ResonatorParameters(), noise=NOISE)
    hot = base.drifted(0.4, 1.05)
    old = self_calibrate(base, SelfCalConfig())
    new = compare(hot, SelfCalConfig())
    ff = FeedForward(old.feedthrough, old.rho, old.feedthrough * 0)
    table = rate_table(replace(hot, noise=0.0), ff, SelfCalConfig())
    print(row("new calibration of the drifted gyro", new))
    stale = {"d_bias": old.bias - table.bias, "sigma_bias": old.sigma_bias,
             "d_sf_ppm": (old.scale_factor / table.scale_factor - 1) * 1e6,
             "sigma_sf_ppm": old.sigma_scale_factor / old.scale_factor * 1e6, "wall": 0.0}
    print(row("old calibration, drifted gyro", stale))
    table_old = rate_table(replace(base, noise=0.0), ff, SelfCalConfig())
    print(f"table bias moved {table.bias - table_old.bias:+.2e} rad/s, "
          f"SF {(table.scale_factor / table_old.scale_factor - 1) * 1e6:+.1f} ppm")


def rate_noise(noise: float = NOISE, duration: float = 80.0,
               figure: Path | None = Path("runs/selfcal_accuracy/allan.png")) -> None:
    """Allan deviation of the normal (mode 1) read-out for white pick-off noise."""
    from gyro_fmu.model.loops import LoopSettings
    from gyro_fmu.selfcal.inprocess import CarrierSimulation
    from gyro_fmu.studies.allan import allan_deviation

    print(f"\n## Rate noise of the read-out: Allan deviation, pick-off noise {noise} V "
          f"per sample, {duration:g} s record")
    sim = CarrierSimulation(replace(ResonatorParameters(), noise=noise), LoopSettings(mode=1),
                            seed=7)
    rec = sim.run(duration + 2.0, record_from=2.0)
    sf = rate_table(ResonatorParameters(), FeedForward(np.zeros((2, 2)), 1.0,
                                                       np.zeros((2, 2)))).scale_factor
    rate = rec["rate"][:-1] / sf
    taus = np.logspace(math.log10(sim.step * 4), math.log10(duration / 4), 25)
    adev = allan_deviation(rate, sim.step, taus)
    slopes = np.gradient(np.log(adev), np.log(taus))
    print(f"{'tau s':>10} {'sigma rad/s':>12} {'deg/h':>10} {'slope':>6}")
    for tau, a, k in list(zip(taus, adev, slopes, strict=True))[::3]:
        print(f"{tau:10.4g} {a:12.3e} {math.degrees(a) * 3600:10.2f} {k:6.2f}")
    if figure is not None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        figure.parent.mkdir(parents=True, exist_ok=True)
        fig, ax = plt.subplots(figsize=(6, 4))
        ax.loglog(taus, np.degrees(adev) * 3600, "o-", ms=3, label="rate read-out, mode 1")
        ax.set_xlabel("averaging time tau (s)")
        ax.set_ylabel("Allan deviation (deg/h)")
        ax.set_title(f"white pick-off noise {noise} V per 25 us sample")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
        fig.tight_layout()
        fig.savefig(figure, dpi=120)
        plt.close(fig)
        print(f"figure: {figure}")


def uncertainty(seeds: int) -> None:
    """Are the reported 1-sigmas right? RMS of error / sigma over seeds should be 1."""
    print(f"\n## Reported 1-sigma against the scatter over {seeds} seeds (noise {NOISE} V)")
    print(f"{'seed':<6} {'bias - table (1σ, of it rho)':<36} {'SF - table ppm (1σ, of it rho)'}")
    rows = []
    for seed in range(1, seeds + 1):
        r = compare(replace(ResonatorParameters(), noise=NOISE), SelfCalConfig(seed=seed))
        rows.append(r)
        print(f"{seed:<6} {r['d_bias']:+.2e} ({r['sigma_bias']:.1e}, {r['sigma_bias_rho']:.1e})"
              f"       {r['d_sf_ppm']:+7.1f} ({r['sigma_sf_ppm']:5.1f}, "
              f"{r['sigma_sf_rho_ppm']:4.1f})")

    def rms(values) -> float:
        return float(np.sqrt(np.mean(np.square(values))))

    for what, d, s_total, s_rho in (("bias", "d_bias", "sigma_bias", "sigma_bias_rho"),
                                    ("SF", "d_sf_ppm", "sigma_sf_ppm", "sigma_sf_rho_ppm")):
        err = np.array([r[d] for r in rows])
        total = np.array([r[s_total] for r in rows])
        fit_only = np.sqrt(np.maximum(total**2 - np.array([r[s_rho] for r in rows])**2, 0.0))
        print(f"{what}: error RMS {rms(err):.2e} (max {np.abs(err).max():.2e}); "
              f"RMS(error / 1-sigma) {rms(err / total):.2f} with rho's part, "
              f"{rms(err / fit_only):.2f} with the fit's alone (1.00 +- "
              f"{1 / math.sqrt(2 * seeds):.2f} expected)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--sigma-seeds", type=int, default=16)
    ap.add_argument("--only", choices=("noise", "headline", "uncertainty", "factors", "earth",
                                       "drift"))
    a = ap.parse_args()
    studies = {"noise": rate_noise, "headline": lambda: headline(a.seeds),
               "uncertainty": lambda: uncertainty(a.sigma_seeds),
               "factors": one_at_a_time,
               "earth": earth_rate, "drift": drift}
    for name, fn in studies.items():
        if a.only in (None, name):
            fn()


if __name__ == "__main__":
    main()
