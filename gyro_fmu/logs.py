"""What gyro_fmu says while it works goes through the standard `logging` module.

The library logs under "gyro_fmu.*" (`logging.getLogger(__name__)`) and configures
nothing: an application's own logging setup decides what shows. The command line runs
each command inside `command_logging(verbosity)`: -q shows warnings and errors only, the
default adds what the command is doing (info), -v adds debug lines (every FMU log
message of a co-simulation, the builds' details) and the other libraries' info. One
line each on stderr ("warning: ..." for a warning). The command's answer (its tables,
its verdict, the files it wrote) is printed on stdout and is no log line.
"""

from __future__ import annotations

import contextlib
import logging
import sys
from collections.abc import Iterator

#: The package's logger: the parent of every module's.
LOGGER = "gyro_fmu"
#: Libraries that log on a command's way (Dask's cluster, matplotlib's font cache, the
#: PNG writer, numba): at warning, at info with -v, at error with -q.
THIRD_PARTY = ("distributed", "dask", "matplotlib", "PIL", "numba", "tornado", "asyncio")


class _Lines(logging.Formatter):
    def format(self, record: logging.LogRecord) -> str:
        text = super().format(record)
        if record.levelno >= logging.ERROR:
            return f"error: {text}"
        if record.levelno >= logging.WARNING:
            return f"warning: {text}"
        if record.levelno < logging.INFO:
            return f"debug: {record.name}: {text}"
        return text


class _Stderr(logging.StreamHandler):
    """Writes to the sys.stderr of the moment (a test's capture, a redirected one)."""

    def emit(self, record: logging.LogRecord) -> None:
        self.stream = sys.stderr
        super().emit(record)


@contextlib.contextmanager
def command_logging(verbosity: int = 0) -> Iterator[None]:
    """Log lines on stderr while a command runs: verbosity -1 (-q), 0, or 1 (-v)."""
    ours = {-1: logging.WARNING, 0: logging.INFO}.get(verbosity, logging.DEBUG)
    others = {-1: logging.ERROR, 0: logging.WARNING}.get(verbosity, logging.INFO)
    handler = _Stderr()
    handler.setFormatter(_Lines("%(message)s"))
    package, root = logging.getLogger(LOGGER), logging.getLogger()
    saved = (package.level, root.level, [(n, logging.getLogger(n).level) for n in THIRD_PARTY])
    package.setLevel(ours)
    root.setLevel(others)
    for name in THIRD_PARTY:
        logging.getLogger(name).setLevel(others)
    root.addHandler(handler)
    try:
        yield
    finally:
        root.removeHandler(handler)
        package.setLevel(saved[0])
        root.setLevel(saved[1])
        for name, level in saved[2]:
            logging.getLogger(name).setLevel(level)


def quiet() -> bool:
    """Whether the package's logger was set above info (-q): progress bars follow it. A
    library user who configured nothing gets them, as before logging."""
    return logging.getLogger(LOGGER).level > logging.INFO
