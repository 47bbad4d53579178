"""Resonator and loops at carrier rate, in process, in the FMUs' Jacobi order.

At every communication point t_k both units publish their outputs, each receives the
other's, and both step to t_k + h (the core's gyro_carrier_run): exactly what the fmpy
master does with GyroResonator.fmu and GyroLoops.fmu, which step the same core, so the
two runs are bit-identical (tests hold this) and long calibration records run here
without a call per step.
"""

from __future__ import annotations

import ctypes
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..core import selfcal as c
from ..cosim.master import check_result_memory
from ..model.loops import OUTPUTS as LOOP_OUTPUTS
from ..model.loops import LoopSettings, LoopsModel
from ..model.resonator import ResonatorError, ResonatorModel, ResonatorParameters
from ..options import MAX_STEPS

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
        n = self._steps_in(duration, Omega_z, record_from)
        h = self.step
        k_end = self.k + n
        r0 = max(self.k, round(record_from / h)) if record_from > 0.0 else self.k
        if r0 > k_end:
            raise ResonatorError(f"record_from {record_from!r} s is after the end of the run "
                                 f"({k_end * h:g} s): record from at most the end")
        check_result_memory(k_end - r0 + 1, len(COLUMNS))
        rec = np.zeros((k_end - r0 + 1, len(COLUMNS)))
        self._step(k_end, rec, r0, chunk)
        pl, lo = self.plant, self.loops
        last = rec[k_end - r0]
        last[0] = k_end * h
        last[1:10] = lo.out
        last[10:12] = pl.out
        return CarrierRecord(rec, h)

    def advance(self, duration: float, sink: Callable[[np.ndarray, int], None],
                chunk: int = 1 << 14) -> None:
        """Advance by duration (s), handing each point's row on as it is made, so that
        memory does not grow with the run: sink(rows, k), rows[i] the point k + i
        (COLUMNS; a view valid during the call), from the current point to the one
        before the end (the end is the next advance's first)."""
        k_end = self.k + self._steps_in(duration)
        rows = np.zeros((chunk, len(COLUMNS)))
        while self.k < k_end:
            k0 = self.k
            self._step(min(k_end, k0 + chunk), rows, k0, chunk)
            sink(rows[: self.k - k0], k0)

    def _steps_in(self, duration: float, Omega_z: float | None = None,
                  record_from: float = 0.0) -> int:
        """Steps of a run of duration (s), every value checked; Omega_z held from now."""
        if Omega_z is not None:
            self.Omega_z = Omega_z
        h = self.step
        for name, value in (("duration", duration), ("record_from", record_from),
                            ("Omega_z", self.Omega_z), ("step", h)):
            if not math.isfinite(value):
                raise ResonatorError(f"{name}={value!r} is not finite: give a finite number")
        n = round(duration / h) if h > 0.0 else 0
        if n < 1:
            raise ResonatorError(f"duration {duration!r} s is shorter than the step {h} s")
        if self.k + n > MAX_STEPS:
            raise ResonatorError(f"duration {duration!r} s is {n:.3g} steps of {h:g} s, more "
                                 f"than the {MAX_STEPS:.3g} a run may take: shorten it")
        return n

    def _step(self, k_end: int, rec: np.ndarray, r0: int, chunk: int) -> None:
        """Step to point k_end, the rows of points from r0 into rec[k - r0]."""
        pl, lo, h = self.plant, self.loops, self.step
        lib, msg, done = c.selfcal_core(), c.message_buffer(), ctypes.c_int64()
        data = rec.ctypes.data_as(ctypes.POINTER(ctypes.c_double))
        while self.k < k_end:  # in chunks, so that Ctrl-C is seen between them
            m = min(chunk, k_end - self.k)
            failed = lib.gyro_carrier_run(ctypes.byref(pl.core), ctypes.byref(lo.core), self.k,
                                          m, h, float(self.Omega_z), data, len(rec), r0,
                                          ctypes.byref(done), msg, len(msg))
            self.k += done.value
            if failed:
                raise ResonatorError(f"{msg.value.decode()} (at t = {self.k * h:g} s)")
