"""A small master for the tests: one FMU (FMI 2.0 or 3.0) stepped through fmpy's
FMU2Slave / FMU3Slave with inputs set exactly (no interpolation), outputs read after every
step. Messages the FMU logs are collected."""

from __future__ import annotations

import shutil
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave


class NativeRun:
    """An instantiated FMU with its variables by name."""

    def __init__(self, fmu: Path, unzipdir: Path | None = None) -> None:
        self.md = read_model_description(str(fmu))
        self._own = unzipdir is None
        self.unzipdir = Path(unzipdir) if unzipdir else Path(extract(str(fmu)))
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.types = {v.name: v.type for v in self.md.modelVariables}
        self.messages: list[tuple[int, str]] = []
        self.version = int(float(self.md.fmiVersion))
        cls = FMU2Slave if self.version == 2 else FMU3Slave
        self.fmu = cls(guid=self.md.guid, unzipDirectory=str(self.unzipdir),
                       modelIdentifier=self.md.coSimulation.modelIdentifier,
                       instanceName="test")
        if self.version == 2:
            self.fmu.instantiate(loggingOn=True, callbacks=self._fmi2_callbacks())
        else:
            self.fmu.instantiate(loggingOn=True, logMessage=self._fmi3_logger())

    def _fmi2_callbacks(self):
        from fmpy.fmi2 import fmi2CallbackFunctions, fmi2CallbackLoggerTYPE

        def log(env, name, status, category, message):
            # the FMI 2.0 message is a format string: a formatting host shows %% and ## as
            # one character (the FMU escapes both; it passes no arguments)
            text = message.decode().replace("%%", "%").replace("##", "#")
            self.messages.append((status, text))

        cb = fmi2CallbackFunctions()
        self._logger = fmi2CallbackLoggerTYPE(log)
        cb.logger = self._logger
        from fmpy import calloc, free
        from fmpy.fmi2 import fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE

        cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        self._cb = cb
        return cb

    def _fmi3_logger(self):
        from fmpy.fmi3 import fmi3LogMessageCallback

        def log(env, status, category, message):
            self.messages.append((status, message.decode()))

        self._logger = fmi3LogMessageCallback(log)
        return self._logger

    # --- values by name ---
    def set(self, **values: float) -> None:
        for name, value in values.items():
            vr = [self.vr[name]]
            if self.types[name] in ("Integer", "Int32"):
                (self.fmu.setInteger if self.version == 2 else self.fmu.setInt32)(vr, [value])
            else:
                (self.fmu.setReal if self.version == 2 else self.fmu.setFloat64)(vr, [value])

    def get(self, names: list[str]) -> list[float]:
        vrs = [self.vr[n] for n in names]
        return list((self.fmu.getReal if self.version == 2 else self.fmu.getFloat64)(vrs))

    def initialize(self, start_time: float = 0.0, **parameters: float) -> None:
        self.set(**parameters)
        if self.version == 2:
            self.fmu.setupExperiment(startTime=start_time)
            self.fmu.enterInitializationMode()
        else:
            self.fmu.enterInitializationMode(startTime=start_time)
        self.fmu.exitInitializationMode()

    def run(self, steps: np.ndarray, outputs: list[str],
            inputs: Mapping[str, np.ndarray] | None = None, start_time: float = 0.0) -> np.ndarray:
        """Rows of `outputs` at start_time and after each step of `steps`; inputs[name][k]
        is held over step k."""
        inputs = inputs or {}
        rows = [self.get(outputs)]
        t = start_time
        for k, h in enumerate(steps):
            for name, column in inputs.items():
                self.set(**{name: float(column[k])})
            self.fmu.doStep(t, float(h))
            t += float(h)
            rows.append(self.get(outputs))
        return np.array(rows)

    def close(self) -> None:
        try:
            self.fmu.terminate()
        except Exception:
            pass
        self.fmu.freeInstance()
        if self._own:
            shutil.rmtree(self.unzipdir, ignore_errors=True)
