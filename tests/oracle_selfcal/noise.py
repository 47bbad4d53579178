"""The resonator's random inputs: seeded block streams and exact white-noise increments.

- `NoiseStream`: seeded Gaussian rows drawn in blocks of 4096, so that an FMU drawing one
  row per step and an in-process run drawing a million at once see the same sequence.
- `white_noise_covariance`: the covariance of the state increment of x' = A x + w over a
  step h, w white with intensity Qc (E w(t) w(s)' = Qc delta(t - s)), the exact
  discretization of continuous white noise (docs/resonator-physics.md).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import expm


def white_noise_covariance(A: np.ndarray, Qc: np.ndarray, h: float) -> np.ndarray:
    """Q(h) = integral over [0, h] of e^{As} Qc e^{A's} ds.

    Van Loan's block exponential over t = h / 2^k, with k chosen so that ||A|| t < 1 (the
    e^{-At} block stays small even with fast pick-off lags, ||A|| h ~ 30), then k
    doublings Q(2t) = Q(t) + Phi(t) Q(t) Phi(t)', sums of positive semi-definite terms.
    """
    k = max(0, math.ceil(math.log2(max(float(np.abs(A).sum(axis=0).max()) * h, 1.0))) + 1)
    t, n = h / 2**k, len(A)
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n], M[:n, n:], M[n:, n:] = -A * t, Qc * t, A.T * t
    E = expm(M)
    Phi = E[n:, n:].T
    Q = Phi @ E[:n, n:]
    for _ in range(k):
        Q, Phi = Q + Phi @ Q @ Phi.T, Phi @ Phi
    return (Q + Q.T) / 2


class NoiseStream:
    """Seeded noise drawn in blocks: the same sequence however it is consumed, so an FMU
    drawing one row per step equals an in-process run. Stream 0 is the pick-off noise;
    another stream is an independent generator, seeded with (seed, stream)."""

    BLOCK = 4096

    def __init__(self, std: float, seed: int, width: int = 2, stream: int = 0) -> None:
        self.std = std
        self.width = width
        entropy = seed if stream == 0 else np.random.SeedSequence([seed, stream])
        self.rng = np.random.Generator(np.random.PCG64(entropy))
        self.block = np.zeros((0, width))
        self.pos = 0

    def prime(self) -> None:  # a fresh model's saved state then has a used one's shape
        if self.std != 0.0 and self.pos == len(self.block):
            self.block = self.rng.standard_normal((self.BLOCK, self.width)) * self.std
            self.pos = 0

    def take(self, n: int) -> np.ndarray:
        """The next n sample rows (n x width)."""
        if self.std == 0.0:
            return np.zeros((n, self.width))
        out = np.empty((n, self.width))
        filled = 0
        while filled < n:
            self.prime()
            k = min(n - filled, len(self.block) - self.pos)
            out[filled:filled + k] = self.block[self.pos:self.pos + k]
            filled += k
            self.pos += k
        return out

    def get_state(self) -> dict:
        return {"rng": self.rng.bit_generator.state, "block": self.block.tolist(),
                "pos": self.pos}

    def set_state(self, state: dict) -> None:
        self.rng.bit_generator.state = state["rng"]
        self.block = np.array(state["block"], dtype=float).reshape(-1, self.width)
        self.pos = int(state["pos"])
