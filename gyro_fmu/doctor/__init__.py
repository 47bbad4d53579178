"""`gyro-fmu doctor`: what a non-Python importer needs to load our FMUs, checked for real.

``environment`` finds the settings (libpython, PYTHONHOME, PYTHONPATH, glibc, compiler),
``host`` runs the compiled C host on an FMU, ``report`` puts both together.
"""

from .report import DoctorReport, doctor, main

__all__ = ["DoctorReport", "doctor", "main"]
