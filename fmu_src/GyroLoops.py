"""GyroLoops.fmu: the closed-loop electronics of US 9,482,553, one sample per step."""

import numpy as np
from pythonfmu.default_experiment import DefaultExperiment

from gyro_fmu.fmu.slave import GyroSlave, Var
from gyro_fmu.selfcal.loops import LoopSettings
from gyro_fmu.selfcal.run import LOOPS_RENAMED, parameter_variables

#: FMI unit of every float field of LoopSettings (mode and sideband_* counts are Integers).
_UNITS = {
    "f_nominal": "Hz", "amplitude": "V", "q_nominal": "1", "plant_gain": "1/s",
    "pll_bandwidth": "Hz", "agc_bandwidth": "Hz", "rebalance_bandwidth": "Hz",
    "demod_cutoff": "Hz", "rebalance_cutoff": "Hz", "drive_limit": "V", "osc_phase": "rad",
    "sideband_index": "1", "sideband_spacing": "Hz", "sideband_start": "s",
    "ff_xx": "1", "ff_xy": "1", "ff_yx": "1", "ff_yy": "1",
    "excitation_amplitude": "V", "excitation_offset_x": "Hz", "excitation_offset_y": "Hz",
}
#: Where a field comment does not read well on its own.
_DESCRIPTIONS = {
    "mode": "0 loops off (feed-forward tones), 1 x oscillator / y rebalanced, 2 reversed",
    "amplitude": "primary pick-off amplitude setpoint (LoopSettings.amplitude)",
    "plant_gain": "nominal P B / (2 omega) of each axis, for tuning",
    "pll_bandwidth": "bandwidth of the phase-locked loop",
    "agc_bandwidth": "bandwidth of the amplitude control",
    "rebalance_bandwidth": "bandwidth of the force rebalance loop",
    "demod_cutoff": "cutoff of each of the 3 low-pass sections of the PLL and AGC demodulators",
    "rebalance_cutoff": "cutoff of each of the 2 low-pass sections of the rebalance demodulator",
    "sideband_spacing": "spacing df of the sideband tones",
    "ff_xx": "feed-forward correction of Vx in the x pick-off",
    "ff_xy": "feed-forward correction of Vy in the x pick-off",
    "ff_yx": "feed-forward correction of Vx in the y pick-off",
    "ff_yy": "feed-forward correction of Vy in the y pick-off",
    "excitation_amplitude": "mode 0: amplitude of each tone on Vx and Vy",
    "excitation_offset_x": "mode 0: Vx tones at f_nominal -/+ this",
    "excitation_offset_y": "mode 0: Vy tones at f_nominal -/+ this",
}
_BOUNDS = {
    "mode": {"min": 0, "max": 2},
    "sideband_first": {"min": 0}, "sideband_count": {"min": 0},
    **{n: {"min": 0.0} for n in ("f_nominal", "amplitude", "q_nominal", "plant_gain",
                                 "pll_bandwidth", "agc_bandwidth", "rebalance_bandwidth",
                                 "demod_cutoff", "rebalance_cutoff", "drive_limit",
                                 "sideband_index", "sideband_spacing")},
}
#: Outputs, in the order of gyro_fmu.selfcal.loops.OUTPUTS.
_OUTPUTS = (
    Var("Vx", "output", 0.0, "V", "x forcer voltage, held over the next step"),
    Var("Vy", "output", 0.0, "V", "y forcer voltage, held over the next step"),
    Var("theta", "output", 0.0, "rad", "NCO phase, wrapped to [0, 2 pi)"),
    Var("omega", "output", 0.0, "rad/s", "NCO frequency"),
    Var("amplitude", "output", 0.0, "V", "demodulated primary pick-off amplitude"),
    Var("phase_error", "output", 0.0, "rad", "PLL phase error"),
    Var("gain", "output", 0.0, "V", "oscillator drive amplitude set by the AGC"),
    Var("rate", "output", 0.0, "V", "in-phase force rebalance command (rate output)"),
    Var("quad", "output", 0.0, "V", "quadrature force rebalance command"),
)


class GyroLoops(GyroSlave):
    """Closed-loop electronics of US 9,482,553 for GyroResonator: from the pick-off
    voltages Vpx, Vpy sampled at t it computes the forcer voltages Vx, Vy held from t.
    Feed-forward removal of the drive feed-through; oscillator loop (PLL on the primary
    pick-off, drive -g sin(theta + osc_phase) 90 deg ahead, PI amplitude control on the
    sideband-modulated position signal); force rebalance of the secondary axis with the
    rate (in-phase) and quadrature outputs; mode 1 x primary, 2 reversed, 0 loops off
    with off-resonant tones. Drive outputs are computed at the middle of the hold."""

    description = " ".join((__doc__ or "").split())
    #: 10 samples per 4 kHz carrier cycle; 0.02 s is the reference run stored in the FMU
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=0.02, step_size=25e-6)
    VARIABLES = (
        *parameter_variables(LoopSettings, _UNITS, _DESCRIPTIONS, _BOUNDS, LOOPS_RENAMED),
        Var("Vpx", "input", 0.0, "V", "x pick-off voltage sampled at the step start"),
        Var("Vpy", "input", 0.0, "V", "y pick-off voltage sampled at the step start"),
        *_OUTPUTS,
    )

    #: `gyro-fmu doctor`'s C-host check: None, no inputs set and every Real output read.
    DOCTOR_CHECK = None

    @classmethod
    def reference_inputs(cls, stop_time: float, step: float) -> np.ndarray:
        """Inputs of the reference run stored in the FMU: a 1 V, 4 kHz primary pick-off
        and a small secondary one (the PLL locks, the AGC and the rebalance act)."""
        from gyro_fmu.fmu.reference import input_table

        t = np.arange(round(stop_time / step) + 1) * step
        carrier = 2 * np.pi * 4000.0 * t
        return input_table(t, {"Vpx": np.cos(carrier + 0.3),
                               "Vpy": 0.01 * np.sin(carrier + 0.1)})

    def setup(self) -> None:
        from gyro_fmu.selfcal.loops import OUTPUTS, LoopsModel
        from gyro_fmu.selfcal.run import settings_from_parameters

        if tuple(v.name for v in _OUTPUTS) != OUTPUTS:
            raise ValueError(f"GyroLoops outputs differ from the library's {OUTPUTS}: rebuild")
        settings = settings_from_parameters(LoopSettings, self, LOOPS_RENAMED)
        problems = settings.problems()
        if problems:
            raise ValueError("unusable loop settings: " + "; ".join(problems))
        self.model = LoopsModel(settings)
        self._names = OUTPUTS
        self._publish()

    def advance(self, t: float, h: float) -> None:
        self.model.step(self.Vpx, self.Vpy, t, h)
        self._publish()

    def _publish(self) -> None:
        self.__dict__.update(zip(self._names, self.model.out.tolist(), strict=True))
