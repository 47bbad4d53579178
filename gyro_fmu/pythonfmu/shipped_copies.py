"""Many FMUs in one Python process, each with its own copy of gyro_fmu.

Every FMU ships the package in its resources folder. The first FMU a Python host loads
(fmpy's simulate_fmu, a user's own loop) imports gyro_fmu from that FMU's extracted
folder; the host may delete the folder when it is done with that FMU (simulate_fmu
does). The next FMU's slave then finds gyro_fmu in sys.modules, pointing to a folder
that is gone, and every submodule not yet imported failed to load: "Failed to
instantiate model" for GyroPlant.fmu after RateProfile.fmu in one process.

`install()` (run by gyro_fmu/__init__) appends a finder to sys.meta_path that the
import system asks only after its own finders failed: for gyro_fmu.X.Y it looks for
X/Y.py (or X/Y/__init__.py) in the gyro_fmu folder of every sys.path entry, which
holds the resources folder of the FMU being loaded. All copies are the same package
(each FMU of a build ships the same files); one module object per name and process.
"""

from __future__ import annotations

import importlib.abc
import importlib.util
import os
import sys


class _ShippedCopyFinder(importlib.abc.MetaPathFinder):
    """Finds gyro_fmu submodules in a living copy when the loaded package's folder is gone."""

    def find_spec(self, fullname, path=None, target=None):
        if not fullname.startswith("gyro_fmu."):
            return None
        parts = fullname.split(".")[1:]
        for entry in list(sys.path):
            base = os.path.join(entry or os.getcwd(), "gyro_fmu", *parts)
            for candidate, is_package in ((os.path.join(base, "__init__.py"), True),
                                          (base + ".py", False)):
                if os.path.isfile(candidate):
                    return importlib.util.spec_from_file_location(
                        fullname, candidate,
                        submodule_search_locations=[base] if is_package else None)
        return None


def install() -> None:
    """Append the finder once per process (idempotent)."""
    if not any(type(f).__name__ == "_ShippedCopyFinder" for f in sys.meta_path):
        sys.meta_path.append(_ShippedCopyFinder())
