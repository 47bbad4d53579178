"""The self-calibration FMUs co-simulated: GyroResonator.fmu and GyroLoops.fmu through the
project's master (gyro_fmu.cosim.master), recorded as a CarrierRecord. Both FMUs step the
C core that CarrierSimulation.run steps in process, so the two records are bit-identical
(the tests hold it); CarrierSimulation is the fast path for long calibration records,
this is the same system as importers see it. Their declarations are
gyro_fmu.model.selfcal_interfaces.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from ..model.loops import OUTPUTS as LOOP_OUTPUTS
from ..model.loops import LoopsError, LoopSettings
from ..model.resonator import ResonatorParameters
from ..model.selfcal_interfaces import LOOPS_RENAMED, SELFCAL_INTERFACES, fmu_parameters
from .inprocess import COLUMNS, DEFAULT_STEP, CarrierRecord

#: The FMUs of the self-calibration system (model identifiers).
SELFCAL_FMUS = tuple(SELFCAL_INTERFACES)


def run_fmus(
    resonator: ResonatorParameters,
    settings: LoopSettings,
    duration: float,
    step: float = DEFAULT_STEP,
    Omega_z: float = 0.0,
    seed: int = 0,
    record_from: float = 0.0,
    models_dir: Path | None = None,
    sink: Callable[[np.ndarray, int], None] | None = None,
) -> CarrierRecord | None:
    """Co-simulate GyroResonator.fmu and GyroLoops.fmu from rest for duration (s).

    Same arguments and record as CarrierSimulation(resonator, settings, seed, step,
    Omega_z).run(duration, record_from): columns carrier.COLUMNS, the communication
    points from record_from (s) to the end, both included. Missing FMUs are built
    into models_dir (default gyro_fmu.fmu.build.MODELS_DIR).

    The constant rate Omega_z is the value of the resonator's unconnected input
    Omega_z, set once before initialization (an FMI 2.0 input holds its last value).
    sink: hand the rows on as they are made instead (CarrierSimulation.advance's
    sink(rows, k), the points 0 .. the one before the end); returns None then.
    """
    from ..cosim.master import Component, Connection, run_cosimulation
    from ..fmu.build import MODELS_DIR, ensure_current

    models_dir = Path(MODELS_DIR if models_dir is None else models_dir)
    ensure_current(SELFCAL_FMUS, models_dir)
    problems = settings.problems()
    if problems:  # the FMU would say the same at initialization, less directly
        raise LoopsError("; ".join(problems))
    components = [
        Component("resonator", models_dir / "GyroResonator.fmu",
                  {**fmu_parameters(resonator), "seed": int(seed)},
                  inputs={"Omega_z": float(Omega_z)}),
        Component("loops", models_dir / "GyroLoops.fmu", fmu_parameters(settings, LOOPS_RENAMED)),
    ]
    connections = [Connection(f"loops.{v}", f"resonator.{v}") for v in ("Vx", "Vy")]
    connections += [Connection(f"resonator.{v}", f"loops.{v}") for v in ("Vpx", "Vpy")]
    record = [f"loops.{v}" for v in LOOP_OUTPUTS] + ["resonator.Vpx", "resonator.Vpy"]
    n = round(duration / step)
    if sink is not None:
        def before_end(rows: np.ndarray, k: int) -> None:
            sink(rows[: max(0, min(len(rows), n - k))], k)

        run_cosimulation(components, connections, n * step, step, record=record,
                         sink=before_end)
        return None
    result = run_cosimulation(components, connections, n * step, step, record=record)
    if result.data.shape != (n + 1, len(COLUMNS)):
        raise RuntimeError(f"the master returned {result.data.shape} samples, "
                           f"expected {(n + 1, len(COLUMNS))}")
    r0 = min(max(0, round(record_from / step)), n)
    return CarrierRecord(np.ascontiguousarray(result.data[r0:]), step)
