"""GyroObserver.fmu, pythonfmu flavour: a thin adapter over the C core's observer (the
native FMU, fmu_src/models/GyroObserver/, is the default; this one is built on request)."""

from pythonfmu.enums import Fmi2Status

from gyro_fmu.estimation.interface import OBSERVER, OUTPUTS
from gyro_fmu.estimation.observer import ObserverDivergedError, ObserverTuning
from gyro_fmu.model.parameters import PARAMETER_UNITS
from gyro_fmu.pythonfmu.slave import GyroSlave, dataclass_from_parameters

#: Status-1 warnings logged per instance (a noisy run may enter and leave status 1 often).
_MAX_WARNINGS = 3


class GyroObserver(GyroSlave):
    description = OBSERVER.description
    VARIABLES = OBSERVER.variables

    state_holder = "observer"
    #: Set by the parameters: a restored state must have the instance's own.
    fixed_model_keys = ("version", "measured_pair", "tuning")

    def setup(self) -> None:
        from gyro_fmu.estimation.observer import GyroStateObserver
        from gyro_fmu.model.parameters import GyroParameters

        initial = GyroParameters(**{n: getattr(self, f"{n}_0") for n in PARAMETER_UNITS})
        tuning = dataclass_from_parameters(ObserverTuning, self)
        self.observer = GyroStateObserver(initial, self.Omega_z_0, int(self.measured_pair), tuning)
        self._guess = initial  # the drive check's, at the first step
        self._warnings_logged = 0
        self._drive_checked = False
        self._publish()

    def advance(self, t: float, h: float) -> None:
        if self.measured_pair == 1:
            z1, z2 = self.x_meas, self.y_meas
        else:
            z1, z2 = self.vx_meas, self.vy_meas
        try:
            self.observer.step(self.ux, self.uy, z1, z2, h)
        except ObserverDivergedError as exc:  # the instance cannot go on: fmi2Discard now,
            self.failed = str(exc)  # fmi2Error from then on (restore an earlier FMU state)
            self._outputs_not_a_number()
            self.status = 2.0
            raise
        if not self._drive_checked:  # the tones, when told, judged at the first step
            self._drive_checked = True
            if self.f1 > 0.0 and self.f2 > 0.0:
                from gyro_fmu.model.drive import TwoToneDrive, drive_warning

                text = drive_warning(self._guess, TwoToneDrive(1.0, self.f1, 1.0, self.f2),
                                     self.Omega_z_0, h, int(self.measured_pair))
                if text:
                    self.log(f"{self.modelName}: {text}", Fmi2Status.warning)
        if self.observer.status != self.status:
            if self.observer.status == 1 and self._warnings_logged < _MAX_WARNINGS:
                self._warnings_logged += 1
                more = (" (further warnings not logged: the status output carries them)"
                        if self._warnings_logged == _MAX_WARNINGS else "")
                self.log(f"{self.modelName}: {self.observer.warning}{more}",
                         Fmi2Status.warning)
            self.status = float(self.observer.status)
        self._publish()

    def _publish(self) -> None:
        self.__dict__.update(zip(OUTPUTS, self.observer.output_row(), strict=True))
        for k, p in self.observer.rate_probabilities().items():
            setattr(self, f"p_rate_{k}", p)
