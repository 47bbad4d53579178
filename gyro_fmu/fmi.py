"""Left for FMUs built with gyro_fmu 0.1: their slaves import ``gyro_fmu.fmi`` first.

In a host that has imported this gyro_fmu (Python caches modules per process, so such
an FMU runs the host's package, not its own), that import would fail deep in
pythonfmu's instantiate with a bare ModuleNotFoundError. This module turns it into a
message that names the cause and the remedy. Nothing imports it.
"""

from . import __version__

raise ImportError(
    f"this FMU was built with gyro_fmu 0.1, whose modules moved in 0.2; the host process "
    f"runs gyro_fmu {__version__}: rebuild the FMU (`gyro-fmu build`) or run it in a "
    f"process that has not imported gyro_fmu {__version__}"
)
