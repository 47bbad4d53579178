"""The gyroscope plant: exact held-input motion plus seeded pick-off noise.

This is what GyroPlant.fmu wraps; the fmpy master's in-process reference run
and the tests use the same class, so the FMU adds only the FMI interface.
"""

from __future__ import annotations

import base64
import ctypes
import math
import operator
from dataclasses import dataclass, fields

import numpy as np

from ..core.library import Params, PickoffNoise, State, core, core_text
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
    """State [x, vx, y, vy] advanced exactly over each step with held ux, uy, Omega_z: the
    C core's GyroPlant (fmu_src/core/gyro_plant.c), the same code GyroPlant.fmu steps.

    Noise is drawn once per communication point, so the measured outputs at a
    time do not depend on how often they are read. The seed is any integer in
    [0, 2^64); GyroPlant.fmu takes [0, 2^31 - 1] (an FMI 2.0 Integer).
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
        seed = operator.index(seed)
        if not 0 <= seed < 2**64:
            raise ParameterError(f"seed={seed} is outside [0, 2^64): give a non-negative "
                                 "64-bit seed")
        self._lib = core()
        self._buf = ctypes.create_string_buffer(self._lib.gyro_plant_size())
        self._ptr = ctypes.c_void_p(ctypes.addressof(self._buf))  # converted once, not per call
        self._out = (ctypes.c_double * 6)()
        self._step, self._outputs = self._lib.gyro_plant_step, self._lib.gyro_plant_outputs
        p = self.params
        self._c_params = Params(p.kxx, p.kyy, p.kxy, p.dxx, p.dyy, p.dxy, p.m)
        self._c_noise = PickoffNoise(*self.noise.as_array())
        s0 = None if state0 is None else State(*(float(v) for v in np.asarray(state0)))
        self._lib.gyro_plant_init(self._buf, ctypes.byref(self._c_params),
                                  ctypes.byref(self._c_noise), seed,
                                  None if s0 is None else ctypes.byref(s0))

    def step(self, ux: float, uy: float, Omega_z: float, h: float) -> None:
        """Advance from t to t+h with ux, uy (N) and Omega_z (rad/s) held over the step."""
        if not h > 0.0:
            raise ValueError(f"step size h={h!r} s must be > 0")
        self._step(self._ptr, ux, uy, Omega_z, h)

    @property
    def c_pointer(self) -> ctypes.c_void_p:
        """The core's GyroPlant this object steps (for a C loop over it: core chain)."""
        return self._ptr

    def output_row(self) -> list[float]:
        """[x, vx, y, vy] measured (noise included), then ax, ay: the FMU's outputs."""
        self._outputs(self._ptr, self._out)
        return self._out[:]

    def measured(self) -> np.ndarray:
        """[x, vx, y, vy] (m, m/s) at the current time, noise included."""
        return np.array(self.output_row()[:4])

    def accelerations(self) -> tuple[float, float]:
        """ax, ay (m/s^2) at the current time with the inputs of the last step (left limit)."""
        row = self.output_row()
        return row[4], row[5]

    @property
    def s(self) -> np.ndarray:
        """The true state [x, vx, y, vy] (no noise)."""
        return np.frombuffer(self._buf.raw, dtype=float, count=4, offset=_STATE_OFFSET).copy()

    # --- state for FMI get/set (everything that determines future outputs) ---
    def get_state(self) -> dict:
        return {"core": base64.b64encode(self._buf.raw).decode("ascii")}

    def set_state(self, state: dict) -> None:
        """Restore get_state's bytes; refused (ValueError naming why, nothing changed)
        unless they are this plant's: same size, parameters and noise, finite values."""
        raw = base64.b64decode(state["core"], validate=True)
        if len(raw) != len(self._buf.raw):
            raise ValueError(f"plant state of {len(raw)} bytes, {len(self._buf.raw)} expected")
        candidate = ctypes.create_string_buffer(raw, len(raw))
        problem = core_text("gyro_plant_restored_problem", candidate,
                            ctypes.byref(self._c_params), ctypes.byref(self._c_noise))
        if problem:
            raise ValueError(problem)
        ctypes.memmove(self._buf, candidate, len(raw))


#: Offset of GyroPlant.s in the core's struct: after GyroParams (7) and GyroPickoffNoise (4).
_STATE_OFFSET = 11 * 8
