"""Names of the recorded columns that summaries and figures read: "instance.variable"
of the standard system (drive, rate, plant, observer)."""

from __future__ import annotations

from ..model.measurement import UNKNOWNS

#: The observer's output for an unknown whose name is not unknown + "_hat".
HAT = {"Omega_z": "Omega_hat"}
TRUE_RATE = "rate.Omega_z"


def estimate_column(name: str) -> str:
    """The observer's estimate of unknown `name`, e.g. observer.kxx_hat."""
    return f"observer.{HAT.get(name, name + '_hat')}"


def sigma_column(name: str) -> str:
    """The observer's reported 1-sigma of unknown `name`."""
    return f"observer.sigma_{name}"


#: What a summary of the observer reads: time, the true rate, each estimate and sigma.
OBSERVED = ("time", TRUE_RATE, *map(estimate_column, UNKNOWNS), *map(sigma_column, UNKNOWNS))
