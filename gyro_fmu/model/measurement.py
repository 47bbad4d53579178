"""What the observer is told and what it must find: the measured pair (eq. 6, claim 4)
and the 8 unknowns of the augmented state (eq. 5), defined once."""

from __future__ import annotations

from enum import IntEnum

from .parameters import PARAMETER_NAMES, PARAMETER_UNITS

#: The unknowns of the augmented state (eq. 5), in the order every estimate is reported.
UNKNOWNS: tuple[str, ...] = ("Omega_z", *PARAMETER_NAMES)

#: SI unit of each unknown.
UNKNOWN_UNITS: dict[str, str] = {"Omega_z": "rad/s", **PARAMETER_UNITS}


class MeasuredPair(IntEnum):
    """The two measured states of eq. 6: positions (x, y) or, by claim 4, velocities."""

    POSITIONS = 1
    VELOCITIES = 2

    @property
    def state_rows(self) -> tuple[int, int]:
        """Indices in the plant state [x, x', y, y'] of the two measured signals."""
        return (0, 2) if self is MeasuredPair.POSITIONS else (1, 3)

    @property
    def plant_outputs(self) -> tuple[str, str]:
        """GyroPlant's output names of the two measured signals."""
        return ("x", "y") if self is MeasuredPair.POSITIONS else ("vx", "vy")

    @classmethod
    def of(cls, value: object) -> MeasuredPair:
        """The pair for 1 or 2; anything else is refused with the remedy."""
        if isinstance(value, bool) or value not in (1, 2):
            raise ValueError(f"measured_pair={value!r} is invalid: use 1 for positions (x, y) "
                             "or 2 for velocities (vx, vy)")
        return cls(int(value))
