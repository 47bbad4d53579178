"""GyroObserver.fmu: the augmented state observer of US 2011/0314910 A1 (eqs. 5-9)."""

import numpy as np
from pythonfmu.enums import Fmi2Status

from gyro_fmu.estimation.observer import ObserverDivergedError, ObserverTuning
from gyro_fmu.estimation.observer_rate import RATE_KINDS
from gyro_fmu.fmu.slave import GyroSlave, Var, dataclass_from_parameters, dataclass_parameters
from gyro_fmu.model.parameters import DEFAULT_PRESET, PARAMETER_BOUNDS, PARAMETER_UNITS, PRESETS
from gyro_fmu.system.scenario import default_initial_guess

_GUESS = default_initial_guess(PRESETS[DEFAULT_PRESET])
_UNITS = {**PARAMETER_UNITS, "Omega_z": "rad/s"}
_ESTIMATED = ("Omega_z", "kxx", "kyy", "kxy", "dxx", "dyy", "dxy", "m")
#: Status-1 warnings logged per instance (a noisy run may enter and leave status 1 often).
_MAX_WARNINGS = 3
_HAT = {"Omega_z": "Omega_hat"}  # the patent's Omega_z' is published as Omega_hat
#: What each of observer_rate.RATE_KINDS means, for the p_rate_* descriptions.
_RATE_KINDS = {"constant": "Omega_z held",
               "rough": "Omega_z wandering (random walk) at up to a tenth of rate_bandwidth",
               "slow": "Omega_z moving smoothly at up to a tenth of rate_bandwidth",
               "agile": "Omega_z moving smoothly at up to rate_bandwidth"}
#: The outputs in the order of GyroStateObserver.output_row().
_OUTPUTS = ("x_hat", "vx_hat", "y_hat", "vy_hat", *(_HAT.get(n, f"{n}_hat") for n in _ESTIMATED),
            *(f"sigma_{n}" for n in _ESTIMATED))


class GyroObserver(GyroSlave):
    """State observer of the single-axis-control-input gyroscope (US 2011/0314910 A1,
    eqs. 5-9): from the drive ux, uy and two measured signals (measured_pair 1: x, y;
    2: vx, vy) it estimates the states and the 8 unknowns kxx, kyy, kxy, dxx, dyy, dxy,
    m and Omega_z with 1-sigma uncertainties. Inputs are held over each communication
    step exactly as GyroPlant holds them; outputs at t+h are predictions from data up
    to t. Output status: 0 ok, 1 warning, 2 lost (then the step is refused with
    fmi2Discard and the cause logged)."""

    description = " ".join((__doc__ or "").split())
    VARIABLES = (
        *(Var(f"{n}_0", "parameter", _GUESS[n], PARAMETER_UNITS[n], f"initial guess of {n}",
              **PARAMETER_BOUNDS[n]) for n in PARAMETER_UNITS),
        Var("Omega_z_0", "parameter", 0.0, "rad/s", "initial guess of Omega_z"),
        Var("measured_pair", "parameter", 1, None,
            "measured signals used: 1 positions x, y; 2 velocities vx, vy",
            integer=True, min=1, max=2),
        *dataclass_parameters(ObserverTuning),
        Var("ux", "input", 0.0, "N", "x-axis drive force, held over the step"),
        Var("uy", "input", 0.0, "N", "y-axis drive force, held over the step"),
        Var("x_meas", "input", 0.0, "m", "measured x-axis position"),
        Var("vx_meas", "input", 0.0, "m/s", "measured x-axis velocity"),
        Var("y_meas", "input", 0.0, "m", "measured y-axis position"),
        Var("vy_meas", "input", 0.0, "m/s", "measured y-axis velocity"),
        Var("x_hat", "output", 0.0, "m", "estimated x-axis position"),
        Var("vx_hat", "output", 0.0, "m/s", "estimated x-axis velocity"),
        Var("y_hat", "output", 0.0, "m", "estimated y-axis position"),
        Var("vy_hat", "output", 0.0, "m/s", "estimated y-axis velocity"),
        *(Var(_HAT.get(n, f"{n}_hat"), "output", 0.0, _UNITS[n], f"estimate of {n}")
          for n in _ESTIMATED),
        *(Var(f"sigma_{n}", "output", 0.0, _UNITS[n], f"1-sigma uncertainty of {n}", min=0.0)
          for n in _ESTIMATED),
        *(Var(f"p_rate_{k}", "output", 1.0 / len(RATE_KINDS), "1",
              f"probability that the rate is {k} ({_RATE_KINDS[k]}; adaptive rate model; "
              "a fixed one: 1 for its kind, 0 else)", min=0.0, max=1.0) for k in RATE_KINDS),
        Var("status", "output", 0.0, "1",
            "observer health: 0 ok; 1 warning (innovations outside their band, logged: the "
            "estimates may be off more than their sigmas say); 2 lost (the filter diverged "
            "or lost its numerical footing: the step is refused with fmi2Discard and the "
            "cause logged, every other output NaN). A Real so that hosts reading every "
            "output as Real get it", min=0.0, max=2.0),
    )

    #: `gyro-fmu doctor`'s C-host check: None, no inputs set and every Real output read.
    DOCTOR_CHECK = None

    @classmethod
    def reference_inputs(cls, stop_time: float, step: float) -> np.ndarray:
        """Inputs of the reference run stored in the FMU: the default scenario's
        two-tone drive and the noise-free measurements of its plant."""
        from gyro_fmu.fmu.reference import input_table
        from gyro_fmu.system.scenario import noise_free_run, scenario

        sc = scenario("default", stop_time=stop_time, step=step)
        t = np.arange(sc.n_steps + 1) * step
        ux = np.array([sc.the_drive.ux(tk) for tk in t])
        s = noise_free_run(sc)
        return input_table(t, {"ux": ux, "uy": 0 * t, "x_meas": s[:, 0], "vx_meas": s[:, 1],
                               "y_meas": s[:, 2], "vy_meas": s[:, 3]})

    state_holder = "observer"
    #: Set by the parameters: a restored state must have the instance's own.
    fixed_model_keys = ("version", "measured_pair", "tuning")

    def setup(self) -> None:
        from gyro_fmu.estimation.observer import GyroStateObserver
        from gyro_fmu.model.parameters import GyroParameters

        initial = GyroParameters(**{n: getattr(self, f"{n}_0") for n in PARAMETER_UNITS})
        tuning = dataclass_from_parameters(ObserverTuning, self)
        self.observer = GyroStateObserver(initial, self.Omega_z_0, int(self.measured_pair), tuning)
        self._warnings_logged = 0
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
        self.__dict__.update(zip(_OUTPUTS, self.observer.output_row(), strict=True))
        for k, p in self.observer.rate_probabilities().items():
            setattr(self, f"p_rate_{k}", p)
