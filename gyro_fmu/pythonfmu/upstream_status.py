"""The slave's line to the C loader: the FMI status pythonfmu's binary cannot return.

pythonfmu 0.7.0 returns only fmi2OK, or fmi2Discard from fmi2DoStep, and answers
fmi2Terminated = true after any fmi2Discard (fmpy.simulate_fmu then ends a run
silently). The loader (python_loader.c) exports `pythonfmu_shim_report(call_status,
failed, why)`: during an FMI call on an instance the slave may raise that call's status
(fmi2Warning, fmi2Error) and say whether it can still step; the loader answers
fmi2Terminated from that. Without the loader (no C compiler at build time, or the slave
run outside an FMU) every report is a no-op.
"""

from __future__ import annotations

import ctypes
import os
from pathlib import Path

WARNING, ERROR = 1, 3  #: fmi2Warning, fmi2Error


class HostStatus:
    """Reports to the loader of this FMU, if it has one."""

    def __init__(self, resources: str | None, model_identifier: str) -> None:
        self._report = None
        if not resources:
            return
        platform = Path(resources).parent / "binaries" / "linux64"
        if not (platform / f"{model_identifier}_pythonfmu.so").is_file():
            return  # pythonfmu's binary alone: nothing to report to
        try:  # already loaded by the host: RTLD_NOLOAD never loads a second copy
            lib = ctypes.CDLL(str(platform / f"{model_identifier}.so"),
                              mode=os.RTLD_NOLOAD | os.RTLD_NOW)
            report = lib.pythonfmu_shim_report
        except (OSError, AttributeError):
            return  # an older loader without the function
        report.argtypes = (ctypes.c_int, ctypes.c_int, ctypes.c_char_p)
        report.restype = None
        self._report = report

    @property
    def connected(self) -> bool:
        return self._report is not None

    def report(self, call_status: int, failed: str | None) -> None:
        """Raise the running call's status to call_status (0: leave it); failed: why the
        instance can no longer step, or None when it can."""
        if self._report is not None:
            why = (failed or "").encode("utf-8", "replace")[:2000]
            self._report(call_status, failed is not None, why)


def host_library_mismatch(resources: Path) -> str | None:
    """Why the gyro_fmu running this FMU is not the one it ships, or None.

    Python caches modules per process: in a host that already imported gyro_fmu (our
    fmpy master, a user's script), every FMU runs the host's copy, not its own. Same
    version, same code; another version is a silent substitution worth a warning.
    """
    import re

    from .. import __file__ as running_file
    from .. import __version__ as running

    shipped = resources / "gyro_fmu" / "__init__.py"
    if not shipped.is_file() or Path(running_file).resolve() == shipped.resolve():
        return None
    match = re.search(r'__version__ = "([^"]+)"', shipped.read_text())
    if match is None or match.group(1) == running:
        return None
    return (f"this FMU ships gyro_fmu {match.group(1)}, but the host process had already "
            f"imported gyro_fmu {running} ({Path(running_file).parent}), which runs instead "
            f"(Python caches modules per process): install gyro_fmu {match.group(1)} in "
            f"the host, or rebuild the FMUs with {running}")
