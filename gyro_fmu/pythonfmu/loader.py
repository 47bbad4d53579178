"""Put a small C loader in front of pythonfmu's binary, so an FMU finds its own Python.

pythonfmu's binary starts an embedded interpreter but does not link libpython: a
non-Python host (a C program, OMSimulator, the `ecos` CLI) would need LD_PRELOAD,
PYTHONHOME and PYTHONPATH set by hand, and fails with `undefined symbol` or a segfault
without them. `install_loader` compiles `python_loader.c` with the system C compiler and
puts it in place of `binaries/linux64/<id>.so`; pythonfmu's binary stays in the FMU as
`<id>_pythonfmu.so`, and `resources/python_env.txt` records the Python that built the
FMU (libpython, home, the folders of numpy, scipy, numba). In a process that already
runs Python (fmpy, libcosimpy, ecospy) the loader loads nothing and forwards every call;
elsewhere it loads that Python first. Where it is gone, fmi2Instantiate logs what was
looked for and how to fix it, and returns NULL. The user's PYTHONHOME and PYTHONPATH,
and PYTHONFMU_LIBPYTHON, override the record. docs/fmi-notes.md has the measurements.
"""

from __future__ import annotations

import functools
import os
import shutil
import subprocess
import sys
import tempfile
import zipfile
from importlib.util import find_spec
from pathlib import Path
from xml.etree import ElementTree

from ..errors import GyroFmuError
from .python_env import REQUIRED_MODULES, find_libpython, python_home, required_paths

LOADER_SOURCE = Path(__file__).resolve().parent / "python_loader.c"
#: The loader's C files: the FMI functions (LOADER_SOURCE), its environment, their header.
LOADER_SOURCES = (LOADER_SOURCE, LOADER_SOURCE.with_name("python_loader_env.c"))
ENV_FILE = "resources/python_env.txt"
MARKER = b"@(#)pythonfmu-shim"


class LoaderUnavailableError(GyroFmuError, RuntimeError):
    """The loader cannot be built here (no C compiler, no shared libpython)."""


def real_binary_name(model_identifier: str) -> str:
    return f"binaries/linux64/{model_identifier}_pythonfmu.so"


def find_compiler() -> str | None:
    """The system C compiler: $CC, then cc, gcc, clang."""
    for name in (os.environ.get("CC"), "cc", "gcc", "clang"):
        if name:
            path = shutil.which(name)
            if path:
                return path
    return None


def fmi2_header_dir() -> Path | None:
    """The folder of fmi2FunctionTypes.h that fmpy ships (fmpy/c-code), if any."""
    spec = find_spec("fmpy")
    if spec is None or not spec.origin:
        return None
    folder = Path(spec.origin).parent / "c-code"
    return folder if (folder / "fmi2FunctionTypes.h").is_file() else None


def loader_binary() -> bytes:
    """The compiled loader, compiled once per process and version of its source."""
    files = (*LOADER_SOURCES, LOADER_SOURCE.with_name("python_loader.h"))
    return _loader_binary(tuple((p.stat().st_mtime_ns, p.stat().st_size) for p in files))


@functools.lru_cache(maxsize=1)
def _loader_binary(stats: tuple) -> bytes:
    with tempfile.TemporaryDirectory() as tmp:
        return compile_loader(Path(tmp)).read_bytes()


def compile_loader(dest_dir: Path) -> Path:
    """The loader compiled into dest_dir (references only GLIBC_2.2.5/2.3 symbols)."""
    cc = find_compiler()
    if not cc:
        raise LoaderUnavailableError("no C compiler (cc, gcc, clang or $CC)")
    headers = fmi2_header_dir()
    if headers is None:
        raise LoaderUnavailableError("fmpy's FMI 2.0 headers (fmpy/c-code) are missing")
    out = Path(dest_dir) / "python_loader.so"
    base = [cc, "-std=c99", "-shared", "-fPIC", "-O2", "-fvisibility=hidden",
            "-U_FORTIFY_SOURCE", "-fno-stack-protector", f"-I{headers}",
            "-o", str(out), *map(str, LOADER_SOURCES)]
    errors = ""
    # libdl.so.2 as NEEDED so that dlopen resolves on glibc < 2.34 too
    for libs in (["-Wl,--no-as-needed", "-l:libdl.so.2"], ["-ldl"]):
        proc = subprocess.run(base + libs, capture_output=True, text=True)
        if proc.returncode == 0:
            return out
        errors = proc.stderr
    raise LoaderUnavailableError(f"compiling {', '.join(p.name for p in LOADER_SOURCES)} "
                                 f"failed:\n{errors}")


def python_env_text() -> str:
    """resources/python_env.txt for this interpreter: key=value lines."""
    lib = find_libpython()
    if lib.path is None:
        raise LoaderUnavailableError(lib.note)
    folders, missing = required_paths(REQUIRED_MODULES)
    if missing:
        raise LoaderUnavailableError(f"{', '.join(missing)} not importable here")
    lines = ["# The Python this FMU was built with (gyro_fmu/pythonfmu/loader.py).",
             "# Overrides: PYTHONFMU_LIBPYTHON, PYTHONHOME (kept if set), PYTHONPATH (prepended).",
             f"python_version={sys.version_info.major}.{sys.version_info.minor}",
             f"python_executable={sys.executable}",
             f"libpython={lib.path}",
             f"pythonhome={python_home()}"]
    lines += [f"pythonpath={p}" for p in folders]
    return "\n".join(lines) + "\n"


def recorded_python(fmu: Path) -> dict[str, list[str]] | None:
    """What an FMU's loader will use (key -> values), or None for an FMU without one."""
    try:
        with zipfile.ZipFile(fmu) as z:
            text = z.read(ENV_FILE).decode("utf-8")
    except (KeyError, OSError, zipfile.BadZipFile):
        return None
    out: dict[str, list[str]] = {}
    for line in text.splitlines():
        if line and not line.startswith("#") and "=" in line:
            key, _, value = line.partition("=")
            out.setdefault(key, []).append(value)
    return out


def install_loader(fmu: Path) -> None:
    """Put the loader in front of pythonfmu's binary in `fmu` (in place, atomically)."""
    fmu = Path(fmu)
    text = python_env_text()
    loader = loader_binary()
    with zipfile.ZipFile(fmu) as z:
        ident = ElementTree.fromstring(z.read("modelDescription.xml")).find(
            "CoSimulation").get("modelIdentifier")
        front, real = f"binaries/linux64/{ident}.so", real_binary_name(ident)
        binary = z.read(front)
        if MARKER in binary:  # already has a loader: keep the real binary it has
            binary = z.read(real)
        stamp = z.getinfo(front).date_time
        fd, temp = tempfile.mkstemp(suffix=".fmu", dir=fmu.parent)  # same file system
        os.close(fd)
        rewritten = Path(temp)
        try:
            with zipfile.ZipFile(rewritten, "w", zipfile.ZIP_DEFLATED) as w:
                for info in z.infolist():
                    if info.filename not in (front, real, ENV_FILE):
                        w.writestr(info, z.read(info.filename))
                for member, data, mode in ((real, binary, 0o755), (front, loader, 0o755),
                                           (ENV_FILE, text.encode(), 0o644)):
                    info = zipfile.ZipInfo(member, date_time=stamp)
                    info.external_attr = (0o100000 | mode) << 16
                    info.compress_type = zipfile.ZIP_DEFLATED
                    w.writestr(info, data)
        except BaseException:
            rewritten.unlink(missing_ok=True)
            raise
    shutil.copymode(fmu, rewritten)  # mkstemp made it private
    os.replace(rewritten, fmu)
