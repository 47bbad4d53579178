"""A lot of resonators, each self-calibrated and checked against its own rate table.

`LotModel.draw(n)` draws n resonators: for each a *design* (the nominal values an
engineer knows: frequency log-uniform 3-15 kHz, Q log-uniform 5e3-2e5, forcer gain
growing as f^2 so the same voltages hold 1 V of pick-off) and the *instrument*
built from it (frequency and Q off the design, mode split, Q mismatch, cross damping
and stiffness, forcer misalignments, pick-off gain, phase and non-orthogonality,
feed-through, cubic and cross-cubic stiffness (either sign), pick-off noise of a
given density; optionally a warm-up and thermomechanical force noise). The loops and
the step are designed from the nominal (design.design); the instrument is calibrated
(sequence.self_calibrate) and its noise-free rate table taken with the same
feed-forward (ratetable.rate_table), as `gyro-fmu selfcal --compare-ratetable` does.

Every resonator is one row: `good` (calibrated, within the targets of the table),
`refused` (an alarm stopped it: its reasons; the untrusted answer and the table
beside it when one was computed), `WRONG` (calibrated, exit 0, outside the targets:
what must never happen) or `failed` (an error, named). The runs are Dask tasks
(studies.tasks.run_tasks).
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from ..errors import GyroFmuError
from ..model.resonator import EARTH_RATE, ResonatorParameters
from ..outputs import csv_writer, save_figure, write_table_and_summary
from .alarms import CalibrationRefusedError
from .design import design

#: |bias - table| and |SF - table| a good calibration must reach.
BIAS_TOLERANCE = 7.27e-5  #: rad/s (earth rate)
SF_TOLERANCE_PPM = 100.0


@dataclass(frozen=True)
class LotModel:
    """Tolerances of a lot (1-sigma of normals, half-widths of uniforms)."""

    f_min: float = 3.0e3  #: Hz, design frequency, log-uniform
    f_max: float = 15.0e3  #: Hz
    Q_min: float = 5.0e3  #: design Q, log-uniform
    Q_max: float = 2.0e5
    f_offset: float = 1.0e-3  #: relative, instrument frequency off the design (uniform)
    Q_offset: float = 0.2  #: relative, instrument Q off the design (uniform)
    split_max: float = 1.0  #: Hz, mode split f_y - f_x, uniform in [-max, max]
    #: fraction of the lot whose modes are matched exactly (f_y = f_x; drawn apart, so
    #: the rest of the lot stays the same resonators)
    split_zero: float = 0.0
    Q_mismatch: float = 0.1  #: relative, Q_y off Q_x (uniform)
    bias_rate: float = 2.0e-3  #: rad/s, 1-sigma of dxy / (2 kappa)
    quadrature_rate: float = 0.2  #: rad/s, 1-sigma of kxy / (2 kappa omega)
    misalignment: float = 2.0e-3  #: rad, 1-sigma of alpha_x, alpha_y
    forcer_gain: float = 0.1  #: relative 1-sigma of Bx, By around 0.05 (f / 4 kHz)^2
    pickoff_gain: float = 0.03  #: relative 1-sigma of Py / Px - 1
    pickoff_phase: float = 0.01  #: rad, phi_x, phi_y uniform in 0.01 +- this
    pickoff_angle: float = 2.0e-3  #: rad, 1-sigma of beta_x, beta_y (non-orthogonality)
    feedthrough: float = 2.0e-3  #: V/V, each entry uniform in [0, this]
    cubic_shift_max: float = 1.0e-2  #: Hz at 1 um, k3x, k3y log-uniform from 1/100 of it
    cross_cubic_shift_max: float = 1.0e-3  #: Hz at 1 um, k3xy, k3yx the same way
    noise_density: float = 1.25e-6  #: V/sqrt(Hz), white pick-off noise
    #: K/s, warm-up through the whole calibration sequence, uniform in [0, this] (drawn
    #: apart from the rest: a lot with and without a warm-up holds the same resonators)
    ramp_max: float = 0.0
    tc_f_min: float = -40e-6  #: 1/K, tc_f uniform in [tc_f_min, tc_f_max] (with a ramp)
    tc_f_max: float = -20e-6
    #: kg, modal mass of the thermomechanical force noise at 300 K, log-uniform in
    #: [m_modal_min, m_modal_max] (0: none; drawn apart, like the warm-up)
    m_modal_min: float = 0.0
    m_modal_max: float = 0.0
    seed: int = 2026

    def draw(self, n: int) -> list[dict[str, dict[str, float]]]:
        """n {"nominal": ResonatorParameters fields, "instrument": ...} pairs."""
        rng = np.random.default_rng(self.seed)
        thermal = np.random.default_rng([self.seed, 1])
        brownian = np.random.default_rng([self.seed, 2])
        matched = np.random.default_rng([self.seed, 3])
        out = []
        for _ in range(n):
            f = math.exp(rng.uniform(math.log(self.f_min), math.log(self.f_max)))
            q = math.exp(rng.uniform(math.log(self.Q_min), math.log(self.Q_max)))
            b = 0.05 * (f / 4.0e3) ** 2
            nominal = {"f_x": f, "f_y": f, "Q_x": q, "Q_y": q, "Bx": b, "By": b,
                       "dxy": 0.0, "kxy": 0.0}
            fx = f * (1 + rng.uniform(-self.f_offset, self.f_offset))
            fy = fx + rng.uniform(-self.split_max, self.split_max)
            qx = q * (1 + rng.uniform(-self.Q_offset, self.Q_offset))
            w = 2 * math.pi * fx
            kappa = ResonatorParameters.kappa
            shift = [top * rng.choice((-1.0, 1.0)) * math.exp(rng.uniform(math.log(1e-2), 0.0))
                     for top in (self.cubic_shift_max, self.cubic_shift_max,
                                 self.cross_cubic_shift_max, self.cross_cubic_shift_max)]
            step = 1.0 / (10 * round(f))
            instrument = {
                "f_x": fx, "f_y": fy, "Q_x": qx,
                "Q_y": qx * (1 + rng.uniform(-self.Q_mismatch, self.Q_mismatch)),
                "dxy": 2 * kappa * rng.normal(0.0, self.bias_rate),
                "kxy": 2 * kappa * w * rng.normal(0.0, self.quadrature_rate),
                "Bx": b * (1 + rng.normal(0.0, self.forcer_gain)),
                "By": b * (1 + rng.normal(0.0, self.forcer_gain)),
                "alpha_x": rng.normal(0.0, self.misalignment),
                "alpha_y": rng.normal(0.0, self.misalignment),
                "Py": 1.0e6 * (1 + rng.normal(0.0, self.pickoff_gain)),
                "phi_x": 0.01 + rng.uniform(-self.pickoff_phase, self.pickoff_phase),
                "phi_y": 0.01 + rng.uniform(-self.pickoff_phase, self.pickoff_phase),
                "beta_x": rng.normal(0.0, self.pickoff_angle),
                "beta_y": rng.normal(0.0, self.pickoff_angle),
                **{k: rng.uniform(0.0, self.feedthrough) for k in ("Exx", "Exy", "Eyx", "Eyy")},
                # amplitude-frequency shift 3 k3 a^2 / (8 omega) rad/s at a = 1 um
                **{k: 8 * w * 2 * math.pi * v / 3 / 1e-12
                   for k, v in zip(("k3x", "k3y", "k3xy", "k3yx"), shift, strict=True)},
                "noise": self.noise_density * math.sqrt(0.5 / step),
                # one Strang splitting per step (2 linear half-steps around the kick):
                # the cubic force is small and 10 samples per cycle resolve it
                "cubic_substeps": 1,
            }
            ramp, tc_f = thermal.uniform(0.0, 1.0), thermal.uniform(self.tc_f_min,
                                                                     self.tc_f_max)
            if self.ramp_max > 0.0:
                instrument.update(temperature_rate=ramp * self.ramp_max, tc_f=tc_f)
            mass = brownian.uniform(0.0, 1.0)
            if self.m_modal_max > 0.0:
                low, high = math.log(self.m_modal_min or self.m_modal_max), \
                    math.log(self.m_modal_max)
                instrument.update(m_modal=math.exp(low + mass * (high - low)))
            if matched.uniform(0.0, 1.0) < self.split_zero:
                instrument["f_y"] = instrument["f_x"]
            instrument["phi_x"] = max(instrument["phi_x"], 0.0)
            instrument["phi_y"] = max(instrument["phi_y"], 0.0)
            out.append({"nominal": nominal, "instrument": instrument})
        return out


def calibrate_one(i: int, drawn: dict, seed: int) -> dict:
    """One resonator of the lot, reduced to a row (never raises for a calibration)."""
    from .ratetable import table_at_readout
    from .sequence import self_calibrate

    start = time.perf_counter()
    nominal = replace(ResonatorParameters(), **drawn["nominal"])
    instrument = replace(ResonatorParameters(), **drawn["instrument"])
    row: dict = {"resonator": i, **{f"true_{k}": v for k, v in drawn["instrument"].items()}}
    result, reason = None, ""
    try:
        cfg = design(nominal, seed=seed)
        try:
            result, status = self_calibrate(instrument, cfg), "good"
        except CalibrationRefusedError as exc:
            result, status, reason = exc.result, "refused", " | ".join(exc.problems)
        if result is not None:
            table = table_at_readout(instrument, result, cfg)
            d_bias = result.bias - table.bias
            d_sf = (result.scale_factor / table.scale_factor - 1) * 1e6
            s_sf = result.sigma_sf_ppm
            within = abs(d_bias) < BIAS_TOLERANCE and abs(d_sf) < SF_TOLERANCE_PPM
            if status == "good" and not within:
                status = "WRONG"
            row.update(
                bias=result.bias, sigma_bias=result.sigma_bias, table_bias=table.bias,
                d_bias=d_bias, z_bias=d_bias / result.sigma_bias,
                scale_factor=result.scale_factor, sigma_sf_ppm=s_sf,
                table_scale_factor=table.scale_factor, d_sf_ppm=d_sf, z_sf=d_sf / s_sf,
                within=within, record_s=result.record, misfit_ratio=result.misfit_ratio,
                amplitude_V=cfg.loops.amplitude, step_s=cfg.step)
    except GyroFmuError as exc:
        status, reason = "failed", f"{type(exc).__name__}: {exc}"
    row.update(status=status, reason=reason[:800], wall_s=time.perf_counter() - start)
    return row


@dataclass
class LotResult:
    rows: list[dict]
    model: LotModel
    wall: float
    n_workers: int
    interrupted: str | None = None

    def summary(self) -> dict:
        n = len(self.rows)
        count = {s: sum(r["status"] == s for r in self.rows)
                 for s in ("good", "refused", "WRONG", "failed")}
        calibrated = [r for r in self.rows if r["status"] in ("good", "WRONG")]

        def rms(key: str) -> float | None:
            v = [r[key] for r in calibrated if r.get(key) is not None]
            return float(np.sqrt(np.mean(np.square(v)))) if v else None

        walls = [r["wall_s"] for r in self.rows]
        return {
            "n": n, **{f"n_{k}": v for k, v in count.items()},
            "fraction_good": count["good"] / n if n else None,
            "fraction_refused": count["refused"] / n if n else None,
            "rms_z_bias": rms("z_bias"), "rms_z_sf": rms("z_sf"),
            "refusal_reasons": [r["reason"] for r in self.rows if r["status"] == "refused"],
            "failures": [r["reason"] for r in self.rows if r["status"] == "failed"],
            "wall_s_per_resonator_median": float(np.median(walls)) if walls else None,
            "wall_s_per_resonator_max": float(np.max(walls)) if walls else None,
            "wall_s": self.wall, "n_workers": self.n_workers, "interrupted": self.interrupted,
            "targets": {"bias_rad_s": BIAS_TOLERANCE, "scale_factor_ppm": SF_TOLERANCE_PPM,
                        "bias_sigma_target_rad_s": EARTH_RATE / 3, "sf_sigma_target_ppm": 30},
            "model": asdict(self.model),
        }


def run_lot(n: int, model: LotModel | None = None, scheduler: str | None = None,
            n_workers: int | None = None, progress: bool = True) -> LotResult:
    """Draw n resonators and calibrate each as a Dask task."""
    from ..studies.tasks import run_tasks

    model = model or LotModel()
    draws = model.draw(n)

    def lost(i: int, exc: BaseException) -> dict:
        return {"resonator": i, "status": "failed", "wall_s": math.nan,
                "reason": f"task error {type(exc).__name__}: {exc}"[:800]}

    rows, wall, workers, interrupted = run_tasks(
        calibrate_one, [(i, d, model.seed + i) for i, d in enumerate(draws)], lost,
        scheduler, n_workers, progress, is_failed=lambda r: r["status"] != "good")
    return LotResult(rows, model, wall, workers, interrupted)


def write_lot(res: LotResult, out: Path, figures: bool = True) -> list[Path]:
    """lot.csv (every resonator) and summary.json naming it, lot_histograms.png; each
    whole under its name or not there (gyro_fmu.outputs)."""
    out.mkdir(parents=True, exist_ok=True)
    paths = list(write_table_and_summary(out, "lot.csv", csv_writer(res.rows), res.summary(),
                                                 ("lot_histograms.png",)))
    if figures and res.rows:
        paths.append(histograms(res, out / "lot_histograms.png"))
    return paths


def histograms(res: LotResult, path: Path) -> Path:
    from ..extras import pyplot

    plt = pyplot()

    cal = [r for r in res.rows if r.get("d_bias") is not None]
    fig, ax = plt.subplots(1, 4, figsize=(16, 3.8))
    for a, key, scale, unit, tol in (
            (ax[0], "d_bias", 1.0, "rad/s", BIAS_TOLERANCE),
            (ax[1], "d_sf_ppm", 1.0, "ppm", SF_TOLERANCE_PPM)):
        for status, color in (("good", "C0"), ("refused", "C1"), ("WRONG", "C3")):
            v = [r[key] * scale for r in cal if r["status"] == status]
            if v:
                a.hist(v, bins=30, color=color, alpha=0.7, label=f"{status} ({len(v)})")
        for s in (-1, 1):
            a.axvline(s * tol, color="k", ls="--", lw=1)
        a.set_xlabel(f"{'bias' if key == 'd_bias' else 'scale factor'} - rate table ({unit})")
        a.legend(fontsize=8)
    ax[0].set_ylabel("resonators")
    z = [(r["z_bias"], r["z_sf"]) for r in cal if r["status"] in ("good", "WRONG")]
    if z:
        zb, zs = np.array(z).T
        ax[2].hist(zb, bins=25, alpha=0.6, label="bias")
        ax[2].hist(zs, bins=25, alpha=0.6, label="scale factor")
    ax[2].set_xlabel("error / reported 1-sigma (1)")
    ax[2].legend(fontsize=8)
    drawn = [r for r in res.rows if "true_f_x" in r]  # a lost task's row has no draw
    ax[3].scatter([r["true_f_x"] / 1e3 for r in drawn], [r["true_Q_x"] for r in drawn],
                  c=["C0" if r["status"] == "good" else "C3" if r["status"] == "WRONG"
                     else "C1" for r in drawn], s=12)
    ax[3].set_xlabel("f_x (kHz)")
    ax[3].set_ylabel("Q_x (1)")
    ax[3].set_yscale("log")
    s = res.summary()
    fig.suptitle(f"self-calibration lot: {s['n_good']}/{s['n']} good, {s['n_refused']} "
                 f"refused, {s['n_WRONG']} wrong, {s['n_failed']} failed")
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)
    return path
