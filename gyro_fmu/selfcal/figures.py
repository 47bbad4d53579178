"""Figure of the calibration: measured vs fitted sideband transfer functions, both modes."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..outputs import save_figure
from .estimator import transfer
from .result import SelfCalResult


def sideband_figure(result: SelfCalResult, path: Path) -> Path:
    """Sideband transfer functions at the carrier and the excited sidebands, both modes,
    measured (markers) and fitted (lines), magnitude and phase against frequency:

    - oscillator pick-off / oscillator drive, fitted = (H D)_p / D_p (eq. 19's estimate);
    - rebalance drive / oscillator drive, fitted = -H_sp / H_ss, the drive that nulls the
      rebalanced pick-off: the channel that carries cross damping, quadrature and rate.
      (The rebalanced pick-off itself is nulled by the loop down to its noise.)"""
    from ..extras import pyplot

    plt = pyplot()

    fit = result.fit
    fig, axes = plt.subplots(2, 2, figsize=(12, 7), sharex=True)
    f_base = result.omega_r / (2 * math.pi)
    for md, color in zip(result.modes, ("C0", "C1"), strict=False):
        H = transfer(fit.x, md.omega, fit.omega_ref, fit.rho, fit.kappa, fit.h,
                     fit.fit_feedthrough)
        est = np.einsum("nij,nj->ni", H, md.D)
        p = md.mode - 1
        excited = np.abs(md.D[:, p]) > 1e-3 * np.abs(md.D[:, p]).max()
        order = np.argsort(md.omega[excited])
        f = (md.omega[excited][order]) / (2 * math.pi) - f_base
        axis = "xy"[p]
        other = "yx"[p]
        s = 1 - p
        panels = (
            (md.PO[excited, p] / md.D[excited, p], est[excited, p] / md.D[excited, p],
             f"mode {md.mode}: V_p{axis} / V{axis}"),
            (md.D[excited, s] / md.D[excited, p], -H[excited, s, p] / H[excited, s, s],
             f"mode {md.mode}: V{other} / V{axis}"),
        )
        for col, (meas, model, name) in enumerate(panels):
            meas, model = meas[order], model[order]
            axes[0, col].semilogy(f, np.abs(meas), "o", color=color, ms=4,
                                  label=f"{name}, measured")
            axes[0, col].semilogy(f, np.abs(model), "-", color=color, lw=1, label="fitted")
            axes[1, col].plot(f, np.unwrap(np.angle(meas)), "o", color=color, ms=4)
            axes[1, col].plot(f, np.unwrap(np.angle(model)), "-", color=color, lw=1)
    for col, title in enumerate(("oscillator pick-off / oscillator drive",
                                 "rebalance drive / oscillator drive")):
        axes[0, col].set_title(title)
        axes[0, col].set_ylabel("magnitude (V/V)")
        axes[1, col].set_ylabel("phase (rad)")
        axes[1, col].set_xlabel(f"frequency - {f_base:.4f} Hz (Hz)")
        axes[0, col].legend(fontsize=7)
    fig.suptitle(f"Sideband transfer functions, measured vs fitted (eq. 19); rms misfit "
                 f"{fit.rms_residual:.2e} V")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    save_figure(fig, path, dpi=110)
    plt.close(fig)
    return path
