"""A sideband record demodulated while it runs, so that memory stays flat in its length.

The resonator and loops run (in process, or GyroResonator.fmu and GyroLoops.fmu through
the master) and hand their rows on in chunks to the core's streaming demodulator
(fmu_src/core/gyro_demod.h): each of Vx, Vy, Vpx, Vpy mixed down at the NCO frequency
the loops have when it starts, low-pass filtered and decimated to a few hundred Hz; the
NCO phase, the lock statistics and a full-rate tail of the pick-offs beside them. What
is kept is about 100 bytes per output sample: a 120 s record at 300 kHz takes under
5 MB where the full record took 11 GB. `mode_phasors` then fits the phasors on the
decimated baseband, demodulated on the loops' smoothed NCO phase (phasors.nco_phase),
with the filter's known response divided out.
"""

from __future__ import annotations

import ctypes
import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..core import selfcal as c
from ..model.loops import LoopSettings
from ..model.resonator import ResonatorError, ResonatorParameters
from .estimator import ModeData
from .inprocess import COLUMNS, CarrierSimulation
from .phasors import baseband_off_grid, baseband_phasors, nco_phase

if TYPE_CHECKING:
    from .sequence import FeedForward, SelfCalConfig

#: Output samples per second of the demodulator per Hz of baseband it must hold (the
#: sidebands' products and the carrier's wander): the filter's droop at the band's
#: edge is then 0.3 % (divided out) and the noise it folds in below 1e-6.
RATE_PER_BAND = 16.0
#: Hz of carrier wander (the NCO away from its frequency at the record's start).
WANDER = 5.0
#: Full-rate pick-off samples kept at the record's end (alarms.pickoff_noise).
TAIL = 1 << 17
_OMEGA = COLUMNS.index("omega")


@dataclass
class StreamedRecord:
    """A record of n steps of h from step r0, decimated by B (M = n / B samples)."""

    step: float
    r0: int
    n: int
    B: int
    omega0: float  #: rad/s, the mixing frequency (the NCO's at the filter's start)
    base: np.ndarray  #: (M, 4) complex: Vx, Vy, Vpx, Vpy mixed down and filtered
    #: (M,) the loops' NCO phase less omega0 t at each centre t_base, filtered like the
    #: channels (rad; unwrapped, up to a whole number of turns)
    theta: np.ndarray
    tail: np.ndarray  #: (TAIL or n, 2): Vpx, Vpy of the record's last steps
    worst_phase_error: float  #: rad, largest |phase_error| over the record
    mean_amplitude: float  #: V, the loops' amplitude output, averaged
    pinned_fraction: float  #: of the steps with the drive gain at its limit
    gain_peak: float  #: V, the largest drive gain over the record
    gain_mean: float  #: V, its mean
    demod: c.Demod  #: the core's demodulator (its response)

    @property
    def t_start(self) -> float:
        return self.r0 * self.step

    @property
    def t_base(self) -> np.ndarray:
        """s, the centre of each decimated sample."""
        return (self.r0 + np.arange(len(self.base)) * self.B + 0.5 * (self.B - 1)) * self.step

    def response(self, f: np.ndarray) -> np.ndarray:
        """The decimating filter's response at f Hz from omega0 (real)."""
        lib = c.selfcal_core()
        return np.array([lib.gyro_demod_response(ctypes.byref(self.demod), float(x))
                         for x in np.ravel(f)]).reshape(np.shape(f))


def decimation(n: int, h: float, band: float) -> int:
    """The largest divisor B of n whose output rate 1 / (B h) is at least RATE_PER_BAND
    times band (Hz); the M = n / B outputs then tile the record exactly."""
    limit = max(1, int(1.0 / (h * RATE_PER_BAND * band)))
    best = 1
    for d in range(1, math.isqrt(n) + 1):
        if n % d == 0:
            for b in (d, n // d):
                if best < b <= limit:
                    best = b
    return best


class Demodulator:
    """The core's demodulator for a record of n steps of h from step r0 (rows fed in
    order by `feed`; the mixing frequency is the NCO's in the first row it reads, or
    omega_nominal when that is no number)."""

    def __init__(self, h: float, r0: int, n: int, band: float, drive_limit: float,
                 omega_nominal: float = 0.0) -> None:
        self.B = decimation(n, h, band)
        self.h, self.r0, self.n, self.drive_limit = h, r0, n, drive_limit
        self.omega_nominal = omega_nominal  # mixing frequency when the NCO's is no number
        m = n // self.B
        self.base = np.zeros((m, c.DEMOD_CHANNELS, 2))
        self.theta = np.zeros(m)
        self.tail = np.zeros((min(TAIL, n), 2))
        self.kernel = np.zeros(c.DEMOD_ORDER * self.B)
        self.lib = c.selfcal_core()
        self.lib.gyro_demod_kernel(self.B, _ptr(self.kernel))
        self.core = c.Demod()
        self.started = False
        first = r0 - (c.DEMOD_ORDER - 1) * (self.B - 1) // 2
        self.first_step = first
        self.last_step = first + (m - 1 + c.DEMOD_ORDER) * self.B - 1
        if first < 0:
            raise ResonatorError(f"a record from step {r0} leaves the demodulator no room "
                                 f"({-first} steps short): settle for at least "
                                 f"{2 * self.B * h:g} s before it")

    def feed(self, rows: np.ndarray, k: int) -> None:
        """Rows of COLUMNS for the points k, k + 1, ... (consecutive across calls)."""
        if not self.started:
            i = self.first_step - k
            if i >= len(rows):
                return
            if i < 0:
                raise ResonatorError(f"the demodulator's first step {self.first_step} was "
                                     f"not fed (rows from {k})")
            msg = c.message_buffer()
            omega0 = float(rows[i, _OMEGA])  # a diverged loop's NaN: the lock alarm names it
            if self.lib.gyro_demod_init(
                    ctypes.byref(self.core), omega0 if math.isfinite(omega0) else
                    self.omega_nominal, self.h, self.r0, self.n,
                    self.B, len(self.tail), self.drive_limit, _ptr(self.base),
                    _ptr(self.theta), _ptr(self.tail), _ptr(self.kernel), msg, len(msg)):
                raise ResonatorError(msg.value.decode())
            self.started = True
        rows = np.ascontiguousarray(rows, dtype=float)
        msg = c.message_buffer()
        if self.lib.gyro_demod_feed(ctypes.byref(self.core), _ptr(rows), k, len(rows), msg,
                                    len(msg)):
            raise ResonatorError(msg.value.decode())

    def result(self) -> StreamedRecord:
        d = c.Demod.from_buffer_copy(self.core)  # its arrays stay here: no pointers out
        d.base = d.theta = d.tail_po = d.kernel = None
        if d.emitted != len(self.base) or d.counted != self.n:
            raise ResonatorError(f"the record ended early: {d.emitted} of {len(self.base)} "
                                 f"demodulated samples, {d.counted} of {self.n} steps")
        base = self.base[..., 0] + 1j * self.base[..., 1]
        return StreamedRecord(self.h, self.r0, self.n, self.B, d.omega0, base, self.theta,
                              self.tail, d.worst_phase_error, d.sum_amplitude / d.counted,
                              d.pinned / d.counted, d.gain_peak, d.sum_gain / d.counted, d)


def _ptr(a: np.ndarray) -> ctypes.POINTER(ctypes.c_double):
    return a.ctypes.data_as(ctypes.POINTER(ctypes.c_double))


def stream_record(res: ResonatorParameters, lo: LoopSettings, cfg: SelfCalConfig, seed: int,
                  settle: float, record: float) -> StreamedRecord:
    """Run from rest for settle (s), then a record of `record` s, demodulated as it runs,
    on the configured engine: in process, or the two FMUs through the master (the same
    core, bit-identical rows; tests/test_selfcal_stream.py)."""
    h = cfg.step
    r0, n = round(settle / h), round(record / h)
    band = 3 * lo.sideband_count * lo.sideband_spacing + WANDER
    dem = Demodulator(h, r0, n, band, lo.drive_limit, 2 * math.pi * lo.f_nominal)
    steps = dem.last_step + 1  # points 0 .. last_step are read
    if cfg.engine == "fmu":
        from .run import run_fmus

        models = Path(cfg.models_dir) if cfg.models_dir else None
        run_fmus(res, lo, steps * h, h, cfg.Omega_z, seed, models_dir=models, sink=dem.feed)
    else:
        sim = CarrierSimulation(res, lo, seed=seed, step=h, Omega_z=cfg.Omega_z)
        sim.advance(steps * h, dem.feed)
    return dem.result()


def mode_phasors(rec: StreamedRecord, mode: int, ff: FeedForward,
                 cfg: SelfCalConfig) -> ModeData:
    """Demodulate a sideband record at the carrier and its sidebands (and their
    intermodulation products up to three times the highest tone), on the loops'
    smoothed NCO phase; the feed-through ff.E removed from the pick-offs."""
    h, spacing = rec.step, cfg.sideband_spacing
    # products up to 3 times the highest tone: the cubic's (a 0.1 Hz cubic shift left a
    # misfit of 2.9e-6 V with 2 times, 2.8e-7 with 3, 1.4e-7 with 4; noise-free)
    harm = np.arange(-3 * cfg.sideband_count, 3 * cfg.sideband_count + 1)
    t = rec.t_base
    nco = nco_phase(rec.omega0 * t + rec.theta, t, rec.t_start, rec.n, h, spacing,
                    3 * cfg.sideband_count)
    omega = nco.omega + harm * 2 * math.pi * spacing
    extra = (nco.omega - rec.omega0) * t + nco.curvature(t)
    offset_hz = (nco.omega - rec.omega0) / (2 * math.pi)

    def response(j: np.ndarray) -> np.ndarray:
        return rec.response(offset_hz + np.asarray(j) * spacing)

    dt, offset = rec.B * h, 0.5 * (rec.B - 1) / rec.B
    ph = [baseband_phasors(rec.base[:, i], t[0], dt, offset, extra, spacing, harm,
                           response(harm)) for i in range(4)]
    off = [baseband_off_grid(rec.base[:, i], dt, extra, spacing, harm, response)
           for i in range(4)]  # the noise between the tones (NoiseModel)
    off_omega = nco.omega + off[0][0] * 2 * math.pi * spacing

    def corrected(ph: list[np.ndarray], w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        D = np.stack(ph[:2], axis=1)
        PO = np.stack(ph[2:], axis=1)
        return D, PO - np.einsum("ij,nj->ni", ff.E, D) * np.exp(-1j * w * h)[:, None]

    D, PO = corrected(ph, omega)
    off_D, off_PO = corrected([v for _, v in off], off_omega)
    amp = float(np.abs(PO[harm == 0, mode - 1][0]))
    return ModeData(mode, omega, D, PO, nco.omega, amp, drift=nco.drift, off_omega=off_omega,
                    off_D=off_D, off_PO=off_PO)
