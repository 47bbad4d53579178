"""RateProfile.fmu: the angular rate Omega_z(t) applied to the gyroscope."""

from gyro_fmu.fmu.slave import GyroSlave, Var
from gyro_fmu.model.rate import RateKind
from gyro_fmu.model.rate import RateProfile as _Defaults

_R = _Defaults()


class RateProfile(GyroSlave):
    """Omega_z(t): kind 1 constant (offset), 2 step (offset + amplitude from t_start),
    3 ramp (offset + slope (t - t_start) from t_start), 4 sine (offset + amplitude
    sin(2 pi frequency (t - t_start)) from t_start; the patent's case is 1 rad/s at 100 Hz)."""

    description = " ".join((__doc__ or "").split())
    VARIABLES = (
        Var("kind", "parameter", int(_R.kind), None,
            "profile: 1 constant, 2 step, 3 ramp, 4 sine", integer=True,
            min=min(RateKind), max=max(RateKind)),
        Var("offset", "parameter", _R.offset, "rad/s", "constant part of the rate"),
        Var("amplitude", "parameter", _R.amplitude, "rad/s", "step height or sine amplitude"),
        Var("frequency", "parameter", _R.frequency, "Hz", "sine frequency", min=0.0),
        Var("slope", "parameter", _R.slope, "rad/s2", "ramp slope"),
        Var("t_start", "parameter", _R.t_start, "s", "time the step, ramp or sine starts"),
        Var("Omega_z", "output", _R.offset, "rad/s", "angular rate about z"),
    )

    #: `gyro-fmu doctor`'s C-host check: (inputs held over every step, outputs read).
    DOCTOR_CHECK = ({}, ("Omega_z",))

    @classmethod
    def reference_inputs(cls, stop_time: float, step: float) -> None:
        """The reference run stored in the FMU has no inputs."""
        return None

    def setup(self) -> None:
        from gyro_fmu.model.rate import RateProfile as Profile

        self.profile = Profile(RateKind(int(self.kind)), self.offset, self.amplitude,
                               self.frequency, self.slope, self.t_start)
        self.Omega_z = self.profile.Omega_z(self.start_time)

    def advance(self, t: float, h: float) -> None:
        self.Omega_z = self.profile.Omega_z(t + h)
