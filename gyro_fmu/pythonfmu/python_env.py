"""Which Python an FMU runs with: the shared libpython, its home, the module folders.

The pythonfmu binaries do not link libpython; our loader (loader.py) records these at
build time and `gyro-fmu doctor` prints them as settings for another machine. One
search serves both (docs/fmi-notes.md says why each setting is needed).
"""

from __future__ import annotations

import os
import platform
import re
import shutil
import subprocess
import sys
import sysconfig
from collections.abc import Sequence
from dataclasses import dataclass
from importlib.util import find_spec
from pathlib import Path

#: Modules the shipped gyro_fmu package imports that are not in the FMU itself.
REQUIRED_MODULES: tuple[str, ...] = ("numpy", "scipy")


@dataclass(frozen=True)
class LibPython:
    """Where the shared libpython of this interpreter is, or why there is none."""

    path: Path | None
    shared_build: bool  #: sysconfig Py_ENABLE_SHARED (always True on Windows)
    tried: tuple[Path, ...]
    note: str


def find_libpython() -> LibPython:
    """Locate the libpython this interpreter was built with.

    INSTSONAME (the file the loader maps) before LDLIBRARY (a -dev symlink), in LIBDIR,
    the prefix's lib folder, LIBPL and the multiarch folders, then whatever the
    executable links to. Only a --enable-shared build's own library counts.
    """
    version = f"{sys.version_info.major}.{sys.version_info.minor}"
    if sys.platform == "win32":
        return _find_python_dll(version)
    cfg = sysconfig.get_config_var
    shared = bool(cfg("Py_ENABLE_SHARED"))
    abiflags = getattr(sys, "abiflags", "")
    names = [str(n) for n in (cfg("INSTSONAME"), cfg("LDLIBRARY"))
             if n and (".so" in str(n) or str(n).endswith(".dylib"))]
    names += [f"libpython{version}{abiflags}.so.1.0", f"libpython{version}{abiflags}.so",
              f"libpython{version}{abiflags}.dylib"]
    dirs = [Path(d) for d in (cfg("LIBDIR"), Path(sys.base_prefix) / "lib",
                              Path(sys.base_exec_prefix) / "lib", cfg("LIBPL")) if d]
    if cfg("MULTIARCH"):
        dirs += [Path("/usr/lib") / cfg("MULTIARCH"), Path("/lib") / cfg("MULTIARCH")]
    dirs += [Path("/usr/lib64"), Path("/usr/lib"), Path("/usr/local/lib")]
    tried = [d / n for d in dict.fromkeys(dirs) for n in dict.fromkeys(names)]
    found = next((c.resolve() for c in tried if c.is_file()), None)
    if found is None:
        found = _linked_libpython(Path(sys.executable))
    if found is not None and shared:
        return LibPython(found, True, tuple(tried), "this Python was built with --enable-shared")
    static = ("this Python was built without a shared libpython (Py_ENABLE_SHARED=0), so a "
              "non-Python host cannot use it. ")
    fix = ("Use a Python with a shared library: pyenv: `env PYTHON_CONFIGURE_OPTS=--enable-shared "
           f"pyenv install {platform.python_version()}`; Debian/Ubuntu: `apt install "
           f"libpython{version}` with the system python{version}; conda and python.org builds "
           "ship one in their lib folder. Then install numpy and scipy for that Python and "
           "run `gyro-fmu doctor` with it")
    if found is not None:  # a same-version libpython of another installation (e.g. Debian's)
        return LibPython(None, False, tuple(tried), static + f"{found} belongs to another "
                         "installation: usable only with that installation's PYTHONHOME and "
                         "numpy/scipy. " + fix)
    return LibPython(None, shared, tuple(tried), ("" if shared else static) +
                     "no shared libpython found. " + fix)


def _linked_libpython(executable: Path) -> Path | None:
    """The libpython the executable is dynamically linked to, per ldd (Linux only)."""
    ldd = shutil.which("ldd")
    if not ldd:
        return None
    try:
        out = subprocess.run([ldd, str(executable)], capture_output=True, text=True,
                             timeout=20).stdout
    except (OSError, subprocess.SubprocessError):
        return None
    match = re.search(r"(libpython\S+)\s+=>\s+(\S+)", out)
    return Path(match.group(2)).resolve() if match and Path(match.group(2)).is_file() else None


def _find_python_dll(version: str) -> LibPython:
    """On Windows the host needs python3X.dll (and python3.dll) on PATH."""
    dll = f"python{version.replace('.', '')}.dll"
    tried = [Path(sys.base_prefix) / dll, Path(sys._base_executable).parent / dll]  # type: ignore[attr-defined]
    for candidate in tried:
        if candidate.is_file():
            return LibPython(candidate, True, tuple(tried), "put its folder on PATH")
    return LibPython(None, True, tuple(tried), f"{dll} not found next to the base interpreter")


def python_home() -> str:
    """PYTHONHOME for the embedded interpreter: the base installation of this Python.

    ``prefix:exec_prefix`` when they differ (POSIX syntax). A venv has no
    standard library of its own, so the base prefix is right there too.
    """
    prefix, exec_prefix = sys.base_prefix, sys.base_exec_prefix
    return prefix if prefix == exec_prefix else f"{prefix}{os.pathsep}{exec_prefix}"


def required_paths(modules: Sequence[str] = REQUIRED_MODULES) -> tuple[list[str], list[str]]:
    """The sys.path folders that hold `modules`, and the modules not importable at all.

    Only these folders go on PYTHONPATH: a whole sys.path would also carry the
    current directory and this interpreter's stdlib, which PYTHONHOME provides.
    Note that .pth files (editable installs) are honoured only in site folders,
    not in PYTHONPATH entries; numpy and scipy need none.
    """
    folders: list[str] = []
    missing: list[str] = []
    for name in modules:
        spec = find_spec(name)
        if spec is None or not spec.origin:
            missing.append(name)
            continue
        origin = Path(spec.origin).resolve()
        top = origin.parent.parent if origin.name == "__init__.py" else origin.parent
        folders.append(str(top))
    return list(dict.fromkeys(folders)), missing

