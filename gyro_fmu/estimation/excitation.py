"""Excitation design: the Cramer-Rao bound of the 8 unknowns as a function of the two drive tones.

For a parameter set, a constant Omega_z, a noise level and a window, this module
evaluates the Cramer-Rao one-sigma bound of Omega_z, kxx, ..., m for every pair
of tone frequencies of a grid and every split of a force limit F between the two
tones (A1 = a F, A2 = (1 - a) F, so |ux| <= F), and proposes the pair and split
that minimize the bound on Omega_z (or a weighted sum of bounds, each divided
by its tolerance of :mod:`gyro_fmu.estimation.metrics`, so the terms are comparable).

It is the quantitative version of the rank test of
:mod:`gyro_fmu.estimation.observability` and uses its exact sensitivities
(:func:`gyro_fmu.estimation.observability.window_jacobian`: held-input, exact). The model
is linear in the input, so the sampled outputs and their sensitivities for a
two-tone drive are a1 * (those of tone 1 alone) + a2 * (tone 2 alone): each
frequency of the grid is simulated once and every pair/split is a cheap
combination (an 8 x 8 Fisher matrix from precomputed Gram blocks).

Noise conventions (docs/observability.md): ``noise_kind="relative"`` (default, as
ObservabilityReport.one_sigma): white noise of std = noise x that channel's own
peak over the window, per channel; then the total force does not matter, only
the split. ``noise_kind="absolute"``: std = noise in m (or m/s for velocities)
for both channels, fixed by the pick-off electronics; then more force is better
and the force limit binds.

Start: ``start="rest"`` (default) as the co-simulations (plant at rest at t = 0,
the free transient at the natural frequencies carries much of the information
on Omega_z); ``"steady"`` on the periodic orbit of the drive.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np

from ..model.drive import (  # noqa: F401 - the drive's warning is the core's, bound there
    DriveFarFromModesWarning,
    TwoToneDrive,
    drive_information_loss,
    drive_warning,
)
from ..model.measurement import UNKNOWNS
from ..model.parameters import GyroParameters, ParameterError
from ..outputs import save_figure
from . import fisher
from .metrics import tolerance
from .sensitivity import drive_tones, window_jacobian

NoiseKind = Literal["relative", "absolute"]


def tolerances(params: GyroParameters, Omega_z: float) -> np.ndarray:
    """The metrics tolerance of each unknown, in UNKNOWNS order (metrics.tolerance)."""
    values = {"Omega_z": Omega_z, **params.as_dict()}
    return np.array([tolerance(n, np.array([values[n]])) for n in UNKNOWNS])


def crb(
    params: GyroParameters,
    drive: TwoToneDrive | Sequence[tuple[float, float]],
    Omega_z: float = 1.0,
    noise: float = 1e-4,
    window: float = 0.04,
    h: float = 5e-6,
    measured_pair: int = 1,
    noise_kind: NoiseKind = "relative",
    start: Literal["rest", "steady"] = "rest",
) -> dict[str, float]:
    """Cramer-Rao one-sigma of the 8 unknowns for one drive (SI units)."""
    z, dz, scales = window_jacobian(params, drive, Omega_z, measured_pair, window, h, start)
    std = _std(z, noise, noise_kind)
    J = (dz / std[None, :, None]).reshape(-1, dz.shape[2])
    sig = _sigmas(J.T @ J, scales, sum(a for a, _ in drive_tones(drive)), noise, noise_kind)
    return dict(zip(UNKNOWNS, (float(v) for v in sig), strict=True))


def _sigmas(F: np.ndarray, scales: np.ndarray, force: float, noise: float,
            kind: NoiseKind) -> np.ndarray:
    """CRB 1-sigma from a Fisher matrix, refused where double precision cannot hold it
    (a force or a noise of no physical size over- or underflows F)."""
    if not (np.all(np.isfinite(F)) and np.any(F != 0.0)):
        raise ParameterError(
            f"the Fisher information over- or underflows double precision at a force of "
            f"{force:g} N and a noise of {noise:g} ({kind}): give a force limit "
            f"(force_limit) and a noise of physical size (the defaults: the preset's drive, "
            f"noise 1e-4 of each signal's peak)")
    return fisher.standard_deviations_from_fisher(F) * scales


#: Most frequencies a design grid may hold: n^2 tone pairs are bounded per split.
MAX_GRID = 400


def frequency_grid(f_min: float, f_max: float, f_step: float) -> np.ndarray:
    """f_min, f_min + f_step, ... up to f_max (Hz), each bound named in its refusal."""
    for name, value in (("f_min", f_min), ("f_max", f_max), ("f_step", f_step)):
        if not (math.isfinite(value) and value > 0.0):
            raise ParameterError(f"{name}={value!r} Hz must be a finite number > 0")
    if not f_min < f_max:
        raise ParameterError(f"f_min={f_min:g} Hz must be below f_max={f_max:g} Hz")
    count = math.floor((f_max - f_min) / f_step + 0.5) + 1
    if count < 2:
        raise ParameterError(f"f_step={f_step:g} Hz leaves one frequency in {f_min:g}.."
                             f"{f_max:g} Hz: give a step below {f_max - f_min:g} Hz")
    if count > MAX_GRID:
        raise ParameterError(f"f_min..f_max = {f_min:g}..{f_max:g} Hz in steps of f_step="
                             f"{f_step:g} Hz is "
                             f"{count:.3g} frequencies, more than {MAX_GRID} ({MAX_GRID}^2 "
                             "tone pairs): narrow the band or give a larger step")
    return f_min + f_step * np.arange(count)


def _std(z: np.ndarray, noise: float, kind: NoiseKind) -> np.ndarray:
    if not (math.isfinite(noise) and noise > 0):
        raise ParameterError(f"noise must be a finite number > 0, got {noise!r}")
    if kind == "relative":
        peak = np.max(np.abs(z), axis=0)
        return noise * np.where(peak > 0, peak, 1.0)
    if kind == "absolute":
        return np.array([noise, noise])
    raise ParameterError(f"noise_kind must be 'relative' or 'absolute', got {kind!r}")


@dataclass(frozen=True, eq=False)
class DriveDesign:
    """CRB over the grid and the proposed drive."""

    frequencies: np.ndarray  #: (n,) Hz
    splits: np.ndarray  #: (s,) fraction a of the force limit on tone 1
    sigma: np.ndarray  #: (n, n, s, 8) CRB 1-sigma, NaN on the diagonal (one tone)
    objective: np.ndarray  #: (n, n, s)
    weights: dict[str, float]
    force_limit: float  #: N, A1 + A2
    noise: float
    noise_kind: str
    window: float
    h: float
    Omega_z: float
    measured_pair: int
    start: str
    params: GyroParameters = field(repr=False)

    @property
    def best_index(self) -> tuple[int, int, int]:
        flat = np.nanargmin(self.objective)
        return tuple(int(v) for v in np.unravel_index(flat, self.objective.shape))  # type: ignore[return-value]

    @property
    def proposal(self) -> TwoToneDrive:
        i, j, s = self.best_index
        a = float(self.splits[s])
        return TwoToneDrive(A1=a * self.force_limit, f1=float(self.frequencies[i]),
                            A2=(1 - a) * self.force_limit, f2=float(self.frequencies[j]))

    @property
    def proposal_sigma(self) -> dict[str, float]:
        i, j, s = self.best_index
        return dict(zip(UNKNOWNS, (float(v) for v in self.sigma[i, j, s]), strict=True))

    def best_over_splits(self, name: str = "Omega_z") -> np.ndarray:
        """(n, n) bound on `name` at the split that minimizes the objective at each pair."""
        k = UNKNOWNS.index(name)
        obj = np.where(np.isnan(self.objective), np.inf, self.objective)
        s = np.argmin(obj, axis=2)
        out = np.take_along_axis(self.sigma[..., k], s[..., None], axis=2)[..., 0]
        return np.where(np.isnan(self.objective).all(axis=2), np.nan, out)

    def sigma_at(self, f1: float, f2: float, split: float = 0.5) -> dict[str, float]:
        i = int(np.argmin(np.abs(self.frequencies - f1)))
        j = int(np.argmin(np.abs(self.frequencies - f2)))
        s = int(np.argmin(np.abs(self.splits - split)))
        return dict(zip(UNKNOWNS, (float(v) for v in self.sigma[i, j, s]), strict=True))


def design_drive(
    params: GyroParameters,
    frequencies: Sequence[float],
    force_limit: float,
    Omega_z: float = 1.0,
    noise: float = 1e-4,
    window: float = 0.04,
    h: float = 5e-6,
    measured_pair: int = 1,
    splits: Sequence[float] = (0.25, 0.5, 0.75),
    weights: Mapping[str, float] | None = None,
    noise_kind: NoiseKind = "relative",
    start: Literal["rest", "steady"] = "rest",
) -> DriveDesign:
    """Cramer-Rao bound over a grid of tone pairs and force splits; see the module doc.

    weights: unknown -> weight of sigma/tolerance in the objective (default Omega_z: 1).
    """
    if not (math.isfinite(force_limit) and force_limit > 0.0):
        raise ParameterError(f"force_limit={force_limit!r} N must be a finite number > 0")
    freqs = np.asarray(sorted(set(float(f) for f in frequencies)))
    if freqs.size < 2 or np.any(freqs <= 0):
        raise ParameterError("give at least two distinct positive frequencies")
    nyquist = 0.5 / h
    if freqs[-1] >= nyquist:
        raise ParameterError(f"frequencies must stay below the Nyquist frequency {nyquist:g} Hz")
    weights = dict(weights or {"Omega_z": 1.0})
    bad = sorted(set(weights) - set(UNKNOWNS))
    if bad:
        raise ParameterError(f"unknown weight name(s) {bad}: use {list(UNKNOWNS)}")
    w = np.array([weights.get(n, 0.0) for n in UNKNOWNS]) / tolerances(params, Omega_z)
    splits_a = np.asarray(splits, float)
    if np.any((splits_a <= 0) | (splits_a >= 1)):
        raise ParameterError("splits must lie strictly between 0 and 1")
    zs, dzs = [], []
    scales = None
    for f in freqs:  # each tone alone at the full force limit
        z, dz, scales = window_jacobian(params, [(force_limit, f)], Omega_z, measured_pair,
                                        window, h, start)
        zs.append(z)
        dzs.append(dz)
    Z = np.stack(zs)  # (n, N, 2)
    D = np.stack(dzs)  # (n, N, 2, 8)
    n = freqs.size
    # Gram blocks per channel: G[c, i, j] = D_i[:, c]^T D_j[:, c]
    G = np.einsum("inca,jncb->cijab", D, D, optimize=True)
    sigma = np.full((n, n, splits_a.size, len(UNKNOWNS)), np.nan)
    for i in range(n):
        for j in range(n):
            if i == j:
                continue
            for s, a in enumerate(splits_a):
                b = 1.0 - a
                std = _std(a * Z[i] + b * Z[j], noise, noise_kind)
                F = sum((a * a * G[c, i, i] + b * b * G[c, j, j]
                         + a * b * (G[c, i, j] + G[c, j, i])) / std[c] ** 2 for c in range(2))
                sigma[i, j, s] = _sigmas(F, scales, force_limit, noise, noise_kind)
    objective = np.einsum("ijsk,k->ijs", np.nan_to_num(sigma, nan=np.inf, posinf=np.inf), w)
    objective[np.arange(n), np.arange(n), :] = np.nan
    return DriveDesign(freqs, splits_a, sigma, objective, weights, float(force_limit), noise,
                       noise_kind, window, h, Omega_z, measured_pair, start, params)


def natural_frequencies(params: GyroParameters, Omega_z: float = 0.0) -> list[float]:
    from ..model.parameters import system_matrix

    ev = np.linalg.eigvals(system_matrix(params, Omega_z))
    return sorted({round(abs(e.imag) / (2 * math.pi), 1) for e in ev if e.imag > 0})


def heat_map(design: DriveDesign, path: Path, name: str = "Omega_z") -> Path:
    """Heat map of the bound on `name` over (f1, f2), log color, proposal marked."""
    from ..extras import pyplot

    plt = pyplot()
    from matplotlib.colors import LogNorm

    from ..model.measurement import UNKNOWN_UNITS

    data = design.best_over_splits(name)
    f = design.frequencies
    fig, ax = plt.subplots(figsize=(7.2, 6))
    finite = data[np.isfinite(data)]
    norm = LogNorm(vmin=finite.min(), vmax=finite.max()) if finite.size else None
    edges = np.concatenate([[f[0] - (f[1] - f[0]) / 2], (f[1:] + f[:-1]) / 2,
                            [f[-1] + (f[-1] - f[-2]) / 2]])
    mesh = ax.pcolormesh(edges, edges, data.T, norm=norm, cmap="viridis_r", shading="flat")
    cb = fig.colorbar(mesh, ax=ax)
    cb.set_label(f"Cramer-Rao 1-sigma of {name} ({UNKNOWN_UNITS[name]})")
    p = design.proposal
    ax.plot(p.f1, p.f2, "r*", ms=14, label=f"proposal {p.f1:g} + {p.f2:g} Hz "
            f"(A1 {p.A1:.3g}, A2 {p.A2:.3g} N)")
    for fn in natural_frequencies(design.params, design.Omega_z):
        ax.axvline(fn, color="w", ls=":", lw=1)
        ax.axhline(fn, color="w", ls=":", lw=1)
    ax.set_xlabel("tone 1 frequency f1 (Hz)")
    ax.set_ylabel("tone 2 frequency f2 (Hz)")
    noise = (f"{design.noise:g} of each signal's peak" if design.noise_kind == "relative"
             else f"{design.noise:g} (absolute)")
    ax.set_title(f"CRB of {name}: window {design.window * 1e3:g} ms, noise {noise},\n"
                 f"force limit {design.force_limit:g} N (best split per pair); "
                 "dotted: natural frequencies", fontsize=9)
    ax.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    save_figure(fig, path, dpi=120)
    plt.close(fig)
    return Path(path)
