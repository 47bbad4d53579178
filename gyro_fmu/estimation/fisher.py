"""Cramér-Rao bounds from a sensitivity Jacobian or a Fisher matrix, with one rank rule.

For white Gaussian noise of unit variance on the rows of J (rows already divided by
their noise standard deviation), the Fisher information is F = J^T J and the bound on
the unknowns is F^-1. Columns are equilibrated (unit norm) before the decomposition, so
the rank rule does not depend on units: a singular value below ``RTOL`` times the
largest is an unidentifiable direction, and an unknown with a component of more than
1e-6 along such a direction has no finite bound (inf). docs/observability.md explains
the threshold: exact deficiencies come out below 1e-10, the weakest genuine directions
of the presets above 1e-5, and from F alone (eigenvalues = squared singular values) the
decomposition resolves only about 1e-8.
"""

from __future__ import annotations

import math

import numpy as np

#: Relative threshold on the singular values of the column-equilibrated Jacobian
#: (1e-14 on the eigenvalues of the equilibrated Fisher matrix).
RTOL = 1e-7

#: Squared component along the unidentifiable directions above which a bound is inf.
_NULL_COMPONENT = 1e-12


def equilibrated(J: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(J with unit-norm columns, the column norms; a zero column keeps norm 1)."""
    norms = np.linalg.norm(J, axis=0)
    norms = np.where(norms > 0.0, norms, 1.0)
    return J / norms, norms


def _unidentifiable(null_directions: np.ndarray, n: int) -> np.ndarray:
    if not null_directions.size:
        return np.zeros(n, bool)
    return np.sum(null_directions**2, axis=1) > _NULL_COMPONENT


def _decomposition(J: np.ndarray, rtol: float):
    """(column norms, singular values, right singular vectors, which are identifiable,
    which unknowns are not identifiable) of the equilibrated J."""
    Jn, norms = equilibrated(J)
    _, sv, Vt = np.linalg.svd(Jn, full_matrices=False)
    keep = sv > rtol * sv[0]
    return norms, sv, Vt, keep, _unidentifiable(Vt[~keep].T, J.shape[1])


def covariance(J: np.ndarray, rtol: float = RTOL) -> np.ndarray:
    """F^-1 = (J^T J)^-1 restricted to the identifiable subspace; rows and columns of
    unidentifiable unknowns are inf."""
    norms, sv, Vt, keep, null = _decomposition(J, rtol)
    V = Vt[keep].T
    cov = (V / sv[keep] ** 2) @ V.T
    cov = cov / norms[:, None] / norms[None, :]
    cov[null, :] = cov[:, null] = math.inf
    return cov


def standard_deviations(J: np.ndarray, rtol: float = RTOL) -> np.ndarray:
    """sqrt(diag F^-1) per column of J (inf where unidentifiable)."""
    norms, sv, Vt, keep, null = _decomposition(J, rtol)
    var = (Vt[keep].T ** 2) @ (1.0 / sv[keep] ** 2)
    return np.where(null, math.inf, np.sqrt(var) / norms)


def standard_deviations_from_fisher(F: np.ndarray, rtol: float = RTOL) -> np.ndarray:
    """sqrt(diag F^-1) from the Fisher matrix itself (when only F = J^T J is at hand)."""
    d = np.sqrt(np.diag(F))
    d = np.where(d > 0, d, 1.0)
    w, V = np.linalg.eigh(F / d[:, None] / d[None, :])
    if w[-1] <= 0:
        return np.full(F.shape[0], math.inf)
    keep = w > rtol**2 * w[-1]
    var = (V[:, keep] ** 2) @ (1.0 / w[keep])
    sig = np.sqrt(var) / d
    return np.where(_unidentifiable(V[:, ~keep], F.shape[0]), math.inf, sig)
