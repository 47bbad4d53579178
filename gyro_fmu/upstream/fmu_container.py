"""fmu-manipulation-toolbox 2.0's container runtime fails on an embedded FMU's warning at
initialization.

FMI 2.0 (section 2.1.3) makes fmi2Warning a success: "the computation can continue".
The toolbox's container (resources/<platform>/container.so, 2.0) turns an embedded
FMU's fmi2Warning from fmi2ExitInitializationMode into fmi2Error for the whole container
(a warning from fmi2DoStep passes). GyroPlant.fmu warns there when its damping matrix is
indefinite (US 2011/0314910's Table 1: dyy = 0, dxy = 10 1/s), so GyroSystem.fmu cannot
run the patent scenario. `container_init_problem` names that before a user's run fails
without a word (canary `test_fmu_container_still_fails_on_an_init_warning`).
"""

from __future__ import annotations

TOOLBOX = "fmu-manipulation-toolbox 2.0"


def container_init_problem(plant_warning: str) -> str:
    """Why GyroSystem.fmu cannot run a plant that warns at initialization ("" if none)."""
    if not plant_warning:
        return ""
    return (f"GyroPlant.fmu warns at initialization ({plant_warning}), and {TOOLBOX}'s "
            "container runtime turns an embedded FMU's warning at "
            "fmi2ExitInitializationMode into an error for the whole container: run this "
            "scenario with `gyro-fmu run`, or the four FMUs in fmpy, libcosim or Ecos "
            "(`gyro-fmu ssp`)")
