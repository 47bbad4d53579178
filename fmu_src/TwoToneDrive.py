"""TwoToneDrive.fmu: the single-axis two-tone drive force of patent eq. 10."""

from gyro_fmu.fmu.slave import GyroSlave, Var
from gyro_fmu.model.drive import TwoToneDrive as _Defaults

_D = _Defaults()


class TwoToneDrive(GyroSlave):
    """ux = A1 sin(2 pi f1 t) + A2 sin(2 pi f2 t) (US 2011/0314910 A1, eq. 10);
    uy = 0 for a single-axis-control-input gyroscope."""

    description = " ".join((__doc__ or "").split())
    VARIABLES = (
        Var("A1", "parameter", _D.A1, "N", "amplitude of tone 1"),
        Var("f1", "parameter", _D.f1, "Hz", "frequency of tone 1", min=0.0),
        Var("A2", "parameter", _D.A2, "N", "amplitude of tone 2"),
        Var("f2", "parameter", _D.f2, "Hz", "frequency of tone 2", min=0.0),
        Var("ux", "output", 0.0, "N", "x-axis drive force"),
        Var("uy", "output", 0.0, "N", "y-axis drive force (0: single-axis control input)"),
    )

    #: `gyro-fmu doctor`'s C-host check: (inputs held over every step, outputs read).
    DOCTOR_CHECK = ({}, ("ux", "uy"))

    @classmethod
    def reference_inputs(cls, stop_time: float, step: float) -> None:
        """The reference run stored in the FMU has no inputs."""
        return None

    def setup(self) -> None:
        from gyro_fmu.model.drive import TwoToneDrive as Drive

        self.drive = Drive(self.A1, self.f1, self.A2, self.f2)
        problems = self.drive.problems()
        if problems:
            raise ValueError("; ".join(problems))
        self.ux = self.drive.ux(self.start_time)

    def advance(self, t: float, h: float) -> None:
        self.ux = self.drive.ux(t + h)
