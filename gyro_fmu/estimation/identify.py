"""Offline identification: batch output-error least squares with its Cramer-Rao bound.

Fits the 7 fabrication parameters and a constant Omega_z to a recorded run (the
drive ux, uy and the two measured signals, e.g. ``results.csv`` of
``gyro-fmu run`` or any CSV with the columns ``time, drive.ux, drive.uy,
plant.x, plant.y`` (pair 1) or ``plant.vx, plant.vy`` (pair 2)).

Model. Exactly what GyroPlant computes: the input recorded at t_k is held over
[t_k, t_k+1] (zero-order hold) and the state is stepped with the exact
held-input map (Van Loan expm, :mod:`gyro_fmu.model.dynamics`). The parameter
sensitivities are exact too: the sensitivity equations are appended to the state
and stepped with the same held-input map (the system of
:mod:`gyro_fmu.estimation.observability`), so the Jacobian handed to
``scipy.optimize.least_squares`` is the derivative of exactly the simulated
output, not a finite difference.

Initial state: by default the plant is **at rest at the first sample** (how
every co-simulation of this package starts). ``fit_initial_state=True`` adds the
4 initial states as unknowns (for bench data recorded while the part already
moves); their sensitivities Phi^k are exact as well.

Parametrization: relative deviations from a reference set (the start),
delta_i = (theta_i - ref_i) / ref_i, with the input gain 1/m in place of m (the
output is linear in 1/m) and Omega_z in rad/s (absolute). Residuals are
weighted per channel by the noise standard deviation (given, or estimated from
the residuals of a first fit; then refit), so the weighted least-squares
solution is the maximum-likelihood estimate for white Gaussian noise and
(J^T J)^-1 at the solution is the Cramer-Rao bound.

Convergence: an output-error fit of a lightly damped resonator over many cycles
has local minima (a 2% frequency error is several cycles of phase after 40 ms).
The fit therefore grows the window geometrically (from ``first_window``, about
10 periods of the slowest mode, doubling up to the whole record), each stage
starting from the previous solution.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares

from ..model.measurement import UNKNOWN_UNITS, UNKNOWNS, MeasuredPair
from ..model.parameters import PARAMETER_NAMES, GyroParameters, ParameterError
from . import fisher
from .sensitivity import ScaledSensitivitySystem

#: Columns holding the two measured signals of each measured pair.
PAIR_COLUMNS: dict[int, tuple[str, str]] = {
    pair: tuple(f"plant.{name}" for name in pair.plant_outputs) for pair in MeasuredPair}


class IdentificationError(ParameterError):
    """The record cannot be fitted (missing columns, uneven steps, ...)."""


@dataclass(frozen=True)
class Record:
    """A recorded experiment: held inputs u_k (N) and measured pair z_k at t_k."""

    time: np.ndarray  #: (N,) s, uniform steps
    u: np.ndarray  #: (N, 2) ux, uy held over [t_k, t_k+1], N
    z: np.ndarray  #: (N, 2) measured pair, m or m/s
    measured_pair: int = 1

    @property
    def h(self) -> float:
        return float(self.time[1] - self.time[0])

    def head(self, n: int) -> Record:
        return Record(self.time[:n], self.u[:n], self.z[:n], self.measured_pair)


def read_record(path: Path, measured_pair: int = 1, stop_time: float | None = None) -> Record:
    """Read a CSV with columns time, drive.ux, [drive.uy], and the measured pair."""
    path = Path(path)
    try:
        with path.open(encoding="utf-8") as f:
            columns = [c.strip() for c in f.readline().strip().split(",")]
            f.read()  # the whole file must be text
    except UnicodeDecodeError as exc:
        raise IdentificationError(
            f"{path} is not a UTF-8 text CSV (byte 0x{exc.object[exc.start]:02x} at "
            f"{exc.start} cannot be read): save the record as a UTF-8 CSV") from None
    except IsADirectoryError:
        raise IdentificationError(f"{path} is a folder: name the results CSV") from None
    if measured_pair not in PAIR_COLUMNS:
        raise IdentificationError(f"measured_pair must be 1 or 2, got {measured_pair!r}")
    need = ["time", "drive.ux", *PAIR_COLUMNS[measured_pair]]
    missing = [c for c in need if c not in columns]
    if missing:
        raise IdentificationError(f"{path}: missing column(s) {missing}; it has {columns}")
    try:
        with warnings.catch_warnings():  # "input contained no data": checked below
            warnings.simplefilter("ignore", UserWarning)
            data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    except ValueError as exc:  # a cell that is not a number, rows of unequal length
        raise IdentificationError(f"{path} is not a numeric CSV ({exc})") from None
    if data.shape[0] == 0:
        raise IdentificationError(f"{path} has a header but no rows: give a recorded run")
    if data.shape[1] != len(columns):
        raise IdentificationError(f"{path}: rows of {data.shape[1]} values for "
                                  f"{len(columns)} columns in the header")
    col = {c: data[:, columns.index(c)] for c in columns}
    t = col["time"]
    if stop_time is not None:
        keep = t <= t[0] + stop_time + 1e-12
        t, col = t[keep], {c: v[keep] for c, v in col.items()}
    uy = col.get("drive.uy", np.zeros_like(t))
    return make_record(t, col["drive.ux"], uy,
                       np.column_stack([col[c] for c in PAIR_COLUMNS[measured_pair]]),
                       measured_pair)


def make_record(time: np.ndarray, ux: np.ndarray, uy: np.ndarray, z: np.ndarray,
                measured_pair: int = 1) -> Record:
    """Check a record (uniform step, finite values) and build it."""
    t = np.asarray(time, float)
    if t.size < 10:
        raise IdentificationError(f"need at least 10 samples, got {t.size}")
    dt = np.diff(t)
    h = float(np.median(dt))
    if not np.all(dt > 0):
        k = int(np.argmax(dt <= 0))
        raise IdentificationError(
            f"time must increase from row to row: row {k + 1} has t = {t[k]:.9g} s, row "
            f"{k + 2} t = {t[k + 1]:.9g} s (rows sorted? two runs appended?)")
    if not (h > 0 and np.all(np.abs(dt - h) <= 1e-6 * h)):
        raise IdentificationError(
            f"the communication step must be uniform (min {dt.min():.6g}, max {dt.max():.6g} s)")
    u = np.column_stack([np.asarray(ux, float), np.asarray(uy, float)])
    z = np.asarray(z, float).reshape(t.size, 2)
    if not (np.all(np.isfinite(u)) and np.all(np.isfinite(z))):
        raise IdentificationError("the record holds NaN or inf values")
    return Record(t, u, z, measured_pair)


def record_from_result(result, measured_pair: int = 1, stop_time: float | None = None) -> Record:
    """Record from a CoSimulationResult (FMU or in-process run)."""
    t = result["time"]
    n = t.size if stop_time is None else int(np.sum(t <= t[0] + stop_time + 1e-12))
    z = np.column_stack([result[c][:n] for c in PAIR_COLUMNS[measured_pair]])
    return make_record(t[:n], result["drive.ux"][:n], result["drive.uy"][:n], z, measured_pair)


# --------------------------------------------------------------------------- model


def _theta(p: GyroParameters, Omega_z: float) -> np.ndarray:
    return np.array([Omega_z, p.kxx, p.kyy, p.kxy, p.dxx, p.dyy, p.dxy, p.m])


class _Model:
    """Outputs and exact sensitivities with respect to the fit coordinates delta."""

    def __init__(self, record: Record, ref: np.ndarray, fit_initial_state: bool) -> None:
        self.record = record
        self.ref = ref.copy()  # theta at delta = 0
        # coordinate scales: Omega absolute (1 rad/s); others relative to the reference;
        # a zero reference falls back to a typical size (as in observability)
        fallback = np.array([1.0, 1.0, abs(ref[1]) or 1.0, 1e-3 * (abs(ref[1]) or 1.0),
                             1.0, 1.0, 1.0, 1.0])
        self.c = np.where(np.abs(ref) > 0, np.abs(ref), fallback)
        self.c[0] = 1.0
        self.fit_s0 = fit_initial_state
        self.n_par = 8 + (4 if fit_initial_state else 0)
        self._key: bytes | None = None
        self._val: tuple[np.ndarray, np.ndarray] | None = None

    def theta(self, delta: np.ndarray) -> tuple[GyroParameters, float, np.ndarray]:
        th = self.ref.copy()
        th[:7] = self.ref[:7] + self.c[:7] * delta[:7]
        g_ref = 1.0 / self.ref[7]
        th[7] = 1.0 / (g_ref * (1.0 + delta[7]))  # 1/m = g_ref (1 + delta_m)
        p = GyroParameters(*th[1:])
        s0 = delta[8:12] * self.s0_scale if self.fit_s0 else np.zeros(4)
        return p, float(th[0]), s0

    @property
    def s0_scale(self) -> np.ndarray:
        peak = np.max(np.abs(self.record.z), axis=0)
        w0 = math.sqrt(abs(self.ref[1])) or 1.0
        if self.record.measured_pair == 1:
            px, py = peak
        else:
            px, py = peak / w0
        return np.array([px, px * w0, py, py * w0])

    def evaluate(self, delta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(z_model (N, 2), dz/ddelta (N, 2, n_par))."""
        key = delta.tobytes()
        if key == self._key and self._val is not None:
            return self._val
        p, Om, s0 = self.theta(delta)
        rec = self.record
        sys = ScaledSensitivitySystem.build(p, Om, rec.h)
        sigma0 = np.zeros(sys.Phi.shape[0])
        sigma0[:4] = s0 * sys.T
        sigma = sys.simulate(sigma0, rec.u)
        s, dS = sys.unscale(sigma)  # dS[..., i, :] = scales_i ds/dtheta_i
        rows = list(MeasuredPair(rec.measured_pair).state_rows)
        z = s[:, rows]
        dth = np.moveaxis(dS[:, :, rows], 1, 2) / sys.scales  # (N, 2, 8) d z / d theta
        # chain rule to delta
        dtheta_ddelta = self.c.copy()
        g_ref = 1.0 / self.ref[7]
        dtheta_ddelta[7] = -(p.m**2) * g_ref  # dm/ddelta_m = dm/dg * g_ref
        dz = dth * dtheta_ddelta
        if self.fit_s0:
            Phi4 = sys.Phi[:4, :4] / sys.T[:, None] * sys.T[None, :]
            n = rec.time.size
            P = np.eye(4)
            ds0 = np.empty((n, 2, 4))
            for k in range(n):
                ds0[k] = P[rows]
                P = Phi4 @ P
            dz = np.concatenate([dz, ds0 * self.s0_scale], axis=2)
        self._key, self._val = key, (z, dz)
        return z, dz


# --------------------------------------------------------------------------- result


@dataclass(frozen=True)
class Identification:
    """Estimates, Cramer-Rao one-sigma bounds and fit diagnostics."""

    estimates: dict[str, float]  #: Omega_z (rad/s), kxx ... m (SI)
    crb_sigma: dict[str, float]  #: Cramer-Rao 1-sigma at the solution, same units
    noise_std: tuple[float, float]  #: per channel, given or estimated from residuals
    noise_estimated: bool
    residual_rms: tuple[float, float]  #: per channel
    n_samples: int
    window: float  #: s
    measured_pair: int
    fit_initial_state: bool
    initial_state: tuple[float, float, float, float]
    cost: float
    nfev: int
    success: bool
    message: str
    covariance: np.ndarray = field(repr=False)  #: of the 8 unknowns (SI), initial state excluded

    def error(self, truth: GyroParameters, Omega_z: float) -> dict[str, float]:
        values = dict(zip(UNKNOWNS, _theta(truth, Omega_z), strict=True))
        return {n: self.estimates[n] - values[n] for n in UNKNOWNS}

    def table(self, truth: dict[str, float] | None = None) -> str:
        lines = [f"{'unknown':>8} {'estimate':>15} {'CRB 1-sigma':>12} "
                 + (f"{'truth':>15} {'err/sigma':>9} " if truth else "") + "unit"]
        for n in UNKNOWNS:
            e, s = self.estimates[n], self.crb_sigma[n]
            extra = ""
            if truth is not None:
                z = (e - truth[n]) / s if s > 0 else math.nan
                extra = f"{truth[n]:15.9g} {z:9.2f} "
            lines.append(f"{n:>8} {e:15.9g} {s:12.3g} {extra}{UNKNOWN_UNITS[n]}")
        return "\n".join(lines)


def identify(
    record: Record,
    start: GyroParameters,
    Omega_z_0: float = 0.0,
    noise_std: Sequence[float] | None = None,
    fit_initial_state: bool = False,
    first_window: float | None = None,
    max_nfev: int = 200,
) -> Identification:
    """Fit the 8 unknowns (and optionally the initial state) to a record; see the module doc.

    start: the parameters the fit starts from (e.g. a preset, the nominal part);
    noise_std: absolute std of the two measured channels (m or m/s); None: estimated
    from the residuals of a first fit, then refit with those weights.
    """
    ref = _theta(start, Omega_z_0)
    model = _Model(record, ref, fit_initial_state)
    n_total = record.time.size
    if first_window is None:
        w_min = math.sqrt(min(np.linalg.eigvalsh(start.K)[0], start.kxx, start.kyy))
        first_window = 10.0 * 2.0 * math.pi / w_min if w_min > 0 else 2e-3
    n = min(n_total, max(20, round(first_window / record.h)))
    delta = np.zeros(model.n_par)
    peak = np.max(np.abs(record.z), axis=0)
    std = np.asarray(noise_std, float) if noise_std is not None else np.where(
        peak > 0, peak * 1e-6, 1.0)
    if std.shape != (2,) or not np.all(std > 0):
        raise IdentificationError(f"noise_std must be two positive numbers, got {noise_std!r}")
    res = None
    while True:
        sub = _Model(record.head(n), ref, fit_initial_state)
        res = _solve(sub, delta, std, max_nfev)
        delta = res.x
        if n >= n_total:
            break
        n = min(n_total, 2 * n)
    model = _Model(record, ref, fit_initial_state)
    estimated = noise_std is None
    if estimated:  # reweight with the residual noise of each channel, refit
        z, _ = model.evaluate(delta)
        r = z - record.z
        std = np.sqrt(np.mean(r**2, axis=0) * n_total / max(1, n_total - model.n_par / 2))
        std = np.where(std > 0, std, np.finfo(float).tiny ** 0.5 * np.maximum(peak, 1e-300))
        res = _solve(model, delta, std, max_nfev)
        delta = res.x
        z, _ = model.evaluate(delta)
        r = z - record.z
        std = np.sqrt(np.mean(r**2, axis=0) * n_total / max(1, n_total - model.n_par / 2))
        std = np.where(std > 0, std, np.finfo(float).tiny ** 0.5 * np.maximum(peak, 1e-300))
    z, dz = model.evaluate(delta)
    r = z - record.z
    J = (dz / std[None, :, None]).reshape(-1, model.n_par)
    cov_delta = fisher.covariance(J)
    p, Om, s0 = model.theta(delta)
    th = _theta(p, Om)
    # d theta / d delta at the solution (diagonal)
    d = model.c[:8].copy()
    d[7] = p.m**2 / ref[7]
    cov = cov_delta[:8, :8] * d[:, None] * d[None, :]
    sig = np.sqrt(np.clip(np.diag(cov), 0, None))
    return Identification(
        estimates=dict(zip(UNKNOWNS, (float(v) for v in th), strict=True)),
        crb_sigma=dict(zip(UNKNOWNS, (float(v) for v in sig), strict=True)),
        noise_std=(float(std[0]), float(std[1])),
        noise_estimated=estimated,
        residual_rms=tuple(float(v) for v in np.sqrt(np.mean(r**2, axis=0))),  # type: ignore[arg-type]
        n_samples=n_total,
        window=float(n_total * record.h),
        measured_pair=record.measured_pair,
        fit_initial_state=fit_initial_state,
        initial_state=tuple(float(v) for v in s0),  # type: ignore[arg-type]
        cost=float(res.cost),
        nfev=int(res.nfev),
        success=bool(res.success),
        message=str(res.message),
        covariance=cov,
    )


def _solve(model: _Model, delta0: np.ndarray, std: np.ndarray, max_nfev: int):
    zm = model.record.z

    def fun(d: np.ndarray) -> np.ndarray:
        z, _ = model.evaluate(d)
        return ((z - zm) / std).ravel()

    def jac(d: np.ndarray) -> np.ndarray:
        _, dz = model.evaluate(d)
        return (dz / std[None, :, None]).reshape(-1, model.n_par)

    return least_squares(fun, delta0, jac=jac, method="lm", x_scale="jac",
                         ftol=1e-15, xtol=1e-15, gtol=1e-15, max_nfev=max_nfev)


def crb_at(
    params: GyroParameters,
    Omega_z: float,
    record: Record,
    noise_std: Sequence[float],
    fit_initial_state: bool = False,
) -> dict[str, float]:
    """Cramer-Rao 1-sigma of the 8 unknowns at the truth, for the inputs of a record."""
    model = _Model(record, _theta(params, Omega_z), fit_initial_state)
    dz = sensitivities_at(params, Omega_z, record, fit_initial_state, model)
    std = np.asarray(noise_std, float)
    cov = fisher.covariance((dz / std[None, :, None]).reshape(-1, model.n_par))
    d = model.c[:8].copy()
    d[7] = params.m
    sig = np.sqrt(np.clip(np.diag(cov)[:8], 0, None)) * d
    return dict(zip(UNKNOWNS, (float(v) for v in sig), strict=True))


def sensitivities_at(params: GyroParameters, Omega_z: float, record: Record,
                     fit_initial_state: bool = False, model: _Model | None = None
                     ) -> np.ndarray:
    """dz/ddelta (N, 2, 8 or 12) at the truth for the inputs of a record: column 0 per
    rad/s of Omega_z, the parameters relative to their values, then (fit_initial_state)
    the starting state. Each channel's Fisher matrix is J[:, c].T @ J[:, c] / std_c^2."""
    if model is None:
        model = _Model(record, _theta(params, Omega_z), fit_initial_state)
    return model.evaluate(np.zeros(model.n_par))[1]


def parameters_of(ident: Identification) -> GyroParameters:
    return GyroParameters(**{n: ident.estimates[n] for n in PARAMETER_NAMES})
