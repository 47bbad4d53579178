"""GyroLoops: the closed-loop electronics of US 9,482,553, one sample at a time.

The settings are declared here; the loops' equations and step live in the C core
(fmu_src/core/gyro_loops.h), which GyroLoops.fmu steps too.

- Oscillator loop (primary axis): a PLL locks the NCO phase theta to the primary
  pick-off (I/Q demodulation, three low-pass sections, PI on the phase error) and the
  drive is regenerated 90 deg ahead of it, -g sin(theta + phi_osc), so the mode runs at
  its resonance; a PI amplitude control (AGC) sets g to hold the pick-off amplitude.
- Sideband excitation: the *position* signal used by the amplitude control is
  amplitude-modulated, (1 + sum_k m sin(2 pi k df t + psi_k)) with Schroeder phases
  (seed: "the position signal rather than the force signal is modulated"), so the
  drive acquires sidebands at k df around the carrier.
- Force rebalance (secondary axis): demodulate, PI-compensate with a -90 deg rotation
  (the resonator's envelope responds to force as -i/(2 omega)), remodulate (eq. 7);
  the in-phase command Im(u) is the rate output, Re(u) the quadrature output.
- Feed-forward removal: the measured feed-through E_hat of the drive voltages is
  subtracted from the pick-offs before anything else (seed: "feed forward errors are
  removed from the position signal rather than from the force rebalance").
- Mode 1: x oscillates, y is rebalanced; mode 2 swaps them (mode reversal);
  mode 0: loops off, off-resonant tones on Vx and Vy (feed-forward measurement; the
  resonator's ring tones, switched on with it, give the relative pick-off phase).

Drive outputs are computed at the middle of the hold interval (theta + omega h / 2),
which removes the zero-order hold's half-sample carrier delay.
"""

from __future__ import annotations

import ctypes
from dataclasses import asdict

import numpy as np

from ..core import selfcal as c
from ..core.structs import declared
from ..core.structs.selfcal import LOOP_SETTINGS
from ..errors import GyroFmuError
from .resonator import core_struct

#: Outputs of one loops step, in order.
OUTPUTS = c.LOOP_OUTPUTS


class LoopsError(GyroFmuError, ValueError):
    """A loop setting is unusable; the message names it and the remedy."""


@declared(LOOP_SETTINGS)
class LoopSettings:
    """Electronics settings; tuning uses nominal plant values, not the true ones. The fields
    (defaults, units, meaning) are declared with the core's struct
    (gyro_fmu.core.structs.selfcal.LOOP_SETTINGS)."""

    def problems(self) -> list[str]:
        """Problems (empty when usable), each naming the value and the remedy (the core's
        gyro_loop_settings_problems: the FMU refuses the same values with the same words)."""
        try:
            settings = _settings(self)
        except LoopsError as exc:
            return [str(exc)]
        msg = c.message_buffer()
        c.selfcal_core().gyro_loop_settings_problems(settings, msg, len(msg))
        return msg.value.decode().split("; ") if msg.value else []

    def as_dict(self) -> dict:
        return asdict(self)


def _settings(s: LoopSettings) -> c.LoopSettings:
    return core_struct(s, c.LoopSettings, c.LOOP_INTEGERS, LoopsError)


def sideband_phases(count: int) -> np.ndarray:
    """Schroeder phases psi_k = -pi k (k - 1) / count: a low crest factor multisine (the
    phases gyro_loops_step modulates with)."""
    k = np.arange(1, count + 1)
    return -np.pi * k * (k - 1) / max(count, 1)


class LoopsModel(c.CoreStructState):
    """The electronics as a stepping model over the core (what GyroLoops.fmu steps)."""

    _state_error = LoopsError

    def __init__(self, settings: LoopSettings) -> None:
        problems = settings.problems()
        if problems:
            raise LoopsError("; ".join(problems))
        self.settings = settings
        self.core = c.Loops()
        msg = c.message_buffer()
        if c.selfcal_core().gyro_loops_init(ctypes.byref(self.core), _settings(settings), msg,
                                            len(msg)):
            raise LoopsError(msg.value.decode())
        self._bind()

    def _bind(self) -> None:
        #: the outputs, a view of the core's GyroLoopOutputs (OUTPUTS order)
        self.out = np.frombuffer(self.core.out, dtype=float)
        self._step = c.selfcal_core().gyro_loops_step
        self._ref = ctypes.byref(self.core)

    def step(self, px: float, py: float, t: float, h: float) -> np.ndarray:
        """Consume the pick-offs sampled at t; returns the outputs for the hold from t + h."""
        self._step(self._ref, px, py, t, h)
        return self.out

    def __getstate__(self) -> dict:
        return {"settings": self.settings, **self.get_state()}

    def __setstate__(self, state: dict) -> None:
        self.settings = state["settings"]
        self.core = c.Loops()
        self.set_state(state)
        self._bind()
