"""GyroResonator.fmu, pythonfmu flavour: a thin adapter over the C core's resonator (the
native FMU, fmu_src/models/GyroResonator/, is the default; this one is built on request)."""

from pythonfmu.default_experiment import DefaultExperiment

from gyro_fmu.model.resonator import ResonatorParameters
from gyro_fmu.model.selfcal_interfaces import RESONATOR
from gyro_fmu.pythonfmu.slave import GyroSlave, dataclass_from_parameters


class GyroResonator(GyroSlave):
    description = RESONATOR.description
    VARIABLES = RESONATOR.variables
    default_experiment = DefaultExperiment(0.0, *RESONATOR.default_experiment)

    def setup(self) -> None:
        import numpy as np

        from gyro_fmu.model.resonator import ResonatorModel

        params = dataclass_from_parameters(ResonatorParameters, self)
        self.model = ResonatorModel(params, seed=int(self.seed))
        self._V = np.zeros(2)
        self._publish()

    def advance(self, t: float, h: float) -> None:
        V = self._V
        V[0], V[1] = self.Vx, self.Vy
        self.model.step(V, self.Omega_z, h)
        self._publish()

    def _publish(self) -> None:
        self.Vpx, self.Vpy = self.model.out.tolist()
        self.T_sensor = self.model.T_sensor
