"""The optional parts of gyro_fmu: each behind a pip extra, imported where it is used.

The core (the FMUs, the master, `gyro-fmu run`, `validate`, `fmus`, reading results)
needs numpy, scipy and fmpy only. What needs more names its extra: `require(module,
extra)` imports a module of an extra, or raises `MissingExtraError` with the pip line that
installs it; `has(module)` asks without raising. EXTRAS (kept equal to pyproject.toml's
optional-dependencies by tests/test_extras.py) says what each brings and what for.
"""

from __future__ import annotations

import importlib
from types import ModuleType

from .errors import GyroFmuError

#: extra -> (the distributions it installs, what needs them).
EXTRAS: dict[str, tuple[str, str]] = {
    "figures": ("matplotlib", "the PNG figures"),
    "parquet": ("pyarrow", "results.parquet, and results.csv written 4.6x faster"),
    "pandas": ("pandas", "results as a pandas DataFrame"),
    "lots": ("dask[distributed]", "sweeps and lots on many cores or a cluster"),
    "ssp": ("libcosimpy", "running the SSP packages in libcosim"),
    "container": ("fmu-manipulation-toolbox", "the container FMU (gyro-fmu container)"),
    "pythonfmu": ("pythonfmu", "the pythonfmu flavour (gyro-fmu build --flavour pythonfmu)"),
    "ecos": ("ecospy, tbb", "running the SSP packages in Ecos"),
}


class MissingExtraError(GyroFmuError, ImportError):
    """A command needs a package of an extra that is not installed."""


def install_line(extra: str) -> str:
    """The pip line that installs an extra."""
    return f"pip install 'gyro_fmu[{extra}]'"


def require(module: str, extra: str, what: str | None = None) -> ModuleType:
    """`module` imported, or MissingExtraError naming what needs it and the pip line."""
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as exc:
        _reraise_unless_absent(exc, module)
        dists, purpose = EXTRAS[extra]
        raise MissingExtraError(f"{dists} is needed for {what or purpose} and is not "
                                f"installed here: {install_line(extra)} (or 'gyro_fmu[all]')"
                                ) from None


def has(module: str) -> bool:
    """Whether `module` can be imported (it is imported if it can)."""
    try:
        importlib.import_module(module)
    except ModuleNotFoundError as exc:
        _reraise_unless_absent(exc, module)
        return False
    return True


def _reraise_unless_absent(exc: ModuleNotFoundError, module: str) -> None:
    """Raise exc again unless it says `module`'s own package is absent (a package that is
    there but fails to import what it needs is a different error: say that one)."""
    if exc.name is None or exc.name.split(".")[0] != module.split(".")[0]:
        raise exc


def pyplot(what: str = "the figures") -> ModuleType:
    """matplotlib's pyplot on the Agg backend (files, no window), imported when a figure
    is drawn: a process that draws none does not pay its 0.24 s."""
    matplotlib = require("matplotlib", "figures", what)
    matplotlib.use("Agg")
    return importlib.import_module("matplotlib.pyplot")
