"""argparse types of every `gyro-fmu` option: a number is parsed once, here, and refused
with the option's name (argparse: "argument --window: ...", exit 2) when it is no number,
not finite or outside the range the option can mean. Physics limits (a step against a
frequency, a window against memory) are the library's, checked where the value is used,
so that the Python API refuses them too."""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable

#: Largest seed of every generator: FMI 2.0 Integers are 32-bit signed (GyroPlant.fmu,
#: GyroResonator.fmu).
SEED_MAX = 2**31 - 1
#: Most steps a simulation may take (2^53: every step count exact in a double, far inside
#: the core's int64 clocks; 1.4 years at 5 us).
MAX_STEPS = 2**53


def number(low: float | None = None, high: float | None = None, *, low_open: bool = False,
           high_open: bool = False, what: str = "a number") -> Callable[[str], float]:
    """A finite float in [low, high] (an end excluded where low_open, high_open)."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
        if not math.isfinite(value):
            raise argparse.ArgumentTypeError(f"{text!r} is not finite: give {what}")
        if low is not None and (value <= low if low_open else value < low):
            raise argparse.ArgumentTypeError(
                f"{text} must be {'>' if low_open else '>='} {low:g}: give {what}")
        if high is not None and (value >= high if high_open else value > high):
            raise argparse.ArgumentTypeError(
                f"{text} must be {'<' if high_open else '<='} {high:g}: give {what}")
        return value

    parse.__name__ = what
    return parse


def whole(low: int | None = None, high: int | None = None,
          what: str = "a whole number") -> Callable[[str], int]:
    """An int in [low, high] ("1.5" and "1e3" are refused: no silent truncation)."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
        if (low is not None and value < low) or (high is not None and value > high):
            span = f"[{low if low is not None else '-inf'}, {high if high is not None else 'inf'}]"
            raise argparse.ArgumentTypeError(f"{value} is outside {span}: give {what}")
        return value

    parse.__name__ = what
    return parse


finite = number(what="a finite number")
positive = number(0.0, low_open=True, what="a finite number > 0")
non_negative = number(0.0, what="a finite number >= 0")
open_fraction = number(0.0, 1.0, low_open=True, high_open=True, what="a fraction in (0, 1)")
band = number(0.0, 1.0, low_open=True, high_open=True,
              what="a fraction in (0, 1) of each signal's range")
latitude = number(-90.0, 90.0, what="a latitude in [-90, 90] degrees")
count = whole(1, what="a whole number >= 1")
seed = whole(0, SEED_MAX, what=f"a seed in [0, {SEED_MAX}]")


def assignment(known: tuple[str, ...] | Callable[[], tuple[str, ...]] | None = None,
               example: str = "kxy=7.1e7", what: str = "a known name"
               ) -> Callable[[str], tuple[str, float]]:
    """The one parser of every repeatable `--option NAME=VALUE`: (name, value), the value
    a number, the name one of `known` when given (a callable is asked only when the
    option is used, so the parser imports nothing for it). `dict(args.option or ())`
    collects them, the last of a name winning."""

    def parse(text: str) -> tuple[str, float]:
        name, sep, value = text.partition("=")
        name = name.strip()
        if not sep:
            raise argparse.ArgumentTypeError(f"{text!r} must read NAME=VALUE, e.g. {example}")
        names = known() if callable(known) else known
        if names is not None and name not in names:
            raise argparse.ArgumentTypeError(f"{text!r}: {name!r} is not {what}; known: "
                                             f"{', '.join(names)}")
        try:
            return name, float(value)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r}: {value!r} is not a number") from None

    parse.__name__ = "NAME=VALUE"
    return parse
