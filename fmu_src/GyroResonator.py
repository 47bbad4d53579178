"""GyroResonator.fmu: the resonator of US 9,482,553 (eq. 1), voltages in and out."""

import numpy as np
from pythonfmu.default_experiment import DefaultExperiment

from gyro_fmu.fmu.slave import GyroSlave, Var
from gyro_fmu.selfcal.resonator import ResonatorParameters
from gyro_fmu.selfcal.run import parameter_variables

#: FMI unit of every field of ResonatorParameters.
_UNITS = {
    "f_x": "Hz", "f_y": "Hz", "Q_x": "1", "Q_y": "1", "dxy": "1/s", "kxy": "1/s2",
    "kappa": "1", "Bx": "m/s2/V", "By": "m/s2/V", "alpha_x": "rad", "alpha_y": "rad",
    "Px": "V/m", "Py": "V/m", "phi_x": "rad", "phi_y": "rad",
    "Exx": "1", "Exy": "1", "Eyx": "1", "Eyy": "1", "c_ring": "m/V",
    "ring_amplitude": "V", "ring_frequency_1": "Hz", "ring_frequency_2": "Hz", "noise": "V",
    "k3x": "1/(m2.s2)", "k3y": "1/(m2.s2)", "k3xy": "1/(m2.s2)", "k3yx": "1/(m2.s2)",
    "beta_x": "rad", "beta_y": "rad", "m_modal": "kg", "temperature": "K", "drive_noise": "V",
    "temperature_rate": "K/s", "tc_f": "1/K", "tc_Q": "1/K",
}
#: Declared bounds (check_resonator states the strict ones at initialization).
_BOUNDS = {
    **{n: {"min": 0.0} for n in ("f_x", "f_y", "Q_x", "Q_y", "kappa", "Bx", "By", "Px", "Py",
                                 "noise", "drive_noise", "m_modal", "temperature")},
    **{n: {"min": -0.5, "max": 0.5} for n in ("beta_x", "beta_y")},
    **{n: {"min": 0.0, "max": 1.5} for n in ("phi_x", "phi_y")},
    "Px": {"min": 0.0, "nominal": 1e6}, "Py": {"min": 0.0, "nominal": 1e6},
    "c_ring": {"nominal": 1e-7},
    "cubic_substeps": {"min": 1}, "thermal_update_steps": {"min": 1},
}


class GyroResonator(GyroSlave):
    """Near mode-matched resonator of US 9,482,553, eq. 1, per unit modal mass:
    x'' + dxx x' + (dxy - 2 kappa Omega_z) y' + kxx x + kxy y = fx,
    y'' + dyy y' + (dxy + 2 kappa Omega_z) x' + kyy y + kxy x = fy,
    plus optional cubic stiffness k3x x^3 + k3xy y^3, k3y y^3 + k3yx x^3 (eqs. 20-23),
    fx = Bx (Vx + alpha_y Vy), fy = By (Vy + alpha_x Vx), with kxx = (2 pi f_x)^2,
    dxx = 2 pi f_x / Q_x (y alike). Pick-offs: Vpx = Px zx + Exx Vx + Exy Vy + noise,
    Vpy = Py zy + Eyx Vx + Eyy Vy + noise, first-order lags tau z' = q_s - z + c_ring
    V_ring with tan phi = 2 pi f_x tau, sensed displacements (non-orthogonal pick-offs)
    x_s = cos(beta_x) x + sin(beta_x) y, y_s = cos(beta_y) y + sin(beta_y) x,
    V_ring = ring_amplitude (cos 2 pi ring_frequency_1 t + cos 2 pi ring_frequency_2 t)
    generated inside. Inputs Vx, Vy,
    Omega_z are held over each communication step, which is integrated exactly
    (matrix exponential). Optional thermomechanical force noise (one-sided PSD
    4 k_B T D / m_modal, D the damping matrix), white noise of std drive_noise on the
    held Vx, Vy, and a temperature ramp temperature_rate moving f by tc_f and Q by tc_Q
    per kelvin (step matrices recomputed every thermal_update_steps steps). The seeded
    noise (pick-off noise and, from an independent stream, force and drive noise)
    equals the in-process gyro_fmu.selfcal.inprocess run sample for sample."""

    description = " ".join((__doc__ or "").split())
    #: 10 samples per 4 kHz carrier cycle; 0.02 s is the reference run stored in the FMU
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=0.02, step_size=25e-6)
    VARIABLES = (
        *parameter_variables(ResonatorParameters, _UNITS, bounds=_BOUNDS),
        Var("seed", "parameter", 0, None, "seed of the noise generators", integer=True,
            min=0),
        Var("Vx", "input", 0.0, "V", "x forcer voltage, held over the step"),
        Var("Vy", "input", 0.0, "V", "y forcer voltage, held over the step"),
        Var("Omega_z", "input", 0.0, "rad/s", "angular rate about z, held over the step"),
        Var("Vpx", "output", 0.0, "V", "x pick-off voltage"),
        Var("Vpy", "output", 0.0, "V", "y pick-off voltage"),
    )

    #: `gyro-fmu doctor`'s C-host check: None, no inputs set and every Real output read.
    DOCTOR_CHECK = None

    @classmethod
    def reference_inputs(cls, stop_time: float, step: float) -> np.ndarray:
        """Inputs of the reference run stored in the FMU: a 0.6 V drive at 4 kHz on x
        and a constant 1 rad/s."""
        from gyro_fmu.fmu.reference import input_table

        t = np.arange(round(stop_time / step) + 1) * step
        carrier = 2 * np.pi * 4000.0 * t
        return input_table(t, {"Vx": 0.6 * np.sin(carrier), "Vy": 0 * t,
                               "Omega_z": np.ones_like(t)})

    def setup(self) -> None:
        import numpy as np

        from gyro_fmu.fmu.slave import dataclass_from_parameters
        from gyro_fmu.selfcal.resonator import ResonatorModel, check_resonator

        params = dataclass_from_parameters(ResonatorParameters, self)
        problems = check_resonator(params)
        if problems:
            raise ValueError("unusable resonator parameters: " + "; ".join(problems))
        self.model = ResonatorModel(params, seed=int(self.seed))
        self._V = np.zeros(2)
        self._publish()

    def model_state_problem(self, state: dict) -> str | None:
        """The noise block positions must lie within the blocks they index."""
        for key in ("noise", "extra"):
            noise = state[key]
            if not 0 <= noise["pos"] <= len(noise["block"]):
                return (f"model.{key}.pos={noise['pos']} is outside its block "
                        f"0..{len(noise['block'])}")
        if state["k"] < 0:
            return f"model.k={state['k']} must be >= 0 (steps taken)"
        return None

    def advance(self, t: float, h: float) -> None:
        V = self._V
        V[0], V[1] = self.Vx, self.Vy
        self.model.step(V, self.Omega_z, h)
        self._publish()

    def _publish(self) -> None:
        out = self.model.out
        self.Vpx, self.Vpy = float(out[0]), float(out[1])
