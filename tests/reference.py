"""Independent reference solutions for the tests (written apart from gyro_fmu.model.dynamics)."""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp


def held_input_reference(p, ux: np.ndarray, Omega: np.ndarray, h: float) -> np.ndarray:
    """States [x, vx, y, vy] at k*h, with ux[k], Omega[k] held on [k h, (k+1) h).

    Each hold interval is integrated on its own by DOP853 (rtol 1e-12), so no
    input discontinuity falls inside an integrator step. The right-hand side is
    the consistent form of patent eqs. 3-4 typed afresh here.
    """

    def rhs(t, s, u, om):
        x, vx, y, vy = s
        return [
            vx,
            -p.kxx * x - p.kxy * y - p.dxx * vx - p.dxy * vy + 2 * om * vy + u / p.m,
            vy,
            -p.kxy * x - p.kyy * y - p.dxy * vx - p.dyy * vy - 2 * om * vx,
        ]

    s = np.zeros(4)
    out = [s]
    for k in range(len(ux)):
        sol = solve_ivp(rhs, (k * h, (k + 1) * h), s, method="DOP853", rtol=1e-12,
                        atol=1e-30, args=(ux[k], Omega[k]))
        s = sol.y[:, -1]
        out.append(s)
    return np.array(out)
