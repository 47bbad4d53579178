"""What a non-Python importer of our FMUs needs from this machine, for `gyro-fmu doctor`.

The shared libpython to preload, ``PYTHONHOME``, the folders holding numpy and scipy
(``PYTHONPATH``), this machine's glibc and the glibc an FMU binary needs, the system C
compiler and the FMI 2.0 headers fmpy ships. The pythonfmu binaries do not link
libpython; why each setting is needed is in docs/fmi-notes.md.
"""

from __future__ import annotations

import os
import re
import site
from pathlib import Path

from ..pythonfmu.loader import find_compiler, fmi2_header_dir
from ..pythonfmu.python_env import (
    REQUIRED_MODULES,
    LibPython,
    find_libpython,
    python_home,
    required_paths,
)

__all__ = ["GLIBC_NEEDED", "REQUIRED_MODULES", "LibPython", "find_compiler", "find_libpython",
           "fmi2_header_dir", "glibc_required", "glibc_version", "python_home",
           "required_paths", "site_packages"]


#: Oldest glibc the pythonfmu 0.7.0 binary runs on (its newest GLIBC_ symbol version;
#: used when a binary names none, docs/fmi-notes.md).
GLIBC_NEEDED = (2, 32)















def site_packages() -> list[str]:
    """Every site-packages folder of this interpreter (venv and user site included)."""
    dirs = list(site.getsitepackages())
    if site.ENABLE_USER_SITE and Path(site.getusersitepackages()).is_dir():
        dirs.append(site.getusersitepackages())
    return dirs


def glibc_version() -> tuple[int, int] | None:
    """The glibc of this machine, or None (musl, macOS, Windows)."""
    try:
        text = os.confstr("CS_GNU_LIBC_VERSION") or ""
    except (AttributeError, ValueError, OSError):
        text = ""
    match = re.search(r"glibc (\d+)\.(\d+)", text)
    return (int(match.group(1)), int(match.group(2))) if match else None


def glibc_required(binary: bytes) -> tuple[int, int] | None:
    """The newest GLIBC_x.y symbol version an ELF binary references (its real need)."""
    versions = {(int(a), int(b)) for a, b in re.findall(rb"GLIBC_(\d+)\.(\d+)", binary)}
    return max(versions) if versions else None
