"""Self-calibration on resonators that are not the preset, before and after issue 14's
points 1-3: loops designed for the resonator, alarms, record length for the target.

    python benchmarks/selfcal_design.py              # the three cases, ~10 min
    python benchmarks/selfcal_design.py --only 10k --seeds 2

"before" is the same computation with the preset's hand-made loops (4 kHz), a fixed
10 s record and the alarms' verdict ignored: the number the earlier code printed
(with exit 0). "after" is `gyro-fmu selfcal` today: loops from design.design, the
record chosen for the targets, the alarms acting. Each is compared with the
instrument's noise-free rate table under the same feed-forward correction.
"""

from __future__ import annotations

import argparse
import math
from dataclasses import replace

import numpy as np

from gyro_fmu.model.resonator import ResonatorParameters
from gyro_fmu.selfcal.alarms import CalibrationRefusedError
from gyro_fmu.selfcal.design import design
from gyro_fmu.selfcal.ratetable import rate_table
from gyro_fmu.selfcal.sequence import FeedForward, SelfCalConfig, self_calibrate

NOISE = 2.5e-4
CASES = {
    "10k": ("10 kHz, Q 1e5", dict(f_x=10000.0, f_y=10000.25, Q_x=1e5, Q_y=1e5)),
    "weak": ("12 kHz, forcers 5x weaker", dict(f_x=12000.0, f_y=12000.3, Bx=0.01, By=0.0096)),
    "lowq": ("Q 3000/2800, split 1 Hz", dict(Q_x=3000.0, Q_y=2800.0, f_y=4001.0)),
}


def calibrate(res: ResonatorParameters, cfg: SelfCalConfig) -> dict:
    try:
        r, verdict = self_calibrate(res, cfg), "calibrated"
    except CalibrationRefusedError as exc:
        r, verdict = exc.result, "REFUSED: " + exc.problems[0][:90]
    out = {"verdict": verdict}
    if r is not None:
        ff = FeedForward(r.feedthrough, r.rho, r.feedthrough * 0)
        table = rate_table(res.without_noise(), ff, cfg)
        out.update(d_bias=r.bias - table.bias, sigma_bias=r.sigma_bias,
                   d_sf=(r.scale_factor / table.scale_factor - 1) * 1e6,
                   sigma_sf=r.sigma_sf_ppm,
                   record=r.record, misfit=r.misfit_ratio, wall=r.wall_time)
    return out


def line(label: str, o: dict) -> str:
    if "d_bias" not in o:
        return f"  {label:<7} no number   {o['verdict']}"
    ok = abs(o["d_bias"]) < 7.27e-5 and abs(o["d_sf"]) < 100
    return (f"  {label:<7} bias-table {o['d_bias']:+.2e} ({o['sigma_bias']:.1e}) rad/s, "
            f"SF-table {o['d_sf']:+8.1f} ({o['sigma_sf']:5.1f}) ppm, record {o['record']:g} s, "
            f"misfit {o['misfit']:.2f}, {o['wall']:.0f} s  {'within' if ok else 'OUTSIDE'}"
            f"  {o['verdict']}")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--only", choices=tuple(CASES))
    ap.add_argument("--seeds", type=int, default=3)
    args = ap.parse_args()
    for key, (title, changes) in CASES.items():
        if args.only and key != args.only:
            continue
        res = replace(ResonatorParameters(noise=NOISE), **changes)
        print(f"\n## {title} (pick-off noise {NOISE} V)")
        errs = {"before": [], "after": []}
        for seed in range(1, args.seeds + 1):
            before = calibrate(res, SelfCalConfig(seed=seed, auto_record=False))
            after = calibrate(res, design(res, seed=seed))
            print(f" seed {seed}")
            print(line("before", before))
            print(line("after", after))
            for k, o in (("before", before), ("after", after)):
                if "d_bias" in o and not o["verdict"].startswith("REFUSED"):
                    errs[k].append((o["d_bias"] / o["sigma_bias"], o["d_sf"] / o["sigma_sf"]))
        for k, z in errs.items():
            if z:
                zb, zs = np.array(z).T
                print(f"  {k}: {len(z)} numbers given, RMS(error/sigma) bias "
                      f"{math.sqrt(np.mean(zb**2)):.2f}, SF {math.sqrt(np.mean(zs**2)):.2f}")


if __name__ == "__main__":
    main()
