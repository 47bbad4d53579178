"""GyroLoops.fmu, pythonfmu flavour: a thin adapter over the C core's loops (the native
FMU, fmu_src/models/GyroLoops/, is the default; this one is built on request)."""

from pythonfmu.default_experiment import DefaultExperiment

from gyro_fmu.model.loops import OUTPUTS, LoopSettings
from gyro_fmu.model.selfcal_interfaces import LOOPS, LOOPS_RENAMED, settings_from_parameters
from gyro_fmu.pythonfmu.slave import GyroSlave


class GyroLoops(GyroSlave):
    description = LOOPS.description
    VARIABLES = LOOPS.variables
    default_experiment = DefaultExperiment(0.0, *LOOPS.default_experiment)

    def setup(self) -> None:
        from gyro_fmu.model.loops import LoopsModel

        self.model = LoopsModel(settings_from_parameters(LoopSettings, self, LOOPS_RENAMED))
        self._publish()

    def advance(self, t: float, h: float) -> None:
        self.model.step(self.Vpx, self.Vpy, t, h)
        self._publish()

    def _publish(self) -> None:
        self.__dict__.update(zip(OUTPUTS, self.model.out.tolist(), strict=True))
