"""The system example as one file: GyroSensor in the rate loop of StabilizedPlatform on a
swaying vehicle (gyro_fmu.sensor.platform), as an SSP package that libcosim and Ecos run
(`gyro-fmu ssp --system platform`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..cosim.master import run_cosimulation
from ..sensor.platform import STEP, STOP_TIME, platform_system
from .ssp import relative_differences, run_ssp_libcosim, write_system_ssp

RECORD = ("platform.theta", "platform.w", "gyro.Omega_meas")


def platform_ssp(models: Path, dest: Path | None = None, run: bool = False,
                 compare: bool = False) -> int:
    """Write models/StabilizedPlatform.ssp (or dest); run: in libcosim, printing the RMS
    pointing error over the second half; compare: also the differences from fmpy's
    master on the same FMUs."""
    components, connections = platform_system(models)
    path = write_system_ssp(components, connections, STOP_TIME, STEP,
                            dest or models / "StabilizedPlatform.ssp")
    print(f"wrote {path}")
    if run or compare:
        result = run_ssp_libcosim(path, record=RECORD)
        late = np.asarray(result["time"]) >= STOP_TIME / 2
        rms = float(np.sqrt(np.mean(np.asarray(result["platform.theta"])[late] ** 2)))
        print(f"libcosim: RMS pointing error over the second half {rms * 1e3:.4g} mrad")
        if compare:
            rel = relative_differences(result, run_cosimulation(components, connections,
                                                                STOP_TIME, STEP))
            print("max |libcosim - fmpy| / max |fmpy|: "
                  + ", ".join(f"{name} {value:.3g}" for name, value in rel.items()))
    return 0
