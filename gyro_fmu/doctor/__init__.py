"""`gyro-fmu doctor`: whether a non-Python importer loads our FMUs, checked for real.

The native FMUs need nothing on the host; the pythonfmu flavour needs this Python.
``environment`` finds the settings that flavour needs (libpython, PYTHONHOME, PYTHONPATH,
glibc, compiler), ``host`` runs the compiled C host on an FMU, ``report`` puts both
together.
"""

from .report import DoctorReport, doctor, main

__all__ = ["DoctorReport", "doctor", "main"]
