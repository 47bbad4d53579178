"""GyroPlant.fmu: the 2-DOF MEMS gyroscope of US 2011/0314910 A1 (eqs. 3-5)."""

import numpy as np

from gyro_fmu.fmu.slave import GyroSlave, Var
from gyro_fmu.model.parameters import DEFAULT_PRESET, PARAMETER_BOUNDS, PARAMETER_UNITS, PRESETS

_P = PRESETS[DEFAULT_PRESET]
_DESCRIPTIONS = {
    "kxx": "x-axis stiffness / m", "kyy": "y-axis stiffness / m",
    "kxy": "cross-axis stiffness / m", "dxx": "x-axis damping / m",
    "dyy": "y-axis damping / m", "dxy": "cross-axis damping / m", "m": "proof mass",
}


class GyroPlant(GyroSlave):
    """MEMS vibratory gyroscope (US 2011/0314910 A1, eqs. 3-5, consistent form).
    Inputs ux, uy, Omega_z are held over each communication step and the step is
    integrated exactly (matrix exponential); outputs x, vx, y, vy are the measured
    signals (seeded white noise when noise_* > 0)."""

    description = " ".join((__doc__ or "").split())
    VARIABLES = (
        *(Var(n, "parameter", getattr(_P, n), PARAMETER_UNITS[n], d, **PARAMETER_BOUNDS[n])
          for n, d in _DESCRIPTIONS.items()),
        Var("noise_x", "parameter", 0.0, "m", "std of white noise on measured x", min=0.0,
            nominal=1e-12),
        Var("noise_vx", "parameter", 0.0, "m/s", "std of white noise on measured vx", min=0.0,
            nominal=1e-8),
        Var("noise_y", "parameter", 0.0, "m", "std of white noise on measured y", min=0.0,
            nominal=1e-12),
        Var("noise_vy", "parameter", 0.0, "m/s", "std of white noise on measured vy", min=0.0,
            nominal=1e-8),
        Var("seed", "parameter", 0, None, "seed of the noise generator", integer=True, min=0),
        Var("ux", "input", 0.0, "N", "x-axis drive force, held over the step", nominal=1e-7),
        Var("uy", "input", 0.0, "N", "y-axis drive force, held over the step", nominal=1e-7),
        Var("Omega_z", "input", 0.0, "rad/s", "angular rate about z, held over the step"),
        Var("x", "output", 0.0, "m", "measured x-axis position", nominal=1e-9),
        Var("vx", "output", 0.0, "m/s", "measured x-axis velocity", nominal=1e-5),
        Var("y", "output", 0.0, "m", "measured y-axis position", nominal=1e-9),
        Var("vy", "output", 0.0, "m/s", "measured y-axis velocity", nominal=1e-5),
        Var("ax", "output", 0.0, "m/s2", "x-axis acceleration (inputs of the last step)"),
        Var("ay", "output", 0.0, "m/s2", "y-axis acceleration (inputs of the last step)"),
    )

    #: `gyro-fmu doctor`'s C-host check: (inputs held over every step, outputs read);
    #: 1e-7 N on x at 1 rad/s moves the default plant by a few nm.
    DOCTOR_CHECK = ({"ux": 1e-7, "uy": 0.0, "Omega_z": 1.0}, ("x", "vx", "y", "vy"))

    @classmethod
    def reference_inputs(cls, stop_time: float, step: float) -> np.ndarray:
        """Inputs of the reference run stored in the FMU: the default scenario's
        two-tone drive and a constant 1 rad/s."""
        from gyro_fmu.fmu.reference import input_table
        from gyro_fmu.system.scenario import scenario

        sc = scenario("default", stop_time=stop_time, step=step)
        t = np.arange(sc.n_steps + 1) * step
        ux = np.array([sc.the_drive.ux(tk) for tk in t])
        return input_table(t, {"ux": ux, "uy": 0 * t, "Omega_z": np.ones_like(t)})

    def setup(self) -> None:
        from gyro_fmu.model.parameters import GyroParameters
        from gyro_fmu.model.plant import GyroPlantModel, MeasurementNoise

        params = GyroParameters(**{n: getattr(self, n) for n in _DESCRIPTIONS})
        noise = MeasurementNoise(self.noise_x, self.noise_vx, self.noise_y, self.noise_vy)
        self.model = GyroPlantModel(params, noise, seed=int(self.seed))
        self._publish()

    def advance(self, t: float, h: float) -> None:
        self.model.step(self.ux, self.uy, self.Omega_z, h)
        self._publish()

    def _publish(self) -> None:
        self.x, self.vx, self.y, self.vy, self.ax, self.ay = self.model.output_row()
