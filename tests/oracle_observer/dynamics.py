"""dynamics.system_matrix_of and inf_norm_rows of gyro_fmu 0.3.0 (numba)."""

import numpy as np
from numba import njit


@njit(cache=True)
def system_matrix_of(kxx, kyy, kxy, dxx, dyy, dxy, Omega_z):  # pragma: no cover
    """Continuous-time 4x4 matrix A of the state [x, x', y, y'] (patent eqs. 3-4).

    The printed eqs. 1-5 mix up subscripts; the model implemented is the one the
    observability matrix C1 of eq. 7 implies (k's in 1/s^2, d's in 1/s, Omega_z in rad/s):
        x'' = -kxx x - kxy y - dxx x' - dxy y' + 2 Omega_z y' + ux/m
        y'' = -kxy x - kyy y - dxy x' - dyy y' - 2 Omega_z x' + uy/m
    The plant's is the C core's gyro_system_matrix; this compiled copy is the observer's
    until its kernels move to the core (numba's last user); parameters.system_matrix is
    its numpy entry point.
    """
    A = np.zeros((4, 4))
    A[0, 1] = 1.0
    A[1, 0] = -kxx
    A[1, 1] = -dxx
    A[1, 2] = -kxy
    A[1, 3] = 2.0 * Omega_z - dxy
    A[2, 3] = 1.0
    A[3, 0] = -kxy
    A[3, 1] = -dxy - 2.0 * Omega_z
    A[3, 2] = -kyy
    A[3, 3] = -dyy
    return A


@njit(cache=True)
def inf_norm_rows(M, rows, cols):  # pragma: no cover
    """Infinity norm of the block M[:rows, :cols] (max absolute row sum)."""
    norm = 0.0
    for i in range(rows):
        r = 0.0
        for j in range(cols):
            r += abs(M[i, j])
        norm = max(norm, r)
    return norm
