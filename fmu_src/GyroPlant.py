"""GyroPlant.fmu, pythonfmu flavour: a thin adapter over the C core's plant (the native
FMU, fmu_src/models/GyroPlant/, is the default; this one is built on request)."""

from gyro_fmu.model.interfaces import PLANT
from gyro_fmu.model.parameters import PARAMETER_NAMES
from gyro_fmu.pythonfmu.slave import GyroSlave


class GyroPlant(GyroSlave):
    description = PLANT.description
    VARIABLES = PLANT.variables

    def setup(self) -> None:
        from gyro_fmu.model.parameters import GyroParameters
        from gyro_fmu.model.plant import GyroPlantModel, MeasurementNoise

        params = GyroParameters(**{n: getattr(self, n) for n in PARAMETER_NAMES})
        noise = MeasurementNoise(self.noise_x, self.noise_vx, self.noise_y, self.noise_vy)
        self.model = GyroPlantModel(params, noise, seed=int(self.seed))
        self._publish()

    def advance(self, t: float, h: float) -> None:
        self.model.step(self.ux, self.uy, self.Omega_z, h)
        self._publish()

    def _publish(self) -> None:
        self.x, self.vx, self.y, self.vy, self.ax, self.ay = self.model.output_row()
