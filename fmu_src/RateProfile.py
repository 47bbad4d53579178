"""RateProfile.fmu, pythonfmu flavour: a thin adapter over the C core's rate profiles."""

from gyro_fmu.model.interfaces import RATE
from gyro_fmu.pythonfmu.slave import GyroSlave


class RateProfile(GyroSlave):
    description = RATE.description
    VARIABLES = RATE.variables

    def setup(self) -> None:
        from gyro_fmu.model.rate import RateKind
        from gyro_fmu.model.rate import RateProfile as Profile

        self.profile = Profile(RateKind(int(self.kind)), self.offset, self.amplitude,
                               self.frequency, self.slope, self.t_start)
        problems = self.profile.problems()
        if problems:
            raise ValueError("; ".join(problems))
        self.Omega_z = self.profile.Omega_z(self.start_time)

    def advance(self, t: float, h: float) -> None:
        self.Omega_z = self.profile.Omega_z(t + h)
