"""GyroObserver.fmu at its defaults in a plain fmpy loop, on a gyro that is no preset.

What a user does: build the FMUs (`gyro-fmu build`), set the observer's initial guesses,
leave every tuning parameter at its default (rate model, noise: nothing told), and step
it with fmpy's FMU2Slave from their own data. The data here come from the independent
reference integrator of the tests (tests/reference.py: DOP853 per held interval, the
equations typed afresh), not from the project's plant or scenario code; the noise is
white, std = noise x each signal's own peak.

The gyro: park-horowitz's values times 1.07, 0.94, 1.25, 0.85, 1.15, 0.9, 1.03 (kxx, kyy,
kxy, dxx, dyy, dxy, m); drive 1e-7 N at 4000 Hz + 1e-7 N at 1200 Hz on x, scaled so that
the peak displacement is 6.6e-9 m (as is), 1e-15 m or 1e-6 m. Step 5 us.

Cases (issue 15, "what it must show"):
  constant   Omega_z = 1 rad/s, noise 1e-4, guesses 5-20 % off: |error| at 80 ms against
             the Cramer-Rao bound of the same data (gyro_fmu.estimation.identify.crb_at);
             target RMS over seeds <= 2 x the bound
  sine       Omega_z = sin(2 pi 100 t), noise 1e-5: RMS error over 80-100 ms; target 3 %
  far start  Omega_z = 1 rad/s, noise 1e-5, every parameter 20 % off (signs +-+++-+) and
             Omega_z_0 = 0: time after which Omega_hat stays within 1 %

    python benchmarks/observer_user_cases.py [--models models] [--seeds 6]
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
from reference import held_input_reference

from gyro_fmu.estimation.identify import crb_at, make_record
from gyro_fmu.model.parameters import GyroParameters, preset

H = 5e-6
FACTORS = {"kxx": 1.07, "kyy": 0.94, "kxy": 1.25, "dxx": 0.85, "dyy": 1.15, "dxy": 0.9,
           "m": 1.03}
GUESS = {"kxx": 1.05, "kyy": 0.95, "kxy": 1.05, "dxx": 1.2, "dyy": 1.2, "dxy": 0.8, "m": 1.05}
FAR = {"kxx": 1.2, "kyy": 0.8, "kxy": 1.2, "dxx": 1.2, "dyy": 1.2, "dxy": 0.8, "m": 1.2}
SCALES = {"as is": 1.0, "1e-15 m": None, "1e-6 m": None}


def truth() -> GyroParameters:
    p = preset("park-horowitz")
    return GyroParameters(**{n: getattr(p, n) * f for n, f in FACTORS.items()})


def drive(t: np.ndarray) -> np.ndarray:
    return 1e-7 * (np.sin(2 * np.pi * 4000 * t) + np.sin(2 * np.pi * 1200 * t))


class Observer:
    """GyroObserver.fmu through fmpy's FMU2Slave: set, doStep, get."""

    def __init__(self, fmu: Path, start: dict[str, float]) -> None:
        self.md = read_model_description(fmu)
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.unzipped = extract(fmu)
        self.slave = FMU2Slave(guid=self.md.guid, unzipDirectory=self.unzipped,
                               modelIdentifier=self.md.coSimulation.modelIdentifier,
                               instanceName="observer")
        self.slave.instantiate()
        self.slave.setupExperiment(startTime=0.0)
        self.slave.enterInitializationMode()
        names = list(start)
        self.slave.setReal([self.vr[n] for n in names], [start[n] for n in names])
        self.slave.exitInitializationMode()
        self.inputs = [self.vr[n] for n in ("ux", "x_meas", "y_meas")]
        self.outputs = [self.vr[n] for n in ("Omega_hat", "sigma_Omega_z", "status")]

    def run(self, u: np.ndarray, z: np.ndarray) -> np.ndarray:
        """Rows [Omega_hat, sigma, status] at t_k + h for k = 0 .. n-1."""
        out = np.empty((len(u), 3))
        for k in range(len(u)):
            self.slave.setReal(self.inputs, [u[k], z[k, 0], z[k, 1]])
            self.slave.doStep(k * H, H)
            out[k] = self.slave.getReal(self.outputs)
        return out

    def close(self) -> None:
        self.slave.terminate()
        self.slave.freeInstance()


def reference(p: GyroParameters, Omega: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(n) * H
    u = drive(t)
    s = held_input_reference(p, u, Omega[:n], H)
    return u, s[:n]  # states at t_k (the measurement the observer gets at t_k)


def one_run(fmu: Path, p, u, s, scale, noise, seed, guess_factors, Omega_0=0.0):
    rng = np.random.default_rng(seed)
    z = s[:, [0, 2]] * scale
    z = z + rng.standard_normal(z.shape) * noise * np.abs(z).max(axis=0)
    start = {f"{n}_0": getattr(p, n) * f for n, f in guess_factors.items()}
    start["Omega_z_0"] = Omega_0
    obs = Observer(fmu, start)
    t0 = time.perf_counter()
    out = obs.run(u * scale, z)
    wall = time.perf_counter() - t0
    obs.close()
    return out, z, wall


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", default="models", help="folder with GyroObserver.fmu")
    ap.add_argument("--seeds", type=int, default=6)
    args = ap.parse_args()
    fmu = Path(args.models) / "GyroObserver.fmu"
    if not fmu.is_file():
        raise SystemExit(f"{fmu} not found: run `gyro-fmu build` first (or --models)")
    p = truth()
    print(f"gyro: {p}")
    n_const, n_sine = 16000, 20000
    t_all = (np.arange(n_sine) + 1) * H
    t0 = time.perf_counter()
    u_c, s_c = reference(p, np.ones(n_const), n_const)
    u_s, s_s = reference(p, np.sin(2 * np.pi * 100 * np.arange(n_sine) * H), n_sine)
    u_f, s_f = reference(p, np.ones(n_sine), n_sine)
    print(f"reference trajectories (DOP853): {time.perf_counter() - t0:.0f} s")
    peak = np.abs(s_c[:, 0]).max()
    scales = {"as is": 1.0, "1e-15 m": 1e-15 / peak, "1e-6 m": 1e-6 / peak}
    walls = []
    print("\n| displacement | constant, noise 1e-4: RMS |err| at 80 ms / CRB (seeds) | "
          "status | 100 Hz sine, noise 1e-5: RMS err 80-100 ms | 20 % off: within 1 % "
          "from |")
    print("| --- | --- | --- | --- | --- |")
    for label, sc in scales.items():
        errs, ratio_rows, stat = [], [], 0
        crb = None
        for seed in range(args.seeds):
            out, z, wall = one_run(fmu, p, u_c, s_c, sc, 1e-4, seed, GUESS)
            walls.append(wall / n_const)
            e = out[-1, 0] - 1.0
            errs.append(e)
            stat = max(stat, int(out[-1, 2]))
            if crb is None:
                std = 1e-4 * np.abs(z).max(axis=0) / 1.0  # the noise std of this data
                tt = np.arange(n_const) * H
                rec = make_record(tt, u_c * sc, 0 * tt, s_c[:, [0, 2]] * sc, 1)
                crb = crb_at(GyroParameters(**{k: getattr(p, k) for k in FACTORS}), 1.0, rec,
                             tuple(std))["Omega_z"]
            ratio_rows.append(abs(e) / crb)
        rms_ratio = math.sqrt(np.mean(np.square(errs))) / crb
        sine_rms = []
        for seed in range(3):
            out, _, wall = one_run(fmu, p, u_s, s_s, sc, 1e-5, seed, GUESS)
            walls.append(wall / n_sine)
            true = np.sin(2 * np.pi * 100 * t_all)
            w = t_all >= 0.08
            sine_rms.append(math.sqrt(np.mean((out[w, 0] - true[w]) ** 2)))
            stat = max(stat, int(out[-1, 2]))
        out, _, wall = one_run(fmu, p, u_f, s_f, sc, 1e-5, 0, FAR)
        bad = np.nonzero(np.abs(out[:, 0] - 1.0) > 0.01)[0]
        conv = t_all[bad[-1] + 1] if bad.size and bad[-1] + 1 < n_sine else (
            t_all[0] if not bad.size else math.inf)
        stat = max(stat, int(out[-1, 2]))
        print(f"| {label} | {rms_ratio:.2f} (CRB {crb:.2e} rad/s; per seed "
              f"{', '.join(f'{r:.1f}' for r in ratio_rows)}) | {stat} | "
              f"{100 * max(sine_rms):.2f} % worst of 3 "
              f"({', '.join(f'{100 * v:.2f}' for v in sine_rms)}) | "
              f"{1e3 * conv:.2f} ms |", flush=True)
    print(f"\nfmpy loop: median {1e6 * np.median(walls):.1f} us per step (set, doStep, get)")


if __name__ == "__main__":
    main()
