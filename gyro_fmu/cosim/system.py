"""The vocabulary of a co-simulation: components, connections, results, errors."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import GyroFmuError
from ..extras import require


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
    """Recorded signals: `data[:, j]` is column `columns[j]` ("time" first), `units` each
    signal's unit. As others hold a result: `to_records()` (fmpy's form), `to_pandas()`,
    `to_arrow()` (both with each column's unit), `write_csv(path)`."""

    columns: tuple[str, ...]
    data: np.ndarray
    units: dict[str, str]

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.data[:, self.columns.index(name)]
        except ValueError:
            raise KeyError(f"no recorded signal {name!r}; recorded: {list(self.columns)}") from None

    @property
    def column_units(self) -> dict[str, str]:
        """Every column's unit ("" for a signal declared without one), "time" in s."""
        return {c: "s" if c == "time" else self.units.get(c, "") for c in self.columns}

    def to_records(self) -> np.ndarray:
        """A structured array, one field per column ("time" first): fmpy's result form,
        what fmpy.util.write_csv and plot_result take."""
        out = np.empty(len(self.data), dtype=[(c, "f8") for c in self.columns])
        for j, c in enumerate(self.columns):
            out[c] = self.data[:, j]
        return out

    def to_pandas(self):
        """A pandas DataFrame, one column per signal, with df.attrs["units"] the units
        (pandas keeps attrs through DataFrame.to_parquet and read_parquet)."""
        pd = require("pandas", "pandas")
        df = pd.DataFrame(self.data, columns=list(self.columns), copy=True)
        df.attrs["units"] = self.column_units
        return df

    def to_arrow(self):
        """A pyarrow Table, each field's unit in its metadata ({"unit": ...}), as
        results.parquet keeps them."""
        pa = require("pyarrow", "parquet")
        units = self.column_units
        fields = [pa.field(c, pa.float64(), nullable=False, metadata={"unit": units[c]})
                  for c in self.columns]
        return pa.Table.from_arrays([pa.array(np.ascontiguousarray(self.data[:, j]))
                                     for j in range(len(self.columns))],
                                    schema=pa.schema(fields))

    def write_csv(self, path: Path) -> None:
        header = ",".join(self.columns)
        np.savetxt(path, self.data, delimiter=",", header=header, comments="", fmt="%.17g")
