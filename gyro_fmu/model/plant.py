"""The gyroscope plant: exact held-input motion plus seeded pick-off noise.

This is what GyroPlant.fmu wraps; the fmpy master's in-process reference run
and the tests use the same class, so the FMU adds only the FMI interface.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from .dynamics import HeldInputStepper, accelerations
from .parameters import GyroParameters, ParameterError, validate_for_plant

#: Names of the plant's measured outputs, in output order.
MEASURED = ("x", "vx", "y", "vy")


@dataclass(frozen=True)
class MeasurementNoise:
    """Standard deviations of white Gaussian pick-off noise on each measured signal."""

    x: float = 0.0  #: m
    vx: float = 0.0  #: m/s
    y: float = 0.0  #: m
    vy: float = 0.0  #: m/s

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ParameterError(
                    f"noise standard deviation noise_{f.name}={value!r} must be finite and >= 0"
                )

    def as_array(self) -> np.ndarray:
        return np.array([self.x, self.vx, self.y, self.vy])

    @property
    def is_off(self) -> bool:
        return not self.as_array().any()


class GyroPlantModel:
    """State [x, vx, y, vy] advanced exactly over each step with held ux, uy, Omega_z.

    Noise is drawn once per communication point, so the measured outputs at a
    time do not depend on how often they are read.
    """

    def __init__(
        self,
        params: GyroParameters,
        noise: MeasurementNoise | None = None,
        seed: int = 0,
        state0: np.ndarray | None = None,
    ) -> None:
        self.params = validate_for_plant(params)
        self.noise = noise or MeasurementNoise()
        self._sigma = self.noise.as_array()
        self._noisy = bool(self._sigma.any())
        self._rng = np.random.default_rng(seed)
        self._stepper = HeldInputStepper(self.params)
        self.s = np.zeros(4) if state0 is None else np.asarray(state0, dtype=float).copy()
        self.held = (0.0, 0.0, 0.0)  # ux, uy, Omega_z over the last step
        self._draw_noise()

    def _draw_noise(self) -> None:
        self._noise = self._rng.standard_normal(4) * self._sigma if self._noisy else None

    def step(self, ux: float, uy: float, Omega_z: float, h: float) -> None:
        """Advance from t to t+h with ux, uy (N) and Omega_z (rad/s) held over the step."""
        if not h > 0.0:
            raise ValueError(f"step size h={h!r} s must be > 0")
        self.s = self._stepper.step(self.s, ux, uy, Omega_z, h)
        self.held = (ux, uy, Omega_z)
        self._draw_noise()

    def measured(self) -> np.ndarray:
        """[x, vx, y, vy] (m, m/s) at the current time, noise included."""
        return self.s if self._noise is None else self.s + self._noise

    def accelerations(self) -> tuple[float, float]:
        """ax, ay (m/s^2) at the current time with the inputs of the last step (left limit)."""
        ux, uy, Omega_z = self.held
        return accelerations(self.params, self.s, ux, uy, Omega_z)

    def output_row(self) -> list[float]:
        """[x, vx, y, vy] measured (noise included), then ax, ay: the FMU's outputs."""
        return [*self.measured().tolist(), *self.accelerations()]

    # --- state for FMI get/set (everything that determines future outputs) ---
    def get_state(self) -> dict:
        return {
            "s": self.s.tolist(),
            "held": list(self.held),
            "rng": self._rng.bit_generator.state,
            "noise": None if self._noise is None else self._noise.tolist(),
        }

    def set_state(self, state: dict) -> None:
        self.s = np.array(state["s"], dtype=float)
        self.held = tuple(state["held"])
        self._rng.bit_generator.state = state["rng"]
        self._noise = None if state["noise"] is None else np.array(state["noise"])
