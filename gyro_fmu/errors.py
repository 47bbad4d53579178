"""The one base of every error the library raises on purpose: `GyroFmuError`.

A `GyroFmuError` means the input, a file or an FMU is not usable, and its message
names the offending value and the remedy. The command line turns it (and OS errors
such as an unwritable folder) into one line on stderr and exit code 2; anything
else is a bug and keeps its traceback. Each subpackage derives its own errors from
it (ParameterError, CoSimulationError, ReferenceResultError, ...), so a caller can
catch all of them at once.
"""

from __future__ import annotations


class GyroFmuError(Exception):
    """An input, file or FMU gyro_fmu cannot use; the message says why and what to do."""
