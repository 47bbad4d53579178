"""The units of every FMU variable, as FMI 2.0 <BaseUnit> exponents (used by slave.py)."""

#: SI base-unit exponents of every unit the FMUs use (FMI 2.0 <BaseUnit>).
UNITS: dict[str, dict[str, int]] = {
    "1": {},
    "m": {"m": 1},
    "m/s": {"m": 1, "s": -1},
    "m/s2": {"m": 1, "s": -2},
    "N": {"kg": 1, "m": 1, "s": -2},
    "kg": {"kg": 1},
    "s": {"s": 1},
    "Hz": {"s": -1},
    "1/s": {"s": -1},
    "1/s2": {"s": -2},
    "rad/s": {"rad": 1, "s": -1},
    "rad/s2": {"rad": 1, "s": -2},
    "rad/s3": {"rad": 1, "s": -3},
    "rad2/s": {"rad": 2, "s": -1},
    "rad2/s3": {"rad": 2, "s": -3},
    "rad2/s5": {"rad": 2, "s": -5},
    "rad": {"rad": 1},
    "V": {"kg": 1, "m": 2, "s": -3, "A": -1},
    "V/m": {"kg": 1, "m": 1, "s": -3, "A": -1},
    "m/V": {"kg": -1, "m": -1, "s": 3, "A": 1},
    "m/s2/V": {"kg": -1, "m": -1, "s": 1, "A": 1},
    "1/(m2.s2)": {"m": -2, "s": -2},
}
