"""Resonator and loops at carrier rate, in process, in the FMUs' Jacobi order.

At every communication point t_k both units publish their outputs, each receives the
other's, and both step to t_k + h: exactly what the fmpy master does with
GyroResonator.fmu and GyroLoops.fmu, so the two runs are bit-identical (tests hold
this) and long calibration records can run here at a fraction of the FMI cost.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from .loops import OUTPUTS as LOOP_OUTPUTS
from .loops import LoopSettings, LoopsModel, loops_step
from .resonator import ResonatorModel, ResonatorParameters, resonator_step

#: Recorded columns (after "time").
COLUMNS = ("time", *LOOP_OUTPUTS, "Vpx", "Vpy")
#: Default communication step: 10 samples per cycle of the 4 kHz carrier.
DEFAULT_STEP = 25e-6


@dataclass
class CarrierRecord:
    """Recorded signals, one row per communication point."""

    data: np.ndarray
    step: float

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.data[:, COLUMNS.index(name)]
        except ValueError:
            raise KeyError(f"no signal {name!r}; recorded: {list(COLUMNS)}") from None

    @property
    def time(self) -> np.ndarray:
        return self.data[:, 0]


@njit(cache=True)
def _run(k0, n, t0, h, Phi, Gamma, s, gains, E, noise, par, st, lout, pout, rec, r0,
         cubic, nsub, L, extra, drive_std):  # pragma: no cover
    V = np.empty(2)
    drawn = extra.shape[0] > 1  # force or drive noise: one row of 8 normals per step
    for j in range(n):
        k = k0 + j
        t = t0 + k * h
        if k >= r0:
            row = rec[k - r0]
            row[0] = t
            for i in range(9):
                row[1 + i] = lout[i]
            row[10], row[11] = pout[0], pout[1]
        V[0], V[1] = lout[0], lout[1]
        px, py = pout[0], pout[1]
        resonator_step(Phi, Gamma, s, V, gains, E, noise[j], pout, cubic, nsub, h, L,
                       extra[j] if drawn else extra[0], drive_std)
        loops_step(px, py, t, h, par, st, lout)


class CarrierSimulation:
    """One resonator and its loops, advanced together from rest (or a given state)."""

    def __init__(self, resonator: ResonatorParameters, settings: LoopSettings,
                 seed: int = 0, step: float = DEFAULT_STEP, Omega_z: float = 0.0) -> None:
        self.plant = ResonatorModel(resonator, seed=seed)
        self.loops = LoopsModel(settings)
        self.step = step
        self.Omega_z = Omega_z
        self.k = 0

    def run(self, duration: float, record_from: float = 0.0, Omega_z: float | None = None,
            chunk: int = 1 << 20) -> CarrierRecord:
        """Advance by duration (s); record the points from record_from (s, absolute)
        to the end, both included."""
        if Omega_z is not None:
            self.Omega_z = Omega_z
        h = self.step
        n = round(duration / h)
        if n < 1:
            raise ValueError(f"duration {duration!r} s is shorter than the step {h} s")
        k_end = self.k + n
        r0 = max(self.k, round(record_from / h))
        if r0 > k_end:
            raise ValueError(f"record_from {record_from!r} s is after the end of the run "
                             f"({k_end * h:g} s): record from at most the end")
        rec = np.zeros((k_end - r0 + 1, len(COLUMNS)))
        pl, lo = self.plant, self.loops
        done = 0
        while done < n:  # in chunks that end where the temperature ramp re-discretizes
            m = min(chunk, n - done, pl.steps_left())
            Phi, Gamma = pl.matrices(self.Omega_z, h)
            noise = pl.noise.take(m)
            extra = pl.extra.take(m) if pl.extra.std != 0.0 else np.zeros((1, 8))
            _run(self.k, m, 0.0, h, Phi, Gamma, pl.s, pl.gains, pl.E, noise, lo.par, lo.st,
                 lo.out, pl.out, rec, r0, pl.cubic, pl.nsub, pl.L, extra, pl.p.drive_noise)
            self.k += m
            pl.k += m
            done += m
        last = rec[k_end - r0]
        last[0] = k_end * h
        last[1:10] = lo.out
        last[10:12] = pl.out
        return CarrierRecord(rec, h)
