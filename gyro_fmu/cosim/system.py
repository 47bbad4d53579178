"""The vocabulary of a co-simulation: components, connections, results, errors."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import GyroFmuError


class CoSimulationError(GyroFmuError, RuntimeError):
    """A co-simulation could not be set up or an FMU refused a step."""


class CoSimulationInterrupted(KeyboardInterrupt):
    """Ctrl-C stopped a co-simulation between steps; `result` holds every communication
    point simulated so far (None when it came before the first step)."""

    def __init__(self, message: str, result: CoSimulationResult | None = None) -> None:
        super().__init__(message)
        self.result = result


@dataclass(frozen=True)
class Component:
    """One FMU instance: a name used in connections, its file, parameter values, and
    values for inputs that no connection drives (set before initialization; an FMI 2.0
    input keeps the last value set, so they hold for the whole run)."""

    name: str
    fmu: Path
    parameters: Mapping[str, float | int] = field(default_factory=dict)
    inputs: Mapping[str, float | int] = field(default_factory=dict)


@dataclass(frozen=True)
class Connection:
    """Output `src` ("instance.variable") feeds input `dst` ("instance.variable")."""

    src: str
    dst: str

    @classmethod
    def parse(cls, text: str) -> Connection:
        """From 'drive.ux->plant.ux'."""
        try:
            src, dst = (s.strip() for s in text.split("->"))
        except ValueError:
            raise CoSimulationError(
                f"connection {text!r} must read 'instance.output->instance.input'"
            ) from None
        return cls(src, dst)


@dataclass(frozen=True)
class CoSimulationResult:
    """Recorded signals: `data[:, j]` is column `columns[j]` ("time" first)."""

    columns: tuple[str, ...]
    data: np.ndarray
    units: dict[str, str]

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.data[:, self.columns.index(name)]
        except ValueError:
            raise KeyError(f"no recorded signal {name!r}; recorded: {list(self.columns)}") from None

    def write_csv(self, path: Path) -> None:
        header = ",".join(self.columns)
        np.savetxt(path, self.data, delimiter=",", header=header, comments="", fmt="%.17g")
