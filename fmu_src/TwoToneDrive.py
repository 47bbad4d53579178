"""TwoToneDrive.fmu, pythonfmu flavour: a thin adapter over the C core's drive (eq. 10)."""

from gyro_fmu.model.interfaces import DRIVE
from gyro_fmu.pythonfmu.slave import GyroSlave


class TwoToneDrive(GyroSlave):
    description = DRIVE.description
    VARIABLES = DRIVE.variables

    def setup(self) -> None:
        from gyro_fmu.model.drive import TwoToneDrive as Drive

        self.drive = Drive(self.A1, self.f1, self.A2, self.f2)
        problems = self.drive.problems()
        if problems:
            raise ValueError("; ".join(problems))
        self.ux = self.drive.ux(self.start_time)

    def advance(self, t: float, h: float) -> None:
        self.ux = self.drive.ux(t + h)
